"""Numba kernels of the exact, event-located propagator.

Conventions (all kernels): float64 and complex128 arrays only, no Python objects; times in
seconds; ``y`` is the complex first-order modal state of :mod:`.flow`; state arrays passed
in are updated in place. Every kernel is written as plain Python/NumPy (``*_py``) and
compiled with ``numba.njit(cache=True)``; the plain version is the kernel's NumPy twin and
tests run both (``test/test_kernels.py``) so that the JIT cannot hide an untested path.

Event handling inside :func:`advance`:

* gap functions: SDOF ``g = D/2 - s (z - x_h)`` for each wall ``s = +-1``; planar
  ``g = c^2 - |z - x_h|^2``; stuck impactors have the release function ``f = -n . a_h``
  (the normal contact force over the impactor mass);
* grazing guard: from a point with exact ``g, g', g''`` the scan advances only as far as the
  cubic lower bound ``g + g' s + g'' s^2/2 - G3 s^3/6`` stays positive, where ``G3`` bounds
  ``|g'''|`` over the step from the modal amplitudes; a dip and return inside a step cannot
  be missed;
* roots are refined by safeguarded Newton-bisection to a few ulps of time;
* chatter: impacts per step are capped; sticking (paper's rule or the accumulation-point
  rule) takes over, and a configuration change is handed back to the caller.
"""
from __future__ import annotations

import numpy as np
from numba import njit

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

_MAX_SCAN = 2000
_TWO_PI = 2.0 * np.pi


def phis_py(z):
    """Return ``((e^z - 1)/z, (e^z - 1 - z)/z^2)`` for complex ``z``, accurate near 0."""
    if abs(z) < 0.2:
        # Taylor series; |z|^k/k! < 1e-17 by k = 12 for |z| < 0.2
        a = 1.0 + 0j
        b = 0.5 + 0j
        term = 1.0 + 0j
        for k in range(1, 14):
            term *= z * (1.0 / k)
            a += term * (1.0 / (k + 1))
            b += term * (1.0 / ((k + 1) * (k + 2)))
            if abs(term) < 1e-18:
                break
        return a, b
    ez = np.exp(z)
    # 1/z by real arithmetic: complex division is several times slower
    inv = np.conj(z) * (1.0 / (z.real * z.real + z.imag * z.imag))
    return (ez - 1.0) * inv, (ez - 1.0 - z) * inv * inv


phis = njit(cache=True)(phis_py)


def propagate_py(yh, lam, tau, w0, ws, out):
    """Homogeneous-plus-first-order-hold flow over ``tau`` (s): ``out = yh(tau)``.

    ``yh' = lam yh + w0 + ws t`` exactly, for ``t`` in ``[0, tau]``.
    """
    if tau == 0.0:
        for k in range(lam.size):
            out[k] = yh[k]
        return
    for k in range(lam.size):
        z = lam[k] * tau
        if abs(z) < 0.2:
            f1, f2 = phis(z)
            out[k] = np.exp(z) * yh[k] + tau * f1 * w0[k] + tau * tau * f2 * ws[k]
        else:
            ez = np.exp(z)
            inv = np.conj(lam[k]) * (1.0 / (lam[k].real * lam[k].real + lam[k].imag * lam[k].imag))
            em1 = (ez - 1.0) * inv  # tau phi1
            out[k] = ez * yh[k] + em1 * w0[k] + (em1 - tau) * inv * ws[k]


propagate = njit(cache=True)(propagate_py)


def step_factors_py(lam, h, e_h, p1_h, p2_h):
    """Factors of the flow over a full step ``h`` (s): ``exp(lam h)``, ``h phi1``, ``h^2 phi2``."""
    for k in range(lam.size):
        z = lam[k] * h
        f1, f2 = phis(z)
        e_h[k] = np.exp(z)
        p1_h[k] = h * f1
        p2_h[k] = h * h * f2


step_factors = njit(cache=True)(step_factors_py)


def add_particular_py(yh, omegas, part_plus, part_minus, t, out):
    """``out = yh + y_p(t)``: add the harmonic particular solution at absolute time ``t``."""
    for k in range(yh.size):
        out[k] = yh[k]
    for h in range(omegas.size):
        ep = np.exp(1j * omegas[h] * t)
        em = np.conj(ep)
        for k in range(yh.size):
            out[k] += part_plus[h, k] * ep + part_minus[h, k] * em


add_particular = njit(cache=True)(add_particular_py)


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


input_derivs = njit(cache=True)(input_derivs_py)


def state_derivs_py(y, lam, W, uder, order, out):
    """``out[m] = d^m y / dt^m`` for ``m <= order`` from ``y' = lam y + W u``."""
    n2 = y.size
    nf = W.shape[1]
    for k in range(n2):
        out[0, k] = y[k]
    for m in range(1, order + 1):
        for k in range(n2):
            acc = lam[k] * out[m - 1, k]
            for f in range(nf):
                acc += W[k, f] * uder[m - 1, f]
            out[m, k] = acc


state_derivs = njit(cache=True)(state_derivs_py)


def derivative_bounds_py(yh, lam, W, part_plus, part_minus, w0, ws, tau, Th, u_abs, us_abs,
                         omegas, amps, order, ub, wu, out):
    """Bounds on ``|d^m y_k/dt^m|`` over ``[tau, Th]`` (s) for ``m <= order``.

    ``yh`` is the homogeneous-plus-hold part at ``tau``; the held input term is
    ``W u = w0 + ws t``; ``u_abs``/``us_abs`` bound the held inputs and their slope; ``ub`` and
    ``wu`` are scratch arrays. With ``T = Th - tau`` the bound on ``|yh_k|`` is
    ``exp(max(Re lam_k, 0) T) (|yh_k| + T max|W u|_k)``, and
    ``|y^(m)| <= |lam|^m |y| + sum_j |lam|^(m-1-j) |W u^(j)|``.
    """
    n2 = lam.size
    nf = W.shape[1]
    nh = omegas.size
    T = Th - tau
    for j in range(order + 1):
        for f in range(nf):
            ub[j, f] = 0.0
    for f in range(nf):
        ub[0, f] = u_abs[f]
        if order >= 1:
            ub[1, f] = us_abs[f]
    for h in range(nh):
        for f in range(nf):
            a = abs(amps[h, f])
            p = 1.0
            for j in range(order + 1):
                ub[j, f] += a * p
                p *= omegas[h]
    for k in range(n2):
        grow = np.exp(max(lam[k].real, 0.0) * T)
        b = grow * (abs(yh[k]) + T * max(abs(w0[k] + ws[k] * tau), abs(w0[k] + ws[k] * Th)))
        for h in range(nh):
            b += abs(part_plus[h, k]) + abs(part_minus[h, k])
        lk = abs(lam[k])
        for j in range(order + 1):
            s = 0.0
            for f in range(nf):
                s += abs(W[k, f]) * ub[j, f]
            wu[j] = s
        # Horner-like recurrence: B_m = |lam| B_{m-1} + |W u^(m-1)|, B_0 = b
        acc = b
        out[0, k] = acc
        for m in range(1, order + 1):
            acc = lk * acc + wu[m - 1]
            out[m, k] = acc


derivative_bounds = njit(cache=True)(derivative_bounds_py)


def cubic_safe_step_py(g0, g1, g2, g3max, T):
    """Largest ``s <= T`` with ``p(s) = g0 + g1 s + g2 s^2/2 - g3max s^3/6 > 0`` on ``[0, s)``.

    ``p`` is a lower bound of ``g`` when ``g3max`` bounds the third derivative of ``g``.
    Returns ``T`` when ``p`` stays positive over the whole interval. The search splits
    ``[0, T]`` at the roots of ``dp/ds`` so that every piece is monotone, then bisects in the
    first piece that ends at or below zero, returning its last point known to be positive.
    """
    if g0 <= 0.0:
        return 0.0
    cuts = np.empty(3)
    n_cut = 0
    a2 = -0.5 * g3max  # dp/ds = g1 + g2 s + a2 s^2
    if a2 != 0.0:
        disc = g2 * g2 - 4.0 * a2 * g1
        if disc >= 0.0:
            r = np.sqrt(disc)
            s1 = (-g2 + r) / (2.0 * a2)
            s2 = (-g2 - r) / (2.0 * a2)
            if s1 > s2:
                s1, s2 = s2, s1
            if 0.0 < s1 < T:
                cuts[n_cut] = s1
                n_cut += 1
            if 0.0 < s2 < T:
                cuts[n_cut] = s2
                n_cut += 1
    elif g2 != 0.0:
        s1 = -g1 / g2
        if 0.0 < s1 < T:
            cuts[n_cut] = s1
            n_cut += 1
    cuts[n_cut] = T
    n_cut += 1
    lo = 0.0
    for i in range(n_cut):
        hi = cuts[i]
        if g0 + hi * (g1 + hi * (0.5 * g2 - hi * g3max / 6.0)) <= 0.0:
            for _ in range(80):
                mid = 0.5 * (lo + hi)
                if g0 + mid * (g1 + mid * (0.5 * g2 - mid * g3max / 6.0)) > 0.0:
                    lo = mid
                else:
                    hi = mid
                if hi - lo <= 1e-3 * hi:
                    break
            return lo
        lo = hi
    return T


cubic_safe_step = njit(cache=True)(cubic_safe_step_py)


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


point_eval = njit(cache=True)(point_eval_py)


def row_derivs_py(rows, n_rows, yd, order, out):
    """``out[m, r] = Re(rows[r] . yd[m])``: housing kinematics (m, m/s, m/s^2, ...)."""
    n2 = yd.shape[1]
    for m in range(order + 1):
        for r in range(n_rows):
            acc = 0j
            for k in range(n2):
                acc += rows[r, k] * yd[m, k]
            out[m, r] = acc.real


row_derivs = njit(cache=True)(row_derivs_py)


def row_bound_py(rows, n_rows, ybound, m):
    """Bound of ``|d^m x_r/dt^m|`` per row from per-coordinate bounds; returns the 2-norm."""
    total = 0.0
    for r in range(n_rows):
        acc = 0.0
        for k in range(ybound.shape[1]):
            acc += abs(rows[r, k]) * ybound[m, k]
        total += acc * acc
    return np.sqrt(total)


row_bound = njit(cache=True)(row_bound_py)

# event function ids
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


fn_values = njit(cache=True)(fn_values_py)


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


fn_third_bound = njit(cache=True)(fn_third_bound_py)


def fn_at_py(fid, tau, t_cur, yh, lam, W, w0, ws, part_plus, part_minus, omegas, amps, u0, us,
             rows, n_rows, z, v, limit, normal, shift, yh_tau, y_tau, uder, yd, X):
    """Event function ``(f + shift, f', f'')`` at ``t_cur + tau`` (fills the work arrays)."""
    order = 4 if fid == FN_RELEASE else 2
    point_eval(yh, lam, W, w0, ws, part_plus, part_minus, omegas, amps, u0, us, t_cur, tau,
               order, yh_tau, y_tau, uder, yd)
    row_derivs(rows, n_rows, yd, order, X)
    f0, f1, f2 = fn_values(fid, X, z, v, tau, limit, normal)
    return f0 + shift, f1, f2


fn_at = njit(cache=True)(fn_at_py)


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


refine = njit(cache=True)(refine_py)


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
            s = cubic_safe_step(f0, f1, f2, g3, T)
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


scan_multi = njit(cache=True)(scan_multi_py)


def ledger_panel_py(yh, lam, W, w0, ws, part_plus, part_minus, omegas, amps, u0, us, t_cur,
                    tau, Vq, Vv, Cmat, Kskew, Bmat, yh_tau, y_tau, uder, yd, ledger):
    """Add damping dissipation, forcing work and circulatory work over ``[0, tau]`` (J).

    Composite 4-point Gauss-Legendre, with panels no wider than ``0.5/max|lambda|`` so the
    relative quadrature error stays below about 1e-10.
    """
    if tau <= 0.0:
        return
    lam_max = 0.0
    for k in range(lam.size):
        lam_max = max(lam_max, abs(lam[k]))
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


ledger_panel = njit(cache=True)(ledger_panel_py)



_GL4_X = np.array([-0.8611363115940526, -0.3399810435848563, 0.3399810435848563,
                   0.8611363115940526])
_GL4_W = np.array([0.3478548451374538, 0.6521451548625461, 0.6521451548625461,
                   0.3478548451374538])


def ledger_node_count_py(lam, h):
    """Number of Gauss nodes of :func:`ledger_panel` over a step of ``h`` (s)."""
    lam_max = 0.0
    for k in range(lam.size):
        lam_max = max(lam_max, abs(lam[k]))
    n_panels = int(np.ceil(h * lam_max / 0.5))
    return 4 * max(n_panels, 1)


ledger_node_count = njit(cache=True)(ledger_node_count_py)


def ledger_nodes_py(lam, omegas, h, s_nodes, w_nodes, E, P1, P2, EH):
    """Nodes ``s`` (s), weights (s) and flow factors of :func:`ledger_panel`'s rule over a
    whole step ``h``: ``E = exp(lam s)``, ``P1 = s phi1(lam s)``, ``P2 = s^2 phi2(lam s)`` and
    ``EH = exp(i omegas s)``, so that a whole step's quadrature needs no exponentials."""
    n_nodes = s_nodes.size
    width = h / (n_nodes // 4)
    for p in range(n_nodes // 4):
        mid = (p + 0.5) * width
        for g in range(4):
            i = 4 * p + g
            s = mid + 0.5 * width * _GL4_X[g]
            s_nodes[i] = s
            w_nodes[i] = 0.5 * width * _GL4_W[g]
            for k in range(lam.size):
                f1, f2 = phis(lam[k] * s)
                E[i, k] = np.exp(lam[k] * s)
                P1[i, k] = s * f1
                P2[i, k] = s * s * f2
            for hh in range(omegas.size):
                EH[i, hh] = np.exp(1j * omegas[hh] * s)


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
                   Kskew, circulatory, Bmat, y_tau, ledger):
    """:func:`ledger_panel` over a whole step with the node factors of :func:`ledger_nodes`.

    The same rule and nodes, so the same result to round-off, at a fraction of the cost: no
    exponentials, the sparsity of ``Vq``/``Vv`` (two entries per row for uncoupled modes)
    and no circulatory term without a skew stiffness.
    """
    n = Vq.shape[0]
    n2 = yh.size
    nf = u0.size
    nh = omegas.size
    q = np.zeros(n)
    qd = np.empty(n)
    u = np.empty(nf)
    eh_t = np.empty(nh, dtype=np.complex128)
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
            for k2 in range(n):
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


def housing_velocity_py(yh, lam, W, w0, ws, part_plus, part_minus, omegas, amps, u0, us, t,
                        rows, n_rows, yh_tau, y_tau, uder, yd, X):
    """Housing displacement and velocity rows at ``t`` from the current state into ``X``."""
    point_eval(yh, lam, W, w0, ws, part_plus, part_minus, omegas, amps, u0, us, t, 0.0, 1,
               yh_tau, y_tau, uder, yd)
    row_derivs(rows, n_rows, yd, 1, X)


housing_velocity = njit(cache=True)(housing_velocity_py)


def excursion_bounds_py(yh, lam, w0, ws, part_plus, part_minus, omegas, T, out):
    """Bound on ``|y_k(t) - y_k(0)|`` over ``[0, T]`` (s), into ``out``.

    Homogeneous part: ``|exp(lam t) - 1| <= min(|lam| t, 2) exp(max(Re lam, 0) t)``; held
    inputs add at most ``T max|W u|``; each harmonic's particular part moves by at most
    ``min(Omega T, 2)`` times its size. Much tighter than ``|y| + |y(0)|`` for short steps,
    since the transient and particular parts of ``y`` may cancel.
    """
    for k in range(lam.size):
        grow = np.exp(max(lam[k].real, 0.0) * T)
        held = T * max(abs(w0[k]), abs(w0[k] + ws[k] * T))
        b = grow * (abs(yh[k]) * min(abs(lam[k]) * T, 2.0) + held)
        for h in range(omegas.size):
            b += (abs(part_plus[h, k]) + abs(part_minus[h, k])) * min(omegas[h] * T, 2.0)
        out[k] = b


excursion_bounds = njit(cache=True)(excursion_bounds_py)


def excursion_clear_py(rows, n_rows, exc, X, z, v, limit, T):
    """True if a free impactor cannot reach its clearance within ``T`` (s).

    Each housing row moves by at most ``sum_k |rows_k| exc_k`` from ``X[0]`` (``exc`` from
    :func:`excursion_bounds`); the impactor moves on a straight line.
    """
    reach = 0.0
    for r in range(n_rows):
        acc = 0.0
        for k in range(exc.size):
            acc += abs(rows[r, k]) * exc[k]
        reach += acc * acc
    reach = np.sqrt(reach)
    if n_rows == 1:
        r0 = z[0] - X[0, 0]
        r_end = r0 + v[0] * T
        return max(r0, r_end) + reach < limit and min(r0, r_end) - reach > -limit
    d0 = np.hypot(z[0] - X[0, 0], z[1] - X[0, 1])
    d1 = np.hypot(z[0] + v[0] * T - X[0, 0], z[1] + v[1] * T - X[0, 1])
    return max(d0, d1) + reach < limit


excursion_clear = njit(cache=True)(excursion_clear_py)


def advance_py(t_state, t_base, h, k_start, n_steps, u_grid, omegas, amps,
               yh, lam, W, Vq, Vv, part_plus, part_minus, sensor_q, sensor_v,
               house_q, kick, mobility, release_map,
               imp_dim, imp_mass, imp_cor, imp_limit,
               imp_z, imp_v, imp_stuck, imp_normal, imp_last_t, imp_rel, imp_grace, count_step,
               stick_rule, stick_time, max_events_per_step,
               ledger_on, Cmat, Kskew, Bmat, ledger,
               out_disp, out_vel, out_acc,
               ev_t, ev_imp, ev_kind, ev_n, ev_vn, ev_J, ev_loss, ev_after, ev_count, info):
    """Advance the model with its impactors over grid steps ``k_start .. n_steps-1``.

    Step ``k`` ends at ``t_base + (k + 1) h`` where sensor outputs are recorded; the
    current time ``t_state[0]`` lies in step ``k_start``. Returns a status code; ``info[0]``
    holds the step in progress, ``info[1]`` the impactor that changed state, ``info[2]``
    the number of undecided grazing scans, ``info[3]`` the largest impacts in one step.
    On ``CONFIG_CHANGE`` the state is at the event time and the caller must rebuild the
    flow arrays for the new stuck set, convert ``yh`` and call again.
    """
    n2 = lam.size
    nf = W.shape[1]
    ni = imp_dim.size
    order_max = 5
    yh_tau = np.empty(n2, dtype=np.complex128)
    y_tau = np.empty(n2, dtype=np.complex128)
    yd = np.empty((order_max + 1, n2), dtype=np.complex128)
    uder = np.empty((order_max + 1, nf))
    X = np.zeros((order_max + 1, 2))
    Xa = np.zeros((order_max + 1, 2))
    ybound = np.empty((order_max + 1, n2))
    u_abs = np.empty(nf)
    us_abs = np.empty(nf)
    exc = np.empty(n2)
    cand_j = np.empty(2 * ni + 1, dtype=np.int64)
    cand_fid = np.empty(2 * ni + 1, dtype=np.int64)
    active = np.empty(2 * ni + 1, dtype=np.bool_)
    shifts = np.empty(2 * ni + 1)
    scan_result = np.empty(2)
    ub = np.empty((order_max + 1, nf))
    wu = np.empty(order_max + 1)
    w0 = np.empty(n2, dtype=np.complex128)
    ws = np.empty(n2, dtype=np.complex128)
    u0 = np.empty(nf)
    us = np.empty(nf)
    # the normal of each release function: release_map^T n (frictionless contact force)
    release_n = np.zeros((ni, 2))
    for j in range(ni):
        for r in range(2):
            release_n[j, r] = (release_map[j, 0, r] * imp_normal[j, 0]
                               + release_map[j, 1, r] * imp_normal[j, 1])
    cap = ev_t.size
    e_h = np.empty(n2, dtype=np.complex128)
    p1_h = np.empty(n2, dtype=np.complex128)
    p2_h = np.empty(n2, dtype=np.complex128)
    step_factors(lam, h, e_h, p1_h, p2_h)
    # the ledger's quadrature over a whole step: node factors once per call (see ledger_step)
    n_nodes = ledger_node_count(lam, h) if ledger_on else 0
    s_nodes = np.empty(n_nodes)
    w_nodes = np.empty(n_nodes)
    E_n = np.empty((n_nodes, n2), dtype=np.complex128)
    P1_n = np.empty((n_nodes, n2), dtype=np.complex128)
    P2_n = np.empty((n_nodes, n2), dtype=np.complex128)
    EH_n = np.empty((n_nodes, omegas.size), dtype=np.complex128)
    n_q = Vq.shape[0]
    q_cols = np.empty((n_q, n2), dtype=np.int64)
    q_counts = np.empty(n_q, dtype=np.int64)
    v_cols = np.empty((n_q, n2), dtype=np.int64)
    v_counts = np.empty(n_q, dtype=np.int64)
    circulatory = False
    if ledger_on:
        ledger_nodes(lam, omegas, h, s_nodes, w_nodes, E_n, P1_n, P2_n, EH_n)
        row_pattern(Vq, q_cols, q_counts)
        row_pattern(Vv, v_cols, v_counts)
        for i in range(Kskew.shape[0]):
            for i2 in range(Kskew.shape[1]):
                if Kskew[i, i2] != 0.0:
                    circulatory = True
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
        while True:
            for f in range(nf):
                u0[f] = u_grid[k, f] + us[f] * (t_cur - t_k)
            for i in range(n2):
                acc0 = 0j
                accs = 0j
                for f in range(nf):
                    acc0 += W[i, f] * u0[f]
                    accs += W[i, f] * us[f]
                w0[i] = acc0
                ws[i] = accs
            horizon = t_b - t_cur
            best = horizon
            best_j = -1
            best_fid = -1
            if ni > 0:
                # one evaluation at the start, shared by every impactor: exact derivatives and
                # bounds over the whole sub-interval; most impactors are cleared right here
                any_stuck = False
                for j in range(ni):
                    if imp_stuck[j] == 1:
                        any_stuck = True
                order_pt = 4 if any_stuck else 2
                point_eval(yh, lam, W, w0, ws, part_plus, part_minus, omegas, amps, u0, us,
                           t_cur, 0.0, order_pt, yh_tau, y_tau, uder, yd)
                for f in range(nf):
                    u_abs[f] = max(abs(u0[f]), abs(u0[f] + us[f] * horizon))
                    us_abs[f] = abs(us[f])
                derivative_bounds(yh, lam, W, part_plus, part_minus, w0, ws, 0.0, horizon,
                                  u_abs, us_abs, omegas, amps, order_pt + 1, ub, wu, ybound)
                excursion_bounds(yh, lam, w0, ws, part_plus, part_minus, omegas, horizon, exc)
            n_cand = 0
            for j in range(ni):
                n_rows = imp_dim[j]
                if imp_stuck[j] == 1:
                    fids = (FN_RELEASE, -1)
                elif n_rows == 1:
                    fids = (FN_WALL_POS, FN_WALL_NEG)
                else:
                    fids = (FN_PLANAR, -1)
                if imp_grace[j] == 0 and imp_stuck[j] == 0:
                    # excursion test: the housing moves by at most sum_k |H_k| exc_k and the
                    # impactor on a straight line, so a gap that cannot close over the
                    # sub-interval needs no derivative-based guard at all
                    row_derivs(house_q[j], n_rows, yd, 0, X)
                    if excursion_clear(house_q[j], n_rows, exc, X, imp_z[j], imp_v[j],
                                       imp_limit[j], best):
                        continue
                if imp_grace[j] == 0:
                    row_derivs(house_q[j], n_rows, yd, 4 if imp_stuck[j] == 1 else 2, X)
                for fid in fids:
                    if fid < 0:
                        continue
                    if imp_grace[j] == 0:
                        f0, f1, f2 = fn_values(fid, X, imp_z[j], imp_v[j], 0.0, imp_limit[j],
                                               release_n[j])
                        if f0 > 0.0:
                            g3 = fn_third_bound(fid, X, imp_z[j], imp_v[j], 0.0, imp_limit[j],
                                                release_n[j], ybound, house_q[j], n_rows,
                                                horizon)
                            if cubic_safe_step(f0, f1, f2, g3, best) >= best:
                                continue
                    cand_j[n_cand] = j
                    cand_fid[n_cand] = fid
                    n_cand += 1
            if n_cand > 0:
                info[2] += scan_multi(n_cand, cand_j, cand_fid, horizon, t_cur, yh, lam, W, w0,
                                      ws, part_plus, part_minus, omegas, amps, u0, us, house_q,
                                      imp_dim, imp_z, imp_v, imp_limit, release_n, imp_grace,
                                      yh_tau, y_tau, uder, yd, X, ybound, u_abs, us_abs, ub, wu,
                                      active, shifts, scan_result)
                if scan_result[0] >= 0.0:
                    best = scan_result[0]
                    best_j = cand_j[int(scan_result[1])]
                    best_fid = cand_fid[int(scan_result[1])]
            tau = best
            if ledger_on and best_j < 0 and t_cur == t_k:
                ledger_step(yh, w0, ws, part_plus, part_minus, omegas, amps, u0, us, t_cur,
                            s_nodes, w_nodes, E_n, P1_n, P2_n, EH_n, Vq, Vv, q_cols, q_counts,
                            v_cols, v_counts, Cmat, Kskew, circulatory, Bmat, y_tau, ledger)
            elif ledger_on:
                ledger_panel(yh, lam, W, w0, ws, part_plus, part_minus, omegas, amps, u0, us,
                             t_cur, tau, Vq, Vv, Cmat, Kskew, Bmat, yh_tau, y_tau, uder, yd,
                             ledger)
            if best_j < 0 and t_cur == t_k:
                # a whole step without events: the cached step factors
                for i in range(n2):
                    yh[i] = e_h[i] * yh[i] + p1_h[i] * w0[i] + p2_h[i] * ws[i]
            else:
                point_eval(yh, lam, W, w0, ws, part_plus, part_minus, omegas, amps, u0, us,
                           t_cur, tau, 2, yh_tau, y_tau, uder, yd)
                for i in range(n2):
                    yh[i] = yh_tau[i]
            for j in range(ni):
                if imp_stuck[j] == 0:
                    for r in range(imp_dim[j]):
                        imp_z[j, r] += imp_v[j, r] * tau
            t_cur = t_cur + tau if best_j >= 0 else t_b
            if tau > 0.0:
                for j in range(ni):
                    imp_grace[j] = 0
            if best_j < 0:
                break
            # ---- an event at t_cur for impactor j
            j = best_j
            n_rows = imp_dim[j]
            row_derivs(house_q[j], n_rows, yd, 2, X)
            if ev_count[0] >= cap:
                t_state[0] = t_cur
                info[0] = k
                return BUFFER_FULL
            count_step[j] += 1
            if count_step[j] > 4 * max_events_per_step + 16:
                t_state[0] = t_cur
                info[0] = k
                info[1] = j
                return CHATTER
            if best_fid == FN_RELEASE:
                imp_stuck[j] = 0
                imp_grace[j] = 1
                for r in range(n_rows):
                    imp_z[j, r] = X[0, r] + imp_rel[j, r]
                    imp_v[j, r] = X[1, r]
                imp_last_t[j] = t_cur
                e = ev_count[0]
                ev_t[e] = t_cur
                ev_imp[e] = j
                ev_kind[e] = EV_RELEASE
                ev_n[e, 0] = imp_normal[j, 0]
                ev_n[e, 1] = imp_normal[j, 1]
                ev_vn[e] = 0.0
                ev_J[e] = 0.0
                ev_loss[e] = 0.0
                ev_after[e, 0] = 0.0
                ev_after[e, 1] = 0.0
                ev_count[0] = e + 1
                t_state[0] = t_cur
                info[0] = k
                info[1] = j
                return CONFIG_CHANGE
            # contact normal (outward) and relative velocity
            nrm0 = 0.0
            nrm1 = 0.0
            if n_rows == 1:
                nrm0 = 1.0 if best_fid == FN_WALL_POS else -1.0
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
            g_nn = (nrm0 * (mobility[j, 0, 0] * nrm0 + mobility[j, 0, 1] * nrm1)
                    + nrm1 * (mobility[j, 1, 0] * nrm0 + mobility[j, 1, 1] * nrm1))
            e_cor = imp_cor[j]
            same_wall = (nrm0 * imp_normal[j, 0] + nrm1 * imp_normal[j, 1]) > 0.95
            dt_prev = t_cur - imp_last_t[j]
            J = 0.0
            loss = 0.0
            if v_n > 0.0:
                J = (1.0 + e_cor) * v_n / (1.0 / m_i + g_nn)
                loss = 0.5 * (1.0 - e_cor * e_cor) * v_n * v_n / (1.0 / m_i + g_nn)
                imp_v[j, 0] -= J * nrm0 / m_i
                imp_v[j, 1] -= J * nrm1 / m_i
                for i in range(n2):
                    yh[i] += kick[j, 0, i] * (J * nrm0)
                    if n_rows == 2:
                        yh[i] += kick[j, 1, i] * (J * nrm1)
                ledger[0] += loss
                if count_step[j] > info[3]:
                    info[3] = count_step[j]
                e = ev_count[0]
                ev_t[e] = t_cur
                ev_imp[e] = j
                ev_kind[e] = EV_IMPACT
                ev_n[e, 0] = nrm0
                ev_n[e, 1] = nrm1
                ev_vn[e] = v_n
                ev_J[e] = J
                ev_loss[e] = loss
                vh0 = X[1, 0]
                vh1 = X[1, 1] if n_rows == 2 else 0.0
                housing_velocity(yh, lam, W, w0, ws, part_plus, part_minus, omegas, amps, u0,
                                 us, t_cur, house_q[j], n_rows, yh_tau, y_tau, uder, yd, Xa)
                vh0a = Xa[1, 0]
                vh1a = Xa[1, 1] if n_rows == 2 else 0.0
                ev_after[e, 0] = (nrm0 * (imp_v[j, 0] - vh0a)
                                  + nrm1 * ((imp_v[j, 1] - vh1a) if n_rows == 2 else 0.0))
                ev_after[e, 1] = nrm0 * (vh0a - vh0) + nrm1 * (vh1a - vh1)
                ev_count[0] = e + 1
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
            # v_t^2/c for an impactor sliding round a cylindrical housing.
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
            if stick and pushes:
                # plastic completion of the bounce-down: cancel the relative velocity
                vr0 = imp_v[j, 0] - X[1, 0]
                vr1 = (imp_v[j, 1] - X[1, 1]) if n_rows == 2 else 0.0
                if n_rows == 1:
                    P0 = vr0 / (1.0 / m_i + mobility[j, 0, 0])
                    P1 = 0.0
                else:
                    a00 = 1.0 / m_i + mobility[j, 0, 0]
                    a01 = mobility[j, 0, 1]
                    a10 = mobility[j, 1, 0]
                    a11 = 1.0 / m_i + mobility[j, 1, 1]
                    det = a00 * a11 - a01 * a10
                    P0 = (a11 * vr0 - a01 * vr1) / det
                    P1 = (-a10 * vr0 + a00 * vr1) / det
                lock_loss = 0.5 * (vr0 * P0 + vr1 * P1)
                imp_v[j, 0] -= P0 / m_i
                imp_v[j, 1] -= P1 / m_i
                for i in range(n2):
                    yh[i] += kick[j, 0, i] * P0
                    if n_rows == 2:
                        yh[i] += kick[j, 1, i] * P1
                ledger[1] += lock_loss
                imp_stuck[j] = 1
                imp_grace[j] = 1
                if n_rows == 1:
                    imp_rel[j, 0] = nrm0 * imp_limit[j]
                else:
                    imp_rel[j, 0] = nrm0 * imp_limit[j]
                    imp_rel[j, 1] = nrm1 * imp_limit[j]
                if ev_count[0] >= cap:
                    t_state[0] = t_cur
                    info[0] = k
                    info[1] = j
                    return CONFIG_CHANGE
                e = ev_count[0]
                ev_t[e] = t_cur
                ev_imp[e] = j
                ev_kind[e] = EV_STICK
                ev_n[e, 0] = nrm0
                ev_n[e, 1] = nrm1
                ev_vn[e] = nrm0 * vr0 + nrm1 * vr1
                ev_J[e] = np.sqrt(P0 * P0 + P1 * P1)
                ev_loss[e] = lock_loss
                housing_velocity(yh, lam, W, w0, ws, part_plus, part_minus, omegas, amps, u0,
                                 us, t_cur, house_q[j], n_rows, yh_tau, y_tau, uder, yd, Xa)
                ev_after[e, 0] = nrm0 * (imp_v[j, 0] - Xa[1, 0]) + (
                    nrm1 * (imp_v[j, 1] - Xa[1, 1]) if n_rows == 2 else 0.0)
                ev_after[e, 1] = nrm0 * (Xa[1, 0] - X[1, 0]) + (
                    nrm1 * (Xa[1, 1] - X[1, 1]) if n_rows == 2 else 0.0)
                ev_count[0] = e + 1
                t_state[0] = t_cur
                info[0] = k
                info[1] = j
                return CONFIG_CHANGE
        # ---- end of step k: record outputs at t_b
        for f in range(nf):
            u0[f] = u_grid[k + 1, f]
        point_eval(yh, lam, W, w0, ws, part_plus, part_minus, omegas, amps, u0, us, t_b, 0.0,
                   1, yh_tau, y_tau, uder, yd)
        finite = True
        for i in range(n2):
            if not (np.isfinite(yh[i].real) and np.isfinite(yh[i].imag)):
                finite = False
        if not finite:
            t_state[0] = t_cur
            info[0] = k
            return NONFINITE
        for s_ in range(sensor_q.shape[0]):
            ad = 0j
            av = 0j
            aa = 0j
            for i in range(n2):
                ad += sensor_q[s_, i] * yd[0, i]
                av += sensor_v[s_, i] * yd[0, i]
                aa += sensor_v[s_, i] * yd[1, i]
            out_disp[k, s_] = ad.real
            out_vel[k, s_] = av.real
            out_acc[k, s_] = aa.real
    t_state[0] = t_cur
    info[0] = n_steps
    return DONE


advance = njit(cache=True)(advance_py)
