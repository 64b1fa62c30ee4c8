"""Numba kernel of the exact, event-located propagator: :func:`advance`, the event loop.

Between events the modal state flows exactly (:mod:`.flow_eval`). Events are impacts, sticks and
releases; every one of them, and the change of the model's configuration when an impactor
sticks or is released, is handled inside the compiled loop: each sub-interval is searched for
its first event (:mod:`.search`), the state is moved to it, and the event is applied
(:mod:`.contact`: the impact law, sticking, releases and the switch between configuration
slots). The energy ledger integrates over each piece between events (:mod:`.ledger`).

This module is the kernel package's entry point for the propagator
(:mod:`impact_damper_sim.integrate.exact` imports it as ``kernels``): besides :func:`advance`
and :func:`advance_work` it exposes the codes the propagator passes in and reads back (the
sticking rules, the status codes, ``N_COUNTERS`` and ``CNT_SWITCHES``: ``__all__``), which are
defined in :mod:`.codes`.

Conventions as in :mod:`.flow_eval`; ``counters`` (``CNT_*``, :mod:`.codes`) count the work done.
"""
from __future__ import annotations

import numpy as np

from . import kernel
from .codes import (
    BUFFER_FULL,
    CHATTER,
    CNT_EVALS,
    CNT_LEDGER_CLOSED,
    CNT_LEDGER_PANELS,
    CNT_QUIET,
    CNT_STEPS,
    CNT_SWITCHES,
    CNT_TAYLOR,
    CONFIG_CHANGE,
    DONE,
    EV_RELEASE,
    N_COUNTERS,
    NONFINITE,
    STICK_ACCUMULATION,
    STICK_NONE,
    STICK_PAPER,
)
from .contact import impact, record, release_normals, switch_slot
from .flow_eval import point_eval, row_derivs
from .ledger import ledger_closed, ledger_modal, ledger_taylor
from .quadrature import N_TERMS as LEDGER_TERMS
from .quadrature import harmonic_factors, piece_factors
from .scan import FN_RELEASE
from .search import quiet_window, search

#: What :mod:`impact_damper_sim.integrate.exact` reads here (the codes from :mod:`.codes`).
__all__ = ['advance', 'advance_work', 'BUFFER_FULL', 'CHATTER', 'CONFIG_CHANGE', 'DONE',
           'NONFINITE', 'CNT_SWITCHES', 'N_COUNTERS', 'STICK_ACCUMULATION', 'STICK_NONE',
           'STICK_PAPER']

#: Output steps ahead that a quiet-window certificate tries to cover.
QUIET_STEPS = 8


def advance_work(n2, nf, ni, nh, n, taylor_order, ledger_on):
    """The work arrays of :func:`advance`, as the tuple its ``work`` argument takes.

    Made once per integrator by the caller, which keeps them alive while the kernel runs
    (kernels hold no references: they compile without reference counting). Sizes: ``n2``
    complex state coordinates, ``nf`` inputs, ``ni`` impactors, ``nh`` harmonics, ``n`` modal
    coordinates, the Taylor order, and whether the energy ledger is kept (its series arrays
    are empty otherwise).
    """
    order_max = taylor_order + 4
    terms = LEDGER_TERMS if ledger_on else 0
    return (
        np.empty(n2, dtype=np.complex128),  # yh_tau
        np.empty(n2, dtype=np.complex128),  # y_tau
        np.empty(n2, dtype=np.complex128),  # y_sw
        np.empty(2 * n),  # x_sw
        np.empty((order_max + 1, n2), dtype=np.complex128),  # yd
        np.empty((order_max + 1, nf)),  # uder
        np.zeros((ni + 1, order_max + 1, 2)),  # Xs
        np.zeros((order_max + 1, 2)),  # X
        np.zeros((ni + 1, order_max + 2)),  # Eb
        np.zeros(ni + 1),  # reach
        np.empty((order_max + 2, n2)),  # ybound
        np.empty(nf),  # u_abs
        np.empty(nf),  # us_abs
        np.empty(n2),  # exc
        np.empty(2 * ni + 1),  # cand_key
        np.empty(2 * ni + 1, dtype=np.int64),  # cand_j
        np.empty(2 * ni + 1, dtype=np.int64),  # cand_fid
        np.empty(2 * ni + 1),  # cand_s0
        np.empty(2 * ni + 1),  # cand_shift
        np.empty(2 * ni + 1, dtype=np.int64),  # cand_lv
        np.empty((2 * ni + 1, 3)),  # cand_out
        np.zeros(2 * ni + 1, dtype=np.bool_),  # active
        np.empty(2 * ni + 1),  # shifts
        np.empty(order_max + 2),  # coef
        np.empty((2, order_max + 2)),  # rwork
        np.empty(3 * (order_max + 2) + 6),  # pwork
        np.empty(3),  # root_out
        np.empty(2),  # scan_result
        np.empty(4),  # search_result
        np.empty((order_max + 2, nf)),  # ub
        np.empty(order_max + 2),  # wu
        np.empty(n2, dtype=np.complex128),  # w0
        np.empty(n2, dtype=np.complex128),  # ws
        np.empty(nf),  # u0
        np.empty(nf),  # us
        np.zeros((ni, 2)),  # release_n
        np.empty(nf),  # u_max
        np.empty(n2, dtype=np.complex128),  # w_max
        np.empty(n2, dtype=np.complex128),  # w_zero
        np.empty((n2, terms), dtype=np.complex128),  # led_coef
        np.empty((5, max(n, n2), terms)),  # led_rows
        np.empty((nf, terms)),  # led_u
        np.empty(n2 + n, dtype=np.int64),  # led_degs
        np.empty(n2, dtype=np.complex128),  # led_y0
        np.empty((4, terms + 9 if ledger_on else 0, max(n, n2))),  # led_soa
        np.empty((3, n2 if ledger_on else 0), dtype=np.complex128),  # led_fac
        np.empty(n2 if ledger_on else 0),  # led_m
        np.empty((4 + 2 * nh, nh) if ledger_on else (0, 0), dtype=np.complex128),  # led_harm
        np.empty((2, nh), dtype=np.complex128),  # led_rg
    )


def advance_py(t_state, t_base, h, k_start, n_steps, u_grid, omegas, amps, yh, slot_state,
               table_mode, tb_built, tb_lam, tb_lam_max, tb_V, tb_Vinv, tb_W, tb_pp, tb_pm,
               tb_sq, tb_sv, tb_house, tb_house_abs, tb_kick, tb_mob, tb_lawmob, tb_relmap, tb_eh,
               tb_p1h, tb_p2h, tb_mh, tb_vt, tb_qcols, tb_qcounts, tb_vcols, tb_vcounts,
               tb_vmodal,
               imp_rep, imp_group, group_radix, imp_dim, imp_mass, imp_cor, imp_limit,
               imp_z, imp_v, imp_stuck, imp_normal, imp_last_t, imp_rel, imp_grace, count_step,
               stick_rule, stick_time, max_events_per_step, taylor_order,
               ledger_model, c_pattern, ledger,
               out_disp, out_vel, out_acc,
               ev_t, ev_imp, ev_kind, ev_n, ev_vn, ev_J, ev_loss, ev_after, ev_count, info,
               counters, work):
    """Advance the model with its impactors over grid steps ``k_start .. n_steps-1``.

    Step ``k`` ends at ``t_base + (k + 1) h`` where sensor outputs are recorded; the current
    time ``t_state[0]`` lies in step ``k_start``; ``slot_state[0]`` is the configuration slot
    of ``yh``. Returns a status code; ``info[0]`` holds the step in progress, ``info[1]`` the
    impactor that changed state, ``info[2]`` the number of undecided grazing scans,
    ``info[3]`` the largest impacts in one step. On ``CONFIG_CHANGE`` the state is at the
    event time in the old slot; the caller builds the new configuration, converts ``yh``,
    sets ``slot_state`` and calls again.

    The energy ledger integrates over each piece of a step when ``ledger_model`` is the
    tuple ``(C, K_skew, B)`` (damping, skew stiffness and input matrices of the model); with
    ``None`` it is off. ``c_pattern`` is ``None`` for a diagonal ``C`` (its closed and modal
    forms) or ``(cols, counts)`` of ``C``'s non-zero entries per row (its general form).
    Both branch on ``is None``, which Numba decides from the argument types when it
    compiles: a kernel without the ledger, or without the general form, does not compile
    them (the ledger is a fifth of hpotp's compile time).
    """
    (yh_tau, y_tau, y_sw, x_sw, yd, uder, Xs, X, Eb, reach, ybound, u_abs, us_abs, exc,
     cand_key, cand_j, cand_fid, cand_s0, cand_shift, cand_lv, cand_out, active, shifts, coef,
     rwork, pwork, root_out, scan_result, search_result, ub, wu, w0, ws, u0, us, release_n, u_max,
     w_max, w_zero, led_coef, led_rows, led_u, led_degs, led_y0, led_soa, led_fac,
     led_m, led_harm, led_rg) = work
    Xs[...] = 0
    X[...] = 0
    Eb[...] = 0
    reach[...] = 0
    active[...] = 0
    release_n[...] = 0
    n2 = yh.size
    nf = u_grid.shape[1]
    ni = imp_dim.size
    nh = omegas.size
    P = taylor_order
    cap = ev_t.size
    quiet_until = -np.inf
    circulatory = False
    if ledger_model is not None:
        Cmat, Kskew, Bmat = ledger_model
        n = Cmat.shape[0]
        for i in range(Kskew.shape[0]):
            for i2 in range(Kskew.shape[1]):
                if Kskew[i, i2] != 0.0:
                    circulatory = True
    slot = slot_state[0]
    release_normals(imp_stuck, imp_normal, tb_relmap[slot], release_n)
    t_cur = t_state[0]
    for k in range(k_start, n_steps):
        t_k = t_base + k * h
        t_b = t_base + (k + 1) * h
        for f in range(nf):
            us[f] = (u_grid[k + 1, f] - u_grid[k, f]) / h
        if t_cur <= t_k:
            # a fresh step (not a resumption after a configuration change): reset the counts
            for j in range(ni):
                count_step[j] = 0
            counters[CNT_STEPS] += 1
        while True:
            lam = tb_lam[slot]
            W = tb_W[slot]
            part_plus = tb_pp[slot]
            part_minus = tb_pm[slot]
            house = tb_house[slot]
            for f in range(nf):
                u0[f] = u_grid[k, f] + us[f] * (t_cur - t_k)
            for i in range(n2):
                # by real parts: a complex product would multiply by 0j
                w0_r = 0.0
                w0_i = 0.0
                ws_r = 0.0
                ws_i = 0.0
                for f in range(nf):
                    w0_r += W[i, f].real * u0[f]
                    w0_i += W[i, f].imag * u0[f]
                    ws_r += W[i, f].real * us[f]
                    ws_i += W[i, f].imag * us[f]
                w0[i] = complex(w0_r, w0_i)
                ws[i] = complex(ws_r, ws_i)
            horizon = t_b - t_cur
            best_j = -1
            best_fid = -1
            tau = horizon
            have_state = False
            if ni > 0 and t_cur == t_k and quiet_until >= t_b:
                counters[CNT_QUIET] += 1  # certified event-free: the whole step, no search
            elif ni > 0:
                taylor_before = counters[CNT_TAYLOR]
                undecided = search(t_cur, horizon, yh, lam, tb_lam_max[slot], W, w0, ws,
                                   part_plus, part_minus, omegas, amps, u0, us, house,
                                   tb_house_abs[slot], imp_rep, imp_dim, imp_z, imp_v,
                                   imp_limit, imp_stuck, imp_grace, release_n, P, yh_tau, y_tau,
                                   uder, yd, Xs, ybound, u_abs, us_abs, ub, wu, exc, Eb, reach,
                                   cand_key, cand_j, cand_fid, cand_s0, cand_shift, cand_lv,
                                   cand_out, active, shifts, rwork, coef, pwork, root_out,
                                   scan_result, counters, search_result)
                if undecided < 0:
                    t_state[0] = t_cur
                    info[0] = k
                    return NONFINITE
                info[2] += undecided
                tau = search_result[0]
                best_j = int(search_result[1])
                best_fid = int(search_result[2])
                have_state = search_result[3] == 1.0
                if best_j == -1 and t_cur == t_k and counters[CNT_TAYLOR] == taylor_before \
                        and k + 1 < n_steps:
                    # nothing came near a wall in this step: try to certify the next ones too
                    k_end = min(k + QUIET_STEPS, n_steps - 1)
                    t_end = t_base + (k_end + 1) * h
                    if quiet_window(t_end - t_cur, yh, lam, W, part_plus, part_minus, omegas,
                                    u_grid, k, k_end + 1, tb_house_abs[slot], imp_rep, imp_dim,
                                    imp_z, imp_v, imp_limit, imp_stuck, imp_grace, Xs, u_max,
                                    w_max, w_zero, exc):
                        quiet_until = t_end
            whole_step = best_j == -1 and t_cur == t_k
            if ledger_model is not None:
                # the piece [t_cur, t_cur + tau], or the whole step
                piece = tau
                if whole_step:
                    piece = h
                used = -1 if piece > 0.0 else 0   # nothing to add over an empty piece
                # the forms for diagonal damping (closed form: also no skew stiffness and,
                # per slot, one state coordinate per velocity row)
                if used < 0 and c_pattern is None and not circulatory and tb_vmodal[slot]:
                    # closed form: the step's own flow factors, or the piece's
                    if nh > 0:
                        harmonic_factors(omegas, t_cur, piece, led_harm)
                    if whole_step:
                        used = ledger_closed(yh, lam, w0, ws, u0, us, h, tb_eh[slot],
                                             tb_p1h[slot], tb_p2h[slot], tb_mh[slot],
                                             part_plus, part_minus, omegas, amps, led_harm,
                                             tb_V[slot, n:], tb_vcols[slot], Cmat, Bmat,
                                             led_rows[4, 0], led_rg, ledger)
                    else:
                        piece_factors(lam, piece, led_fac[0], led_fac[1], led_fac[2], led_m)
                        used = ledger_closed(yh, lam, w0, ws, u0, us, piece, led_fac[0],
                                             led_fac[1], led_fac[2], led_m, part_plus,
                                             part_minus, omegas, amps, led_harm,
                                             tb_V[slot, n:], tb_vcols[slot], Cmat, Bmat,
                                             led_rows[4, 0], led_rg, ledger)
                if used >= 0:
                    counters[CNT_LEDGER_CLOSED] += used
                elif c_pattern is None:
                    counters[CNT_LEDGER_PANELS] += ledger_modal(
                        yh, lam, w0, ws, part_plus, part_minus, omegas, amps, u0, us, t_cur,
                        piece, tb_lam_max[slot], tb_V[slot, n:], tb_vcols[slot],
                        circulatory or not tb_vmodal[slot], tb_vt[slot], circulatory, Cmat,
                        Bmat, led_soa, led_u, led_y0, ledger)
                else:
                    c_cols, c_counts = c_pattern
                    counters[CNT_LEDGER_PANELS] += ledger_taylor(
                        yh, lam, w0, ws, part_plus, part_minus, omegas, amps, u0, us, t_cur,
                        piece, tb_lam_max[slot], tb_V[slot, :n], tb_V[slot, n:],
                        tb_qcols[slot], tb_qcounts[slot], tb_vcols[slot], tb_vcounts[slot],
                        Cmat, c_cols, c_counts, Kskew, circulatory, Bmat, led_coef, led_rows,
                        led_u, led_degs, led_y0, ledger)
            if whole_step:
                e_h = tb_eh[slot]
                p1_h = tb_p1h[slot]
                p2_h = tb_p2h[slot]
                for i in range(n2):
                    yh[i] = e_h[i] * yh[i] + p1_h[i] * w0[i] + p2_h[i] * ws[i]
            elif have_state:
                for i in range(n2):
                    yh[i] = yh_tau[i]
            else:
                point_eval(yh, lam, W, w0, ws, part_plus, part_minus, omegas, amps, u0, us,
                           t_cur, tau, 2, yh_tau, y_tau, uder, yd)
                counters[CNT_EVALS] += 1
                for i in range(n2):
                    yh[i] = yh_tau[i]
            for j in range(ni):
                if imp_stuck[j] == 0:
                    for r in range(imp_dim[j]):
                        imp_z[j, r] += imp_v[j, r] * tau
            t_cur = t_cur + tau if best_j != -1 else t_b
            if tau > 0.0:
                for j in range(ni):
                    imp_grace[j] = 0
            if best_j == -1:
                break
            if best_j == -2:
                continue  # end of a Taylor segment: search on from here
            # ---- an event at t_cur for impactor j; the state and derivatives are in yd
            j = best_j
            n_rows = imp_dim[j]
            row_derivs(house[j], n_rows, yd, 2, X)
            if ev_count[0] + 2 > cap:
                # the caller flushes the buffer; the event is found again at once (tau = 0)
                t_state[0] = t_cur
                info[0] = k
                return BUFFER_FULL
            count_step[j] += 1
            if count_step[j] > 4 * max_events_per_step + 16:
                t_state[0] = t_cur
                info[0] = k
                info[1] = j
                return CHATTER
            mob = tb_mob[slot, j]
            if best_fid == FN_RELEASE:
                imp_stuck[j] = 0
                imp_grace[j] = 1
                for r in range(n_rows):
                    imp_z[j, r] = X[0, r] + imp_rel[j, r]
                    imp_v[j, r] = X[1, r]
                imp_last_t[j] = t_cur
                record(ev_t, ev_imp, ev_kind, ev_n, ev_vn, ev_J, ev_loss, ev_after, ev_count,
                        t_cur, j, EV_RELEASE, imp_normal[j, 0], imp_normal[j, 1], 0.0, 0.0,
                        0.0, 0.0, 0.0)
                new_slot = slot - group_radix[imp_group[j]]
            elif impact(j, best_fid, n_rows, t_cur, X, yh, tb_kick[slot, j], mob,
                        tb_lawmob[slot, j], imp_mass, imp_cor, imp_limit, imp_z, imp_v,
                        imp_stuck, imp_normal, imp_last_t, imp_rel, imp_grace, count_step,
                        stick_rule, stick_time, max_events_per_step, ledger, ev_t, ev_imp,
                        ev_kind, ev_n, ev_vn, ev_J, ev_loss, ev_after, ev_count, info) == 1:
                new_slot = slot + group_radix[imp_group[j]]  # it stuck
            else:
                continue  # an impact without a change of configuration
            # ---- the stuck set changed: switch configuration here if its slot is built
            if table_mode and tb_built[new_slot] == 1:
                switch_slot(yh, tb_V[slot], tb_pp[slot], tb_pm[slot], tb_Vinv[new_slot],
                            tb_pp[new_slot], tb_pm[new_slot], omegas, t_cur, y_sw, x_sw)
                slot = new_slot
                slot_state[0] = slot
                release_normals(imp_stuck, imp_normal, tb_relmap[slot], release_n)
                counters[CNT_SWITCHES] += 1
                continue
            t_state[0] = t_cur
            info[0] = k
            info[1] = j
            return CONFIG_CHANGE
        # ---- end of step k: record outputs at t_b
        lam = tb_lam[slot]
        W = tb_W[slot]
        for f in range(nf):
            u0[f] = u_grid[k + 1, f]
        point_eval(yh, lam, W, w0, ws, tb_pp[slot], tb_pm[slot], omegas, amps, u0, us, t_b,
                   0.0, 1, yh_tau, y_tau, uder, yd)
        finite = True
        for i in range(n2):
            if not (np.isfinite(yh[i].real) and np.isfinite(yh[i].imag)):
                finite = False
        if not finite:
            t_state[0] = t_cur
            info[0] = k
            return NONFINITE
        sq = tb_sq[slot]
        sv = tb_sv[slot]
        for s_ in range(sq.shape[0]):
            ad = 0j
            av = 0j
            aa = 0j
            for i in range(n2):
                ad += sq[s_, i] * yd[0, i]
                av += sv[s_, i] * yd[0, i]
                aa += sv[s_, i] * yd[1, i]
            out_disp[k, s_] = ad.real
            out_vel[k, s_] = av.real
            out_acc[k, s_] = aa.real
    t_state[0] = t_cur
    info[0] = n_steps
    return DONE


advance = kernel()(advance_py)
