"""Numba kernels of the energy ledger: damping, forcing and circulatory work (J).

The exact engine integrates the powers over each piece of a step exactly: in closed form
where each velocity row reads one modal coordinate (:func:`ledger_closed`: exponential
integrals of the piece's flow factors, held inputs and harmonics), otherwise term by term on
Taylor series of the exact flow (:func:`ledger_modal` for diagonal damping, rows innermost;
:func:`ledger_taylor` in general). :func:`ledger_panel`, composite 4-point Gauss-Legendre on
flow evaluations, is the independent reference the tests hold them to. The pieces the forms
share (series degrees and panels, integrals of polynomial products, closed-form factors) are
in :mod:`.quadrature`. Conventions as in :mod:`.flow_eval`.
"""
from __future__ import annotations

import numpy as np
from numba import types

from . import kernel
from .flow_eval import cabs, point_eval, propagate
from .quadrature import (
    _HILBERT,
    _INV,
    N_TERMS,
    PANEL_RADIUS,
    damping_row,
    dense_row_sums,
    hilbert_dot,
    input_series,
    panel_plan,
    phi1_ledger,
    row_series,
    taylor_degree,
)


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


ledger_panel = kernel(_nrt=True)(ledger_panel_py)   # allocates its nodes (a test reference)


def row_pattern_py(V, cols, counts):
    """Column indices of the non-zero entries of each row of ``V`` (``cols[i, :counts[i]]``)."""
    for i in range(V.shape[0]):
        c = 0
        for k in range(V.shape[1]):
            if V[i, k] != 0:
                cols[i, c] = k
                c += 1
        counts[i] = c


row_pattern = kernel()(row_pattern_py)


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
        The flow over the piece, as in :func:`.flow_eval.point_eval` (state in modal units,
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
        Work arrays: ``(n2, N_TERMS)`` complex, ``(5, max(n, n2), N_TERMS)`` float,
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
    n_pan, width, deg_h = panel_plan(lam_max, omegas, tau)
    deg_u = max(1, deg_h)
    qd = rows[0]
    q = rows[1]
    acc = rows[2]
    cr = rows[3]
    ci = rows[4]
    p_damp = 0.0
    p_force = 0.0
    p_circ = 0.0
    for p in range(n_pan):
        s0 = p * width
        propagate(yh, lam, s0, w0, ws, y0)   # the state at the panel's start (s0 = 0: yh)
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
        input_series(u0, us, amps, omegas, t0, s0, width, deg_u, deg_h, u_t)
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
        # velocity (and coordinate) polynomials of each row: real parts of V coef, the
        # degrees innermost and contiguous (the compiler vectorizes them; rows are dense in
        # a stuck configuration)
        for k in range(n2):
            for m in range(d_top + 1):
                cr[k, m] = coef[k, m].real
                ci[k, m] = coef[k, m].imag
        for i in range(n):
            d = 0
            for c in range(v_counts[i]):
                d = max(d, degs[v_cols[i, c]])
            degs[n2 + i] = d
            for m in range(d_top + 1):
                qd[i, m] = 0.0
            for c in range(v_counts[i]):
                k = v_cols[i, c]
                vr = Vv[i, k].real
                vi = Vv[i, k].imag
                for m in range(d + 1):
                    qd[i, m] += vr * cr[k, m] - vi * ci[k, m]
            if circulatory:
                for m in range(d_top + 1):
                    q[i, m] = 0.0
                for c in range(q_counts[i]):
                    k = q_cols[i, c]
                    vr = Vq[i, k].real
                    vi = Vq[i, k].imag
                    for m in range(d_top + 1):
                        q[i, m] += vr * cr[k, m] - vi * ci[k, m]
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
                pf += bu * hilbert_dot(qd, i, di, b)
            if circulatory:
                for b in range(d_top + 1):
                    kq = 0.0
                    for k2 in range(n):
                        kq += Kskew[i, k2] * q[k2, b]
                    pc -= kq * hilbert_dot(qd, i, di, b)
        p_damp += width * pd
        p_force += width * pf
        p_circ += width * pc
    ledger[2] += p_damp
    ledger[3] += p_force
    ledger[4] += p_circ
    return n_pan


ledger_taylor = kernel()(ledger_taylor_py)


def rows_transposed(Vv, KVq):
    """The dense rows of :func:`ledger_modal`, transposed and split, for one configuration:
    ``vt[0]``, ``vt[1]`` the real and imaginary parts of ``Vv.T`` (velocity rows), ``vt[2]``,
    ``vt[3]`` those of ``KVq.T`` (skew stiffness force rows; zeros when ``KVq`` is None).
    Shape ``(4, n2, n)``: the rows innermost, as the kernel sums them."""
    vt = np.zeros((4,) + Vv.T.shape)
    vt[0] = Vv.T.real
    vt[1] = Vv.T.imag
    if KVq is not None:
        vt[2] = KVq.T.real
        vt[3] = KVq.T.imag
    return vt


def ledger_modal_py(yh, lam, w0, ws, part_plus, part_minus, omegas, amps, u0, us, t_cur, tau,
                    lam_max, Vv, v_cols, dense, vt, circulatory, Cmat, Bmat, soa, u_t, y0,
                    ledger):
    """:func:`ledger_taylor` for diagonal damping.

    The same series and exact integration, laid out so that the inner loops run over rows or
    coordinates with nothing but independent chains, which the compiler vectorizes, all to the
    degree of the fastest coordinate. With ``dense`` false each velocity row reads one state
    coordinate (``v_cols[i, 0]``: a modal configuration) and the series is kept per row; with
    ``dense`` true (a stuck configuration, or a rotor with cross-coupled stiffness: every
    row reads every coordinate) it is kept per coordinate and the rows are sums of them.
    With ``circulatory`` (dense only) the skew stiffness force rows ``K_skew q`` are sums of
    the coordinates too, through ``KVq = K_skew Vq`` (N/m per modal unit, per configuration),
    and their work goes to ``ledger[4]``. ``vt`` holds the dense rows of the configuration
    (:func:`rows_transposed` of ``Vv`` and ``KVq``, built with its table; unused when not
    dense). Work arrays: ``soa`` ``(4, N_TERMS + 9, max(n, n2))`` float, ``u_t``
    ``(nf, N_TERMS)`` float, ``y0`` ``n2`` complex. Returns the panels used.
    """
    if tau <= 0.0:
        return 0
    n = Vv.shape[0]
    n2 = lam.size
    nj = n2 if dense else n   # series columns: coordinates, or rows
    nf = u0.size
    nh = omegas.size
    n_pan, width, deg_h = panel_plan(lam_max, omegas, tau)
    deg = max(2, deg_h, taylor_degree(lam_max * lam_max * width * width))
    deg_u = max(1, deg_h)
    cr = soa[0]
    ci = soa[1]
    qd = soa[2]
    kq = soa[3]
    acc_c = soa[0, N_TERMS + 8]
    # per-column and per-row vectors after the series rows
    zr = soa[0, N_TERMS]
    zi = soa[0, N_TERMS + 1]
    vr = soa[0, N_TERMS + 2]
    vi = soa[0, N_TERMS + 3]
    acc_d = soa[0, N_TERMS + 4]
    acc_f = soa[0, N_TERMS + 5]
    part = soa[0, N_TERMS + 6]
    bu = soa[0, N_TERMS + 7]
    for i in range(n):
        if not dense:
            k = v_cols[i, 0]
            vr[i] = Vv[i, k].real
            vi[i] = Vv[i, k].imag
        acc_d[i] = 0.0
        acc_f[i] = 0.0
        acc_c[i] = 0.0
    for p in range(n_pan):
        s0 = p * width
        propagate(yh, lam, s0, w0, ws, y0)   # the state at the panel's start (s0 = 0: yh)
        t0 = t_cur + s0
        for j in range(nj):
            k = j if dense else v_cols[j, 0]
            lk = lam[k]
            z = lk * width
            zr[j] = z.real
            zi[j] = z.imag
            c = y0[k]
            cr[0, j] = c.real
            ci[0, j] = c.imag
            c = width * (lk * c + w0[k] + ws[k] * s0)
            cr[1, j] = c.real
            ci[1, j] = c.imag
            c = 0.5 * (z * c + (width * width) * ws[k])
            cr[2, j] = c.real
            ci[2, j] = c.imag
        for m in range(3, deg + 1):
            inv = _INV[m]
            for j in range(nj):
                ar = cr[m - 1, j]
                ai = ci[m - 1, j]
                cr[m, j] = (ar * zr[j] - ai * zi[j]) * inv
                ci[m, j] = (ar * zi[j] + ai * zr[j]) * inv
        input_series(u0, us, amps, omegas, t0, s0, width, deg_u, deg_h, u_t)
        for hh in range(nh):
            e = np.exp(1j * (omegas[hh] * t0))
            zh = 1j * (omegas[hh] * width)
            for j in range(nj):
                k = j if dense else v_cols[j, 0]
                a = part_plus[hh, k] * e
                b = part_minus[hh, k] * np.conj(e)
                for m in range(deg_h + 1):
                    c = a + b
                    cr[m, j] += c.real
                    ci[m, j] += c.imag
                    a = a * zh * _INV[m + 1]
                    b = -b * zh * _INV[m + 1]
        if dense:
            for m in range(deg + 1):
                dense_row_sums(cr, ci, vt, 0, m, n, n2, qd)
                if circulatory:
                    dense_row_sums(cr, ci, vt, 2, m, n, n2, kq)
        else:
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
        # circulatory: -qd_i (K_skew q)_i
        if dense and circulatory:
            for a in range(deg + 1):
                for i in range(n):
                    part[i] = 0.0
                for b in range(deg + 1):
                    h_ab = _HILBERT[a + b]
                    for i in range(n):
                        part[i] += h_ab * kq[b, i]
                for i in range(n):
                    acc_c[i] -= width * qd[a, i] * part[i]
    p_damp = 0.0
    p_force = 0.0
    p_circ = 0.0
    for i in range(n):
        p_damp += Cmat[i, i] * acc_d[i]
        p_force += acc_f[i]
        p_circ += acc_c[i]
    ledger[2] += p_damp
    ledger[3] += p_force
    ledger[4] += p_circ
    return n_pan


ledger_modal = kernel(returns=types.int64)(ledger_modal_py)


#: Largest ``(|c|^2 max(1, |e^(lam tau)|^2) + |a|^2 + |b tau|^2) / (|y0|^2 + |w0 tau|^2 +
#: |ws tau^2|^2)`` (the particular solution's size against the flow's own) at which
#: :func:`ledger_closed` answers for a row in closed form (rounding error about
#: ``10 eps CLOSED_COND``, 2e-13, of the row's scale); beyond it the row takes its Taylor
#: series (:func:`.quadrature.row_series`), short there: the ratio is large only when
#: ``|lam| tau`` is small.
CLOSED_COND = 100.0


def ledger_closed_py(yh, lam, w0, ws, u0, us, tau, e_tau, p1_tau, p2_tau, m_tau, part_plus,
                     part_minus, omegas, amps, harm, Vv, v_cols, Cmat, Bmat, work, rg, ledger):
    """:func:`ledger_modal` in closed form: each coordinate is ``y(s) = c e^(lam s) + a + b s``
    plus its harmonic particular solution, so each row's velocity is
    ``Re(A e^(lam s)) + alpha + beta s + sum_h Re(R_h e^(i omega_h s))`` (and each input
    ``g0 + g1 s + sum_h Re(G_h e^(i omega_h s))``), and its damping and forcing powers integrate to
    exponential integrals: the factors of :func:`.quadrature.piece_factors` (or the whole-step
    ones of the propagator's table) give ``int e^(lam s)``, ``int s e^(lam s)``,
    ``int e^(2 lam s) = int e^(lam s) (e^(lam tau) + 1)/2`` and ``int |e^(lam s)|^2``.

    Parameters
    ----------
    yh : ndarray of complex
        State coordinates at the start of the piece (modal units).
    lam : ndarray of complex
        Eigenvalues (1/s).
    w0, ws : ndarray of complex
        Held input ``W u0`` (modal units/s) and its slope ``W us`` (modal units/s^2).
    u0, us : ndarray
        Held inputs (N) and their slopes (N/s).
    tau : float
        Length of the piece (s).
    e_tau, p1_tau, p2_tau : ndarray of complex
        ``exp(lam tau)`` (1), ``tau phi1(lam tau)`` (s), ``tau^2 phi2(lam tau)`` (s^2).
    m_tau : ndarray
        ``int_0^tau |e^(lam s)|^2 ds`` (s).
    part_plus, part_minus, omegas, amps : ndarray
        Harmonic particular solution (modal units), frequencies (rad/s) and input amplitudes
        (N), as in :func:`.flow_eval.point_eval`; empty without harmonics.
    harm : ndarray of complex
        :func:`.quadrature.harmonic_factors` of the piece.
    Vv : ndarray of complex
        Velocity rows (m/s per modal unit); row ``i`` reads coordinate ``v_cols[i, 0]``.
    v_cols : ndarray of int
        Coordinate read by each row.
    Cmat : ndarray
        Damping (N s/m), diagonal.
    Bmat : ndarray
        Input matrix (1).
    work : ndarray
        ``N_TERMS`` floats.
    rg : ndarray of complex
        ``(2, nh)``: a row's harmonic velocity and input amplitudes ``R_h``, ``G_h``.
    ledger : ndarray
        Adds damping dissipation to ``ledger[2]`` and forcing work to ``ledger[3]`` (J).

    Returns
    -------
    int
        1; or -1 (ledger untouched) if a row whose particular solution is more than
        ``sqrt(CLOSED_COND)`` times the flow's size has harmonics or ``|lam| tau >
        PANEL_RADIUS`` (such a row takes its series otherwise): the caller takes
        :func:`ledger_modal` instead.
    """
    n = Vv.shape[0]
    nf = u0.size
    nh = part_plus.shape[0]
    tau2 = tau * tau
    p_damp = 0.0
    p_force = 0.0
    for i in range(n):
        k = v_cols[i, 0]
        lk = lam[k]
        v = Vv[i, k]
        y0 = yh[k]
        g0 = 0.0
        g1 = 0.0
        for f in range(nf):
            g0 += Bmat[i, f] * u0[f]
            g1 += Bmat[i, f] * us[f]
        l2 = lk.real * lk.real + lk.imag * lk.imag
        size_y = y0.real * y0.real + y0.imag * y0.imag \
            + (w0[k].real * w0[k].real + w0[k].imag * w0[k].imag) * tau2 \
            + (ws[k].real * ws[k].real + ws[k].imag * ws[k].imag) * tau2 * tau2
        closed = l2 > 0.0
        if closed:
            inv = np.conj(lk) * (1.0 / l2)
            b = -ws[k] * inv
            a = (b - w0[k]) * inv
            c = y0 - a
            e = e_tau[k]
            e2 = max(1.0, e.real * e.real + e.imag * e.imag)
            size_p = (c.real * c.real + c.imag * c.imag) * e2 + a.real * a.real \
                + a.imag * a.imag + (b.real * b.real + b.imag * b.imag) * tau2
            closed = size_p <= CLOSED_COND * size_y
        if not closed:
            if nh > 0 or l2 * tau2 > PANEL_RADIUS * PANEL_RADIUS:
                return -1
            d, fw = row_series(y0, lk, w0[k], ws[k], v, tau, g0, g1, work)
            p_damp += Cmat[i, i] * d
            p_force += fw
            continue
        amp = v * c
        alpha = (v * a).real
        beta = (v * b).real
        i1 = p1_tau[k]
        i_s = tau * i1 - p2_tau[k]
        i2 = 0.5 * i1 * (e + 1.0)
        im = m_tau[k]
        amp2 = amp.real * amp.real + amp.imag * amp.imag
        d = 0.5 * (amp * amp * i2).real + 0.5 * amp2 * im \
            + 2.0 * (amp * (alpha * i1 + beta * i_s)).real \
            + tau * (alpha * alpha + tau * (alpha * beta + tau * beta * beta / 3.0))
        fw = (amp * (g0 * i1 + g1 * i_s)).real \
            + tau * (alpha * g0 + tau * (0.5 * (alpha * g1 + beta * g0) + tau * beta * g1 / 3.0))
        # the harmonic terms: R_h in the velocity, G_h in the input
        for h in range(nh):
            g_h = 0j
            for f in range(nf):
                g_h += Bmat[i, f] * amps[h, f]
            rg[0, h] = harm[0, h] * (v * part_plus[h, k] + np.conj(v * part_minus[h, k]))
            rg[1, h] = harm[0, h] * g_h
        z = lk * tau
        for h in range(nh):
            r_h = rg[0, h]
            g_h = rg[1, h]
            om = harm[1, h]
            w_tau = 1j * (omegas[h] * tau)
            j_plus = tau * phi1_ledger(z + w_tau, e * om)
            j_minus = tau * phi1_ledger(z - w_tau, e * np.conj(om))
            lin = alpha * harm[2, h] + beta * harm[3, h]
            d += (amp * r_h * j_plus).real + (amp * np.conj(r_h) * j_minus).real \
                + 2.0 * (r_h * lin).real
            fw += 0.5 * ((amp * g_h * j_plus).real + (amp * np.conj(g_h) * j_minus).real) \
                + (g_h * lin).real + (r_h * (g0 * harm[2, h] + g1 * harm[3, h])).real
            for g in range(nh):
                pp_hg = harm[4 + h, g]
                pm_hg = harm[4 + nh + h, g]
                d += 0.5 * ((r_h * rg[0, g] * pp_hg).real
                            + (r_h * np.conj(rg[0, g]) * pm_hg).real)
                fw += 0.5 * ((r_h * rg[1, g] * pp_hg).real
                             + (r_h * np.conj(rg[1, g]) * pm_hg).real)
        p_damp += Cmat[i, i] * d
        p_force += fw
    ledger[2] += p_damp
    ledger[3] += p_force
    return 1


ledger_closed = kernel(returns=types.int64)(ledger_closed_py)
