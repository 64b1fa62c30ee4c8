"""Numba kernels of the exact propagator's event search: the first event of any impactor in a
sub-interval (:func:`search`), and the quiet-window certificate (:func:`quiet_window`).

Separate from the event loop (:mod:`.event_loop`), which calls :func:`search` once per
sub-interval and handles what it finds (:mod:`.contact`): the search reads the state and
writes only its result, its work arrays and the counters. Conventions as in
:mod:`.flow_eval`; ``counters`` as in :mod:`.codes`.

Event search over a sub-interval (from the current time to the end of the output step, or a
shorter Taylor segment):

1. *Filters.* With the exact state and its first derivatives at the start, and bounds of the
   derivatives over the sub-interval (:func:`.flow_eval.derivative_bounds`), an impactor is
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
"""
from __future__ import annotations

import math

import numpy as np
from numba import types

from . import kernel
from .codes import (
    CNT_CANDIDATES,
    CNT_CERTIFIED,
    CNT_EVALS,
    CNT_FALLBACK,
    CNT_SEARCHES,
    CNT_SEGMENTS,
    CNT_TAYLOR,
)
from .flow_eval import (
    add_particular,
    cabs,
    excursion_bounds,
    input_derivs,
    more_derivs,
    point_eval,
    row_derivs,
    search_bounds,
    site_bounds,
    site_reach,
    state_derivs,
)
from .poly import (
    BINOM,
    ROOT_FOUND,
    ROOT_NONE,
    certified_first_root,
    cubic_safe_step,
    positive_until,
    quadratic_first_root,
)
from .scan import FN_PLANAR, FN_RELEASE, FN_WALL_NEG, FN_WALL_POS, fn_values, scan_multi

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

    The housing moves by at most ``reach`` (m, see :func:`.flow_eval.site_bounds`) from ``X[0]``;
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
    largest ``|W u|`` over the window (:func:`.flow_eval.excursion_bounds`), and each impactor
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
