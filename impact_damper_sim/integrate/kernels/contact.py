"""Numba kernels of what the exact propagator does at an event: an impact, a stick or a
release (:func:`impact`, :func:`record`), and the change of configuration that a stick or a
release brings (:func:`switch_slot`, :func:`release_normals`).

Separate from the event loop (:mod:`.event_loop`) that calls them and from the event search
(:mod:`.search`) that finds the events: these kernels apply the impact law and the sticking
rules (codes in :mod:`.codes`) to the state at the event and append it to the event buffers.

Configurations: a stuck impactor adds its mass to its housing rows, in the same coordinates
(:class:`~impact_damper_sim.integrate.exact.MassUpdate`). Impactors with equal rows and mass
are interchangeable, so a configuration is the number stuck in each such group, and its slot
in the table ``tb_*`` is ``sum_g count_g radix_g``. The caller builds a slot on first use;
the event loop switches between built slots itself (:func:`switch_slot`:
``y_new = V_new^-1 Re(V_old y)``, lossless) and returns ``CONFIG_CHANGE`` only for a slot not
built yet, or at every change when ``table_mode`` is off (a provider that changes
coordinates, such as the paper's basis switch).
"""
from __future__ import annotations

import numpy as np

from . import kernel
from .codes import EV_IMPACT, EV_STICK, STICK_ACCUMULATION, STICK_PAPER
from .flow_eval import add_particular
from .scan import FN_WALL_POS


def switch_slot_py(yh, V_old, pp_old, pm_old, Vinv_new, pp_new, pm_new, omegas, t, y, x):
    """Carry the state from one configuration to another with the same coordinates.

    ``[q; q'] = Re(V_old y_old)``, ``y_new = V_new^-1 [q; q']`` (the harmonic particular parts
    of each configuration taken off at ``t``); ``yh`` is overwritten. Lossless.
    """
    n2 = yh.size
    n_x = V_old.shape[0]
    add_particular(yh, omegas, pp_old, pm_old, t, y)
    for i in range(n_x):
        acc = 0j
        for k in range(n2):
            acc += V_old[i, k] * y[k]
        x[i] = acc.real
    for i in range(n2):
        acc = 0j
        for k in range(n_x):
            acc += Vinv_new[i, k] * x[k]
        yh[i] = acc
    for hh in range(omegas.size):
        ep = np.exp(1j * omegas[hh] * t)
        em = np.conj(ep)
        for i in range(n2):
            yh[i] -= pp_new[hh, i] * ep + pm_new[hh, i] * em


switch_slot = kernel()(switch_slot_py)


def release_normals_py(imp_stuck, imp_normal, relmap, release_n):
    """The normal of each stuck impactor's release function, ``relmap^T n`` (see :mod:`.scan`)."""
    for j in range(imp_stuck.size):
        for r in range(2):
            release_n[j, r] = (relmap[j, 0, r] * imp_normal[j, 0]
                               + relmap[j, 1, r] * imp_normal[j, 1])


release_normals = kernel()(release_normals_py)


def record_py(ev_t, ev_imp, ev_kind, ev_n, ev_vn, ev_J, ev_loss, ev_after, ev_count, t, j,
              kind, n0, n1, v_n, J, loss, after_rel, after_jump):
    """Append one event to the buffers (see ``EVENT_DTYPE``)."""
    e = ev_count[0]
    ev_t[e] = t
    ev_imp[e] = j
    ev_kind[e] = kind
    ev_n[e, 0] = n0
    ev_n[e, 1] = n1
    ev_vn[e] = v_n
    ev_J[e] = J
    ev_loss[e] = loss
    ev_after[e, 0] = after_rel
    ev_after[e, 1] = after_jump
    ev_count[0] = e + 1


record = kernel(forceinline=True)(record_py)


def impact_py(j, fid, n_rows, t_cur, X, yh, kick, mob, lawmob, imp_mass, imp_cor, imp_limit,
              imp_z, imp_v, imp_stuck, imp_normal, imp_last_t, imp_rel, imp_grace, count_step,
              stick_rule, stick_time, max_events_per_step, ledger, ev_t, ev_imp, ev_kind, ev_n,
              ev_vn, ev_J, ev_loss, ev_after, ev_count, info):
    """A free impactor ``j`` meets its wall at ``t_cur`` (s): restitution, maybe sticking.

    ``X`` holds the housing rows' position, velocity and acceleration (m, m/s, m/s^2) just
    before; ``kick`` the change of ``yh`` per unit housing impulse (N s) on each row; ``mob``
    the model's housing mobility and ``lawmob`` the impact law's (1/kg). A closing contact
    gets the restitution impulse ``J = (1 + e) v_n / (1/m + n^T G n)``; a bounce-down (the
    sticking rule), a contact without closing velocity or chatter is completed plastically
    into the stuck state when the housing presses on the impactor. The housing velocity after
    each impulse follows from the model's mobility. Returns 1 when the impactor stuck, else -1.
    """
    nrm0 = 0.0
    nrm1 = 0.0
    if n_rows == 1:
        nrm0 = 1.0 if fid == FN_WALL_POS else -1.0
        vrel0 = imp_v[j, 0] - X[1, 0]
        vrel1 = 0.0
    else:
        d0 = imp_z[j, 0] - X[0, 0]
        d1 = imp_z[j, 1] - X[0, 1]
        dn = np.sqrt(d0 * d0 + d1 * d1)
        nrm0 = d0 / dn
        nrm1 = d1 / dn
        vrel0 = imp_v[j, 0] - X[1, 0]
        vrel1 = imp_v[j, 1] - X[1, 1]
    v_n = nrm0 * vrel0 + nrm1 * vrel1
    m_i = imp_mass[j]
    g_nn = (nrm0 * (lawmob[0, 0] * nrm0 + lawmob[0, 1] * nrm1)
            + nrm1 * (lawmob[1, 0] * nrm0 + lawmob[1, 1] * nrm1))
    # the model's own n^T G n: what an impulse takes out of the simulated model
    g_model = (nrm0 * (mob[0, 0] * nrm0 + mob[0, 1] * nrm1)
               + nrm1 * (mob[1, 0] * nrm0 + mob[1, 1] * nrm1))
    e_cor = imp_cor[j]
    same_wall = (nrm0 * imp_normal[j, 0] + nrm1 * imp_normal[j, 1]) > 0.95
    dt_prev = t_cur - imp_last_t[j]
    if v_n > 0.0:
        J = (1.0 + e_cor) * v_n / (1.0 / m_i + g_nn)
        # the kinetic energy the impulse takes out of impactor and model,
        # J v_n - J^2 (1/m + g_model)/2, without cancellation; with the effective-mass law
        # (g_model = g_nn) the law's 0.5 (1 - e^2) v_n^2 / (1/m + g_nn)
        loss = 0.5 * J * (v_n * (1.0 - e_cor) + J * (g_nn - g_model))
        imp_v[j, 0] -= J * nrm0 / m_i
        imp_v[j, 1] -= J * nrm1 / m_i
        for i in range(yh.size):
            yh[i] += kick[0, i] * (J * nrm0)
            if n_rows == 2:
                yh[i] += kick[1, i] * (J * nrm1)
        ledger[0] += loss
        if count_step[j] > info[3]:
            info[3] = count_step[j]
        # the housing velocity jumps by G (J n): the model's mobility, whatever the law
        vh0 = X[1, 0]
        vh1 = X[1, 1] if n_rows == 2 else 0.0
        vh0a = vh0 + (mob[0, 0] * nrm0 + mob[0, 1] * nrm1) * J
        vh1a = vh1 + (mob[1, 0] * nrm0 + mob[1, 1] * nrm1) * J if n_rows == 2 else 0.0
        after_rel = nrm0 * (imp_v[j, 0] - vh0a) + (
            nrm1 * (imp_v[j, 1] - vh1a) if n_rows == 2 else 0.0)
        record(ev_t, ev_imp, ev_kind, ev_n, ev_vn, ev_J, ev_loss, ev_after, ev_count, t_cur, j,
               EV_IMPACT, nrm0, nrm1, v_n, J, loss, after_rel,
               nrm0 * (vh0a - vh0) + nrm1 * (vh1a - vh1))
        # the lock below needs the housing velocity after this impulse
        X[1, 0] = vh0a
        X[1, 1] = vh1a
    # sticking: bounce-down detected, or a contact without closing velocity
    stick = v_n <= 0.0
    if same_wall and v_n > 0.0:
        if stick_rule == STICK_PAPER and dt_prev < stick_time:
            stick = True
        elif stick_rule == STICK_ACCUMULATION and e_cor < 1.0 and \
                dt_prev * e_cor / (1.0 - e_cor) < stick_time:
            stick = True
    if count_step[j] > max_events_per_step:
        stick = True
    imp_last_t[j] = t_cur
    imp_normal[j, 0] = nrm0
    imp_normal[j, 1] = nrm1
    # Will the contact persist? The normal contact force per unit mass is -n . a_h, plus
    # v_t^2/c for an impactor sliding round a cylindrical housing. The lock cancels the
    # sliding too (the paper's realignment remedy), so a lock held by v_t^2/c alone is
    # released at the same instant: a realignment, booked as sticking loss. Locking on the
    # push alone instead doubles the impacts on hpotp (47,720 -> 103,802 in 6 s): each
    # sliding episode becomes chatter up to the per-step cap.
    a_n = nrm0 * X[2, 0] + (nrm1 * X[2, 1] if n_rows == 2 else 0.0)
    centripetal = 0.0
    if n_rows == 2:
        wr0 = imp_v[j, 0] - X[1, 0]
        wr1 = imp_v[j, 1] - X[1, 1]
        wn = nrm0 * wr0 + nrm1 * wr1
        centripetal = (wr0 * wr0 + wr1 * wr1 - wn * wn) / imp_limit[j]
    pushes = centripetal - a_n > 0.0
    if count_step[j] > max_events_per_step:
        pushes = True  # chatter: complete it plastically; release follows if not pressed
    if not (stick and pushes):
        return -1
    # plastic completion of the bounce-down: cancel the relative velocity
    vr0 = imp_v[j, 0] - X[1, 0]
    vr1 = (imp_v[j, 1] - X[1, 1]) if n_rows == 2 else 0.0
    if n_rows == 1:
        P0 = vr0 / (1.0 / m_i + lawmob[0, 0])
        P1 = 0.0
    else:
        a00 = 1.0 / m_i + lawmob[0, 0]
        a01 = lawmob[0, 1]
        a10 = lawmob[1, 0]
        a11 = 1.0 / m_i + lawmob[1, 1]
        det = a00 * a11 - a01 * a10
        P0 = (a11 * vr0 - a01 * vr1) / det
        P1 = (-a10 * vr0 + a00 * vr1) / det
    imp_v[j, 0] -= P0 / m_i
    imp_v[j, 1] -= P1 / m_i
    for i in range(yh.size):
        yh[i] += kick[0, i] * P0
        if n_rows == 2:
            yh[i] += kick[1, i] * P1
    imp_stuck[j] = 1
    imp_grace[j] = 1
    imp_rel[j, 0] = nrm0 * imp_limit[j]
    imp_rel[j, 1] = nrm1 * imp_limit[j] if n_rows == 2 else 0.0
    vh0a = X[1, 0] + mob[0, 0] * P0 + mob[0, 1] * P1
    vh1a = X[1, 1] + mob[1, 0] * P0 + mob[1, 1] * P1 if n_rows == 2 else 0.0
    # The energy the lock takes out of impactor and model: the impulse's
    # P.v_r - P^T (I/m + G_model) P / 2 = (P.v_r + P^T (G_law - G_model) P) / 2 (as
    # (I/m + G_law) P = v_r), plus m (|v_i|^2 - |v_h|^2) / 2: the stuck impactor rides
    # with the housing's velocity, so a relative velocity the law left is dropped. Both
    # extra terms vanish with the effective-mass law (G_law = G_model).
    dg0 = (lawmob[0, 0] - mob[0, 0]) * P0 + (lawmob[0, 1] - mob[0, 1]) * P1
    dg1 = (lawmob[1, 0] - mob[1, 0]) * P0 + (lawmob[1, 1] - mob[1, 1]) * P1
    w0 = imp_v[j, 0] - vh0a
    w1 = imp_v[j, 1] - vh1a if n_rows == 2 else 0.0
    drop = w0 * (imp_v[j, 0] + vh0a) + (w1 * (imp_v[j, 1] + vh1a) if n_rows == 2 else 0.0)
    lock_loss = 0.5 * (vr0 * P0 + vr1 * P1 + P0 * dg0 + P1 * dg1 + m_i * drop)
    ledger[1] += lock_loss
    after_rel = nrm0 * w0 + nrm1 * w1
    after_jump = nrm0 * (vh0a - X[1, 0]) + (nrm1 * (vh1a - X[1, 1]) if n_rows == 2 else 0.0)
    record(ev_t, ev_imp, ev_kind, ev_n, ev_vn, ev_J, ev_loss, ev_after, ev_count, t_cur, j,
           EV_STICK, nrm0, nrm1, nrm0 * vr0 + nrm1 * vr1, np.sqrt(P0 * P0 + P1 * P1),
           lock_loss, after_rel, after_jump)
    return 1


impact = kernel()(impact_py)
