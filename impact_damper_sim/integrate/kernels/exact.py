"""Numba kernel of the exact, event-located propagator: :func:`advance`.

Between events the modal state flows exactly (:mod:`.flow`). Events are impacts, sticks and
releases; every one of them, and the change of the model's configuration when an impactor
sticks or is released, is handled inside the compiled loop.

Event search over a sub-interval (from the current time to the end of the output step, or a
shorter Taylor segment):

1. *Filters.* With the exact state and its first derivatives at the start, and bounds of the
   derivatives over the sub-interval (:func:`.flow.derivative_bounds`), an impactor is
   cleared by an excursion bound or by the cubic lower bound of its event function
   (:mod:`.scan`) when it cannot reach a wall (or, stuck, its release) in the sub-interval.
2. *Taylor models.* Each remaining event function gets its Taylor polynomial of degree ``P``
   at the start and a bound of its ``(P + 1)``-th derivative over the segment; Bernstein
   range tests then either clear it or certify its first root: positive before a small
   bracket, strictly decreasing inside it (:func:`.poly.certified_first_root`). This needs
   no flow evaluation. The functions are taken by the first root of their quadratic model
   (:func:`.poly.quadratic_first_root`), an estimate: the earliest root tends to be
   certified first, and one range bound up to its bracket then clears most of the others.
3. *Refinement.* The earliest root is refined by Newton's method on the exact flow: one
   evaluation at the Taylor root, then, the correction being a few ulps, a third-order
   Taylor step of the state.
4. *Fallback.* A function the Taylor model cannot decide (a graze within its remainder)
   goes to the rigorous safe-step scan of :mod:`.scan`; so does nothing else.

Configurations: a stuck impactor adds its mass to its housing rows, in the same coordinates
(:class:`~impact_damper_sim.integrate.exact.MassUpdate`). Impactors with equal rows and mass
are interchangeable, so a configuration is the number stuck in each such group, and its slot
in the table ``tb_*`` is ``sum_g count_g radix_g``. The caller builds a slot on first use;
the kernel switches between built slots itself (``y_new = V_new^-1 Re(V_old y)``, lossless)
and returns ``CONFIG_CHANGE`` only for a slot not built yet, or at every change when
``table_mode`` is off (a provider that changes coordinates, such as the paper's basis switch).

Conventions as in :mod:`.flow`; ``counters`` (``CNT_*``) count the work done.
"""
from __future__ import annotations

import math

import numpy as np
from numba import types

from . import kernel

from .flow import (add_particular, cabs, excursion_bounds, input_derivs, more_derivs,
                   point_eval, row_derivs, search_bounds, site_bounds, site_reach, state_derivs)
from .ledger import N_TERMS as LEDGER_TERMS, harmonic_factors, ledger_closed, ledger_modal, \
    ledger_taylor, piece_factors
from .poly import (BINOM, ROOT_FOUND, ROOT_NONE, certified_first_root, cubic_safe_step,
                   positive_until, quadratic_first_root)
from .scan import FN_PLANAR, FN_RELEASE, FN_WALL_NEG, FN_WALL_POS, fn_values, scan_multi

# status codes returned by advance()
DONE = 0
CONFIG_CHANGE = 1
BUFFER_FULL = 2
NONFINITE = 3
CHATTER = 4

# event kinds
EV_IMPACT = 0
EV_STICK = 1
EV_RELEASE = 2
EV_GRAZE = 3

# sticking rules
STICK_NONE = 0
STICK_PAPER = 1
STICK_ACCUMULATION = 2

# counters
CNT_STEPS = 0          # output steps
CNT_SEARCHES = 1       # event searches (sub-intervals with impactors)
CNT_CANDIDATES = 2     # event functions that passed the filters (Taylor stage)
CNT_TAYLOR = 3         # high-order expansions of the state
CNT_EVALS = 4          # flow evaluations at arbitrary times, outside the ledger
CNT_LEDGER_PANELS = 5  # Taylor panels of the energy ledger (pieces it takes in series)
CNT_FALLBACK = 6       # event functions decided by the safe-step scan
CNT_SWITCHES = 7       # configuration switches inside the kernel
CNT_SEGMENTS = 8       # sub-intervals cut short at a Taylor segment end
CNT_QUIET = 9          # output steps certified event-free in advance (no search)
CNT_LEDGER_CLOSED = 10  # pieces of a step whose ledger is in closed form (no series)
CNT_CERTIFIED = 11     # Taylor models sent to certified_first_root (after the range bounds)
N_COUNTERS = 12

#: Output steps ahead that a quiet-window certificate tries to cover.
QUIET_STEPS = 8

#: Degree of the model that tries to clear a candidate up to the best bracket first.
CUBIC_MODEL = 3
#: Longest Taylor segment in units of the fastest mode's time constant (|lambda| S).
SEGMENT_REACH = 1.5
#: Largest |lambda| d of a correction taken by a Taylor step instead of a flow evaluation.
TAYLOR_STEP_REACH = 1e-4
_EPS = 2.220446049250313e-16
#: 1/m! (m <= 16; m! is exact in a double, so each entry is correctly rounded), to scale
#: Taylor coefficients by products: a division per term was the event functions' hottest chain
_INV_FACT = np.array([1.0 / math.factorial(m) for m in range(17)])
#: 1/m! rounded up (relative 1e-14), so that a derivative bound times it stays a bound
_INV_FACT_UP = _INV_FACT * (1.0 + 1e-14)


def grace_shift_py(fid, X, limit):
    """Shift of an event function whose impactor has just stuck, been released or impacted.

    The boundary it starts on is being left; moving it by a negligible physical amount keeps
    round-off from creating a contact at once.
    """
    if fid == FN_RELEASE:
        return 1e-9 * (abs(X[2, 0]) + abs(X[2, 1])) + 1e-300
    if fid == FN_PLANAR:
        return 1e-9 * limit * limit
    return 1e-9 * limit


grace_shift = kernel(forceinline=True)(grace_shift_py)


def fn_taylor_py(fid, X, z, v, limit, normal, P, Eb, S, shift, rw, a):
    """Taylor polynomial of an event function and a bound of its next derivative.

    ``X[m, r]`` holds exact derivatives of the housing rows at the start (m <= P, or P + 2 for
    a release), ``Eb[m]`` bounds ``|x^(m)|`` (2-norm over rows) on ``[0, S]`` (s); ``rw`` is
    scratch of shape ``(2, P + 1)``. Writes the normalized coefficients ``a[0..P]`` (``a[0]``
    shifted by ``shift``) and returns ``G``, a bound of ``|g^(P+1)|`` on ``[0, S]``.
    """
    if fid == FN_WALL_POS or fid == FN_WALL_NEG:
        sg = 1.0 if fid == FN_WALL_POS else -1.0
        a[0] = limit - sg * (z[0] - X[0, 0]) + shift
        a[1] = -sg * (v[0] - X[1, 0])
        for m in range(2, P + 1):
            a[m] = sg * X[m, 0] * _INV_FACT[m]
        return Eb[P + 1]
    if fid == FN_PLANAR:
        # g = c^2 - r.r with r = z + v s - x_h(s): Taylor coefficients of r, then of r.r
        for c in range(2):
            rw[c, 0] = z[c] - X[0, c]
            rw[c, 1] = v[c] - X[1, c]
        for m in range(2, P + 1):
            for c in range(2):
                rw[c, m] = -X[m, c] * _INV_FACT[m]
        for m in range(P + 1):
            acc = 0.0
            for i in range(m + 1):
                acc += rw[0, i] * rw[0, m - i] + rw[1, i] * rw[1, m - i]
            a[m] = -acc
        a[0] += limit * limit + shift
        # (P+1)-th derivative of r.r by Leibniz, with sup bounds of |r^(i)| over [0, S]
        r1 = np.sqrt(rw[0, 1] * rw[0, 1] + rw[1, 1] * rw[1, 1])
        b0 = np.sqrt(rw[0, 0] * rw[0, 0] + rw[1, 0] * rw[1, 0]) + r1 * S + 0.5 * Eb[2] * S * S
        b1 = r1 + Eb[2] * S
        G = 0.0
        n = P + 1
        for i in range(n + 1):
            bi = b0 if i == 0 else (b1 if i == 1 else Eb[i])
            k = n - i
            bk = b0 if k == 0 else (b1 if k == 1 else Eb[k])
            G += BINOM[n, i] * bi * bk
        return G
    # release: f = -n . a_h
    for m in range(P + 1):
        a[m] = -(normal[0] * X[m + 2, 0] + normal[1] * X[m + 2, 1]) * _INV_FACT[m]
    a[0] += shift
    return np.sqrt(normal[0] * normal[0] + normal[1] * normal[1]) * Eb[P + 3]


fn_taylor = kernel()(fn_taylor_py)


def near_eval_py(yh_tau, lam, W, w0, ws, s, d, omegas, part_plus, part_minus, amps, u0, us,
                 t_cur, order, y_tau, uder, yd):
    """Move ``yh_tau`` (the homogeneous-plus-hold part at ``s``) to ``s + d`` by its Taylor
    series to third order (for ``|lambda d| <= TAYLOR_STEP_REACH`` the error is below 1e-17
    relative), then fill the full state ``y_tau`` and its derivatives ``yd`` there."""
    for k in range(lam.size):
        d1 = lam[k] * yh_tau[k] + w0[k] + ws[k] * s
        d2 = lam[k] * d1 + ws[k]
        d3 = lam[k] * d2
        yh_tau[k] += d * (d1 + 0.5 * d * (d2 + d * d3 / 3.0))
    add_particular(yh_tau, omegas, part_plus, part_minus, t_cur + s + d, y_tau)
    input_derivs(u0, us, omegas, amps, t_cur + s + d, s + d, order, uder)
    state_derivs(y_tau, lam, W, uder, order, yd)


near_eval = kernel()(near_eval_py)


def refine_root_py(fid, s_a, s_b, r_hat, shift, t_cur, yh, lam, lam_max, W, w0, ws, part_plus,
                   part_minus, omegas, amps, u0, us, rows, n_rows, z, v, limit, normal,
                   yh_tau, y_tau, uder, yd, X, counters):
    """Root of an event function in its certified bracket ``[s_a, s_b]`` (s into the interval).

    Newton's method on the exact flow, safeguarded by the bracket; when the correction is a
    few ulps, the state is moved by a Taylor step instead of a new evaluation. Leaves the
    homogeneous part, the full state and its derivatives at the returned time in ``yh_tau``,
    ``y_tau`` and ``yd``.
    """
    order = 4 if fid == FN_RELEASE else 2
    lo = s_a
    hi = s_b
    s = min(max(r_hat, lo), hi)
    for _ in range(60):
        point_eval(yh, lam, W, w0, ws, part_plus, part_minus, omegas, amps, u0, us, t_cur, s,
                   order, yh_tau, y_tau, uder, yd)
        counters[CNT_EVALS] += 1
        row_derivs(rows, n_rows, yd, order, X)
        f, f1, f2 = fn_values(fid, X, z, v, s, limit, normal)
        f += shift
        if f > 0.0:
            lo = s
        else:
            hi = s
        tol = 4.0 * _EPS * max(abs(t_cur + s), 1e-300)
        if f1 < 0.0:
            step = -f / f1
            s_new = s + step
            # Newton's error after this step is about |f''/(2 f')| step^2: when that is below
            # the tolerance and the step is short, a Taylor step of the state replaces the
            # flow evaluation at the new point
            if lo <= s_new <= hi and abs(step) * lam_max <= TAYLOR_STEP_REACH and \
                    0.5 * abs(f2 / f1) * step * step <= tol:
                if abs(step) > tol:
                    near_eval(yh_tau, lam, W, w0, ws, s, step, omegas, part_plus, part_minus,
                              amps, u0, us, t_cur, order, y_tau, uder, yd)
                    return s_new
                return s
        else:
            s_new = 0.5 * (lo + hi)
        if hi - lo <= tol:
            return s
        if not (lo < s_new < hi):
            s_new = 0.5 * (lo + hi)
        s = s_new
    return s


refine_root = kernel()(refine_root_py)


def third_bound_py(fid, X, z, v, limit, normal, Eb, T):
    """Bound of the third derivative of an event function over ``[0, T]`` (s).

    From its site's bounds ``Eb[m]`` of the housing rows' m-th derivative (2-norm) over the
    interval and the rows' exact derivatives ``X`` at its start; the same bound as
    :func:`.scan.fn_third_bound`, which computes the row bounds itself.
    """
    if fid == FN_WALL_POS or fid == FN_WALL_NEG:
        return Eb[3]
    if fid == FN_PLANAR:
        e0 = v[0] - X[1, 0]
        e1 = v[1] - X[1, 1]
        dd = np.sqrt(e0 * e0 + e1 * e1) + T * Eb[2]
        d0 = z[0] - X[0, 0]
        d1 = z[1] - X[0, 1]
        d = np.sqrt(d0 * d0 + d1 * d1) + T * dd
        return 2.0 * (3.0 * dd * Eb[2] + d * Eb[3])
    return np.sqrt(normal[0] * normal[0] + normal[1] * normal[1]) * Eb[5]


third_bound = kernel(forceinline=True)(third_bound_py)


def out_of_reach_py(n_rows, reach, X, z, v, limit, T):
    """True if a free impactor cannot reach its clearance within ``T`` (s).

    The housing moves by at most ``reach`` (m, see :func:`.flow.site_bounds`) from ``X[0]``;
    the impactor moves on a straight line.
    """
    if n_rows == 1:
        r0 = z[0] - X[0, 0]
        r_end = r0 + v[0] * T
        return max(r0, r_end) + reach < limit and min(r0, r_end) - reach > -limit
    a0 = z[0] - X[0, 0]
    a1 = z[1] - X[0, 1]
    b0 = a0 + v[0] * T
    b1 = a1 + v[1] * T
    room = limit - reach
    return room > 0.0 and max(a0 * a0 + a1 * a1, b0 * b0 + b1 * b1) < room * room


out_of_reach = kernel(forceinline=True)(out_of_reach_py)


def sort_candidates_py(n_cand, cand_key, cand_j, cand_fid, cand_s0, cand_shift, cand_lv):
    """Order the first ``n_cand`` candidates by ``cand_key`` (s), ascending (insertion sort,
    stable: a handful of entries), each row's fields together."""
    for c in range(1, n_cand):
        j, fid, s0, shift, lv = cand_j[c], cand_fid[c], cand_s0[c], cand_shift[c], cand_lv[c]
        key = cand_key[c]
        d = c - 1
        while d >= 0 and cand_key[d] > key:
            cand_key[d + 1] = cand_key[d]
            cand_j[d + 1] = cand_j[d]
            cand_fid[d + 1] = cand_fid[d]
            cand_s0[d + 1] = cand_s0[d]
            cand_shift[d + 1] = cand_shift[d]
            cand_lv[d + 1] = cand_lv[d]
            d -= 1
        cand_key[d + 1] = key
        cand_j[d + 1] = j
        cand_fid[d + 1] = fid
        cand_s0[d + 1] = s0
        cand_shift[d + 1] = shift
        cand_lv[d + 1] = lv


sort_candidates = kernel()(sort_candidates_py)


def search_py(t_cur, horizon, yh, lam, lam_max, W, w0, ws, part_plus, part_minus, omegas, amps,
              u0, us, house, house_abs, imp_rep, imp_dim, imp_z, imp_v, imp_limit, imp_stuck,
              imp_grace, release_n, P, yh_tau, y_tau, uder, yd, Xs, ybound, u_abs, us_abs, ub,
              wu, exc, Eb, reach, cand_key, cand_j, cand_fid, cand_s0, cand_shift, cand_lv,
              cand_out, active, shifts, rwork, coef, pwork, root_out, scan_result, counters,
              result):
    """First event of any impactor in ``(0, horizon]`` (s into the interval from ``t_cur``).

    Writes ``result[0]`` = time into the interval (s), ``result[1]`` = impactor (-1: none
    before ``horizon``; -2: none before ``result[0]``, the end of a Taylor segment shorter
    than the horizon), ``result[2]`` = event function id, ``result[3]`` = 1 when ``yh_tau``,
    ``y_tau`` and ``yd`` (orders 0-2) hold the state at the event. Returns the number of
    functions the fallback scan left undecided (a tangential touch), -1 for a non-finite
    state.
    """
    ni = imp_dim.size
    nf = u0.size
    counters[CNT_SEARCHES] += 1
    # The filters (stage 1) bound the whole interval; the Taylor models (stage 2) are
    # certified over at most SEGMENT_REACH / lam_max, so a step longer than that is cut only
    # when a function comes near zero.
    S = horizon
    S_taylor = min(horizon, SEGMENT_REACH / lam_max) if lam_max > 0.0 else horizon
    result[0] = S
    result[1] = -1.0
    result[2] = -1.0
    result[3] = 0.0
    any_stuck = False
    for j in range(ni):
        if imp_stuck[j] == 1:
            any_stuck = True
    order_pt = 4 if any_stuck else 2
    order_b = P + 3 if any_stuck else P + 1
    point_eval(yh, lam, W, w0, ws, part_plus, part_minus, omegas, amps, u0, us, t_cur, 0.0,
               order_pt, yh_tau, y_tau, uder, yd)
    for f in range(nf):
        u_abs[f] = max(abs(u0[f]), abs(u0[f] + us[f] * S))
        us_abs[f] = abs(us[f])
    search_bounds(yh, lam, W, part_plus, part_minus, w0, ws, S, u_abs, us_abs, omegas, amps,
                  order_b, ub, wu, ybound, exc)
    for j in range(ni):
        if imp_rep[j] == j:
            row_derivs(house[j], imp_dim[j], yd, order_pt, Xs[j])
            reach[j] = site_bounds(house_abs[j], imp_dim[j], ybound, order_b, exc, Eb[j])
    # ---- stage 1: filters
    n_cand = 0
    any_release = False
    for j in range(ni):
        site = imp_rep[j]
        X = Xs[site]
        n_rows = imp_dim[j]
        if imp_stuck[j] == 1:
            f_first = FN_RELEASE
            f_last = FN_RELEASE
        elif n_rows == 1:
            f_first = FN_WALL_POS
            f_last = FN_WALL_NEG
        else:
            f_first = FN_PLANAR
            f_last = FN_PLANAR
        if imp_grace[j] == 0 and imp_stuck[j] == 0:
            if out_of_reach(n_rows, reach[site], X, imp_z[j], imp_v[j], imp_limit[j], S):
                continue
        for fid in range(f_first, f_last + 1):
            f0, f1, f2 = fn_values(fid, X, imp_z[j], imp_v[j], 0.0, imp_limit[j], release_n[j])
            if not (np.isfinite(f0) and np.isfinite(f1) and np.isfinite(f2)):
                return -1
            shift = grace_shift(fid, X, imp_limit[j]) if imp_grace[j] == 1 else 0.0
            f0 += shift
            leaving = False
            if f0 <= 0.0:
                if fid != FN_RELEASE and (f1 > 0.0 or (f1 == 0.0 and f2 >= 0.0)):
                    leaving = True  # on the wall and leaving it
                    f0 = 1e-300
                else:
                    result[0] = 0.0
                    result[1] = j
                    result[2] = fid
                    result[3] = 1.0
                    return 0
            g3 = third_bound(fid, X, imp_z[j], imp_v[j], imp_limit[j], release_n[j], Eb[site], S)
            s0 = cubic_safe_step(f0, f1, f2, g3, S, S_taylor)
            if s0 >= S:
                continue
            cand_j[n_cand] = j
            cand_fid[n_cand] = fid
            cand_s0[n_cand] = s0
            cand_shift[n_cand] = shift
            cand_lv[n_cand] = 1 if leaving else 0
            # stage 2 takes the earliest estimated root first: its bracket then clears most
            # of the others by one range bound (by safe step, x10 certified 2 roots a search)
            key = max(s0, quadratic_first_root(f0, f1, f2, leaving))
            cand_key[n_cand] = key if key < S else S + s0
            if fid == FN_RELEASE:
                any_release = True
            n_cand += 1
    if n_cand == 0:
        return 0
    if S_taylor < S:
        # the filters certify every function positive up to its safe step: no event before
        # the earliest of those; beyond the Taylor reach, search on from there
        first_s0 = S
        n_keep = 0
        for c in range(n_cand):
            first_s0 = min(first_s0, cand_s0[c])
            if cand_s0[c] < S_taylor:
                cand_j[n_keep] = cand_j[c]
                cand_fid[n_keep] = cand_fid[c]
                cand_s0[n_keep] = cand_s0[c]
                cand_shift[n_keep] = cand_shift[c]
                cand_lv[n_keep] = cand_lv[c]
                cand_key[n_keep] = cand_key[c]
                n_keep += 1
        if n_keep == 0:
            counters[CNT_SEGMENTS] += 1
            result[0] = first_s0
            result[1] = -2.0
            return 0
        n_cand = n_keep
        any_release = False
        for c in range(n_cand):
            if cand_fid[c] == FN_RELEASE:
                any_release = True
        S = S_taylor
        result[0] = S
        result[1] = -2.0
    # ---- stage 2: Taylor models on [0, S]
    order_hi = P + 2 if any_release else P
    counters[CNT_TAYLOR] += 1
    input_derivs(u0, us, omegas, amps, t_cur, 0.0, order_hi, uder)
    more_derivs(lam, W, uder, order_pt, order_hi, yd)
    for c in range(n_cand):
        site = imp_rep[cand_j[c]]
        if not active[site]:
            active[site] = True  # this site's rows are done
            row_derivs(house[site], imp_dim[site], yd, order_hi, Xs[site])
    n_slow = 0
    best_c = -1
    best_sb = S
    # 1/(P + 1)!, rounded up so that G/(P + 1)! stays a bound
    inv_fact = _INV_FACT_UP[P + 1]
    sort_candidates(n_cand, cand_key, cand_j, cand_fid, cand_s0, cand_shift, cand_lv)
    for c in range(n_cand):
        j = cand_j[c]
        site = imp_rep[j]
        active[site] = False
        cand_out[c, 0] = -1.0
        if best_c >= 0 and cand_s0[c] > best_sb:
            # positive up to its safe step, past the best bracket: it cannot hold the first
            # event
            continue
        counters[CNT_CANDIDATES] += 1
        if best_c >= 0 and cand_lv[c] == 0 and P > CUBIC_MODEL:
            # over the short span up to the best bracket a cubic model clears most functions
            # (a model of degree P costs P^2 for a cylinder)
            G = fn_taylor(cand_fid[c], Xs[site], imp_z[j], imp_v[j], imp_limit[j],
                          release_n[j], CUBIC_MODEL, Eb[site], S, cand_shift[c], rwork, coef)
            if positive_until(coef, CUBIC_MODEL, G * _INV_FACT_UP[CUBIC_MODEL + 1], best_sb,
                              pwork):
                continue
        G = fn_taylor(cand_fid[c], Xs[site], imp_z[j], imp_v[j], imp_limit[j], release_n[j], P,
                      Eb[site], S, cand_shift[c], rwork, coef)
        n = P
        K = G * inv_fact  # G / (P + 1)!
        Kd = K * (P + 1)  # G / P!
        if cand_lv[c] == 1:
            # g(0) = 0 and g leaves: certify the roots of g(s)/s instead
            for i in range(P):
                coef[i] = coef[i + 1]
            n = P - 1
            Kd = Kd + K
        if best_c >= 0 and positive_until(coef, n, K, best_sb, pwork):
            continue   # certified positive up to the best bracket's end
        counters[CNT_CERTIFIED] += 1
        status = certified_first_root(coef, n, K, Kd, S, cand_s0[c], pwork, root_out)
        if status == ROOT_NONE:
            continue
        if status == ROOT_FOUND:
            cand_out[c, 0] = root_out[0]
            cand_out[c, 1] = root_out[1]
            cand_out[c, 2] = root_out[2]
            if root_out[1] < best_sb or best_c < 0:
                best_sb = root_out[1]
                best_c = c
        else:
            cand_out[c, 0] = -2.0
            n_slow += 1
    # ---- stage 3: the earliest certified root, refined on the flow
    best_t = S
    best_j = -1
    best_fid = -1
    have_state = False
    undecided = 0
    if best_c >= 0:
        # a bracket overlapping the best one could hold an earlier root: refine those too
        for c in range(n_cand):
            if cand_out[c, 0] < 0.0 or not (c == best_c or cand_out[c, 0] < best_sb):
                continue
            j = cand_j[c]
            tc = refine_root(cand_fid[c], cand_out[c, 0], cand_out[c, 1], cand_out[c, 2],
                             cand_shift[c], t_cur, yh, lam, lam_max, W, w0, ws, part_plus,
                             part_minus, omegas, amps, u0, us, house[j], imp_dim[j], imp_z[j],
                             imp_v[j], imp_limit[j], release_n[j], yh_tau, y_tau, uder, yd,
                             Xs[ni], counters)
            if best_j < 0 or tc < best_t:
                best_t = tc
                best_j = j
                best_fid = cand_fid[c]
                have_state = True
            else:
                have_state = False  # the work arrays hold another candidate's state
    # ---- stage 4: undecided functions by the safe-step scan, up to the best root
    if n_slow > 0:
        n_scan = 0
        for c in range(n_cand):
            if cand_out[c, 0] == -2.0:
                cand_j[n_scan] = cand_j[c]
                cand_fid[n_scan] = cand_fid[c]
                n_scan += 1
        counters[CNT_FALLBACK] += n_scan
        undecided = scan_multi(n_scan, cand_j, cand_fid, best_t, t_cur, yh, lam, W, w0, ws,
                               part_plus, part_minus, omegas, amps, u0, us, house, imp_dim,
                               imp_z, imp_v, imp_limit, release_n, imp_grace, yh_tau, y_tau,
                               uder, yd, Xs[ni], ybound, u_abs, us_abs, ub, wu, active, shifts,
                               scan_result)
        for c in range(n_scan):
            active[c] = False
        have_state = False  # the scan used the work arrays
        if scan_result[0] >= 0.0 and (best_j < 0 or scan_result[0] < best_t):
            best_t = scan_result[0]
            best_j = cand_j[int(scan_result[1])]
            best_fid = cand_fid[int(scan_result[1])]
    if best_j >= 0:
        result[0] = best_t
        result[1] = best_j
        result[2] = best_fid
        result[3] = 1.0 if have_state else 0.0
    elif S < horizon:
        counters[CNT_SEGMENTS] += 1
    return undecided


search = kernel(returns=types.int64)(search_py)


def quiet_window_py(T, yh, lam, W, part_plus, part_minus, omegas, u_grid, k0, k1, house_abs,
                    imp_rep, imp_dim, imp_z, imp_v, imp_limit, imp_stuck, imp_grace, Xs, u_max,
                    w_max, w_zero, exc):
    """True if no free impactor can reach its clearance within ``T`` (s) from now.

    Valid whatever the input does between the grid samples ``u_grid[k0..k1]`` (N) that span
    the window, so unlike a search it may cross output steps, where the held input has kinks:
    the housing's excursion is bounded from ``|exp(lam t) - 1| |yh|`` plus ``T`` times the
    largest ``|W u|`` over the window (:func:`.flow.excursion_bounds`), and each impactor
    flies straight (:func:`out_of_reach`). ``Xs[site, 0]`` holds the housing rows' position
    now (m); a stuck impactor, or one on a boundary, is never certified.
    """
    ni = imp_dim.size
    for j in range(ni):
        if imp_stuck[j] == 1 or imp_grace[j] == 1:
            return False
    nf = W.shape[1]
    for f in range(nf):
        m = 0.0
        for g in range(k0, k1 + 1):
            m = max(m, abs(u_grid[g, f]))
        u_max[f] = m
    for k in range(lam.size):
        acc = 0.0
        for f in range(nf):
            acc += cabs(W[k, f]) * u_max[f]
        w_max[k] = acc + 0j
        w_zero[k] = 0j
    excursion_bounds(yh, lam, w_max, w_zero, part_plus, part_minus, omegas, T, exc)
    for j in range(ni):
        site = imp_rep[j]
        n_rows = imp_dim[j]
        reach = site_reach(house_abs[site], n_rows, exc)
        if not out_of_reach(n_rows, reach, Xs[site], imp_z[j], imp_v[j], imp_limit[j], T):
            return False
    return True


quiet_window = kernel()(quiet_window_py)


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
    order_max = P + 4
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
