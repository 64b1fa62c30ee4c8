"""Numba kernels the energy ledger's forms are built from (:mod:`.ledger`).

Taylor series of the exact flow over a panel: how many terms a coordinate needs
(:func:`taylor_degree`), how a piece is cut into panels (:func:`panel_plan`), the inputs'
series (:func:`input_series`); the exact integrals of products of such polynomials
(``int_0^1 x^(a+b) dx = 1/(a+b+1)``: :func:`hilbert_dot`, :func:`damping_row`,
:func:`dense_row_sums`, and one modal row's series form, :func:`row_series`); and the
closed-form factors of a piece (:func:`piece_factors`, :func:`harmonic_factors`,
:func:`phi1_real`, :func:`phi1_ledger`). Separate from the forms because they share these
pieces: the series forms the degrees and polynomial integrals, the closed form the factors
(and the series of a row it cannot take in closed form), the event loop (:mod:`.event_loop`) the
factors of a piece. Conventions as in :mod:`.flow_eval`.
"""
from __future__ import annotations

import numpy as np

from . import kernel
from .flow_eval import _PHI1_SERIES, flow_factors, phis_from

#: Relative size of the first dropped term of each coordinate's Taylor series in
#: :func:`.ledger.ledger_taylor` (the Gauss rule of :func:`.ledger.ledger_panel` keeps its
#: error below about 1e-10).
TAYLOR_TOL = 1e-12
#: Largest ``|lambda| tau`` of one Taylor panel: longer pieces are cut into panels.
PANEL_RADIUS = 1.0
#: Series length: the degree that ``TAYLOR_TOL`` needs at ``PANEL_RADIUS``, plus one.
N_TERMS = 16


def _degree_radii(tol, n_terms):
    """``r2[m]``: the largest ``|z|^2`` at which degree ``m`` (at least 2) leaves a first
    dropped term ``2 |z|^(m-1)/(m+1)!`` below ``tol``.

    Beyond degree 2 the coefficients of a coordinate's series are ``c_m = c_2 2 z^(m-2)/m!``
    (the second derivative is ``lam y' + ws``, the third ``lam`` times the second), and
    ``c_2`` may be as large as the series' scale when the held input dominates (a piece of
    ``|z| = 5e-5`` near rest: a rule on ``|z|^(m+1)/(m+1)!`` alone kept degree 2 and lost
    5e-10 there).
    """
    r2 = np.zeros(n_terms)
    fact = 2.0
    for m in range(2, n_terms):
        fact *= m + 1
        r2[m] = (0.5 * tol * fact) ** (2.0 / (m - 1))
    return r2


_DEGREE_R2 = _degree_radii(TAYLOR_TOL, N_TERMS)
_INV = np.array([0.0] + [1.0 / m for m in range(1, N_TERMS + 1)])
#: ``1/(a + b + 1)``: the integral over [0, 1] of ``x^(a+b)``.
_HILBERT = 1.0 / np.arange(1.0, 2.0 * N_TERMS)


def taylor_degree_py(z2):
    """Degree (at least 2) of the series of a coordinate on ``x in [0, 1]`` for
    ``|z|^2 = z2``: the first dropped term is below ``TAYLOR_TOL`` of the series' scale
    (:func:`_degree_radii`)."""
    for m in range(2, N_TERMS - 1):
        if z2 <= _DEGREE_R2[m]:
            return m
    return N_TERMS - 1


taylor_degree = kernel(forceinline=True)(taylor_degree_py)


def panel_plan_py(lam_max, omegas, tau):
    """Panels of a piece of length ``tau`` (s): their number and width (s), no wider than
    ``PANEL_RADIUS / max(max|lam|, max|omega|)``, and the series degree of the harmonics."""
    w_top = 0.0
    for hh in range(omegas.size):
        w_top = max(w_top, abs(omegas[hh]))
    n_pan = int(np.ceil(max(lam_max, w_top) * tau / PANEL_RADIUS))
    if n_pan < 1:
        n_pan = 1
    width = tau / n_pan
    deg_h = taylor_degree(w_top * w_top * width * width) if omegas.size > 0 else 0
    return n_pan, width, deg_h


panel_plan = kernel(forceinline=True)(panel_plan_py)


def input_series_py(u0, us, amps, omegas, t0, s0, width, deg_u, deg_h, u_t):
    """``u_t[f, m]``: Taylor coefficients (in the panel's ``x = s/width``) of the inputs over a
    panel starting at ``s0`` (s) of a piece starting at ``t0 - s0`` (s): the held input and
    its slope, plus the harmonics (their series to degree ``deg_h``)."""
    for f in range(u0.size):
        u_t[f, 0] = u0[f] + us[f] * s0
        u_t[f, 1] = us[f] * width
        for m in range(2, deg_u + 1):
            u_t[f, m] = 0.0
    for hh in range(omegas.size):
        e = np.exp(1j * (omegas[hh] * t0))
        zh = 1j * (omegas[hh] * width)
        for f in range(u0.size):
            a = amps[hh, f] * e
            for m in range(deg_h + 1):
                u_t[f, m] += a.real
                a = a * zh * _INV[m + 1]


input_series = kernel(forceinline=True)(input_series_py)


def hilbert_dot_py(qd, i, di, b):
    """``int_0^1 qd_i(x) x^b dx`` of row ``i``'s polynomial (degree ``di``)."""
    x = 0.0
    for a in range(di + 1):
        x += qd[i, a] * _HILBERT[a + b]
    return x


hilbert_dot = kernel(forceinline=True)(hilbert_dot_py)


def damping_row_py(qd, Cmat, c_cols, c_counts, degs, n2, i, di, acc):
    """``int_0^1 qd_i (C qd)_i dx`` of the velocity polynomials ``qd`` (rows, by degree)."""
    dc = 0
    for c in range(c_counts[i]):
        dc = max(dc, degs[n2 + c_cols[i, c]])
    for b in range(dc + 1):
        x = 0.0
        for c in range(c_counts[i]):
            k2 = c_cols[i, c]
            x += Cmat[i, k2] * qd[k2, b]
        acc[i, b] = x
    total = 0.0
    for a in range(di + 1):
        x = 0.0
        for b in range(dc + 1):
            x += acc[i, b] * _HILBERT[a + b]
        total += qd[i, a] * x
    return total


damping_row = kernel(forceinline=True)(damping_row_py)


def dense_row_sums_py(cr, ci, vt, part, m, n, n2, out):
    """``out[m, i] = Re(sum_k R[i, k] c[k, m])`` for the rows ``R`` stored transposed as
    ``vt[part]`` (real) and ``vt[part + 1]`` (imaginary), the rows innermost."""
    for i in range(n):
        out[m, i] = 0.0
    for k in range(n2):
        a = cr[m, k]
        b = ci[m, k]
        for i in range(n):
            out[m, i] += vt[part, k, i] * a - vt[part + 1, k, i] * b


dense_row_sums = kernel(forceinline=True)(dense_row_sums_py)


def row_series_py(y0, lk, w0k, wsk, v, tau, g0, g1, qd):
    """Damping integral ``int_0^tau qd^2`` (m^2/s) and forcing integral
    ``int_0^tau qd (g0 + g1 s)`` (J per unit force scale) of one modal row
    ``qd = Re(v y)``, from the Taylor series of ``y' = lam y + w0 + ws s`` (``|lam| tau`` at
    most ``PANEL_RADIUS``): the series form of :func:`.ledger.ledger_modal`, for one row. ``qd``:
    work array of ``N_TERMS`` floats."""
    z = lk * tau
    deg = max(2, taylor_degree(z.real * z.real + z.imag * z.imag))
    c1 = tau * (lk * y0 + w0k)
    c2 = 0.5 * (z * c1 + (tau * tau) * wsk)
    qd[0] = (v * y0).real
    qd[1] = (v * c1).real
    c = c2
    for m in range(2, deg + 1):
        qd[m] = (v * c).real
        c = c * z * _INV[m + 1]
    damp = 0.0
    force = 0.0
    for a in range(deg + 1):
        x = 0.5 * qd[a] * _HILBERT[2 * a]
        for b in range(a + 1, deg + 1):
            x += qd[b] * _HILBERT[a + b]
        damp += 2.0 * qd[a] * x
        force += qd[a] * (g0 * _HILBERT[a] + g1 * tau * _HILBERT[a + 1])
    return tau * damp, tau * force


row_series = kernel(forceinline=True)(row_series_py)


def phi1_real_py(x):
    """``(e^x - 1)/x`` of a real ``x``, accurate near 0 (Horner below ``|x| = 0.2``)."""
    if x * x < 0.04:
        top = 13 if x * x > 1e-4 else (7 if x * x > 1e-10 else 3)
        a = _PHI1_SERIES[top]
        for k in range(top - 1, -1, -1):
            a = a * x + _PHI1_SERIES[k]
        return a
    return np.expm1(x) / x


phi1_real = kernel(forceinline=True)(phi1_real_py)


def phi1_ledger_py(z, ez):
    """``phi1(z)`` given ``ez = e^z``, for the ledger's harmonic cross terms: ``(ez - 1)/z``
    down to ``|z| = 0.01`` (rounding about ``eps/|z|``, 2e-14, well inside the ledger's
    1e-12), the short Horner chain of :func:`phis_from` below (degree 7 at most)."""
    r2 = z.real * z.real + z.imag * z.imag
    if r2 < 1e-4:
        return phis_from(z, ez)[0]
    return (ez - 1.0) * np.conj(z) * (1.0 / r2)   # complex division is several times slower


phi1_ledger = kernel(forceinline=True)(phi1_ledger_py)


def piece_factors_py(lam, tau, e_tau, p1_tau, p2_tau, m_tau):
    """Flow factors of a piece of length ``tau`` (s), per coordinate: ``exp(lam tau)`` (1),
    ``tau phi1(lam tau)`` (s), ``tau^2 phi2(lam tau)`` (s^2) and
    ``int_0^tau |e^(lam s)|^2 ds = tau phi1(2 Re(lam) tau)`` (s).

    One exponential per coordinate at ``|lam tau| >= 0.2``; below, none
    (:func:`.flow_eval.flow_factors`).
    """
    for k in range(lam.size):
        z = lam[k] * tau
        e, f1, f2 = flow_factors(z)
        e_tau[k] = e
        p1_tau[k] = tau * f1
        p2_tau[k] = tau * tau * f2
        m_tau[k] = tau * phi1_real(2.0 * z.real)


def harmonic_factors_py(omegas, t0, tau, harm):
    """Factors of the harmonics over a piece ``[t0, t0 + tau]`` (s), ``harm`` of shape
    ``(4 + 2 nh, nh)`` complex: ``e^(i omega t0)`` (1), ``e^(i omega tau)`` (1),
    ``int_0^tau e^(i omega s) ds`` (s), ``int_0^tau s e^(i omega s) ds`` (s^2), then the
    products ``int e^(i (omega_h + omega_g) s)`` and ``int e^(i (omega_h - omega_g) s)`` (s)."""
    nh = omegas.size
    for h in range(nh):
        harm[0, h] = np.exp(1j * (omegas[h] * t0))
        harm[1, h] = np.exp(1j * (omegas[h] * tau))
        f1, f2 = phis_from(1j * (omegas[h] * tau), harm[1, h])
        harm[2, h] = tau * f1
        harm[3, h] = tau * tau * (f1 - f2)
    for h in range(nh):
        for g in range(nh):
            f1, f2 = phis_from(1j * ((omegas[h] + omegas[g]) * tau), harm[1, h] * harm[1, g])
            harm[4 + h, g] = tau * f1
            f1, f2 = phis_from(1j * ((omegas[h] - omegas[g]) * tau),
                               harm[1, h] * np.conj(harm[1, g]))
            harm[4 + nh + h, g] = tau * f1


harmonic_factors = kernel(forceinline=True)(harmonic_factors_py)


piece_factors = kernel(forceinline=True)(piece_factors_py)
