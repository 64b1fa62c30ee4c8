"""Numba kernels of the energy ledger: damping, forcing and circulatory work (J).

The exact engine integrates the powers over each piece of a step from Taylor series of the
exact flow (:func:`ledger_taylor`, and :func:`ledger_modal` for modal coordinates), exactly
term by term. :func:`ledger_panel`, composite 4-point Gauss-Legendre on flow evaluations, is
the independent reference the tests hold them to. Conventions as in :mod:`.flow`.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from .flow import cabs, point_eval, propagate


def ledger_panel_py(yh, lam, W, w0, ws, part_plus, part_minus, omegas, amps, u0, us, t_cur,
                    tau, Vq, Vv, Cmat, Kskew, Bmat, yh_tau, y_tau, uder, yd, ledger):
    """Add damping dissipation, forcing work and circulatory work over ``[0, tau]`` (J).

    Composite 4-point Gauss-Legendre, with panels no wider than ``0.5/max|lambda|`` so the
    relative quadrature error stays below about 1e-10. Returns the number of flow
    evaluations (nodes).
    """
    if tau <= 0.0:
        return 0
    lam_max = 0.0
    for k in range(lam.size):
        lam_max = max(lam_max, cabs(lam[k]))
    n_panels = int(np.ceil(tau * lam_max / 0.5))
    if n_panels < 1:
        n_panels = 1
    xs = np.array([-0.8611363115940526, -0.3399810435848563, 0.3399810435848563,
                   0.8611363115940526])
    ws_g = np.array([0.3478548451374538, 0.6521451548625461, 0.6521451548625461,
                     0.3478548451374538])
    n = Vq.shape[0]
    q = np.empty(n)
    qd = np.empty(n)
    width = tau / n_panels
    for p in range(n_panels):
        mid = (p + 0.5) * width
        for g in range(4):
            s = mid + 0.5 * width * xs[g]
            point_eval(yh, lam, W, w0, ws, part_plus, part_minus, omegas, amps, u0, us, t_cur,
                       s, 0, yh_tau, y_tau, uder, yd)
            for i in range(n):
                aq = 0j
                av = 0j
                for k in range(lam.size):
                    aq += Vq[i, k] * y_tau[k]
                    av += Vv[i, k] * y_tau[k]
                q[i] = aq.real
                qd[i] = av.real
            p_damp = 0.0
            p_circ = 0.0
            p_force = 0.0
            for i in range(n):
                cq = 0.0
                kq = 0.0
                bu = 0.0
                for k2 in range(n):
                    cq += Cmat[i, k2] * qd[k2]
                    kq += Kskew[i, k2] * q[k2]
                for f in range(uder.shape[1]):
                    bu += Bmat[i, f] * uder[0, f]
                p_damp += qd[i] * cq
                p_circ -= qd[i] * kq
                p_force += qd[i] * bu
            wgt = 0.5 * width * ws_g[g]
            ledger[2] += wgt * p_damp
            ledger[3] += wgt * p_force
            ledger[4] += wgt * p_circ
    return 4 * n_panels


ledger_panel = njit(cache=True)(ledger_panel_py)



def row_pattern_py(V, cols, counts):
    """Column indices of the non-zero entries of each row of ``V`` (``cols[i, :counts[i]]``)."""
    for i in range(V.shape[0]):
        c = 0
        for k in range(V.shape[1]):
            if V[i, k] != 0:
                cols[i, c] = k
                c += 1
        counts[i] = c


row_pattern = njit(cache=True)(row_pattern_py)


#: Relative size of the first dropped term of each coordinate's Taylor series in
#: :func:`ledger_taylor` (the Gauss rule above keeps its error below about 1e-10).
TAYLOR_TOL = 1e-12
#: Largest ``|lambda| tau`` of one Taylor panel: longer pieces are cut into panels.
PANEL_RADIUS = 1.0
#: Series length: the degree that ``TAYLOR_TOL`` needs at ``PANEL_RADIUS``, plus one.
N_TERMS = 16


def _degree_radii(tol, n_terms):
    """``r2[m]``: the largest ``|z|^2`` at which degree ``m`` leaves a first dropped term
    ``|z|^(m+1)/(m+1)!`` below ``tol``."""
    r2 = np.empty(n_terms)
    fact = 1.0
    for m in range(n_terms):
        fact *= m + 1
        r2[m] = (tol * fact) ** (2.0 / (m + 1))
    return r2


_DEGREE_R2 = _degree_radii(TAYLOR_TOL, N_TERMS)
_INV = np.array([0.0] + [1.0 / m for m in range(1, N_TERMS + 1)])
#: ``1/(a + b + 1)``: the integral over [0, 1] of ``x^(a+b)``.
_HILBERT = 1.0 / np.arange(1.0, 2.0 * N_TERMS)


def taylor_degree_py(z2):
    """Degree of the series of ``exp(z x)`` on ``x in [0, 1]`` for ``|z|^2 = z2``: the first
    dropped term is below ``TAYLOR_TOL`` (relative)."""
    for m in range(N_TERMS - 1):
        if z2 <= _DEGREE_R2[m]:
            return m
    return N_TERMS - 1


taylor_degree = njit(cache=True, inline='always')(taylor_degree_py)


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


damping_row = njit(cache=True, inline='always')(damping_row_py)


def ledger_taylor_py(yh, lam, w0, ws, part_plus, part_minus, omegas, amps, u0, us, t_cur, tau,
                     lam_max, Vq, Vv, q_cols, q_counts, v_cols, v_counts, Cmat, c_cols,
                     c_counts, Kskew, circulatory, Bmat, coef, rows, u_t, degs, y0, ledger):
    """Add damping dissipation, forcing work and circulatory work over ``[0, tau]`` (J), from
    Taylor series of the exact flow integrated exactly.

    Between events every coordinate solves ``y' = lam y + w0 + ws s`` (plus harmonics), so
    its Taylor coefficients follow from one complex product each, with no exponential; the
    powers are then products of polynomials, integrated term by term
    (``int_0^1 x^(a+b) dx = 1/(a+b+1)``). Each coordinate keeps the terms its own
    ``|lam| tau`` needs: the first dropped one is below ``TAYLOR_TOL`` of the series' scale
    (slow modes need a few terms, the fastest one of HPOTP 13). A piece with
    ``max(|lam|, omega) tau`` above ``PANEL_RADIUS`` is cut into panels, each started from
    the exact flow.

    Parameters
    ----------
    yh, lam, w0, ws, part_plus, part_minus, omegas, amps, u0, us, t_cur
        The flow over the piece, as in :func:`.flow.point_eval` (state in modal units,
        ``lam`` in 1/s, ``omegas`` in rad/s, inputs in their SI units, ``t_cur`` in s).
    tau : float
        Length of the piece (s).
    lam_max : float
        ``max |lam|`` (1/s).
    Vq, Vv, q_cols, q_counts, v_cols, v_counts : ndarray
        Coordinates (m, rad) and velocities (m/s, rad/s) from the state, with the column
        pattern of their rows (:func:`row_pattern`).
    Cmat, c_cols, c_counts : ndarray
        Damping matrix (N s/m) and its row pattern.
    Kskew : ndarray
        Skew (circulatory) stiffness (N/m); used only if ``circulatory``.
    Bmat : ndarray
        Input matrix (force per unit input).
    coef, rows, u_t, degs, y0 : ndarray
        Work arrays: ``(n2, N_TERMS)`` complex, ``(3, n, N_TERMS)`` float,
        ``(nf, N_TERMS)`` float, ``n2 + n`` int, ``n2`` complex.
    ledger : ndarray
        Entries 2, 3, 4 receive damping (J), forcing (J) and circulatory (J) work.

    Returns
    -------
    int
        Panels used.
    """
    if tau <= 0.0:
        return 0
    n = Vq.shape[0]
    n2 = lam.size
    nf = u0.size
    nh = omegas.size
    w_top = 0.0
    for hh in range(nh):
        w_top = max(w_top, abs(omegas[hh]))
    n_pan = int(np.ceil(max(lam_max, w_top) * tau / PANEL_RADIUS))
    if n_pan < 1:
        n_pan = 1
    width = tau / n_pan
    deg_h = taylor_degree(w_top * w_top * width * width) if nh > 0 else 0
    deg_u = max(1, deg_h)
    qd = rows[0]
    q = rows[1]
    acc = rows[2]
    p_damp = 0.0
    p_force = 0.0
    p_circ = 0.0
    for p in range(n_pan):
        s0 = p * width
        if p == 0:
            for k in range(n2):
                y0[k] = yh[k]
        else:
            propagate(yh, lam, s0, w0, ws, y0)
        t0 = t_cur + s0
        # coef[k, m] = y_k^(m)(s0) width^m / m!, the forced part in closed form
        d_top = 2
        for k in range(n2):
            lk = lam[k]
            z = lk * width
            d = max(2, deg_h, taylor_degree(z.real * z.real + z.imag * z.imag))
            degs[k] = d
            d_top = max(d_top, d)
            c = y0[k]
            coef[k, 0] = c
            c = width * (lk * c + w0[k] + ws[k] * s0)
            coef[k, 1] = c
            c = 0.5 * (z * c + (width * width) * ws[k])
            coef[k, 2] = c
            for m in range(3, d + 1):
                c = c * z * _INV[m]
                coef[k, m] = c
        for k in range(n2):
            for m in range(degs[k] + 1, d_top + 1):
                coef[k, m] = 0.0
        for f in range(nf):
            u_t[f, 0] = u0[f] + us[f] * s0
            u_t[f, 1] = us[f] * width
            for m in range(2, deg_u + 1):
                u_t[f, m] = 0.0
        for hh in range(nh):
            e = np.exp(1j * (omegas[hh] * t0))
            zh = 1j * (omegas[hh] * width)
            for k in range(n2):
                a = part_plus[hh, k] * e
                b = part_minus[hh, k] * np.conj(e)
                for m in range(deg_h + 1):
                    coef[k, m] += a + b
                    a = a * zh * _INV[m + 1]
                    b = -b * zh * _INV[m + 1]
            for f in range(nf):
                a = amps[hh, f] * e
                for m in range(deg_h + 1):
                    u_t[f, m] += a.real
                    a = a * zh * _INV[m + 1]
        # velocity (and coordinate) polynomials of each row
        for i in range(n):
            d = 0
            for c in range(v_counts[i]):
                d = max(d, degs[v_cols[i, c]])
            degs[n2 + i] = d
            for m in range(d + 1):
                av = 0.0
                for c in range(v_counts[i]):
                    k = v_cols[i, c]
                    x = Vv[i, k] * coef[k, m]
                    av += x.real
                qd[i, m] = av
            for m in range(d + 1, d_top + 1):
                qd[i, m] = 0.0
            if circulatory:
                for m in range(d_top + 1):
                    aq = 0.0
                    for c in range(q_counts[i]):
                        k = q_cols[i, c]
                        x = Vq[i, k] * coef[k, m]
                        aq += x.real
                    q[i, m] = aq
        pd = 0.0
        pf = 0.0
        pc = 0.0
        for i in range(n):
            di = degs[n2 + i]
            if c_counts[i] == 1 and c_cols[i, 0] == i:
                # diagonal damping: the symmetric form qd_i' H qd_i, each pair once
                x = 0.0
                for a in range(di + 1):
                    qa = qd[i, a]
                    y = 0.5 * qa * _HILBERT[2 * a]
                    for b in range(a + 1, di + 1):
                        y += qd[i, b] * _HILBERT[a + b]
                    x += qa * y
                pd += 2.0 * Cmat[i, i] * x
            else:
                pd += damping_row(qd, Cmat, c_cols, c_counts, degs, n2, i, di, acc)
            for b in range(deg_u + 1):
                bu = 0.0
                for f in range(nf):
                    bu += Bmat[i, f] * u_t[f, b]
                x = 0.0
                for a in range(di + 1):
                    x += qd[i, a] * _HILBERT[a + b]
                pf += bu * x
            if circulatory:
                for b in range(d_top + 1):
                    kq = 0.0
                    for k2 in range(n):
                        kq += Kskew[i, k2] * q[k2, b]
                    x = 0.0
                    for a in range(di + 1):
                        x += qd[i, a] * _HILBERT[a + b]
                    pc -= kq * x
        p_damp += width * pd
        p_force += width * pf
        p_circ += width * pc
    ledger[2] += p_damp
    ledger[3] += p_force
    ledger[4] += p_circ
    return n_pan


ledger_taylor = njit(cache=True)(ledger_taylor_py)


def ledger_modal_py(yh, lam, w0, ws, part_plus, part_minus, omegas, amps, u0, us, t_cur, tau,
                    lam_max, Vv, v_cols, Cmat, Bmat, soa, u_t, y0, ledger):
    """:func:`ledger_taylor` for modal coordinates: each velocity row reads one state
    coordinate (``v_cols[i, 0]``), the damping is diagonal and there is no skew stiffness.

    The same series and exact integration, laid out mode by mode (``soa[part, degree, row]``)
    so that the rows are independent chains the compiler vectorizes, all rows to the degree
    of the fastest one. Work arrays: ``soa`` ``(3, N_TERMS + 8, n)`` float, ``u_t``
    ``(nf, N_TERMS)`` float, ``y0`` ``n2`` complex. Returns the panels used.
    """
    if tau <= 0.0:
        return 0
    n = Vv.shape[0]
    nf = u0.size
    nh = omegas.size
    w_top = 0.0
    for hh in range(nh):
        w_top = max(w_top, abs(omegas[hh]))
    n_pan = int(np.ceil(max(lam_max, w_top) * tau / PANEL_RADIUS))
    if n_pan < 1:
        n_pan = 1
    width = tau / n_pan
    deg_h = taylor_degree(w_top * w_top * width * width) if nh > 0 else 0
    deg = max(2, deg_h, taylor_degree(lam_max * lam_max * width * width))
    deg_u = max(1, deg_h)
    cr = soa[0]
    ci = soa[1]
    qd = soa[2]
    # per-row vectors after the series rows
    zr = soa[0, N_TERMS]
    zi = soa[0, N_TERMS + 1]
    vr = soa[0, N_TERMS + 2]
    vi = soa[0, N_TERMS + 3]
    acc_d = soa[0, N_TERMS + 4]
    acc_f = soa[0, N_TERMS + 5]
    part = soa[0, N_TERMS + 6]
    bu = soa[0, N_TERMS + 7]
    for i in range(n):
        k = v_cols[i, 0]
        vr[i] = Vv[i, k].real
        vi[i] = Vv[i, k].imag
        acc_d[i] = 0.0
        acc_f[i] = 0.0
    for p in range(n_pan):
        s0 = p * width
        if p == 0:
            for k in range(lam.size):
                y0[k] = yh[k]
        else:
            propagate(yh, lam, s0, w0, ws, y0)
        t0 = t_cur + s0
        for i in range(n):
            k = v_cols[i, 0]
            lk = lam[k]
            z = lk * width
            zr[i] = z.real
            zi[i] = z.imag
            c = y0[k]
            cr[0, i] = c.real
            ci[0, i] = c.imag
            c = width * (lk * c + w0[k] + ws[k] * s0)
            cr[1, i] = c.real
            ci[1, i] = c.imag
            c = 0.5 * (z * c + (width * width) * ws[k])
            cr[2, i] = c.real
            ci[2, i] = c.imag
        for m in range(3, deg + 1):
            inv = _INV[m]
            for i in range(n):
                ar = cr[m - 1, i]
                ai = ci[m - 1, i]
                cr[m, i] = (ar * zr[i] - ai * zi[i]) * inv
                ci[m, i] = (ar * zi[i] + ai * zr[i]) * inv
        for f in range(nf):
            u_t[f, 0] = u0[f] + us[f] * s0
            u_t[f, 1] = us[f] * width
            for m in range(2, deg_u + 1):
                u_t[f, m] = 0.0
        for hh in range(nh):
            e = np.exp(1j * (omegas[hh] * t0))
            zh = 1j * (omegas[hh] * width)
            for i in range(n):
                k = v_cols[i, 0]
                a = part_plus[hh, k] * e
                b = part_minus[hh, k] * np.conj(e)
                for m in range(deg_h + 1):
                    c = a + b
                    cr[m, i] += c.real
                    ci[m, i] += c.imag
                    a = a * zh * _INV[m + 1]
                    b = -b * zh * _INV[m + 1]
            for f in range(nf):
                a = amps[hh, f] * e
                for m in range(deg_h + 1):
                    u_t[f, m] += a.real
                    a = a * zh * _INV[m + 1]
        for m in range(deg + 1):
            for i in range(n):
                qd[m, i] = vr[i] * cr[m, i] - vi[i] * ci[m, i]
        # damping: qd_i' H qd_i, each pair of degrees once (H[a, b] = 1/(a+b+1))
        for a in range(deg + 1):
            h_aa = 0.5 * _HILBERT[2 * a]
            for i in range(n):
                part[i] = h_aa * qd[a, i]
            for b in range(a + 1, deg + 1):
                h_ab = _HILBERT[a + b]
                for i in range(n):
                    part[i] += h_ab * qd[b, i]
            for i in range(n):
                acc_d[i] += 2.0 * width * qd[a, i] * part[i]
        # forcing: qd_i (B u)_i
        for b in range(deg_u + 1):
            for i in range(n):
                x = 0.0
                for f in range(nf):
                    x += Bmat[i, f] * u_t[f, b]
                bu[i] = x
            for a in range(deg + 1):
                h_ab = width * _HILBERT[a + b]
                for i in range(n):
                    acc_f[i] += h_ab * qd[a, i] * bu[i]
    p_damp = 0.0
    p_force = 0.0
    for i in range(n):
        p_damp += Cmat[i, i] * acc_d[i]
        p_force += acc_f[i]
    ledger[2] += p_damp
    ledger[3] += p_force
    return n_pan


ledger_modal = njit(cache=True)(ledger_modal_py)

