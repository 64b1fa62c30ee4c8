r"""Exact symmetric two-impact periodic orbit of the SDOF impact damper.

Reference solution for the integrator tests (Masri & Caughey 1966, J. Appl. Mech. 33;
Masri 1970, JASA 47, with viscous damping of the primary system). Nothing here steps in
time: the orbit follows from the closed-form flow of the damped oscillator, the impact law
and a trigonometric equation for the impact phase; its stability from the analytic Jacobian
of the impact-to-impact map.

Model
-----
Primary (housing) mass ``M`` with spring ``K`` and damper ``c``, force ``F0 cos(Omega t)``:
``M x'' + c x' + K x = F0 cos(Omega t)``. The impactor ``m = mu M`` flies freely,
``z'' = 0``, while the relative coordinate ``r = z - x`` lies in ``(-D/2, +D/2)``. At a wall
``x'+ = ((1 - mu e) x'- + mu (1 + e) z'-)/(1 + mu)`` and
``z'+ = ((1 + e) x'- + (mu - e) z'-)/(1 + mu)``, which is equivalent to momentum
conservation ``x'- + mu z'- = x'+ + mu z'+`` and ``z'+ - x'+ = -e (z'- - x'-)``.

Orbit
-----
Impact on the ``+D/2`` wall at ``t0 = alpha/Omega`` and on the ``-D/2`` wall at
``t1 = t0 + h``, ``h = pi/Omega``, with ``x(t + h) = -x(t)`` and ``z(t + h) = -z(t)``.
Unknowns: ``alpha`` and the post-impact state ``(x0, v0, w0)`` at ``t0``
(``z0 = x0 + D/2``, ``w0`` = impactor velocity). Split ``x = x_p + y`` with the steady
particular solution ``x_p = X cos(Omega t - phi)``, which satisfies ``x_p(t + h) = -x_p(t)``;
``(y, y')`` then evolves by the state-transition matrix ``Phi(h)`` of the free damped
oscillator. With ``y0 = x0 - x_p(t0)``, ``u0 = v0 - x_p'(t0)`` and the pre-impact housing
velocity ``V1 = -x_p'(t0) + u1`` at ``t1`` the four conditions are

1. ``x(t1-) = -x0``                     ->  ``y1 = -y0``
2. ``z(t1) = -z0``                      ->  ``w0 h = -(2 x0 + D)``
3. momentum, post state ``(-v0, -w0)``  ->  ``V1 = -v0 - 2 mu w0``  ->  ``u1 = -u0 - 2 mu w0``
4. restitution                          ->  ``-(1 + e) V1 = (1 + 2 mu - e) w0``

(1) and (3) read ``(Phi(h) + I) (y0, u0) = (0, -2 mu w0)``, so ``(y0, u0) = (g_y, g_u) w0``
with ``(g_y, g_u) = -2 mu (Phi(h) + I)^-1 e_2``. (4) then gives ``w0 = kappa x_p'(t0)``,
``kappa = (1 + e)/((1 + 2 mu - e) - (1 + e)(g_u + 2 mu))``, and (2) becomes, with
``theta = alpha - phi``,

    ``P cos(theta) + Q sin(theta) = -D``,  ``P = 2 X``,  ``Q = -kappa (h + 2 g_y) Omega X``,

so ``theta = beta +/- arccos(-D/R)`` with ``R = hypot(P, Q)`` and ``beta = atan2(Q, P)``: no
orbit if ``D > R``, otherwise two candidates (Masri & Caughey's pair). A candidate is an
orbit only if the impactor approaches the wall (``z'- - x'- > 0`` at the ``+`` wall) and does
not touch either wall during the flight ``(t0, t1)``: ``|z - x| < D/2`` on a fine grid and at
every interior extremum of ``z - x`` (roots of ``z' - x' = w0 - x'(t)``, bracketed between the
roots of ``x''``, refined with ``brentq``).

Stability
---------
Section: post-impact state ``s = (t, x, v, w)`` on the ``+`` wall. ``G`` flies to the next
impact (on the ``-`` wall) and applies the impact law; ``S(t, x, v, w) = (t - h, -x, -v, -w)``
maps it back to the ``+`` wall. By the symmetry of the equations the one-period map is
``(S G)^2``, so the Floquet multipliers are the squares of the eigenvalues of ``D(S G)``,
computed analytically: ``dX(t1)/dt = -Phi(t1 - t) f(t, X)`` for the housing state ``X``,
the event time from the implicit function theorem ``dt1 = -(dg/ds)/(w - x'(t1-))`` for
``g = z - x + D/2``, then the linear impact law. Stable if every ``|multiplier| < 1``.

This module is the search for the orbit. The closed-form flow, the impact law, the orbit's
record, its state in time and the analytic Jacobian of the half-cycle map are
:mod:`.analytic_flow`; the closed-form checks of this reduction (the residuals of the
defining conditions, the half-cycle map by event location next to that Jacobian) are in
:mod:`.analytic_checks`.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.optimize import brentq

from .analytic_flow import (
    NoSymmetricOrbit,
    SymmetricTwoImpactOrbit,
    _half_map_jacobian,
    _Oscillator,
    linear_steady_amplitude,
)

#: One root of the phase equation: (branch, t0 (s), x0 (m), x'0 (m/s), z'0 (m/s))
_Root = tuple[int, float, float, float, float]

__all__ = [
    'symmetric_two_impact_orbit',
    'symmetric_two_impact_orbits',
    'phase_equation_roots',
]

# Grid used to bracket extrema and to check the flight for intermediate contact.
_N_GRID = 4001
# A flight closer to a wall than this fraction of D counts as grazing (not strictly inside).
_GRAZE_TOL = 1e-9


def _check_inputs(M: float, K: float, c: float, F0: float, Omega: float, mass_ratio: float,
                  cor: float, clearance: float) -> None:
    if not (M > 0 and K > 0 and Omega > 0 and clearance > 0):
        raise ValueError('M, K, Omega and clearance must be positive')
    if not c >= 0:
        raise ValueError('c must be >= 0')
    if not mass_ratio >= 0:
        raise ValueError('mass_ratio must be >= 0')
    if not 0.0 <= cor <= 1.0:
        raise ValueError('cor must lie in [0, 1]')
    if not np.isfinite(F0):
        raise ValueError('F0 must be finite')


# --------------------------------------------------------------------------- flight checks
def _root(f: Callable[[float], float], a: float, b: float) -> float:
    """Root of ``f`` in the bracket ``[a, b]`` to machine precision."""
    eps = np.finfo(float).eps
    return brentq(f, a, b, xtol=1e-3 * eps * (b - a), rtol=4.0 * eps, maxiter=500)


def _bracketed_roots(f: Callable[[float], float], t: np.ndarray, y: np.ndarray) -> list[float]:
    """Roots of ``f`` at the sign changes of the samples ``y = f(t)``."""
    roots = []
    for i in np.nonzero(y[:-1] * y[1:] < 0.0)[0]:
        roots.append(_root(f, t[i], t[i + 1]))
    for i in np.nonzero(y == 0.0)[0]:
        roots.append(t[i])
    return sorted(roots)


def _flight_extrema(osc: _Oscillator, t0: float, x0: float, v0: float, w0: float, h: float,
                    D: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                       list[float], list[float]]:
    """Interior extrema of ``r = z - x`` and of ``x`` on ``(t0, t0 + h)``.

    Returns the grid ``(t, x, v, r)``, the times of the interior extrema of ``r`` and of ``x``.
    """
    t = t0 + np.linspace(0.0, h, _N_GRID)
    x, v = osc.flow(t0, x0, v0, t)
    r = x0 + D / 2.0 + w0 * (t - t0) - x

    def vel(s: float) -> float:
        return osc.flow(t0, x0, v0, s)[1]

    def acc(s: float) -> float:
        xs, vs = osc.flow(t0, x0, v0, s)
        return osc.accel(s, xs, vs)

    def rdot(s: float) -> float:
        return w0 - vel(s)

    a = osc.accel(t, x, v)
    # r' is monotone between roots of r'' = -x'', so it has at most one root on each piece;
    # this catches pairs of close roots that one grid cell would hide.
    inner = t[1:-1]
    breaks = [t[0]] + _bracketed_roots(acc, inner, a[1:-1]) + [t[-1]]
    r_ext = []
    for lo, hi in zip(breaks[:-1], breaks[1:]):
        flo, fhi = rdot(lo), rdot(hi)
        if flo * fhi < 0.0:
            r_ext.append(_root(rdot, lo, hi))
    r_ext = [s for s in r_ext if t[0] < s < t[-1]]
    x_ext = [s for s in _bracketed_roots(vel, t, v) if t[0] < s < t[-1]]
    return t, x, v, r, r_ext, x_ext


# --------------------------------------------------------------------------- the orbit
def _multipliers(osc: _Oscillator, D: float, mu: float, e: float,
                 s: np.ndarray) -> tuple[complex, ...]:
    J = _half_map_jacobian(osc, D, mu, e, s)
    lam = np.linalg.eigvals(J) ** 2  # one period = (S G)^2
    lam = lam[np.argsort(-np.abs(lam), kind='stable')]
    return tuple(complex(v) for v in lam)


def _phase_roots(M: float, K: float, c: float, F0: float, Omega: float, mass_ratio: float,
                 cor: float, clearance: float) -> tuple[_Oscillator, list[_Root], str]:
    """Roots of the reduced conditions: ``(osc, [(branch, t0, x0, v0, w0)], reason)``."""
    _check_inputs(M, K, c, F0, Omega, mass_ratio, cor, clearance)
    mu, e, D = float(mass_ratio), float(cor), float(clearance)
    osc = _Oscillator(M, K, c, F0, Omega)
    h = np.pi / Omega
    I_plus_Phi = osc.transition(h) + np.eye(2)
    if abs(np.linalg.det(I_plus_Phi)) < 1e-12 * (1.0 + np.abs(I_plus_Phi).max() ** 2):
        return osc, [], ('Phi(pi/Omega) has eigenvalue -1 (undamped, Omega = omega_n/odd): '
                         'degenerate')
    gy, gu = -2.0 * mu * np.linalg.solve(I_plus_Phi, np.array([0.0, 1.0]))
    den = (1.0 + 2.0 * mu - e) - (1.0 + e) * (gu + 2.0 * mu)
    if abs(den) < 1e-12 * (1.0 + e):
        # e.g. e = 1 with c = 0: nothing dissipates, so the orbits form a continuous family
        return osc, [], 'phase equation degenerate (kappa infinite: e = 1 with c = 0, or mu = 0)'
    kappa = (1.0 + e) / den
    P = 2.0 * osc.X
    Q = -kappa * (h + 2.0 * gy) * Omega * osc.X
    R = np.hypot(P, Q)
    if not D <= R:
        return osc, [], f'clearance D = {D:.6g} m exceeds R = {R:.6g} m: phase equation has no root'
    beta = np.arctan2(Q, P)
    acos = np.arccos(-D / R)
    roots = []
    for branch in (+1, -1):
        alpha = float(np.mod(beta + branch * acos + osc.phi, 2.0 * np.pi))
        t0 = alpha / Omega
        xp0, vp0 = osc.particular(t0)
        w0 = kappa * vp0
        roots.append((branch, t0, float(xp0 + gy * w0), float(vp0 + gu * w0), float(w0)))
    return osc, roots, ''


def _admissibility(osc: _Oscillator, D: float, t0: float, x0: float, v0: float,
                   w0: float) -> tuple[str, float, float | None, float | None]:
    """Check one root; returns ``(reason or '', V1, margin, amplitude)``."""
    h = np.pi / osc.Omega
    # pre-impact state at t0 is minus the pre-impact state at t1 = t0 + h
    _, V1 = osc.flow(t0, x0, v0, t0 + h)
    vrel = -w0 + float(V1)
    if not vrel > 0.0:
        return (f"impactor recedes from the wall (z'- - x'- = {vrel:.3e} m/s)", float(V1),
                None, None)
    t, x, v, r, r_ext, x_ext = _flight_extrema(osc, t0, x0, v0, w0, h, D)
    r_at = [x0 + D / 2.0 + w0 * (s - t0) - osc.flow(t0, x0, v0, s)[0] for s in r_ext]
    # Grid points next to the walls sit within |r'| dt of D/2, so only the interior
    # extrema measure how close the flight comes to a second contact.
    margin = D / 2.0 - float(max((abs(q) for q in r_at), default=0.0))
    if not (np.abs(r[1:-1]).max() < D / 2.0 and margin > _GRAZE_TOL * D):
        why = f'impactor reaches a wall during the flight (margin {margin:.3e} m)'
        return why, float(V1), margin, None
    amp = max(abs(x0), float(np.abs(x).max()),
              *(abs(float(osc.flow(t0, x0, v0, s)[0])) for s in x_ext))
    return '', float(V1), margin, amp


def phase_equation_roots(M: float, K: float, c: float, F0: float, Omega: float,
                         mass_ratio: float, cor: float,
                         clearance: float) -> tuple[tuple[int, np.ndarray, str], ...]:
    """Both roots of the phase equation, admissible or not (for diagnostics and tests).

    Parameters are those of :func:`symmetric_two_impact_orbit`.

    Returns
    -------
    tuple of (int, ndarray, str)
        ``(branch, (t0, x0, x'0, z'0), reason)`` per root: the post-impact state on the
        ``+D/2`` wall (s, m, m/s, m/s) and why it is not an orbit (``''`` if it is).
        Empty if the phase equation has no root.
    """
    osc, roots, _ = _phase_roots(M, K, c, F0, Omega, mass_ratio, cor, clearance)
    out = []
    for branch, t0, x0, v0, w0 in roots:
        reason = _admissibility(osc, float(clearance), t0, x0, v0, w0)[0]
        out.append((branch, np.array([t0, x0, v0, w0]), reason))
    return tuple(out)


def _candidates(M: float, K: float, c: float, F0: float, Omega: float, mass_ratio: float,
                cor: float, clearance: float) -> tuple[list[SymmetricTwoImpactOrbit], list[str]]:
    """All admissible orbits and the reasons the other candidates failed."""
    osc, roots, why = _phase_roots(M, K, c, F0, Omega, mass_ratio, cor, clearance)
    if not roots:
        return [], [why]
    mu, e, D = float(mass_ratio), float(cor), float(clearance)
    orbits, reasons = [], []
    for branch, t0, x0, v0, w0 in roots:
        why, V1, margin, amp = _admissibility(osc, D, t0, x0, v0, w0)
        if why:
            reasons.append(f'branch {branch:+d} (alpha = {osc.Omega * t0:.6f} rad): {why}')
            continue
        assert margin is not None and amp is not None   # admissible: both were measured
        mult = _multipliers(osc, D, mu, e, np.array([t0, x0, v0, w0]))
        orbits.append(SymmetricTwoImpactOrbit(
            M=float(M), K=float(K), c=float(c), F0=float(F0), Omega=float(Omega),
            mass_ratio=mu, cor=e, clearance=D, alpha=float(osc.Omega * t0), t_impact=t0,
            half_period=float(np.pi / Omega), x_impact=x0, xdot_pre=-V1, xdot_post=v0,
            zdot_pre=-w0, zdot_post=w0, relative_velocity_pre=V1 - w0,
            amplitude=float(amp), linear_amplitude=linear_steady_amplitude(M, K, c, F0, Omega),
            clearance_margin=float(margin), multipliers=mult,
            stable=bool(abs(mult[0]) < 1.0), branch=branch))
    return orbits, reasons


def symmetric_two_impact_orbits(M: float, K: float, c: float, F0: float, Omega: float,
                                mass_ratio: float, cor: float,
                                clearance: float) -> tuple[SymmetricTwoImpactOrbit, ...]:
    """All symmetric two-impact orbits (at most two), stable ones first.

    Parameters are those of :func:`symmetric_two_impact_orbit`.

    Returns
    -------
    tuple of SymmetricTwoImpactOrbit
        Admissible orbits, stable first, then by increasing spectral radius; empty if none.
    """
    orbits, _ = _candidates(M, K, c, F0, Omega, mass_ratio, cor, clearance)
    return tuple(sorted(orbits, key=lambda o: (not o.stable, o.spectral_radius)))


def symmetric_two_impact_orbit(M: float, K: float, c: float, F0: float, Omega: float,
                               mass_ratio: float, cor: float, clearance: float, *,
                               branch: int | None = None) -> SymmetricTwoImpactOrbit:
    """Symmetric two-impacts-per-cycle steady state of the SDOF impact damper.

    Parameters
    ----------
    M : float
        Primary (housing) mass (kg).
    K : float
        Primary stiffness (N/m).
    c : float
        Primary viscous damping (N s/m).
    F0 : float
        Amplitude of the force ``F0 cos(Omega t)`` on the primary mass (N).
    Omega : float
        Forcing frequency (rad/s).
    mass_ratio : float
        Impactor to primary mass ratio ``mu`` (-).
    cor : float
        Coefficient of restitution ``e`` in ``[0, 1]`` (-).
    clearance : float
        Total free travel ``D``: ``z - x`` lies in ``[-D/2, D/2]`` (m).
    branch : {None, +1, -1}, optional
        Root of the phase equation to return (-). ``None`` returns the stable orbit if there
        is one, otherwise the admissible orbit with the smallest spectral radius.

    Returns
    -------
    SymmetricTwoImpactOrbit
        The orbit, with amplitude, impact phase, velocities and Floquet multipliers.

    Raises
    ------
    NoSymmetricOrbit
        If no admissible orbit exists; ``reason`` lists why each candidate failed.
    ValueError
        For non-physical parameters.
    """
    orbits, reasons = _candidates(M, K, c, F0, Omega, mass_ratio, cor, clearance)
    if branch is not None:
        orbits = [o for o in orbits if o.branch == branch]
    if not orbits:
        raise NoSymmetricOrbit('; '.join(reasons) or f'branch {branch} is not admissible')
    return min(orbits, key=lambda o: (not o.stable, o.spectral_radius))
