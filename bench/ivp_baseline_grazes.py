"""The screen for wall contacts hidden inside one ``solve_ivp`` step (``ivp_baseline.py``).

``solve_ivp`` sees an event only as a sign change between step ends. After every free segment
:func:`_graze_candidates` reconstructs ``r = z - x`` in each step by quintic Hermite
interpolation from the step-end data and flags the steps that come within its error bound of a
wall; :func:`_locate_graze` finds the first contact in such a step on the dense output. Apart
from the event loop because it is a numerical method of its own ("Missed events" in
``ivp_baseline.py``); numpy and scipy only.
"""

import math

import numpy as np
from scipy.optimize import brentq, minimize_scalar

_EPS = np.finfo(float).eps


def _housing_derivatives(p, t, x, xd, order):
    """Time derivatives ``x, x', ..., x^(order)`` of the free housing (no impactor contact).

    Parameters
    ----------
    p : Params
        System parameters.
    t, x, xd : ndarray
        Times (s), positions (m) and velocities (m/s) of the housing.
    order : int
        Highest derivative wanted (>= 1).

    Returns
    -------
    list of ndarray
        ``d[k] = x^(k)`` (m/s^k), from the recursion ``M x^(k+2) = F^(k) - c x^(k+1) - K x^(k)``.
    """
    d = [np.asarray(x, dtype=float), np.asarray(xd, dtype=float)]
    for k in range(order - 1):
        # k-th derivative of F0 cos(Omega t).
        force = p.F0 * p.Omega ** k * np.cos(p.Omega * t + 0.5 * math.pi * k)
        d.append((force - p.c * d[k + 1] - p.K * d[k]) / p.M)
    return d


def _quintic_hermite_basis(tau):
    """Quintic Hermite basis on ``[0, 1]`` for ``f0, h f0', h^2 f0'', h^2 f1'', h f1', f1``."""
    t2, t3 = tau * tau, tau ** 3
    t4, t5 = t3 * tau, t3 * t2
    return np.stack([1 - 10 * t3 + 15 * t4 - 6 * t5,
                     tau - 6 * t3 + 8 * t4 - 3 * t5,
                     0.5 * t2 - 1.5 * t3 + 1.5 * t4 - 0.5 * t5,
                     0.5 * t3 - t4 + 0.5 * t5,
                     -4 * t3 + 7 * t4 - 3 * t5,
                     10 * t3 - 15 * t4 + 6 * t5], axis=-1)


_N_SCREEN = 64
_SCREEN_BASIS = _quintic_hermite_basis(np.arange(1, _N_SCREEN + 1) / (_N_SCREEN + 1))


def _graze_candidates(ts, ys, lim, p):
    """Steps of a free flight in which the impactor may have touched a wall unseen.

    ``solve_ivp`` sees an event only as a sign change between step ends, so an excursion
    through a wall and back within one step (a graze, or a short flight back to the wall just
    left followed by a second separation) is lost. The relative coordinate ``r = z - x`` is
    reconstructed in every step from the step-end data by quintic Hermite interpolation
    (``r, r', r''`` at both ends; in free flight ``r'' = -x''`` follows from the state). A step
    is a candidate if that reconstruction comes closer to a wall than its error bound
    ``h^6 max|x^(6)| / 46080`` (times 4; ``max|x^(6)|`` estimated from ``x^(6)`` and
    ``x^(7)`` at the ends) plus the sampling error.

    Parameters
    ----------
    ts : ndarray, shape (n,)
        Step end times of a free-flight segment (s).
    ys : ndarray, shape (>= 4, n)
        States at ``ts``.
    lim : float
        Wall position ``|r|`` used by the wall events (m).
    p : Params
        System parameters.

    Returns
    -------
    ndarray of int
        Indices ``i`` of the candidate steps ``[ts[i], ts[i+1]]``, ascending.
    """
    h = np.diff(ts)
    d = _housing_derivatives(p, ts, ys[0], ys[1], 7)
    r = ys[2] - ys[0]
    v = ys[3] - ys[1]
    a = -d[2]   # the impactor is force-free in flight
    data = np.stack([r[:-1], h * v[:-1], h * h * a[:-1], h * h * a[1:], h * v[1:], r[1:]])
    rq = _SCREEN_BASIS @ data   # (samples, steps)
    w_min = min(p.omega_n, p.Omega) if p.Omega > 0 else p.omega_n
    b6 = np.sqrt(d[6] ** 2 + (d[7] / w_min) ** 2)
    b6 = np.maximum(b6[:-1], b6[1:])
    amax = np.maximum(np.abs(a[:-1]), np.abs(a[1:]))
    margin = (4.0 * h ** 6 / 46080.0 * b6 + amax * (h / (_N_SCREEN + 1)) ** 2 / 8.0
              + 64 * _EPS * lim)
    near = (np.max(np.abs(rq), axis=0) > lim - margin) & (h > 0)
    return np.nonzero(near)[0]


def _locate_graze(ta, tb, dense, lim, p, depth=0.0, n=65):
    """Find the first wall contact hidden inside ``[ta, tb]`` on the dense output, or None.

    Parameters
    ----------
    ta, tb : float
        Step start and end (s); the impactor is inside the cavity at ``ta``.
    dense : callable
        Dense output of the step, ``dense(t) -> state`` (also for an array of times).
    lim : float
        Wall position ``|r|`` used by the wall events (m).
    p : Params
        System parameters.
    depth : float
        Penetrations up to this depth are not contacts (m); use the position tolerance of the
        solver, below which the dense output cannot tell.
    n : int
        Number of samples of the step.

    Returns
    -------
    tuple or None
        ``(wall, t_contact, y_contact)``: the earliest crossing of ``|r| = lim`` in the step,
        outward (s, state). None if ``r`` stays inside.
    """
    tt = np.linspace(ta, tb, n)
    Y = dense(tt)
    R = Y[2] - Y[0]
    acc = np.abs((p.F0 * np.cos(p.Omega * tt) - p.c * Y[1] - p.K * Y[0]) / p.M)
    slack = np.max(acc) * (tt[1] - tt[0]) ** 2 / 8.0   # peak above the samples, at most
    xtol = 4 * _EPS * max(1.0, abs(tb))
    # Penetrations below what r = z - x and the event times resolve are not contacts (this
    # also keeps the located crossing that ends a terminated segment from counting).
    tol_q = (depth + 64 * _EPS * max(lim, float(np.max(np.abs(Y[0]))))
             + 4 * xtol * float(np.max(np.abs(Y[3] - Y[1]))))
    best = None
    for s in (1, -1):
        def q(t_, s=s):
            y_ = dense(t_)
            return s * (y_[2] - y_[0]) - lim

        Q = s * R - lim
        out = np.nonzero(Q[1:] > tol_q)[0]
        k_out = out[0] + 1 if out.size else n
        bracket = (tt[k_out - 1], tt[k_out]) if k_out < n else None
        # A hidden excursion between two samples shows up as a local maximum close to 0.
        for k in range(1, min(k_out, n)):
            right = Q[k + 1] if k + 1 < n else -np.inf
            if Q[k] >= Q[k - 1] and Q[k] >= right and Q[k] > -slack:
                hi = tt[min(k + 1, n - 1)]
                peak = minimize_scalar(lambda t_: -q(t_), bounds=(tt[k - 1], hi),
                                       method='bounded', options=dict(xatol=xtol))
                if -peak.fun > tol_q:
                    bracket = (tt[k - 1], peak.x)
                    break
        if bracket is not None:
            lo, hi = bracket
            if q(lo) >= 0.0:   # already at the wall at the left sample: contact there
                tc = lo
            else:
                tc = brentq(q, lo, hi, xtol=xtol, rtol=4 * _EPS)
            if best is None or tc < best[1]:
                best = (s, tc)
    if best is None:
        return None
    return best[0], best[1], dense(best[1])
