"""Numba kernels of the safe-step event scan, the rigorous fallback of the event search.

Event functions (per impactor): SDOF ``g = D/2 - s (z - x_h)`` for each wall ``s = +-1``;
planar ``g = c^2 - |z - x_h|^2``; stuck impactors have the release function ``f = -n . a_h``
(the normal contact force over the impactor mass). From a point with exact ``g, g', g''`` the
scan advances only as far as the cubic lower bound ``g + g' s + g'' s^2/2 - G3 s^3/6`` stays
positive, where ``G3`` bounds ``|g'''|`` over the interval from the modal amplitudes, so a dip
and return inside a step cannot be missed; brackets are refined by Illinois regula falsi.
:mod:`.event_loop` falls back on it where its Taylor-model search cannot certify an answer.
Conventions as in :mod:`.flow_eval`.
"""
from __future__ import annotations

import numpy as np
from numba import types

from . import kernel
from .flow_eval import derivative_bounds, point_eval, row_bound, row_derivs
from .poly import cubic_safe_step

_MAX_SCAN = 2000

FN_WALL_POS = 0
FN_WALL_NEG = 1
FN_PLANAR = 2
FN_RELEASE = 3


def fn_values_py(fid, X, z, v, tau, limit, normal):
    """Event function and its first two derivatives from housing kinematics ``X``.

    ``X[m, r]`` is the m-th derivative of housing row ``r``; ``z``/``v`` the impactor position
    and velocity at the start of the interval, ``tau`` the time into it.
    """
    if fid == FN_WALL_POS or fid == FN_WALL_NEG:
        s = 1.0 if fid == FN_WALL_POS else -1.0
        r = z[0] + v[0] * tau - X[0, 0]
        return limit - s * r, -s * (v[0] - X[1, 0]), s * X[2, 0]
    if fid == FN_PLANAR:
        d0 = z[0] + v[0] * tau - X[0, 0]
        d1 = z[1] + v[1] * tau - X[0, 1]
        e0 = v[0] - X[1, 0]
        e1 = v[1] - X[1, 1]
        g = limit * limit - (d0 * d0 + d1 * d1)
        g1 = -2.0 * (d0 * e0 + d1 * e1)
        g2 = -2.0 * (e0 * e0 + e1 * e1 - d0 * X[2, 0] - d1 * X[2, 1])
        return g, g1, g2
    # release: normal contact force per unit impactor mass, -n . a_h
    return (-(normal[0] * X[2, 0] + normal[1] * X[2, 1]),
            -(normal[0] * X[3, 0] + normal[1] * X[3, 1]),
            -(normal[0] * X[4, 0] + normal[1] * X[4, 1]))


fn_values = kernel(forceinline=True)(fn_values_py)


def fn_third_bound_py(fid, X, z, v, tau, limit, normal, ybound, rows, n_rows, T):
    """Bound on the event function's third derivative over the next ``T`` seconds."""
    if fid == FN_WALL_POS or fid == FN_WALL_NEG:
        return row_bound(rows, n_rows, ybound, 3)
    if fid == FN_PLANAR:
        x2 = row_bound(rows, n_rows, ybound, 2)
        x3 = row_bound(rows, n_rows, ybound, 3)
        e0 = v[0] - X[1, 0]
        e1 = v[1] - X[1, 1]
        dd = np.sqrt(e0 * e0 + e1 * e1) + T * x2
        d0 = z[0] + v[0] * tau - X[0, 0]
        d1 = z[1] + v[1] * tau - X[0, 1]
        d = np.sqrt(d0 * d0 + d1 * d1) + T * dd
        return 2.0 * (3.0 * dd * x2 + d * x3)
    return np.sqrt(normal[0] * normal[0] + normal[1] * normal[1]) * row_bound(rows, n_rows,
                                                                              ybound, 5)


fn_third_bound = kernel()(fn_third_bound_py)


def fn_at_py(fid, tau, t_cur, yh, lam, W, w0, ws, part_plus, part_minus, omegas, amps, u0, us,
             rows, n_rows, z, v, limit, normal, shift, yh_tau, y_tau, uder, yd, X):
    """Event function ``(f + shift, f', f'')`` at ``t_cur + tau`` (fills the work arrays)."""
    order = 4 if fid == FN_RELEASE else 2
    point_eval(yh, lam, W, w0, ws, part_plus, part_minus, omegas, amps, u0, us, t_cur, tau,
               order, yh_tau, y_tau, uder, yd)
    row_derivs(rows, n_rows, yd, order, X)
    f0, f1, f2 = fn_values(fid, X, z, v, tau, limit, normal)
    return f0 + shift, f1, f2


fn_at = kernel()(fn_at_py)


def refine_py(fid, a, b, t_cur, yh, lam, W, w0, ws, part_plus, part_minus, omegas, amps, u0,
              us, rows, n_rows, z, v, limit, normal, shift, yh_tau, y_tau, uder, yd, X):
    """Illinois regula falsi on a bracket with ``f(a) > 0 >= f(b)``; returns the ``b`` side."""
    fa, _, _ = fn_at(fid, a, t_cur, yh, lam, W, w0, ws, part_plus, part_minus, omegas, amps, u0,
                     us, rows, n_rows, z, v, limit, normal, shift, yh_tau, y_tau, uder, yd, X)
    fb, _, _ = fn_at(fid, b, t_cur, yh, lam, W, w0, ws, part_plus, part_minus, omegas, amps, u0,
                     us, rows, n_rows, z, v, limit, normal, shift, yh_tau, y_tau, uder, yd, X)
    if fa <= 0.0:
        return a
    side = 0
    tol = 4.0 * 2.220446049250313e-16 * max(abs(t_cur + b), 1e-300)
    for _ in range(200):
        if b - a <= tol:
            break
        c = (a * fb - b * fa) / (fb - fa)
        if not (a < c < b):
            c = 0.5 * (a + b)
        fc, _, _ = fn_at(fid, c, t_cur, yh, lam, W, w0, ws, part_plus, part_minus, omegas, amps,
                         u0, us, rows, n_rows, z, v, limit, normal, shift, yh_tau, y_tau, uder,
                         yd, X)
        if fc > 0.0:
            a = c
            fa = fc
            if side == 1:
                fb *= 0.5
            side = 1
        else:
            b = c
            fb = fc
            if side == -1:
                fa *= 0.5
            side = -1
    return b


refine = kernel()(refine_py)


def scan_multi_py(n_cand, cand_j, cand_fid, Th, t_cur, yh, lam, W, w0, ws, part_plus,
                  part_minus, omegas, amps, u0, us, house_q, imp_dim, imp_z, imp_v, imp_limit,
                  release_n, imp_grace, yh_tau, y_tau, uder, yd, X, ybound, u_abs, us_abs, ub,
                  wu, active, shifts, result):
    """First time in ``(0, Th]`` where any candidate event function reaches zero from above.

    Candidate ``c`` is the function ``cand_fid[c]`` of impactor ``cand_j[c]``. One state
    evaluation per scan point serves every candidate; the scan advances by the smallest safe
    step (cubic lower bound of each function, see :func:`cubic_safe_step`), probes, and
    refines any bracket found, after which the horizon shrinks to that event and the scan
    goes on for earlier ones. Writes ``result[0]`` = event time into the interval (s) or -1,
    ``result[1]`` = candidate index; returns 1 if the iteration budget ran out (a tangential
    touch with vanishing normal velocity), else 0.
    """
    nf = u0.size
    any_release = False
    for c in range(n_cand):
        active[c] = True
        shifts[c] = 0.0
        if cand_fid[c] == FN_RELEASE:
            any_release = True
    order = 4 if any_release else 2
    best_t = Th
    best_c = -1
    tau = 0.0
    undecided = 1
    for _ in range(_MAX_SCAN):
        T = best_t - tau
        n_active = 0
        for c in range(n_cand):
            if active[c]:
                n_active += 1
        if n_active == 0 or T <= 0.0:
            undecided = 0
            break
        point_eval(yh, lam, W, w0, ws, part_plus, part_minus, omegas, amps, u0, us, t_cur, tau,
                   order, yh_tau, y_tau, uder, yd)
        for f in range(nf):
            u_abs[f] = max(abs(u0[f] + us[f] * tau), abs(u0[f] + us[f] * best_t))
            us_abs[f] = abs(us[f])
        derivative_bounds(yh_tau, lam, W, part_plus, part_minus, w0, ws, tau, best_t, u_abs,
                          us_abs, omegas, amps, order + 1, ub, wu, ybound)
        s_min = T
        for c in range(n_cand):
            if not active[c]:
                continue
            j = cand_j[c]
            fid = cand_fid[c]
            n_rows = imp_dim[j]
            row_derivs(house_q[j], n_rows, yd, order, X)
            if tau == 0.0 and imp_grace[j] == 1:
                # just stuck or released: the boundary we start on is being left; shift it by
                # a negligible physical amount so that round-off cannot create a contact
                if fid == FN_RELEASE:
                    shifts[c] = 1e-9 * (abs(X[2, 0]) + abs(X[2, 1])) + 1e-300
                elif fid == FN_PLANAR:
                    shifts[c] = 1e-9 * imp_limit[j] * imp_limit[j]
                else:
                    shifts[c] = 1e-9 * imp_limit[j]
            f0, f1, f2 = fn_values(fid, X, imp_z[j], imp_v[j], tau, imp_limit[j], release_n[j])
            f0 += shifts[c]
            if f0 <= 0.0:
                if tau == 0.0 and (f1 > 0.0 or (f1 == 0.0 and f2 >= 0.0)):
                    f0 = 1e-300  # leaving the boundary we start on
                else:
                    result[0] = tau
                    result[1] = c
                    return 0
            g3 = fn_third_bound(fid, X, imp_z[j], imp_v[j], tau, imp_limit[j], release_n[j],
                                ybound, house_q[j], n_rows, T)
            s = cubic_safe_step(f0, f1, f2, g3, T, 0.0)
            if s >= T:
                active[c] = False  # no event before the current horizon
            elif s < s_min:
                s_min = s
        if s_min >= T:
            undecided = 0
            break
        probe = tau + min(T, max(2.0 * s_min, 1e-3 * T))
        point_eval(yh, lam, W, w0, ws, part_plus, part_minus, omegas, amps, u0, us, t_cur, probe,
                   order, yh_tau, y_tau, uder, yd)
        for c in range(n_cand):
            if not active[c]:
                continue
            j = cand_j[c]
            fid = cand_fid[c]
            row_derivs(house_q[j], imp_dim[j], yd, order, X)
            fp, _, _ = fn_values(fid, X, imp_z[j], imp_v[j], probe, imp_limit[j], release_n[j])
            if fp + shifts[c] <= 0.0:
                tc = refine(fid, tau + s_min, probe, t_cur, yh, lam, W, w0, ws, part_plus,
                            part_minus, omegas, amps, u0, us, house_q[j], imp_dim[j], imp_z[j],
                            imp_v[j], imp_limit[j], release_n[j], shifts[c], yh_tau, y_tau,
                            uder, yd, X)
                active[c] = False
                if tc < best_t or best_c < 0:
                    best_t = tc
                    best_c = c
        tau = tau + s_min
    result[0] = best_t if best_c >= 0 else -1.0
    result[1] = best_c
    return undecided


scan_multi = kernel(returns=types.int64)(scan_multi_py)
