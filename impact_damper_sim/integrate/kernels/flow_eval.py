"""Numba kernels that evaluate the exact modal flow and bound it.

Conventions (every kernel in this package): float64 and complex128 arrays only, no Python
objects; times in seconds; ``y`` is the complex first-order modal state of
:mod:`impact_damper_sim.integrate.flow` (``[q; q'] = Re(V y)``), ``yh`` its homogeneous-plus-
first-order-hold part and the harmonic particular part is added on top; arrays passed in are
updated in place. Every kernel is written as plain Python/NumPy (``*_py``, its NumPy twin) and
compiled by :func:`.kernel`; tests run both.
"""
from __future__ import annotations

import math

import numpy as np

from . import kernel


def cabs_py(z):
    """``|z|`` of a complex number without glibc's ``hypot`` (several times slower here)."""
    return np.sqrt(z.real * z.real + z.imag * z.imag)


cabs = kernel(forceinline=True)(cabs_py)


#: Taylor coefficients of phi1: 1/(k+1)!, k = 0..13 (the ledger's real phi1)
_PHI1_SERIES = np.array([1.0 / math.factorial(k + 1) for k in range(14)])
#: Taylor coefficients of phi2: 1/(k+2)!, k = 0..11
_PHI2_SERIES = np.array([1.0 / math.factorial(k + 2) for k in range(12)])
#: Largest |z|^2 at which degree 3, 5, 7, 9, 11 of the phi2 series leaves a first dropped
#: term below 1e-17 of it (the terms are |z|^(d+1)/(d+3)! against 1/2)
_PHI2_R2 = np.array([(0.5e-17 * math.factorial(d + 3)) ** (2.0 / (d + 1))
                     for d in (3, 5, 7, 9, 11)])


def phis_from_py(z, ez):
    """``(phi1(z), phi2(z))`` of a complex ``z`` given ``ez = e^z``: below ``|z| = 0.2`` one
    Horner chain for ``phi2`` of the degree ``|z|`` needs (3 to 11; ``ez`` unused), then
    ``phi1 = 1 + z phi2``, which cancels nothing there; above, from ``ez``."""
    r2 = z.real * z.real + z.imag * z.imag
    if r2 < 0.04:
        top = 11
        for j in range(5):
            if r2 <= _PHI2_R2[j]:
                top = 3 + 2 * j
                break
        f2 = _PHI2_SERIES[top] + 0j
        for m in range(top - 1, -1, -1):
            f2 = f2 * z + _PHI2_SERIES[m]
        return 1.0 + z * f2, f2
    # 1/z by real arithmetic: complex division is several times slower
    inv = np.conj(z) * (1.0 / r2)
    f1 = (ez - 1.0) * inv
    return f1, (f1 - 1.0) * inv


phis_from = kernel(forceinline=True)(phis_from_py)


def flow_factors_py(z):
    """``(e^z, phi1(z), phi2(z))`` of a complex ``z``: below ``|z| = 0.2`` no exponential
    (:func:`phis_from`, then ``e^z = 1 + z phi1``: one Horner chain for all three)."""
    if z.real * z.real + z.imag * z.imag < 0.04:
        f1, f2 = phis_from(z, 0j)
        return 1.0 + z * f1, f1, f2
    ez = np.exp(z)
    f1, f2 = phis_from(z, ez)
    return ez, f1, f2


flow_factors = kernel(forceinline=True)(flow_factors_py)



def propagate_py(yh, lam, tau, w0, ws, out):
    """Homogeneous-plus-first-order-hold flow over ``tau`` (s): ``out = yh(tau)``.

    ``yh' = lam yh + w0 + ws t`` exactly, for ``t`` in ``[0, tau]``.
    """
    if tau == 0.0:
        for k in range(lam.size):
            out[k] = yh[k]
        return
    for k in range(lam.size):
        ez, f1, f2 = flow_factors(lam[k] * tau)
        out[k] = ez * yh[k] + tau * (f1 * w0[k] + tau * f2 * ws[k])


propagate = kernel(forceinline=True)(propagate_py)


def step_factors_py(lam, h, e_h, p1_h, p2_h):
    """Factors of the flow over a full step ``h`` (s): ``exp(lam h)``, ``h phi1``, ``h^2 phi2``."""
    for k in range(lam.size):
        e_h[k], f1, f2 = flow_factors(lam[k] * h)
        p1_h[k] = h * f1
        p2_h[k] = h * h * f2


step_factors = kernel()(step_factors_py)


def add_particular_py(yh, omegas, part_plus, part_minus, t, out):
    """``out = yh + y_p(t)``: add the harmonic particular solution at absolute time ``t``."""
    for k in range(yh.size):
        out[k] = yh[k]
    for h in range(omegas.size):
        ep = np.exp(1j * omegas[h] * t)
        em = np.conj(ep)
        for k in range(yh.size):
            out[k] += part_plus[h, k] * ep + part_minus[h, k] * em


add_particular = kernel(forceinline=True)(add_particular_py)


def input_derivs_py(u0, us, omegas, amps, t, tau, order, out):
    """Inputs and time derivatives at ``t``: ``out[j] = d^j u / dt^j`` for ``j <= order``.

    ``u = u0 + us tau + Re(sum_h amps[h] exp(i omegas[h] t))``.
    """
    nf = u0.size
    for j in range(order + 1):
        for f in range(nf):
            out[j, f] = 0.0
    for f in range(nf):
        out[0, f] = u0[f] + us[f] * tau
        if order >= 1:
            out[1, f] = us[f]
    for h in range(omegas.size):
        e = np.exp(1j * omegas[h] * t)
        fac = 1.0 + 0j
        for j in range(order + 1):
            for f in range(nf):
                out[j, f] += (fac * amps[h, f] * e).real
            fac *= 1j * omegas[h]


input_derivs = kernel(forceinline=True)(input_derivs_py)


def state_derivs_py(y, lam, W, uder, order, out):
    """``out[m] = d^m y / dt^m`` for ``m <= order`` from ``y' = lam y + W u``."""
    for k in range(y.size):
        out[0, k] = y[k]
    more_derivs(lam, W, uder, 0, order, out)


def more_derivs_py(lam, W, uder, m_from, order, out):
    """Extend ``out[m] = d^m y / dt^m`` from ``m_from`` (filled) up to ``order``."""
    n2 = lam.size
    nf = W.shape[1]
    for m in range(m_from + 1, order + 1):
        forced = False
        for f in range(nf):
            if uder[m - 1, f] != 0.0:
                forced = True
        for k in range(n2):
            acc = lam[k] * out[m - 1, k]
            if forced:
                # complex times real by real parts: a complex product would multiply by 0j
                acc_r = 0.0
                acc_i = 0.0
                for f in range(nf):
                    acc_r += W[k, f].real * uder[m - 1, f]
                    acc_i += W[k, f].imag * uder[m - 1, f]
                acc += complex(acc_r, acc_i)
            out[m, k] = acc


more_derivs = kernel(forceinline=True)(more_derivs_py)


state_derivs = kernel(forceinline=True)(state_derivs_py)


def input_bounds_py(u_abs, us_abs, omegas, amps, order, ub):
    """``ub[j, f]`` (j <= order) bounds ``|d^j u_f/dt^j|``: the held input ``u_abs``, its slope
    ``us_abs``, plus each harmonic's amplitude times ``Omega^j``."""
    nf = ub.shape[1]
    for j in range(order + 1):
        for f in range(nf):
            ub[j, f] = 0.0
    for f in range(nf):
        ub[0, f] = u_abs[f]
        if order >= 1:
            ub[1, f] = us_abs[f]
    for h in range(omegas.size):
        for f in range(nf):
            a = cabs(amps[h, f])
            p = 1.0
            for j in range(order + 1):
                ub[j, f] += a * p
                p *= omegas[h]


input_bounds = kernel(forceinline=True)(input_bounds_py)


def derivative_chain_py(b, lam_abs, W, k, ub, order, u_orders, wu, out):
    """``out[m, k]`` (m <= order) from the bound ``b`` on ``|y_k|`` and ``ub`` on the inputs:
    ``B_m = |lam| B_(m-1) + |W u^(m-1)|_k``, ``B_0 = b``; ``wu`` is scratch. Only the first
    ``u_orders`` rows of ``ub`` may be nonzero (:func:`input_orders`)."""
    for j in range(order + 1):
        wu[j] = 0.0
    for f in range(W.shape[1]):
        w_abs = cabs(W[k, f])
        for j in range(u_orders):
            wu[j] += w_abs * ub[j, f]
    acc = b
    out[0, k] = acc
    for m in range(1, order + 1):
        acc = lam_abs * acc + wu[m - 1]
        out[m, k] = acc


derivative_chain = kernel(forceinline=True)(derivative_chain_py)


def input_orders_py(omegas, order):
    """Rows of :func:`input_bounds` that may be nonzero: all ``order + 1`` with harmonics; the
    held input and its slope without (a held input is linear, so its higher derivatives are
    zero and the bounds' sums over them would add zeros)."""
    return order + 1 if omegas.size > 0 else min(order + 1, 2)


input_orders = kernel(forceinline=True)(input_orders_py)


def derivative_bounds_py(yh, lam, W, part_plus, part_minus, w0, ws, tau, Th, u_abs, us_abs,
                         omegas, amps, order, ub, wu, out):
    """Bounds on ``|d^m y_k/dt^m|`` over ``[tau, Th]`` (s) for ``m <= order``.

    ``yh`` is the homogeneous-plus-hold part at ``tau``; the held input term is
    ``W u = w0 + ws t``; ``u_abs``/``us_abs`` bound the held inputs and their slope; ``ub`` and
    ``wu`` are scratch arrays. With ``T = Th - tau`` the bound on ``|yh_k|`` is
    ``exp(max(Re lam_k, 0) T) (|yh_k| + T max|W u|_k)``, and
    ``|y^(m)| <= |lam|^m |y| + sum_j |lam|^(m-1-j) |W u^(j)|``.
    """
    T = Th - tau
    input_bounds(u_abs, us_abs, omegas, amps, order, ub)
    u_orders = input_orders(omegas, order)
    for k in range(lam.size):
        grow = np.exp(lam[k].real * T) if lam[k].real > 0.0 else 1.0  # exp is the cost here
        b = grow * (cabs(yh[k]) + T * max(cabs(w0[k] + ws[k] * tau), cabs(w0[k] + ws[k] * Th)))
        for h in range(omegas.size):
            b += cabs(part_plus[h, k]) + cabs(part_minus[h, k])
        derivative_chain(b, cabs(lam[k]), W, k, ub, order, u_orders, wu, out)


derivative_bounds = kernel()(derivative_bounds_py)


def point_eval_py(yh, lam, W, w0, ws, part_plus, part_minus, omegas, amps, u0, us,
                  t_cur, tau, order, yh_tau, y_tau, uder, yd):
    """State ``y`` and derivatives ``yd[m]`` (m <= order) at ``t_cur + tau``.

    ``w0``/``ws`` are ``W u0``/``W us`` of the held inputs at ``t_cur``; ``yh_tau`` receives the
    homogeneous-plus-hold part, ``y_tau`` the full state.
    """
    propagate(yh, lam, tau, w0, ws, yh_tau)
    add_particular(yh_tau, omegas, part_plus, part_minus, t_cur + tau, y_tau)
    input_derivs(u0, us, omegas, amps, t_cur + tau, tau, order, uder)
    state_derivs(y_tau, lam, W, uder, order, yd)


point_eval = kernel()(point_eval_py)


def row_derivs_py(rows, n_rows, yd, order, out):
    """``out[m, r] = Re(rows[r] . yd[m])``: housing kinematics (m, m/s, m/s^2, ...)."""
    n2 = yd.shape[1]
    for m in range(order + 1):
        for r in range(n_rows):
            acc = 0j
            for k in range(n2):
                acc += rows[r, k] * yd[m, k]
            out[m, r] = acc.real


row_derivs = kernel(forceinline=True)(row_derivs_py)


def row_bound_py(rows, n_rows, ybound, m):
    """Bound of ``|d^m x_r/dt^m|`` per row from per-coordinate bounds; returns the 2-norm."""
    total = 0.0
    for r in range(n_rows):
        acc = 0.0
        for k in range(ybound.shape[1]):
            acc += cabs(rows[r, k]) * ybound[m, k]
        total += acc * acc
    return np.sqrt(total)


row_bound = kernel()(row_bound_py)


def site_bounds_py(abs_rows, n_rows, ybound, order, exc, Eb):
    """Bounds of a housing site from per-coordinate bounds, with its rows' moduli ``abs_rows``.

    ``Eb[m]`` (m <= order) bounds ``|d^m x/dt^m|`` (2-norm over the rows) from
    ``ybound[m]``; returns the largest excursion of the housing from the ``exc`` bounds of
    :func:`excursion_bounds` (m).
    """
    for m in range(order + 1):
        total = 0.0
        for r in range(n_rows):
            acc = 0.0
            for k in range(abs_rows.shape[1]):
                acc += abs_rows[r, k] * ybound[m, k]
            total += acc * acc
        Eb[m] = np.sqrt(total)
    return site_reach(abs_rows, n_rows, exc)


def site_reach_py(abs_rows, n_rows, exc):
    """Largest excursion (m, 2-norm over the rows) of a housing site whose coordinates move by
    at most ``exc`` (:func:`excursion_bounds`), with its rows' moduli ``abs_rows``."""
    reach = 0.0
    for r in range(n_rows):
        acc = 0.0
        for k in range(abs_rows.shape[1]):
            acc += abs_rows[r, k] * exc[k]
        reach += acc * acc
    return np.sqrt(reach)


site_reach = kernel(forceinline=True)(site_reach_py)
site_bounds = kernel()(site_bounds_py)


def housing_velocity_py(yh, lam, W, w0, ws, part_plus, part_minus, omegas, amps, u0, us, t,
                        rows, n_rows, yh_tau, y_tau, uder, yd, X):
    """Housing displacement and velocity rows at ``t`` from the current state into ``X``."""
    point_eval(yh, lam, W, w0, ws, part_plus, part_minus, omegas, amps, u0, us, t, 0.0, 1,
               yh_tau, y_tau, uder, yd)
    row_derivs(rows, n_rows, yd, 1, X)


housing_velocity = kernel()(housing_velocity_py)


def excursion_bounds_py(yh, lam, w0, ws, part_plus, part_minus, omegas, T, out):
    """Bound on ``|y_k(t) - y_k(0)|`` over ``[0, T]`` (s), into ``out``.

    Homogeneous part: ``|exp(lam t) - 1| <= min(|lam| t, 2) exp(max(Re lam, 0) t)``; held
    inputs add at most ``T max|W u|``; each harmonic's particular part moves by at most
    ``min(Omega T, 2)`` times its size. Much tighter than ``|y| + |y(0)|`` for short steps,
    since the transient and particular parts of ``y`` may cancel.
    """
    for k in range(lam.size):
        grow = np.exp(lam[k].real * T) if lam[k].real > 0.0 else 1.0  # exp is the cost here
        held = T * max(cabs(w0[k]), cabs(w0[k] + ws[k] * T))
        b = grow * (cabs(yh[k]) * min(cabs(lam[k]) * T, 2.0) + held)
        for h in range(omegas.size):
            b += (cabs(part_plus[h, k]) + cabs(part_minus[h, k])) * min(omegas[h] * T, 2.0)
        out[k] = b


excursion_bounds = kernel()(excursion_bounds_py)


def search_bounds_py(yh, lam, W, part_plus, part_minus, w0, ws, S, u_abs, us_abs, omegas,
                     amps, order, ub, wu, out, exc):
    """:func:`derivative_bounds` over ``[0, S]`` (s) into ``out`` and :func:`excursion_bounds`
    over ``S`` into ``exc`` in one pass, with the same values: the moduli and growth factors
    both need are taken once (an event search needs both, and square roots are its cost)."""
    input_bounds(u_abs, us_abs, omegas, amps, order, ub)
    u_orders = input_orders(omegas, order)
    for k in range(lam.size):
        grow = np.exp(lam[k].real * S) if lam[k].real > 0.0 else 1.0
        held = S * max(cabs(w0[k]), cabs(w0[k] + ws[k] * S))
        y_abs = cabs(yh[k])
        lam_abs = cabs(lam[k])
        b = grow * (y_abs + held)
        e = grow * (y_abs * min(lam_abs * S, 2.0) + held)
        for h in range(omegas.size):
            part = cabs(part_plus[h, k]) + cabs(part_minus[h, k])
            b += part
            e += part * min(omegas[h] * S, 2.0)
        exc[k] = e
        derivative_chain(b, lam_abs, W, k, ub, order, u_orders, wu, out)


search_bounds = kernel()(search_bounds_py)
