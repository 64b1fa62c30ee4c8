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

import bisect
import math
from collections.abc import Mapping, Sequence
from typing import Any, cast

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


#: the one-segment paths take times, angles and knot values within +-this (s, rad, rad/s,
#: rad/s^2): nothing there overflows, so no inf or nan arises and their shortcuts hold
_TAME = 1e100
#: arrays up to this size are ranged through a list: its sum, min and max cost less than
#: two NumPy reductions
_SMALL = 64
#: a ramp from rest takes the one-segment angle search when ``2 s d`` is at least this
#: (rad^2/s^2): its square root is then > 0, never a division by zero
_TINY = 1e-300
_MIN = np.minimum.reduce
_TWO_PI = 2.0 * math.pi
_MAX = np.maximum.reduce


def _filled(value: FloatOrArray, t: FloatArray) -> FloatOrArray:
    """``value`` as an array shaped like ``t`` when it is one segment's Python float."""
    if type(value) is float:
        out = np.empty(t.shape)
        out.fill(value)
        return out
    return value


def _one(value: FloatOrArray, t: FloatArray) -> FloatOrArray:
    """``value`` as a numpy scalar for a 0-d ``t`` (what a scalar query returns)."""
    return value[()] if t.ndim == 0 else value   # type: ignore[index]


class _Knots:
    """Piecewise-linear speed on knots with explicit slopes (internal).

    Segment ``k`` spans ``[t_k, t_{k+1})`` with ``omega = w_k + s_k (t - t_k)``; the speed is
    held at ``w_0`` before ``t_0`` and at ``w_last`` after the last knot. ``phi(0) = 0``.

    Times that all lie in one segment (a chunk's output times, one instant: the live node's
    queries) take a path that uses the segment's values as Python floats. It does the general
    path's floating-point operations on every element in the same order, so it returns the
    same bits; where it leaves out a slope term the term is an exact zero that cannot change
    the sum (see :meth:`_angle_one`, :meth:`_speed_one`, :meth:`_time_one`).
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
        # the knots as Python floats for the one-segment paths
        self._tl: list[float] = self.t.tolist()
        self._wl: list[float] = self.w.tolist()
        self._sl: list[float] = self.s.tolist()
        self._phil: list[float] = self.phi.tolist()
        self._tame = all(abs(v) <= _TAME
                         for v in self._tl + self._wl + self._sl + self._phil)   # no nan

    # -- the general path: any times, one search of the knots per element --------------------
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

    # -- the one-segment paths ----------------------------------------------------------------
    def _range(self, x: FloatArray) -> tuple[float, float] | None:
        """``(min, max)`` of a non-empty 1-D ``x`` when every element is within +-_TAME."""
        if x.size <= _SMALL:
            values = x.tolist()
            if not math.isfinite(sum(values)):   # an inf or nan in it: min/max unreliable
                return None
            lo, hi = min(values), max(values)
        else:
            lo, hi = float(_MIN(x)), float(_MAX(x))   # these propagate nan
        if -_TAME <= lo and hi <= _TAME:
            return lo, hi
        return None

    def _segment(self, t: FloatArray) -> tuple[int, float] | None:
        """``(k, s)``: every time of ``t`` lies in segment ``k`` (0 also before the first
        knot) with slope ``s``; None if they span segments or are not tame."""
        if t.ndim == 0:
            x = float(t)
            lo = hi = x
            if not (self._tame and -_TAME <= x <= _TAME):
                return None
        else:
            if not (self._tame and t.ndim == 1 and t.size):
                return None
            span = self._range(t)
            if span is None:
                return None
            lo, hi = span
        knots = self._tl
        k = bisect.bisect_right(knots, lo) - 1   # searchsorted(side='right') - 1
        if k + 1 < len(knots) and hi >= knots[k + 1]:
            return None
        return (k, self._sl[k]) if k >= 0 else (0, 0.0)   # held at w_0 before the first knot

    def _angle_one(self, k: int, dt: FloatArray, s: float) -> FloatArray:
        """``phi_k + w_k dt + 0.5 s dt dt`` on segment ``k`` (a new array).

        With ``s = 0`` and a finite ``dt`` the last term is a zero with the sign of ``s``
        (``dt`` enters it twice), which changes no sum unless it is +0 and
        ``phi_k + w_k dt`` is -0; that needs ``phi_k = -0``, and only then is it added.
        """
        phi_k = self._phil[k]
        angle = self._wl[k] * dt
        angle += phi_k
        if s != 0.0 or math.copysign(1.0, phi_k) < 0.0:
            term = (0.5 * s) * dt
            term *= dt
            angle += term
        return angle

    def _speed_one(self, k: int, t: FloatArray, s: float) -> FloatOrArray:
        """``w_k + s dt`` on segment ``k``: the float ``w_k`` when ``s = 0`` (adding the zero
        ``s dt`` leaves it, unless ``w_k = -0``), else a new array."""
        w_k = self._wl[k]
        if s == 0.0 and math.copysign(1.0, w_k) > 0.0:
            return w_k
        speed = s * (t - self._tl[k])
        speed += w_k
        return speed

    # -- queries -------------------------------------------------------------------------------
    def state_parts(self, t: FloatArray) -> tuple[FloatOrArray, FloatOrArray, FloatOrArray]:
        """``(angle, speed, acceleration)`` at the times ``t``; for times in one segment the
        speed and acceleration may be Python floats, the value at every time."""
        seg = self._segment(t)
        if seg is None:
            k_, dt_, s_ = self._locate(t)
            return self._angle_at(k_, dt_, s_), self._speed_at(k_, dt_, s_), s_
        return self._parts_on(*seg, t)

    def _parts_on(self, k: int, s: float, t: FloatArray
                  ) -> tuple[FloatOrArray, FloatOrArray, FloatOrArray]:
        """:meth:`state_parts` of times ``t`` that all lie in segment ``k`` of slope ``s``."""
        if t.ndim == 0:
            dt = float(t) - self._tl[k]
            w_k = self._wl[k]
            return (np.float64(self._phil[k] + w_k * dt + 0.5 * s * dt * dt),
                    np.float64(w_k + s * dt), np.float64(s))
        return self._angle_one(k, t - self._tl[k], s), self._speed_one(k, t, s), s

    def state(self, t: FloatArray) -> tuple[FloatOrArray, FloatOrArray, FloatOrArray]:
        """``(angle, speed, acceleration)`` at ``t`` from one search of the knots."""
        angle, speed, acceleration = self.state_parts(t)
        return angle, _filled(speed, t), _filled(acceleration, t)

    def speed(self, t: FloatArray) -> FloatOrArray:
        seg = self._segment(t)
        if seg is None:
            return self._speed_at(*self._locate(t))
        k, s = seg
        if t.ndim == 0:
            return np.float64(self._wl[k] + s * (float(t) - self._tl[k]))
        return _filled(self._speed_one(k, t, s), t)

    def acceleration(self, t: FloatArray) -> FloatOrArray:
        seg = self._segment(t)
        if seg is None:
            return self._locate(t)[2]
        return np.float64(seg[1]) if t.ndim == 0 else _filled(seg[1], t)

    def angle(self, t: FloatArray) -> FloatOrArray:
        seg = self._segment(t)
        if seg is None:
            return self._raw_angle(t)
        return self._parts_on(*seg, t)[0]

    def _time_one(self, a: FloatArray) -> FloatOrArray | None:
        """:meth:`time_at` for angles ``a`` all after the first knot's, on one segment, within
        +-_TAME; None for any other.

        There ``d = a - phi_k > 0`` and, with ``w_k > 0`` or ``2 s d >= _TINY`` (a ramp from
        rest), ``w_k + root > 0``, finite: the general path's ``d == 0``, divide-by-zero and
        nan cases cannot arise. With ``s = 0``, ``w_k^2 + 2 s d = w_k^2`` (the zero added to
        ``w_k^2 >= 0`` leaves it): one root for all.
        """
        if not self._tame:
            return None
        if a.ndim == 0:
            lo = hi = float(a)
            if not -_TAME <= lo <= _TAME:
                return None
        elif a.ndim == 1 and a.size:
            span = self._range(a)
            if span is None:
                return None
            lo, hi = span
        else:
            return None
        phis = self._phil
        j = bisect.bisect_left(phis, lo)   # searchsorted(side='left')
        if j == 0 or (j < len(phis) and hi > phis[j]):
            return None
        k = j - 1
        w = self._wl[k]
        s = self._sl[k] if j < len(phis) else 0.0   # held after the last knot
        if not (w > 0.0 or (2.0 * s) * (lo - phis[k]) >= _TINY):   # else a root may be 0
            return None
        if a.ndim == 0:
            d0 = lo - phis[k]
            root0 = math.sqrt(max(w * w + 2.0 * s * d0, 0.0))
            return np.float64(self._tl[k] + 2.0 * d0 / (w + root0))
        d = a - phis[k]
        den: FloatOrArray
        if s == 0.0:
            den = w + math.sqrt(w * w)
        else:
            root = (2.0 * s) * d
            root += w * w
            np.maximum(root, 0.0, out=root)
            np.sqrt(root, out=root)
            root += w
            den = root
        dt = 2.0 * d
        dt /= den
        dt += self._tl[k]
        return dt

    def time_list(self, angles: Sequence[float]) -> list[float] | None:
        """:meth:`time_at` of a few angles (rad) as Python floats, each on its own segment;
        None unless every angle passes :meth:`_time_one`'s conditions (then the caller takes
        :meth:`time_at`). The scalar form of :meth:`_time_one`: the same operations, so the
        same bits."""
        if not self._tame:
            return None
        phis, wl, sl, tl = self._phil, self._wl, self._sl, self._tl
        n = len(phis)
        out = []
        for a in angles:
            if not -_TAME <= a <= _TAME:
                return None
            j = bisect.bisect_left(phis, a)
            if j == 0:
                return None
            k = j - 1
            w = wl[k]
            s = sl[k] if j < n else 0.0   # held after the last knot
            d = a - phis[k]
            if not (w > 0.0 or (2.0 * s) * d >= _TINY):   # else a root may be 0
                return None
            root = math.sqrt(max(w * w + 2.0 * s * d, 0.0))
            out.append(tl[k] + 2.0 * d / (w + root))
        return out

    def speed_list(self, times: Sequence[float]) -> list[float]:
        """:meth:`speed` at a few times (s) as Python floats: the general path's
        ``w_k + s_k (t - t_k)`` per time, the same operations, so the same bits."""
        tl, wl, sl = self._tl, self._wl, self._sl
        out = []
        for x in times:
            k = bisect.bisect_right(tl, x) - 1   # searchsorted(side='right') - 1
            if k < 0:   # held at w_0 before the first knot
                out.append(wl[0] + 0.0 * (x - tl[0]))
            else:
                out.append(wl[k] + sl[k] * (x - tl[k]))
        return out

    def time_at(self, angle: npt.ArrayLike) -> FloatOrArray:
        """The first time the angle reaches each of ``angle`` (rad, non-decreasing angle).

        On its segment the angle is ``phi_k + w_k dt + s_k dt^2 / 2``; the root is taken in
        the form ``2 d / (w_k + sqrt(w_k^2 + 2 s_k d))`` (no cancellation when decelerating).
        Before the first knot the speed is held at ``w_0``; after the last one at ``w_last``
        (inf when that is 0 and the angle is never reached).
        """
        a = np.asarray(angle, dtype=float)
        one = self._time_one(a)
        if one is not None:
            return one
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
        times = np.asarray(t, dtype=float)
        return _one(self._knots().speed(times), times)

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
        times = np.asarray(t, dtype=float)
        return _one(self._knots().acceleration(times), times)

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
        times = np.asarray(t, dtype=float)
        return _one(self._knots().angle(times), times)

    def state(self, t: npt.ArrayLike) -> tuple[FloatOrArray, FloatOrArray, FloatOrArray]:
        """Return ``(phi, omega, alpha)`` at times ``t`` (rad, rad/s, rad/s^2)."""
        times = np.asarray(t, dtype=float)
        phi, omega, alpha = self._knots().state(times)
        if times.ndim == 0:
            return phi[()], omega[()], alpha[()]   # type: ignore[index]
        return phi, omega, alpha

    def angle_speed(self, t: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``(phi, omega)`` at the times of a 1-D float array ``t``: :meth:`state` without
        the acceleration (rad, rad/s), the same values (the live tachometer's per-chunk
        query)."""
        angle, speed, _ = self._knots().state_parts(t)
        return angle, _filled(speed, t)   # type: ignore[return-value]

    def keyphasor(self, first: int, last: int, t_lo: float, t_hi: float
                  ) -> tuple[list[float], list[float]]:
        """The keyphasor times of turns ``first .. last`` and the speeds there, as floats.

        The values of ``t = clip(time_at_angle(2 pi k), t_lo, t_hi)`` and ``speed(t)`` for
        ``k = first .. last`` (s, rad/s), computed on Python floats with the same operations
        (the same bits) when every angle is on a segment it can be solved on alone, else by
        those array methods. A chunk holds a few turns: a list costs less than arrays.

        Parameters
        ----------
        first, last : int
            The turns (dimensionless), ``first <= last``.
        t_lo, t_hi : float
            The bounds the times are clipped to (s), ``t_lo <= t_hi``.

        Returns
        -------
        times, speeds : list of float
        """
        knots = self._knots()
        angles = [_TWO_PI * k for k in range(first, last + 1)]   # as int64 * float: exact
        times = knots.time_list(angles)
        if times is None:
            at = np.clip(self.time_at_angle(np.array(angles)), t_lo, t_hi)
            return at.tolist(), np.atleast_1d(self.speed(at)).tolist()
        # np.clip's float rule: max as a > b ? a : b, then min as a < b ? a : b
        times = [x if x < t_hi else t_hi for x in (x if x > t_lo else t_lo for x in times)]
        return times, knots.speed_list(times)

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
        angles = np.asarray(angle, dtype=float)
        return _one(self._knots().time_at(angles), angles)


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
        if type(t) is np.ndarray and t.ndim == 1 and t.dtype == np.float64:
            times = t   # the sampler's grid: nothing to convert
        else:
            times = np.atleast_1d(np.asarray(t, dtype=float)).ravel()
        n = self.n_inputs if n_inputs is None else int(n_inputs)
        profile = self.profile
        if type(profile).state is SpeedProfile.state:
            # speed and acceleration are Python floats when the times share a segment
            phi, omega, alpha = profile._knots().state_parts(times)
            steady = type(alpha) is float and alpha == 0.0
        else:
            phi, omega, alpha = profile.state(times)
            steady = False
        phi = cast(FloatArray, phi)
        w2 = omega * omega
        columns = self.input_pairs.ravel().tolist()   # [y0, z0, y1, z1, ...]
        if len(set(columns)) < len(columns):
            return self._summed(times, n, phi, w2, alpha)
        # every bearing at once, as a (time, bearing, y/z) array: element by element the
        # operations of the loop in _summed, and cos/sin of the same angles
        if isinstance(w2, np.ndarray) and w2.ndim == 1:
            w2 = w2[:, None]
        angle = phi[:, None] + self.phase
        c, s = np.cos(angle), np.sin(angle)
        both = np.empty(angle.shape + (2,))
        fy, fz = both[:, :, 0], both[:, :, 1]
        np.multiply(w2, c, out=fy)
        np.multiply(w2, s, out=fz)
        if not steady:
            # (steady: one segment's tame times, so c and s are finite and these terms are
            # +-0, which leave the sums but for the sign of a zero; adding the result to
            # zeros below gives +0 either way)
            if isinstance(alpha, np.ndarray) and alpha.ndim == 1:
                alpha = alpha[:, None]
            fy += alpha * s
            fz -= alpha * c
        both *= (self._multiplier * self.m_e)[:, None]
        both += 0.0   # what adding to zeros does: -0 becomes +0
        flat = both.reshape(times.size, 2 * angle.shape[1])
        if columns == list(range(n)):
            return flat
        out = np.zeros((times.size, n))
        out[:, columns] = flat
        return out

    def _summed(self, times: FloatArray, n: int, phi: FloatArray, w2: FloatOrArray,
                alpha: FloatOrArray) -> FloatArray:
        """:meth:`forces` summed bearing by bearing, for bearings that share an input."""
        out = np.zeros((times.size, n))
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
