"""Numba kernels of the energy ledger: damping, forcing and circulatory work (J).

The integrands are evaluated on the exact flow (see :mod:`.flow`) at composite 4-point
Gauss-Legendre nodes. Conventions as in :mod:`.flow`.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from .flow import cabs, phis, point_eval

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



_GL4_X = np.array([-0.8611363115940526, -0.3399810435848563, 0.3399810435848563,
                   0.8611363115940526])
_GL4_W = np.array([0.3478548451374538, 0.6521451548625461, 0.6521451548625461,
                   0.3478548451374538])


def ledger_node_count_py(lam, h):
    """Number of Gauss nodes of :func:`ledger_panel` over a step of ``h`` (s)."""
    lam_max = 0.0
    for k in range(lam.size):
        lam_max = max(lam_max, cabs(lam[k]))
    n_panels = int(np.ceil(h * lam_max / 0.5))
    return 4 * max(n_panels, 1)


ledger_node_count = njit(cache=True)(ledger_node_count_py)


def ledger_nodes_py(lam, omegas, h, s_nodes, w_nodes, E, P1, P2, EH):
    """Nodes ``s`` (s), weights (s) and flow factors of :func:`ledger_panel`'s rule over
    ``[0, h]`` (s): ``E = exp(lam s)``, ``P1 = s phi1(lam s)``, ``P2 = s^2 phi2(lam s)`` and
    ``EH = exp(i omegas s)``, so that the quadrature itself needs no exponentials.

    The nodes of a panel lie symmetrically about its middle (``mid -/+ a1``, ``mid -/+ a2``),
    so four exponentials per coordinate serve every node: ``exp(lam mid)`` advanced panel by
    panel with ``exp(lam width)``, times ``exp(+/-lam a)``.
    """
    n_panels = s_nodes.size // 4
    width = h / n_panels
    a_in = 0.5 * width * _GL4_X[2]
    a_out = 0.5 * width * _GL4_X[3]
    for p in range(n_panels):
        mid = (p + 0.5) * width
        for g in range(4):
            i = 4 * p + g
            s_nodes[i] = mid + 0.5 * width * _GL4_X[g]
            w_nodes[i] = 0.5 * width * _GL4_W[g]
    for k in range(lam.size):
        lk = lam[k]
        e_mid = np.exp(lk * (0.5 * width))
        e_step = np.exp(lk * width) if n_panels > 1 else 1.0 + 0j
        e_in = np.exp(lk * a_in)
        e_out = np.exp(lk * a_out)
        # exp(-lam a) = conj(e) / |e|^2: a division in real arithmetic
        e_in_inv = np.conj(e_in) * (1.0 / (e_in.real * e_in.real + e_in.imag * e_in.imag))
        e_out_inv = np.conj(e_out) * (1.0 / (e_out.real * e_out.real + e_out.imag * e_out.imag))
        mod2 = lk.real * lk.real + lk.imag * lk.imag
        inv = np.conj(lk) * (1.0 / mod2) if mod2 > 0.0 else 0j
        for p in range(n_panels):
            for g in range(4):
                i = 4 * p + g
                if g == 0:
                    e = e_mid * e_out_inv
                elif g == 1:
                    e = e_mid * e_in_inv
                elif g == 2:
                    e = e_mid * e_in
                else:
                    e = e_mid * e_out
                s = s_nodes[i]
                z = lk * s
                az = cabs(z)
                E[i, k] = e
                # (e - 1)/lam and (e - 1 - z)/lam^2 lose eps/|z| and 2 eps/|z|^2 (relative) to
                # cancellation: short series below the switch points keep both under 3e-13,
                # far below the rule's 1e-10 (the propagator itself keeps its exact phis)
                if az >= 1e-3:
                    P1[i, k] = (e - 1.0) * inv
                else:
                    P1[i, k] = s * (1.0 + z * (0.5 + z * (1.0 / 6.0 + z * (1.0 / 24.0
                                                                          + z / 120.0))))
                if az >= 0.05:
                    P2[i, k] = (e - 1.0 - z) * inv * inv
                else:
                    P2[i, k] = s * s * (0.5 + z * (1.0 / 6.0 + z * (1.0 / 24.0 + z * (
                        1.0 / 120.0 + z * (1.0 / 720.0 + z * (1.0 / 5040.0 + z / 40320.0))))))
            e_mid = e_mid * e_step
    for i in range(s_nodes.size):
        for hh in range(omegas.size):
            EH[i, hh] = np.exp(1j * omegas[hh] * s_nodes[i])


ledger_nodes = njit(cache=True)(ledger_nodes_py)


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


def ledger_step_py(yh, w0, ws, part_plus, part_minus, omegas, amps, u0, us, t_cur, s_nodes,
                   w_nodes, E, P1, P2, EH, Vq, Vv, q_cols, q_counts, v_cols, v_counts, Cmat,
                   c_cols, c_counts, Kskew, circulatory, Bmat, y_tau, real_work, eh_t, ledger):
    """:func:`ledger_panel` over a whole step with the node factors of :func:`ledger_nodes`.

    The same rule and nodes, so the same result to round-off, at a fraction of the cost: no
    exponentials, the sparsity of ``Vq``/``Vv`` (two entries per row for uncoupled modes)
    and of ``Cmat`` (``c_cols``/``c_counts`` of :func:`row_pattern`: modal damping is
    diagonal), and no circulatory term without a skew stiffness. Work arrays (no allocation
    per call): ``real_work`` at least ``2 n + nf`` floats, ``eh_t`` one complex per harmonic.
    """
    n = Vq.shape[0]
    n2 = yh.size
    nf = u0.size
    nh = omegas.size
    q = real_work[:n]
    qd = real_work[n:2 * n]
    u = real_work[2 * n:2 * n + nf]
    q[:] = 0.0
    for hh in range(nh):
        eh_t[hh] = np.exp(1j * omegas[hh] * t_cur)
    p_damp = 0.0
    p_circ = 0.0
    p_force = 0.0
    for g in range(s_nodes.size):
        s = s_nodes[g]
        for k in range(n2):
            y_tau[k] = E[g, k] * yh[k] + P1[g, k] * w0[k] + P2[g, k] * ws[k]
        for f in range(nf):
            u[f] = u0[f] + us[f] * s
        for hh in range(nh):
            e = eh_t[hh] * EH[g, hh]
            em = np.conj(e)
            for k in range(n2):
                y_tau[k] += part_plus[hh, k] * e + part_minus[hh, k] * em
            for f in range(nf):
                u[f] += (amps[hh, f] * e).real
        for i in range(n):
            av = 0j
            for c in range(v_counts[i]):
                k = v_cols[i, c]
                av += Vv[i, k] * y_tau[k]
            qd[i] = av.real
            if circulatory:
                aq = 0j
                for c in range(q_counts[i]):
                    k = q_cols[i, c]
                    aq += Vq[i, k] * y_tau[k]
                q[i] = aq.real
        pd = 0.0
        pc = 0.0
        pf = 0.0
        for i in range(n):
            cq = 0.0
            for c in range(c_counts[i]):
                k2 = c_cols[i, c]
                cq += Cmat[i, k2] * qd[k2]
            pd += qd[i] * cq
            if circulatory:
                kq = 0.0
                for k2 in range(n):
                    kq += Kskew[i, k2] * q[k2]
                pc -= qd[i] * kq
            bu = 0.0
            for f in range(nf):
                bu += Bmat[i, f] * u[f]
            pf += qd[i] * bu
        wgt = w_nodes[g]
        p_damp += wgt * pd
        p_force += wgt * pf
        p_circ += wgt * pc
    ledger[2] += p_damp
    ledger[3] += p_force
    ledger[4] += p_circ


ledger_step = njit(cache=True)(ledger_step_py)
