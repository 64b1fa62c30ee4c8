"""Rotor speed profiles and the unbalance forces they transmit to the bearings.

A speed profile gives the rotor speed ``omega(t)`` (rad/s), its angular acceleration
``alpha(t)`` (rad/s^2) and the rotor angle ``phi(t) = integral_0^t omega ds`` (rad), all in
closed form and vectorized over ``t`` (s). Every profile here is piecewise linear in speed,
so ``phi`` is piecewise quadratic and exact; no quadrature is used anywhere.

:class:`UnbalanceForce` turns a profile and a base unbalance distribution into bearing forces

    F_y = X m_e (phi'^2 cos(phi + p) + phi'' sin(phi + p))
    F_z = X m_e (phi'^2 sin(phi + p) - phi'' cos(phi + p))

(the inertial reaction of an eccentric mass ``m_e`` at angle ``phi + p``), with ``X`` the
paper's unbalance multiplier (Sec. 4.3). At constant speed the forces are pure harmonics and
:func:`unbalance_forcing` hands them to the propagator as :class:`Harmonic` terms, which it
integrates exactly; otherwise they are a sampled term held first-order between samples.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from ..integrate.forcing import CallableForce, Forcing, Harmonic

#: what a profile returns for times ``t``: a float for a scalar ``t``, else an array
FloatOrArray = npt.NDArray[np.float64] | float
FloatArray = npt.NDArray[np.float64]


def _finite(value: float | str, name: str, low: float | None = None, strict: bool = False,
            unit: str = '') -> float:
    """Return ``value`` as a float after checking it is finite and above ``low``."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ValueError(f'{name} must be a finite number{unit}, got {value!r}') from None
    bad = not np.isfinite(number)
    if low is not None and not bad:
        bad = number <= low if strict else number < low
    if bad:
        if low is None:
            allowed = 'finite'
        else:
            allowed = f'finite and {">" if strict else ">="} {low:g}{unit}'
        raise ValueError(f'{name} must be {allowed}, got {number}')
    return number


def _shaped(t: npt.ArrayLike) -> tuple[FloatArray, Callable[[FloatArray], FloatOrArray]]:
    """Return ``t`` as a float array and a function restoring scalars for scalar input."""
    array = np.asarray(t, dtype=float)
    return array, (lambda a: a[()] if array.ndim == 0 else a)


class _Knots:
    """Piecewise-linear speed on knots with explicit slopes (internal).

    Segment ``k`` spans ``[t_k, t_{k+1})`` with ``omega = w_k + s_k (t - t_k)``; the speed is
    held at ``w_0`` before ``t_0`` and at ``w_last`` after the last knot. ``phi(0) = 0``.
    """

    def __init__(self, times: npt.ArrayLike, speeds: npt.ArrayLike,
                 slopes: npt.ArrayLike) -> None:
        self.t = np.asarray(times, dtype=float)
        self.w = np.asarray(speeds, dtype=float)
        self.s = np.asarray(slopes, dtype=float)   # len(t); the last entry is the hold, 0
        # angle at each knot from the same polynomial the evaluation uses, so phi is
        # continuous at knots to round-off and independent of later knots
        dt = np.diff(self.t)
        inc = self.w[:-1] * dt + 0.5 * self.s[:-1] * dt * dt
        self.phi = np.concatenate(([0.0], np.cumsum(inc)))
        self.phi -= self._raw_angle(np.asarray(0.0))

    def _locate(self, t: FloatArray) -> tuple[np.ndarray, FloatArray, FloatArray]:
        k = np.searchsorted(self.t, t, side='right') - 1
        before = k < 0
        k = np.maximum(k, 0)
        dt = t - self.t[k]
        s = np.where(before, 0.0, self.s[k])   # held at w_0 before the first knot
        return k, dt, s

    def _angle_at(self, k: np.ndarray, dt: FloatArray, s: FloatArray) -> FloatArray:
        return self.phi[k] + self.w[k] * dt + 0.5 * s * dt * dt

    def _speed_at(self, k: np.ndarray, dt: FloatArray, s: FloatArray) -> FloatArray:
        return self.w[k] + s * dt

    def _raw_angle(self, t: FloatArray) -> FloatArray:
        return self._angle_at(*self._locate(t))

    def speed(self, t: FloatArray) -> FloatArray:
        return self._speed_at(*self._locate(t))

    def acceleration(self, t: FloatArray) -> FloatArray:
        return self._locate(t)[2]

    def angle(self, t: FloatArray) -> FloatArray:
        return self._raw_angle(t)

    def state(self, t: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """``(angle, speed, acceleration)`` at ``t`` from one search of the knots."""
        k, dt, s = self._locate(t)
        return self._angle_at(k, dt, s), self._speed_at(k, dt, s), s

    def time_at(self, angle: npt.ArrayLike) -> FloatArray:
        """The first time the angle reaches each of ``angle`` (rad, non-decreasing angle).

        On its segment the angle is ``phi_k + w_k dt + s_k dt^2 / 2``; the root is taken in
        the form ``2 d / (w_k + sqrt(w_k^2 + 2 s_k d))`` (no cancellation when decelerating).
        Before the first knot the speed is held at ``w_0``; after the last one at ``w_last``
        (inf when that is 0 and the angle is never reached).
        """
        a = np.asarray(angle, dtype=float)
        j = np.searchsorted(self.phi, a, side='left')   # first knot at or beyond the angle
        k = np.maximum(j - 1, 0)
        d = a - self.phi[k]
        s = np.where((j == 0) | (j == self.phi.size), 0.0, self.s[k])
        w = self.w[k]
        root = np.sqrt(np.maximum(w * w + 2.0 * s * d, 0.0))
        with np.errstate(divide='ignore', invalid='ignore'):
            dt = np.where(d == 0, 0.0, 2.0 * d / (w + root))
        dt = np.where(np.isnan(dt), np.inf, dt)
        return self.t[k] + dt


class SpeedProfile:
    """Base class of rotor speed profiles: speed, acceleration and angle at times ``t``.

    Subclasses provide ``_knots()`` returning the internal piecewise-linear description.
    The rotor angle is zero at ``t = 0``: ``phi(t) = integral_0^t omega(s) ds``.
    """

    #: whether the speed follows commands (:class:`CommandedSpeed`) or is fixed in advance
    commanded = False

    def _knots(self) -> _Knots:
        raise NotImplementedError

    @property
    def final_speed(self) -> float:
        """float: The speed the profile ends at and holds (rad/s): a commanded profile's
        current target."""
        return float(self._knots().w[-1])

    @property
    def steepest_rate(self) -> float:
        """float: The largest magnitude of the speed's rate of change (rad/s^2); 0 for a
        constant speed."""
        slopes = np.abs(self._knots().s[:-1])
        return float(slopes.max()) if slopes.size else 0.0

    def speed(self, t: npt.ArrayLike) -> FloatOrArray:
        """Rotor speed ``omega(t)``.

        Parameters
        ----------
        t : float or array_like
            Times (s).

        Returns
        -------
        float or ndarray
            Speed (rad/s), same shape as ``t``.
        """
        times, out = _shaped(t)
        return out(self._knots().speed(times))

    def acceleration(self, t: npt.ArrayLike) -> FloatOrArray:
        """Angular acceleration ``alpha(t) = omega'(t)``, right-continuous at knots.

        Parameters
        ----------
        t : float or array_like
            Times (s).

        Returns
        -------
        float or ndarray
            Angular acceleration (rad/s^2), same shape as ``t``.
        """
        times, out = _shaped(t)
        return out(self._knots().acceleration(times))

    def angle(self, t: npt.ArrayLike) -> FloatOrArray:
        """Rotor angle ``phi(t)``, the exact integral of the speed from ``t = 0``.

        Parameters
        ----------
        t : float or array_like
            Times (s).

        Returns
        -------
        float or ndarray
            Angle (rad), same shape as ``t``.
        """
        times, out = _shaped(t)
        return out(self._knots().angle(times))

    def state(self, t: npt.ArrayLike) -> tuple[FloatOrArray, FloatOrArray, FloatOrArray]:
        """Return ``(phi, omega, alpha)`` at times ``t`` (rad, rad/s, rad/s^2)."""
        times, out = _shaped(t)
        phi, omega, alpha = self._knots().state(times)
        return out(phi), out(omega), out(alpha)

    def time_at_angle(self, angle: npt.ArrayLike) -> FloatOrArray:
        """The first time the rotor angle ``phi`` reaches ``angle``, solved exactly.

        ``phi`` never decreases (speeds are >= 0), so this is where ``phi`` crosses
        ``angle``: the keyphasor's once-per-revolution times are ``time_at_angle(2 pi k)``.

        Parameters
        ----------
        angle : float or array_like
            Angles (rad), >= ``phi`` at the first knot.

        Returns
        -------
        float or ndarray
            Times (s), same shape as ``angle``; inf for an angle a rotor held at 0 rad/s
            never reaches.
        """
        angle, out = _shaped(angle)
        return out(self._knots().time_at(angle))


class PiecewiseLinearSpeed(SpeedProfile):
    """Speed linear between given points and held at the end values outside them.

    Parameters
    ----------
    times : array_like
        Strictly increasing, finite times (s), at least one.
    speeds : array_like
        Finite speeds >= 0 at ``times`` (rad/s).
    """

    def __init__(self, times: npt.ArrayLike, speeds: npt.ArrayLike) -> None:
        t = np.atleast_1d(np.asarray(times, dtype=float))
        w = np.atleast_1d(np.asarray(speeds, dtype=float))
        if t.ndim != 1 or t.shape != w.shape or t.size < 1:
            raise ValueError('PiecewiseLinearSpeed: times (s) and speeds (rad/s) must be 1-D '
                             f'of equal length >= 1, got shapes {t.shape} and {w.shape}')
        if not np.all(np.isfinite(t)):
            raise ValueError('PiecewiseLinearSpeed.times must be finite (s)')
        if np.any(np.diff(t) <= 0):
            raise ValueError('PiecewiseLinearSpeed.times must be strictly increasing (s)')
        if not (np.all(np.isfinite(w)) and np.all(w >= 0)):
            raise ValueError('PiecewiseLinearSpeed.speeds must be finite and >= 0 rad/s, '
                             f'got {w.tolist()}')
        self.times = t
        self.speeds = w
        slopes = np.append(np.diff(w) / np.diff(t), 0.0)
        self._k = _Knots(t, w, slopes)

    def _knots(self) -> _Knots:
        return self._k


class PaperRamp(PiecewiseLinearSpeed):
    """The pump start-up of Eq. (4.3.1): a linear ramp to ``omega_f``, then held.

    ``omega = omega_f t / t_ramp`` for ``0 <= t < t_ramp`` and ``omega_f`` after; the rotor is
    at rest before ``t = 0``.

    Parameters
    ----------
    omega_f : float
        Final (running) speed, finite and > 0 (rad/s); the paper's 2400 rad/s.
    t_ramp : float
        Ramp duration, finite and > 0 (s); the paper's 5 s.
    """

    def __init__(self, omega_f: float = 2400.0, t_ramp: float = 5.0) -> None:
        self.omega_f = _finite(omega_f, 'PaperRamp.omega_f', 0.0, True, ' rad/s')
        self.t_ramp = _finite(t_ramp, 'PaperRamp.t_ramp', 0.0, True, ' s')
        super().__init__([0.0, self.t_ramp], [0.0, self.omega_f])


class ConstantSpeed(PiecewiseLinearSpeed):
    """Constant rotor speed, ``phi = omega t``.

    Parameters
    ----------
    omega : float
        Speed, finite and >= 0 (rad/s).
    """

    def __init__(self, omega: float) -> None:
        self.omega = _finite(omega, 'ConstantSpeed.omega', 0.0, False, ' rad/s')
        super().__init__([0.0], [self.omega])


class CommandedSpeed(SpeedProfile):
    """Speed following outside commands under a rate limit (a drive's speed loop).

    After each :meth:`command` the speed ramps at ``+-max_rate`` from its value at that time
    towards the target and then holds it, so the profile stays piecewise linear and closed
    form. The history before the last command is kept: queries for earlier times return what
    they returned before the command (a later command only rewrites the future).

    Parameters
    ----------
    initial : float
        Speed at ``t0`` and before it, finite and >= 0 (rad/s).
    max_rate : float
        Magnitude of the speed change rate, finite and > 0 (rad/s^2).
    t0 : float
        Time from which commands are accepted, finite and >= 0 (s). The angle is zero at
        ``t = 0``, inside the initial hold, so commands never shift the angle's origin.
    """

    commanded = True

    def __init__(self, initial: float, max_rate: float, t0: float = 0.0) -> None:
        initial = _finite(initial, 'CommandedSpeed.initial', 0.0, False, ' rad/s')
        self.max_rate = _finite(max_rate, 'CommandedSpeed.max_rate', 0.0, True, ' rad/s^2')
        t0 = _finite(t0, 'CommandedSpeed.t0', 0.0, False, ' s')
        self._times = [t0]
        self._speeds = [initial]
        self._slopes = [0.0]
        self.target = initial
        self.t_last_command = t0
        self._k: _Knots | None = None

    def _knots(self) -> _Knots:
        if self._k is None:   # rebuilt lazily: commands are rare, queries frequent
            self._k = _Knots(self._times, self._speeds, self._slopes)
        return self._k

    @property
    def t_reached(self) -> float:
        """float: Time at which the current target is (or was) reached (s)."""
        return self._times[-1]

    def command(self, t_now: float, target: float) -> CommandedSpeed:
        """Set a new target speed from time ``t_now`` on.

        Parameters
        ----------
        t_now : float
            Time of the command, finite and >= the previous command's time (s).
        target : float
            Target speed, finite and >= 0 (rad/s).
        """
        t_now = _finite(t_now, 'CommandedSpeed.command: t_now', unit=' s')
        target = _finite(target, 'CommandedSpeed.command: target', 0.0, False, ' rad/s')
        if t_now < self.t_last_command:
            raise ValueError(f'CommandedSpeed.command: t_now must be >= {self.t_last_command} s '
                             f'(the last command; history is not rewritten), got {t_now}')
        w_now = float(self._knots().speed(np.asarray(t_now)))
        # keep every knot at or before t_now (segments there are untouched, so the history
        # evaluates to the same numbers), then cut the running segment at t_now
        keep = int(np.searchsorted(self._times, t_now, side='right'))
        times, speeds, slopes = self._times[:keep], self._speeds[:keep], self._slopes[:keep]
        if times[-1] < t_now:
            times.append(t_now)
            speeds.append(w_now)
            slopes.append(0.0)
        else:
            # a knot exactly at t_now: its speed stays (the speed is continuous there)
            slopes[-1] = 0.0
        if target != w_now:
            slopes[-1] = float(np.copysign(self.max_rate, target - w_now))
            times.append(t_now + abs(target - w_now) / self.max_rate)
            speeds.append(target)   # held exactly from the end of the ramp
            slopes.append(0.0)
        self._times, self._speeds, self._slopes = times, speeds, slopes
        self.target = target
        self.t_last_command = t_now
        self._k = None
        return self


def speed_profile(spec: Mapping[str, Any]) -> SpeedProfile:
    """The speed profile a validated ``rotor.speed`` mapping describes (SI).

    Parameters
    ----------
    spec : dict
        ``kind`` (constant, paper_ramp, piecewise, commanded) and its keys, validated.

    Returns
    -------
    SpeedProfile
    """
    kind = spec['kind']
    if kind == 'constant':
        return ConstantSpeed(spec['speed'])
    if kind == 'paper_ramp':
        ramp = {k: v for k, v in (('omega_f', spec['final_speed']),
                                  ('t_ramp', spec['ramp_time'])) if v is not None}
        return PaperRamp(**ramp)
    if kind == 'piecewise':
        return PiecewiseLinearSpeed(spec['times'], spec['speeds'])
    return CommandedSpeed(spec['speed'], spec['max_rate'])


class UnbalanceForce:
    """Rotor unbalance forces at the bearings for a speed profile.

    Parameters
    ----------
    profile : SpeedProfile
        Rotor speed profile (rad/s, rad/s^2, rad).
    unbalances : sequence of (float, float)
        Per bearing, the base unbalance ``m_e`` (kg m, finite and >= 0) and its phase ``p``
        relative to the rotor angle (rad, finite).
    input_pairs : sequence of (int, int)
        Per bearing, the model force-input indices of its ``y`` and ``z`` forces (dimensionless,
        >= 0, distinct within a pair).
    multiplier : float
        Unbalance multiplier ``X`` of the paper, finite and >= 0 (dimensionless).
    n_inputs : int, optional
        Number of model force inputs (dimensionless); default the largest index plus one.

    Notes
    -----
    Calling the object, ``force(t)``, returns the forces (N) at times ``t`` (s) with shape
    ``(len(t), n_inputs)``, as :class:`~.integrate.forcing.CallableForce` expects.
    """

    def __init__(self, profile: SpeedProfile, unbalances: Sequence[Sequence[float]] | np.ndarray,
                 input_pairs: Sequence[Sequence[int]] | np.ndarray, multiplier: float = 1.0, *,
                 n_inputs: int | None = None) -> None:
        if not isinstance(profile, SpeedProfile):
            raise TypeError(f'UnbalanceForce.profile must be a SpeedProfile, got {profile!r}')
        ub = np.asarray(unbalances, dtype=float).reshape(-1, 2) if len(unbalances) else \
            np.zeros((0, 2))
        pairs = np.asarray(input_pairs).reshape(-1, 2) if len(input_pairs) else \
            np.zeros((0, 2), dtype=int)
        if ub.shape[0] != pairs.shape[0] or ub.shape[0] == 0:
            raise ValueError('UnbalanceForce: one (m_e, phase) per bearing and one (y, z) input '
                             f'pair per bearing, >= 1 bearing; got {ub.shape[0]} unbalances '
                             f'and {pairs.shape[0]} pairs')
        if not (np.all(np.isfinite(ub[:, 0])) and np.all(ub[:, 0] >= 0)):
            raise ValueError('UnbalanceForce.unbalances: m_e must be finite and >= 0 kg m, '
                             f'got {ub[:, 0].tolist()}')
        if not np.all(np.isfinite(ub[:, 1])):
            raise ValueError('UnbalanceForce.unbalances: phase must be finite (rad), '
                             f'got {ub[:, 1].tolist()}')
        if not (np.all(np.asarray(pairs, dtype=float) == np.round(pairs)) and np.all(pairs >= 0)):
            raise ValueError('UnbalanceForce.input_pairs must be integer indices >= 0, '
                             f'got {pairs.tolist()}')
        pairs = pairs.astype(int)
        if np.any(pairs[:, 0] == pairs[:, 1]):
            raise ValueError('UnbalanceForce.input_pairs: y and z of a bearing must be '
                             f'different inputs, got {pairs.tolist()}')
        needed = int(pairs.max()) + 1
        if n_inputs is None:
            n_inputs = needed
        if int(n_inputs) != n_inputs or n_inputs < needed:
            raise ValueError(f'UnbalanceForce.n_inputs must be an integer >= {needed} (the '
                             f'largest input index plus one), got {n_inputs}')
        self.profile = profile
        self.m_e = ub[:, 0].copy()
        self.phase = ub[:, 1].copy()
        self.input_pairs = pairs
        self.n_inputs = int(n_inputs)
        self.multiplier = multiplier

    @property
    def multiplier(self) -> float:
        """float: Unbalance multiplier ``X`` (dimensionless), finite and >= 0; settable."""
        return self._multiplier

    @multiplier.setter
    def multiplier(self, value: float) -> None:
        self._multiplier = _finite(value, 'UnbalanceForce.multiplier', 0.0, False,
                                   ' (dimensionless)')

    def forces(self, t: npt.ArrayLike, n_inputs: int | None = None) -> FloatArray:
        """Bearing forces at times ``t``.

        Parameters
        ----------
        t : float or array_like
            Times (s).
        n_inputs : int, optional
            Columns of the result (dimensionless), >= :attr:`n_inputs`; default
            :attr:`n_inputs`.

        Returns
        -------
        ndarray, shape (len(t), n_inputs)
            Forces (N) on the model's force inputs.
        """
        times = np.atleast_1d(np.asarray(t, dtype=float)).ravel()
        n = self.n_inputs if n_inputs is None else int(n_inputs)
        out = np.zeros((times.size, n))
        phi, omega, alpha = self.profile.state(times)
        w2 = omega * omega
        for m_e, p, (iy, iz) in zip(self.m_e, self.phase, self.input_pairs):
            angle = phi + p
            c, s = np.cos(angle), np.sin(angle)
            a = self._multiplier * m_e
            out[:, iy] += a * (w2 * c + alpha * s)
            out[:, iz] += a * (w2 * s - alpha * c)
        return out

    def __call__(self, t: npt.ArrayLike) -> FloatArray:
        return self.forces(t)

    @property
    def is_constant_speed(self) -> bool:
        """bool: True when the profile is a :class:`ConstantSpeed` (forces are harmonic)."""
        return isinstance(self.profile, ConstantSpeed)

    def harmonic_terms(self) -> list[Harmonic]:
        """The forces as exact :class:`Harmonic` terms (constant speed only).

        With ``phi = omega t``: ``F_y = A cos(omega t + p)`` and
        ``F_z = A sin(omega t + p) = A cos(omega t + p - pi/2)``, ``A = X m_e omega^2``.
        The terms are a snapshot: a later change of :attr:`multiplier` does not alter them.

        Returns
        -------
        list of Harmonic
            Two terms per bearing with a non-zero amplitude (N, rad/s, rad).
        """
        if not isinstance(self.profile, ConstantSpeed):   # is_constant_speed, for mypy
            raise ValueError('UnbalanceForce.harmonic_terms needs a ConstantSpeed profile, '
                             f'got {type(self.profile).__name__}')
        omega = self.profile.omega
        terms: list[Harmonic] = []
        for m_e, p, (iy, iz) in zip(self.m_e, self.phase, self.input_pairs):
            amp = float(self._multiplier * m_e * omega * omega)
            if amp != 0.0:
                terms.append(Harmonic(int(iy), amp, omega, float(p)))
                terms.append(Harmonic(int(iz), amp, omega, float(p) - 0.5 * np.pi))
        return terms


def unbalance_forcing(n_inputs: int, force: UnbalanceForce, *,
                      exact_harmonics: bool = True) -> Forcing:

    """Build a :class:`Forcing` carrying an unbalance force.

    Parameters
    ----------
    n_inputs : int
        Number of force inputs of the model (dimensionless), > the largest input index.
    force : UnbalanceForce
        The unbalance (N).
    exact_harmonics : bool
        At constant speed, use exact :class:`Harmonic` terms (default). Set False to keep a
        sampled term that follows run-time changes of ``force.multiplier``; harmonic terms are
        read once when a propagator is built.

    Returns
    -------
    Forcing
        Harmonic terms at constant speed, otherwise one sampled term (held first-order
        between output samples, so the sample period should resolve the rotation).
    """
    if not isinstance(force, UnbalanceForce):
        raise TypeError(f'force must be an UnbalanceForce, got {force!r}')
    n_inputs = int(n_inputs)
    if n_inputs < force.n_inputs:
        raise ValueError(f'n_inputs must be >= {force.n_inputs} (the unbalance input indices), '
                         f'got {n_inputs}')
    if exact_harmonics and force.is_constant_speed:
        return Forcing(n_inputs, force.harmonic_terms())
    # the closure keeps the live object: multiplier changes and commands act on later samples
    return Forcing(n_inputs, [CallableForce(lambda t: force.forces(t, n_inputs))])


__all__ = ['CommandedSpeed', 'ConstantSpeed', 'PaperRamp', 'PiecewiseLinearSpeed',
           'SpeedProfile', 'UnbalanceForce', 'speed_profile', 'unbalance_forcing']
