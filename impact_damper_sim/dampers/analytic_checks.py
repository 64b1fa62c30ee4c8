"""Closed-form checks of the symmetric two-impact orbit of :mod:`.analytic`: the residuals of
its defining conditions evaluated with the flow and the impact law directly
(:func:`orbit_residuals`), and the half-cycle impact map ``S G`` by event location
(:func:`symmetric_half_map`) next to the analytic Jacobian the Floquet multipliers come from
(:func:`symmetric_half_map_jacobian`), for finite-difference checks. Apart from the orbit
because only the tests use them: they verify the reduction in :mod:`.analytic`, they are not
part of it.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .analytic import _N_GRID, _root
from .analytic_flow import (
    NoSymmetricOrbit,
    SymmetricTwoImpactOrbit,
    _half_map_jacobian,
    _impact,
    _osc_of,
    _Oscillator,
)

__all__ = ['orbit_residuals', 'symmetric_half_map', 'symmetric_half_map_jacobian']


def orbit_residuals(orbit: SymmetricTwoImpactOrbit) -> np.ndarray:
    """Dimensionless residuals of the orbit's defining conditions.

    Evaluated with the closed-form flow and the impact law directly (not with the reduced
    phase equation), so they test the reduction as well.

    Parameters
    ----------
    orbit : SymmetricTwoImpactOrbit
        The orbit.

    Returns
    -------
    ndarray, shape (5,)
        ``[(x(t1-) + x0)/A, (z - x + D/2)(t1-)/D, (x'(t1+) + x'0)/V, (z'(t1+) + z'0)/V,
        (z'- - x'- at t0 from the impact law minus the reported one)/V]`` with ``A`` the
        amplitude and ``V = Omega A + |z'0|`` (-).
    """
    osc = _osc_of(orbit)
    mu, e, D = orbit.mass_ratio, orbit.cor, orbit.clearance
    t0, x0, v0, w0 = orbit.post_impact_state
    t1 = t0 + orbit.half_period
    x1, V1 = osc.flow(t0, x0, v0, t1)
    z1 = x0 + D / 2.0 + w0 * orbit.half_period
    vp, wp = _impact(V1, w0, mu, e)
    A = orbit.amplitude
    V = orbit.Omega * A + abs(w0)
    return np.array([(x1 + x0) / A, (z1 - x1 + D / 2.0) / D, (vp + v0) / V, (wp + w0) / V,
                     ((-w0 + V1) - orbit.relative_velocity_pre) / V])


def _next_impact(osc: _Oscillator, D: float, t0: float, x0: float, v0: float, w0: float,
                 h: float) -> tuple[float, float]:
    """First wall contact after a post-impact state on the ``+`` wall (time, wall sign)."""
    n = 8 * _N_GRID
    t = t0 + np.linspace(0.0, 4.0 * h, n)
    x, _ = osc.flow(t0, x0, v0, t)
    r = x0 + D / 2.0 + w0 * (t - t0) - x
    lo = r[1:] + D / 2.0 <= 0.0  # crossed the - wall
    hi = r[1:] - D / 2.0 >= 0.0  # came back to the + wall
    idx_lo = np.argmax(lo) if lo.any() else n
    idx_hi = np.argmax(hi) if hi.any() else n
    if min(idx_lo, idx_hi) == n:
        raise NoSymmetricOrbit('no impact within two forcing periods')
    wall = -1 if idx_lo <= idx_hi else +1
    i = min(idx_lo, idx_hi)

    def gap(s: float) -> float:
        return x0 + D / 2.0 + w0 * (s - t0) - osc.flow(t0, x0, v0, s)[0] - wall * D / 2.0

    return _root(gap, t[i], t[i + 1]), wall


def symmetric_half_map(orbit: SymmetricTwoImpactOrbit,
                       state: Sequence[float] | np.ndarray) -> np.ndarray:
    """Closed-form half-cycle impact map ``S G`` (for finite-difference checks).

    Parameters
    ----------
    orbit : SymmetricTwoImpactOrbit
        Supplies the system parameters.
    state : array_like, shape (4,)
        Post-impact state ``(t, x, x', z')`` on the ``+D/2`` wall (s, m, m/s, m/s).

    Returns
    -------
    ndarray, shape (4,)
        ``(t1 - pi/Omega, -x1, -x'1+, -z'1+)`` after the next impact, which must be on the
        ``-D/2`` wall (s, m, m/s, m/s); the orbit's post-impact state is a fixed point.
    """
    osc = _osc_of(orbit)
    t0, x0, v0, w0 = map(float, state)
    t1, wall = _next_impact(osc, orbit.clearance, t0, x0, v0, w0, orbit.half_period)
    if wall != -1:
        raise NoSymmetricOrbit('next impact is on the same wall')
    x1, V1 = osc.flow(t0, x0, v0, t1)
    vp, wp = _impact(V1, w0, orbit.mass_ratio, orbit.cor)
    return np.array([t1 - orbit.half_period, -x1, -vp, -wp])


def symmetric_half_map_jacobian(orbit: SymmetricTwoImpactOrbit) -> np.ndarray:
    """Analytic Jacobian of :func:`symmetric_half_map` at the orbit's fixed point.

    Parameters
    ----------
    orbit : SymmetricTwoImpactOrbit
        The orbit.

    Returns
    -------
    ndarray, shape (4, 4)
        ``d(S G)/d(t, x, x', z')`` (mixed units: s, m, m/s); its squared eigenvalues are
        ``orbit.multipliers`` (-).
    """
    return _half_map_jacobian(_osc_of(orbit), orbit.clearance, orbit.mass_ratio, orbit.cor,
                              orbit.post_impact_state)
