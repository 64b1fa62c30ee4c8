"""The closed form of the SDOF impact damper's symmetric two-impact orbit (:mod:`.analytic`).

The flow of the damped, harmonically forced primary system ``M x'' + c x' + K x = F0
cos(Omega t)`` (its particular solution and state-transition matrix), the impact law, the
linear steady amplitude, the orbit's record (:class:`SymmetricTwoImpactOrbit`) and its state
at any time (:func:`orbit_state`), and the analytic Jacobian of the half-cycle impact map the
Floquet multipliers come from. Nothing here searches: :mod:`.analytic` finds the orbit (the
roots of its phase equation and their admissibility) with these pieces, and its docstring
derives them.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import overload

import numpy as np
import numpy.typing as npt

#: A time, or an array of times, and what a function of it returns (np.float64 is a float)
_Times = float | np.ndarray

__all__ = [
    'NoSymmetricOrbit',
    'SymmetricTwoImpactOrbit',
    'linear_steady_amplitude',
    'orbit_state',
]


class NoSymmetricOrbit(ValueError):
    """No symmetric two-impact orbit exists; ``reason`` says why (one entry per candidate)."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


@dataclass(frozen=True)
class SymmetricTwoImpactOrbit:
    """Symmetric two-impacts-per-cycle periodic orbit of the SDOF impact damper.

    The impact on the ``+D/2`` wall (``z - x = +D/2``) happens at ``Omega t = alpha``
    (mod 2 pi), the one on the ``-D/2`` wall at ``alpha + pi``; the state at the second
    impact is the negative of the state at the first.

    Attributes
    ----------
    M : float
        Primary (housing) mass (kg).
    K : float
        Primary stiffness (N/m).
    c : float
        Primary viscous damping (N s/m).
    F0 : float
        Amplitude of the harmonic force ``F0 cos(Omega t)`` on the primary mass (N).
    Omega : float
        Forcing frequency (rad/s).
    mass_ratio : float
        Impactor to primary mass ratio ``mu = m/M`` (-).
    cor : float
        Coefficient of restitution ``e`` (-).
    clearance : float
        Total free travel ``D`` of the impactor; ``z - x`` lies in ``[-D/2, D/2]`` (m).
    alpha : float
        Forcing phase ``Omega t0`` of the impact on the ``+D/2`` wall, in ``[0, 2 pi)`` (rad).
    t_impact : float
        Time ``t0 = alpha/Omega`` of that impact, in ``[0, 2 pi/Omega)`` (s).
    half_period : float
        Time between impacts, ``pi/Omega`` (s).
    x_impact : float
        Housing displacement at the ``+D/2`` impact (m).
    xdot_pre, xdot_post : float
        Housing velocity just before / after the ``+D/2`` impact (m/s).
    zdot_pre, zdot_post : float
        Impactor velocity just before / after the ``+D/2`` impact (m/s); the impactor flies
        at constant speed ``|zdot_post|`` and ``zdot_pre = -zdot_post``.
    relative_velocity_pre : float
        Approach velocity ``z'- - x'-`` at the ``+D/2`` impact, > 0 (m/s).
    amplitude : float
        Steady-state amplitude ``max |x(t)|`` over the cycle (m).
    linear_amplitude : float
        Amplitude of the same primary system without impactor (m).
    clearance_margin : float
        ``D/2 - max |z - x|`` over the interior extrema of ``z - x`` during the flight, or
        ``D/2`` if ``z - x`` is monotone; > 0 by construction (m).
    multipliers : tuple of complex
        Floquet multipliers of the one-period impact map, largest modulus first (-).
    stable : bool
        True if every multiplier has modulus < 1 (asymptotically stable).
    branch : int
        +1 or -1: which root ``theta = beta +/- arccos(-D/R)`` of the phase equation (-).
    """

    M: float
    K: float
    c: float
    F0: float
    Omega: float
    mass_ratio: float
    cor: float
    clearance: float
    alpha: float
    t_impact: float
    half_period: float
    x_impact: float
    xdot_pre: float
    xdot_post: float
    zdot_pre: float
    zdot_post: float
    relative_velocity_pre: float
    amplitude: float
    linear_amplitude: float
    clearance_margin: float
    multipliers: tuple
    stable: bool
    branch: int

    @property
    def natural_frequency(self) -> float:
        """Undamped natural frequency ``sqrt(K/M)`` of the primary system (rad/s)."""
        return float(np.sqrt(self.K / self.M))

    @property
    def frequency_ratio(self) -> float:
        """``Omega/omega_n`` (-)."""
        return self.Omega / self.natural_frequency

    @property
    def damping_ratio(self) -> float:
        """``c/(2 sqrt(K M))`` (-)."""
        return self.c / (2.0 * np.sqrt(self.K * self.M))

    @property
    def spectral_radius(self) -> float:
        """Largest multiplier modulus (-)."""
        return float(abs(self.multipliers[0]))

    @property
    def post_impact_state(self) -> np.ndarray:
        """``(t0, x0, x'0, z'0)`` just after the ``+D/2`` impact (s, m, m/s, m/s)."""
        return np.array([self.t_impact, self.x_impact, self.xdot_post, self.zdot_post])


# --------------------------------------------------------------------------- linear flow
class _Oscillator:
    """Closed-form flow of ``M x'' + c x' + K x = F0 cos(Omega t)``."""

    def __init__(self, M: float, K: float, c: float, F0: float, Omega: float) -> None:
        self.M, self.K, self.c, self.F0, self.Omega = M, K, c, F0, Omega
        self.wn = np.sqrt(K / M)
        self.sigma = c / (2.0 * M)
        zeta = self.sigma / self.wn
        self.under = zeta < 1.0
        self.wd = self.wn * np.sqrt(abs(1.0 - zeta * zeta))
        den = (K - M * Omega**2) ** 2 + (c * Omega) ** 2
        if den == 0.0:
            raise NoSymmetricOrbit('undamped forcing at resonance: no bounded particular solution')
        # x_p = A cos(Omega t) + B sin(Omega t) = X cos(Omega t - phi)
        self.A = F0 * (K - M * Omega**2) / den
        self.B = F0 * c * Omega / den
        self.X = np.hypot(self.A, self.B)
        self.phi = np.arctan2(self.B, self.A)

    @overload
    def particular(self, t: float) -> tuple[float, float]: ...
    @overload
    def particular(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...

    def particular(self, t: _Times) -> tuple[_Times, _Times]:
        wt = self.Omega * np.asarray(t, dtype=float)
        cs, sn = np.cos(wt), np.sin(wt)
        return self.A * cs + self.B * sn, self.Omega * (self.B * cs - self.A * sn)

    def transition(self, tau: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """State-transition matrix ``Phi(tau)`` of the free oscillator, shape (..., 2, 2)."""
        tau = np.asarray(tau, dtype=float)
        a = self.wd * tau
        if self.under:
            C = np.cos(a)
            S = tau * np.sinc(a / np.pi)  # sin(wd tau)/wd, exact at wd = 0
        else:
            C = np.cosh(a)
            safe = np.where(a == 0.0, 1.0, a)
            S = tau * np.where(a == 0.0, 1.0, np.sinh(safe) / safe)
        E = np.exp(-self.sigma * tau)
        Phi = np.empty(tau.shape + (2, 2))
        Phi[..., 0, 0] = E * (C + self.sigma * S)
        Phi[..., 0, 1] = E * S
        Phi[..., 1, 0] = -E * self.wn**2 * S
        Phi[..., 1, 1] = E * (C - self.sigma * S)
        return Phi

    @overload
    def flow(self, t0: float, x0: float, v0: float, t: float) -> tuple[float, float]: ...
    @overload
    def flow(self, t0: float, x0: float, v0: float,
             t: np.ndarray) -> tuple[np.ndarray, np.ndarray]: ...

    def flow(self, t0: float, x0: float, v0: float, t: _Times) -> tuple[_Times, _Times]:
        """Housing ``(x, x')`` at time(s) ``t`` from ``(x0, v0)`` at ``t0``."""
        xp0, vp0 = self.particular(t0)
        Phi = self.transition(np.asarray(t, dtype=float) - t0)
        y0, u0 = x0 - xp0, v0 - vp0
        xp, vp = self.particular(t)
        return (xp + Phi[..., 0, 0] * y0 + Phi[..., 0, 1] * u0,
                vp + Phi[..., 1, 0] * y0 + Phi[..., 1, 1] * u0)

    @overload
    def accel(self, t: float, x: float, v: float) -> float: ...
    @overload
    def accel(self, t: np.ndarray, x: np.ndarray, v: np.ndarray) -> np.ndarray: ...

    def accel(self, t: _Times, x: _Times, v: _Times) -> _Times:
        return (self.F0 * np.cos(self.Omega * t) - self.c * v - self.K * x) / self.M


def _impact(xd: float, zd: float, mu: float, e: float) -> tuple[float, float]:
    """Post-impact velocities (housing, impactor) from pre-impact ones."""
    return (((1.0 - mu * e) * xd + mu * (1.0 + e) * zd) / (1.0 + mu),
            ((1.0 + e) * xd + (mu - e) * zd) / (1.0 + mu))


def linear_steady_amplitude(M: float, K: float, c: float, F0: float, Omega: float) -> float:
    """Steady-state amplitude of the primary system without impactor.

    Parameters
    ----------
    M : float
        Primary mass (kg).
    K : float
        Primary stiffness (N/m).
    c : float
        Primary viscous damping (N s/m).
    F0 : float
        Force amplitude (N).
    Omega : float
        Forcing frequency (rad/s).

    Returns
    -------
    float
        ``|F0|/sqrt((K - M Omega^2)^2 + (c Omega)^2)`` (m); ``inf`` at undamped resonance.
    """
    den = np.hypot(K - M * Omega**2, c * Omega)
    return float(abs(F0) / den) if den > 0 else float('inf')


# --------------------------------------------------------------------------- the orbit in time
def _osc_of(orbit: SymmetricTwoImpactOrbit) -> _Oscillator:
    return _Oscillator(orbit.M, orbit.K, orbit.c, orbit.F0, orbit.Omega)


def orbit_state(orbit: SymmetricTwoImpactOrbit,
                t: npt.ArrayLike) -> tuple[float, ...] | tuple[np.ndarray, ...]:
    """State on the periodic orbit at time(s) ``t``.

    Parameters
    ----------
    orbit : SymmetricTwoImpactOrbit
        The orbit.
    t : float or array_like
        Time(s) (s). At an impact instant the post-impact state is returned.

    Returns
    -------
    x, xdot, z, zdot : float or ndarray
        Housing displacement (m), housing velocity (m/s), impactor position (m, same frame
        as ``x``; ``z - x`` in ``[-D/2, D/2]``) and impactor velocity (m/s).
    """
    osc = _osc_of(orbit)
    t = np.asarray(t, dtype=float)
    h, t0 = orbit.half_period, orbit.t_impact
    k = np.floor((t - t0) / h)
    # an impact instant rounded to just below t0 + k h still gets the post-impact state
    k = np.where(t - t0 - k * h >= h * (1.0 - 1e-13), k + 1.0, k)
    tau = np.clip(t - t0 - k * h, 0.0, h)  # time since the last impact
    sign = np.where(np.mod(k, 2.0) == 0.0, 1.0, -1.0)  # odd half-cycles are mirrored
    x, v = osc.flow(t0, orbit.x_impact, orbit.xdot_post, t0 + tau)
    z = orbit.x_impact + orbit.clearance / 2.0 + orbit.zdot_post * tau
    out = (sign * x, sign * v, sign * z, sign * np.full_like(tau, orbit.zdot_post))
    if out[0].ndim == 0:
        return tuple(float(q) for q in out)
    return out


# --------------------------------------------------------------------------- the half-cycle map
def _half_map_jacobian(osc: _Oscillator, D: float, mu: float, e: float,
                       s: np.ndarray) -> npt.NDArray[np.float64]:
    t0, x0, v0, w0 = s
    h = np.pi / osc.Omega
    t1 = t0 + h  # valid at the fixed point; the Jacobian is only used there
    x1, V1 = osc.flow(t0, x0, v0, t1)
    Phi = osc.transition(h)
    f0 = np.array([v0, osc.accel(t0, x0, v0)])
    # d(x1, V1)/d(t0, x0, v0, w0) at fixed t1
    dX = np.zeros((2, 4))
    dX[:, 0] = -Phi @ f0
    dX[:, 1] = Phi[:, 0]
    dX[:, 2] = Phi[:, 1]
    dz = np.array([-w0, 1.0, 0.0, h])  # z1 = x0 + D/2 + w0 (t1 - t0)
    dg = dz - dX[0]  # g = z - x + D/2
    dt1 = -dg / (w0 - V1)
    a1 = osc.accel(t1, x1, V1)
    dx1 = dX[0] + V1 * dt1
    dV1 = dX[1] + a1 * dt1
    dw = np.array([0.0, 0.0, 0.0, 1.0])
    dvp = ((1.0 - mu * e) * dV1 + mu * (1.0 + e) * dw) / (1.0 + mu)
    dwp = ((1.0 + e) * dV1 + (mu - e) * dw) / (1.0 + mu)
    return np.vstack([dt1, -dx1, -dvp, -dwp])
