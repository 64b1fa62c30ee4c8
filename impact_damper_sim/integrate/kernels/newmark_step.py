"""Numba kernels of the Newmark (average acceleration) integrator.

Conventions (all kernels): float64 arrays only, no Python objects; times in seconds; state
arrays passed in are updated in place. Every kernel ``name`` is :func:`.kernel` of its
plain Python/NumPy twin ``name_py`` defined beside it (``test/test_newmark.py`` runs both).

The step is the average-acceleration method (``beta = 1/4``, ``gamma = 1/2``) written in the
acceleration form: with the predictors ``q* = q0 + h v0 + h^2/4 a0`` and ``v* = v0 + h/2 a0``,

``S a1 = f1 - C v* - K q*``,   ``S = M + h/2 C + h^2/4 K = (h^2/4) K_eff``,

then ``q1 = q* + h^2/4 a1`` and ``v1 = v* + h/2 a1``. This is algebraically the usual
effective-stiffness form (``K_eff = K + 2 C/h + 4 M/h^2``) but stays well conditioned for the
very short re-steps to located events (``S -> M`` as ``h -> 0``).

Event screening inside :func:`run_steps` (the event logic itself is in Python,
:mod:`impact_damper_sim.integrate.newmark`): a step is handed back (not committed) when

* a free impactor may touch a wall inside it. ``located``: the cubic Hermite interpolant of the
  relative coordinate, built from the housing positions and velocities at both step ends,
  leaves the clearance somewhere in ``(0, h]`` (SDOF: exact extremum of the cubic; planar:
  eight samples of ``|r|^2`` plus the step end), or starts on a wall moving in. ``step_end``
  (the paper's baseline): the gap is violated at the step end with a closing velocity;
* a stuck impactor's normal contact force (:func:`release_force`) is ``<= 0`` at the step end
  (release).
"""
from __future__ import annotations

import numpy as np

from . import kernel
from .codes import DONE, NONFINITE

# status codes returned by run_steps(): DONE and NONFINITE are the exact kernels' (.codes);
# FLAGGED, a step handed back to Python for its event (the exact loop's 1 is CONFIG_CHANGE)
FLAGGED = 1


def step_py(Sinv, C, K, f1, h, q0, v0, a0, q1, v1, a1, work):
    """One average-acceleration step of ``h`` (s) with ``Sinv = S^{-1}`` precomputed.

    ``f1`` is the generalized force at the step end; ``(q1, v1, a1)`` receive the end state;
    ``work`` is scratch of length ``n``. The inputs and outputs must not alias.
    """
    n = q0.size
    hh = 0.25 * h * h
    h2 = 0.5 * h
    for i in range(n):
        q1[i] = q0[i] + h * v0[i] + hh * a0[i]
        v1[i] = v0[i] + h2 * a0[i]
    for i in range(n):
        acc = f1[i]
        for k in range(n):
            acc -= C[i, k] * v1[k] + K[i, k] * q1[k]
        work[i] = acc
    for i in range(n):
        acc = 0.0
        for k in range(n):
            acc += Sinv[i, k] * work[k]
        a1[i] = acc
    for i in range(n):
        q1[i] += hh * a1[i]
        v1[i] += h2 * a1[i]


step = kernel()(step_py)


def ledger_step_py(C, Kskew, f0, f1, q0, v0, q1, v1, h, ledger):
    """Add one step's damping dissipation, forcing work and circulatory work (J).

    Trapezoidal means over the step, ``v = (v0 + v1)/2``, ``q = (q0 + q1)/2``,
    ``f = (f0 + f1)/2``: ``h v.C v``, ``h v.f`` and ``-h v.K_skew q``. These are the terms of
    the average-acceleration method's exact discrete energy balance, so the ledger closes to
    round-off; each is an O(h^2) approximation of the true integral. ``ledger[2:5]`` are
    damping, forcing, circulatory.
    """
    n = q0.size
    p_damp = 0.0
    p_force = 0.0
    p_circ = 0.0
    for i in range(n):
        vi = 0.5 * (v0[i] + v1[i])
        cv = 0.0
        kq = 0.0
        for k in range(n):
            cv += C[i, k] * (v0[k] + v1[k])
            kq += Kskew[i, k] * (q0[k] + q1[k])
        p_damp += vi * 0.5 * cv
        p_circ -= vi * 0.5 * kq
        p_force += vi * 0.5 * (f0[i] + f1[i])
    ledger[2] += h * p_damp
    ledger[3] += h * p_force
    ledger[4] += h * p_circ


ledger_step = kernel()(ledger_step_py)


def force_py(B, u, out):
    """Generalized force ``out = B u`` (N, or modal force)."""
    for i in range(B.shape[0]):
        acc = 0.0
        for f in range(B.shape[1]):
            acc += B[i, f] * u[f]
        out[i] = acc


force = kernel()(force_py)


def hermite_relative_py(z, vi, x0, xd0, x1, xd1, h, out):
    """Power-basis coefficients of ``r(s) = z + vi s - x_h(s)`` for ``s`` in ``[0, h]``.

    ``x_h`` is the cubic Hermite interpolant of the housing position from ``(x0, xd0)`` at
    ``s = 0`` and ``(x1, xd1)`` at ``s = h`` (m, m/s). ``out[0..3]`` receive
    ``r = out[0] + out[1] s + out[2] s^2 + out[3] s^3`` (m, m/s, m/s^2, m/s^3).
    """
    dx = (x1 - x0) / h
    c2 = (3.0 * dx - 2.0 * xd0 - xd1) / h
    c3 = (xd0 + xd1 - 2.0 * dx) / (h * h)
    out[0] = z - x0
    out[1] = vi - xd0
    out[2] = -c2
    out[3] = -c3


hermite_relative = kernel()(hermite_relative_py)


def cubic_range_py(c, h):
    """Smallest and largest value of ``c0 + c1 s + c2 s^2 + c3 s^3`` over ``(0, h]``.

    The extremes are at ``s = h`` or at a critical point inside the interval.
    """
    v = c[0] + h * (c[1] + h * (c[2] + h * c[3]))
    lo = v
    hi = v
    a = 3.0 * c[3]
    b = 2.0 * c[2]
    cc = c[1]
    r0 = 0.0   # critical points: scalars, so the kernel allocates nothing
    r1 = 0.0
    nr = 0
    if a != 0.0:
        disc = b * b - 4.0 * a * cc
        if disc >= 0.0:
            sq = np.sqrt(disc)
            # numerically stable pair of roots
            qq = -0.5 * (b + sq) if b >= 0.0 else -0.5 * (b - sq)
            if qq != 0.0:
                r0 = qq / a
                r1 = cc / qq
                nr = 2
            else:
                nr = 1
    elif b != 0.0:
        r0 = -cc / b
        nr = 1
    for i in range(nr):
        s = r0 if i == 0 else r1
        if 0.0 < s < h:
            v = c[0] + s * (c[1] + s * (c[2] + s * c[3]))
            lo = min(lo, v)
            hi = max(hi, v)
    return lo, hi


cubic_range = kernel()(cubic_range_py)


def release_force_py(rows_j, d, rel_T_j, normal_j, a):
    """Normal contact force per unit impactor mass of a stuck impactor (m/s^2).

    ``-n . T (R a)``, with ``R a`` the housing acceleration in the stuck configuration and
    ``T = (I - m G_s)^{-1}`` (``G_s = R M_s^{-1} R^T``); ``T R a`` is the housing acceleration
    the same state would have with this impactor free, so the force is that of a frictionless
    normal contact. For an SDOF impactor ``T`` is a positive scalar: the sign, hence the
    release instant, is that of the exact kernel's ``-n . a_h``.
    """
    n = a.size
    ah0 = 0.0
    ah1 = 0.0
    for k in range(n):
        ah0 += rows_j[0, k] * a[k]
        if d == 2:
            ah1 += rows_j[1, k] * a[k]
    if d == 1:
        return -normal_j[0] * rel_T_j[0, 0] * ah0
    return -(normal_j[0] * (rel_T_j[0, 0] * ah0 + rel_T_j[0, 1] * ah1)
             + normal_j[1] * (rel_T_j[1, 0] * ah0 + rel_T_j[1, 1] * ah1))


release_force = kernel()(release_force_py)


def event_flag_py(located, h, q0, v0, q1, v1, a1, rows, imp_dim, imp_limit, imp_z, imp_v,
                  imp_stuck, imp_normal, rel_T, xw):
    """Return the index of the first impactor that may have an event in this step, or -1.

    ``rows`` has shape ``(n_i, 2, n)``; ``imp_z``/``imp_v`` are impactor positions and
    velocities at the step start (m, m/s); ``rel_T`` the release transforms of
    :func:`release_force`, shape ``(n_i, 2, 2)``; ``xw`` is scratch of shape ``(2, 4)``. The
    screen is conservative in ``located`` mode (see the module docstring); the Python event
    logic decides.
    """
    ni = imp_dim.size
    n = q0.size
    for j in range(ni):
        d = imp_dim[j]
        L = imp_limit[j]
        if imp_stuck[j] == 1:
            # release: the normal contact force at the step end is no longer compressive
            if release_force(rows[j], d, rel_T[j], imp_normal[j], a1) <= 0.0:
                return j
            continue
        for r in range(d):
            x0 = 0.0
            xd0 = 0.0
            x1 = 0.0
            xd1 = 0.0
            for k in range(n):
                x0 += rows[j, r, k] * q0[k]
                xd0 += rows[j, r, k] * v0[k]
                x1 += rows[j, r, k] * q1[k]
                xd1 += rows[j, r, k] * v1[k]
            hermite_relative(imp_z[j, r], imp_v[j, r], x0, xd0, x1, xd1, h, xw[r])
        if not located:
            # paper's baseline: gap violated at the step end with a closing velocity
            g = 0.0
            vn = 0.0
            for r in range(d):
                re = xw[r, 0] + h * (xw[r, 1] + h * (xw[r, 2] + h * xw[r, 3]))
                ve = xw[r, 1] + h * (2.0 * xw[r, 2] + 3.0 * h * xw[r, 3])
                g += re * re
                vn += re * ve
            if g >= L * L and vn > 0.0:
                return j
            continue
        if d == 1:
            c = xw[0]
            lo, hi = cubic_range(c, h)
            if hi >= L or lo <= -L:
                return j
            # starting on a wall and moving into it
            if (c[0] >= L and (c[1] > 0.0 or (c[1] == 0.0 and c[2] > 0.0))) or \
                    (c[0] <= -L and (c[1] < 0.0 or (c[1] == 0.0 and c[2] < 0.0))):
                return j
        else:
            r2 = xw[0, 0] * xw[0, 0] + xw[1, 0] * xw[1, 0]
            rv = xw[0, 0] * xw[0, 1] + xw[1, 0] * xw[1, 1]
            if r2 >= L * L and rv >= 0.0:
                return j
            for i in range(1, 9):
                s = h * i / 8.0
                r2 = 0.0
                for r in range(2):
                    x = xw[r, 0] + s * (xw[r, 1] + s * (xw[r, 2] + s * xw[r, 3]))
                    r2 += x * x
                if r2 >= L * L:
                    return j
    return -1


event_flag = kernel()(event_flag_py)


def run_steps_py(k_start, k_stop, out_base, substeps, h, u_grid, B, Sinv, C, K, Kskew,
                 q, v, a, f_cur, rows, imp_dim, imp_limit, imp_z, imp_v, imp_stuck,
                 imp_normal, rel_T, located, ledger_on, ledger, sensors, out_disp, out_vel,
                 out_acc, info):
    """Newmark steps ``k_start .. k_stop-1`` of one configuration until an event is possible.

    Step ``k`` goes from ``u_grid[k]`` to ``u_grid[k + 1]`` (inputs, N). ``out_base + k + 1``
    counts internal steps from the start of the output block; every ``substeps``-th step end
    is an output sample. ``f_cur`` holds ``B u`` at the current time and is updated.
    Returns ``DONE`` (``info[0] = k_stop``), ``FLAGGED`` (``info[0]`` the step handed back,
    state at its start, ``info[1]`` the impactor) or ``NONFINITE``.
    """
    n = q.size
    qn = np.empty(n)
    vn = np.empty(n)
    an = np.empty(n)
    fn = np.empty(n)
    work = np.empty(n)
    xw = np.empty((2, 4))
    ni = imp_dim.size
    for k in range(k_start, k_stop):
        force(B, u_grid[k + 1], fn)
        step(Sinv, C, K, fn, h, q, v, a, qn, vn, an, work)
        j = event_flag(located, h, q, v, qn, vn, an, rows, imp_dim, imp_limit, imp_z, imp_v,
                       imp_stuck, imp_normal, rel_T, xw)
        if j >= 0:
            info[0] = k
            info[1] = j
            return FLAGGED
        if ledger_on:
            ledger_step(C, Kskew, f_cur, fn, q, v, qn, vn, h, ledger)
        for i in range(n):
            q[i] = qn[i]
            v[i] = vn[i]
            a[i] = an[i]
            f_cur[i] = fn[i]
        for jj in range(ni):
            if imp_stuck[jj] == 0:
                for r in range(imp_dim[jj]):
                    imp_z[jj, r] += imp_v[jj, r] * h
        m = out_base + k + 1
        if m % substeps == 0:
            finite = True
            for i in range(n):
                if not (np.isfinite(q[i]) and np.isfinite(v[i])):
                    finite = False
            if not finite:
                info[0] = k
                return NONFINITE
            o = m // substeps - 1
            for s_ in range(sensors.shape[0]):
                ad = 0.0
                av = 0.0
                aa = 0.0
                for i in range(n):
                    ad += sensors[s_, i] * q[i]
                    av += sensors[s_, i] * v[i]
                    aa += sensors[s_, i] * a[i]
                out_disp[o, s_] = ad
                out_vel[o, s_] = av
                out_acc[o, s_] = aa
    info[0] = k_stop
    return DONE


run_steps = kernel(_nrt=True)(run_steps_py)   # allocates its step arrays once per call
