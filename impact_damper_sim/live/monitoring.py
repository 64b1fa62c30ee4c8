"""Rolling vibration statistics for the ``monitor`` node: the ROS-free core.

:class:`RollingVibrationStats` is fed batches of accelerometer samples (time in s,
acceleration in m/s^2 along x, y, z), impact times (s), optionally with the interval a batch
of them covers, and impactor stuck/free updates, and reports over a rolling window of the
most recent ``window`` seconds:

* per sensor, RMS and peak acceleration in g (``G0`` = 9.80665 m/s^2) along each axis and of
  the vector magnitude ``|a| = sqrt(ax^2 + ay^2 + az^2)``;
* per sensor, the dominant frequency (Hz) of each axis and of the sensor (the peak of the
  power summed over the axes), from a Hann-windowed FFT refined by a parabola through the
  log-power of the peak bin and its neighbours (QIFFT, Smith & Serra), with the frequency
  resolution ``1 / (n dt)`` of the window's samples (:mod:`.spectrum`);
* impacts per second and the time-weighted fraction of impactors stuck.

How the monitor reads ``impactor_state`` and words what it sees is in :mod:`.monitor_text`.

Conventions
-----------
Times are the senders' stamps (sim time), never the receiver's clock. The window is the
half-open interval ``(now - window, now]``, where ``now`` is the latest stamp received on any
stream; a stamp within half a nanosecond (half the resolution of ROS stamps) of
``now - window`` counts as on the boundary, so outside, whatever the rounding.

The RMS is the plain RMS of the samples (the accelerometers are AC-coupled: no mean is
removed). The peak is the largest sample of ``|a|``, not interpolated: a sine of amplitude A
sampled at ``fs`` reads between ``A cos(pi f / fs)`` and A. Before the FFT the window's
samples are resampled onto a uniform grid at their median spacing (dropped samples are
interpolated across) and their mean is removed.

Samples with a non-finite time or acceleration, or a component beyond ``MAX_ACCELERATION``,
are rejected and counted. An accelerometer sample at or before ``now - window`` means that
the sender's clock went back by more than a window (a restarted simulator, a looped bag):
every history is then cleared and the count of time resets increases. Samples late by less
than a window are merged in time order.
"""
from __future__ import annotations

import bisect
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ..scene.units import G0
from .spectrum import dominant_frequencies

#: Largest acceleration component accepted (m/s^2, about 1e11 g): beyond it a reading is not
#: physical, and its square would overflow the sums.
MAX_ACCELERATION = 1e12
AXES = ('x', 'y', 'z')
#: Half the resolution of ROS stamps (s): the margin that puts a sample stamped exactly
#: ``now - window`` outside the window despite rounding.
_BOUNDARY = 0.5e-9


@dataclass(frozen=True)
class SensorStats:
    """Rolling statistics of one accelerometer.

    Attributes
    ----------
    name : str
        Sensor name.
    samples : int
        Samples in the window.
    samples_per_s : float
        Sample rate over the window (1/s): ``(samples - 1)`` over the time between the first
        and last of them; dropped samples lower it. NaN with fewer than 2 samples.
    rms_g, peak_g : float
        RMS and peak of the vector magnitude ``|a|`` (g). NaN without samples.
    rms_g_axes, peak_g_axes : tuple of float
        RMS and peak of ``|a_x|, |a_y|, |a_z|`` (g).
    dominant_hz : float
        Dominant frequency of the sensor (Hz): the peak of the power summed over the three
        axes. NaN with fewer than ``MIN_FFT_SAMPLES`` samples or a constant signal.
    dominant_hz_axes : tuple of float
        Dominant frequency of each axis (Hz).
    resolution_hz : float
        Frequency resolution, ``1 / (n dt)`` for ``n`` samples of spacing ``dt`` in the
        window (Hz); the interpolated peak is good to a small fraction of it.
    last_sample_t : float or None
        Stamp of the sensor's latest sample (s), None if none was received.
    rejected_samples : int
        Samples rejected since the start (non-finite or beyond ``MAX_ACCELERATION``; not
        cleared by time resets).
    """

    name: str
    samples: int
    samples_per_s: float
    rms_g: float
    peak_g: float
    rms_g_axes: tuple[float, ...]
    peak_g_axes: tuple[float, ...]
    dominant_hz: float
    dominant_hz_axes: tuple[float, ...]
    resolution_hz: float
    last_sample_t: float | None
    rejected_samples: int


@dataclass(frozen=True)
class VibrationReport:
    """One report of :class:`RollingVibrationStats`.

    Attributes
    ----------
    t : float
        End of the window, the latest stamp received (s); NaN before any input.
    window : float
        Window length (s).
    span : float
        Part of the window covered by input since the start or the last time reset (s):
        ``min(window, t - first sample or impact stamp)``, where the start of an impact batch
        counts as an impact stamp; rates are per this span (stuck/free updates do not count:
        a latched one may be old).
    sensors : dict of str to SensorStats
        Per-sensor statistics, in the order the sensors were added.
    impacts : int
        Impacts in the window.
    impacts_per_s : float
        ``impacts / span`` (1/s); NaN when ``span`` is 0.
    stuck_fraction : float
        Time average over the window (the part of it after the first stuck/free update) of
        the fraction of impactors stuck (dimensionless, 0..1); the current fraction if that
        part has zero length; 0 with no impactors; NaN before any update.
    impactors : int
        Number of impactors in the latest update (0 before any).
    stuck_impactors : int
        Number of them stuck in the latest update.
    rejected_samples, rejected_impacts, rejected_states : int
        Inputs rejected since the start (non-finite or malformed).
    time_resets : int
        Times the histories were cleared because the stamps went back by more than a window.
    """

    t: float
    window: float
    span: float
    sensors: dict[str, SensorStats]
    impacts: int
    impacts_per_s: float
    stuck_fraction: float
    impactors: int
    stuck_impactors: int
    rejected_samples: int
    rejected_impacts: int
    rejected_states: int
    time_resets: int


class _SampleBuffer:
    """Time-sorted samples ``(t, values)`` in a growable array, evicted from the front."""

    def __init__(self, width: int) -> None:
        self._t = np.empty(0)
        self._v = np.empty((0, width))
        self._start = 0
        self._end = 0

    def __len__(self) -> int:
        return self._end - self._start

    def clear(self) -> None:
        self._start = self._end = 0

    @property
    def last_t(self) -> float | None:
        return float(self._t[self._end - 1]) if self._end > self._start else None

    def view(self) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """Return the stored ``(t, values)`` (views, do not modify)."""
        return self._t[self._start:self._end], self._v[self._start:self._end]

    def append(self, t: npt.NDArray[np.float64], v: npt.NDArray[np.float64]) -> None:
        """Append samples; ``t`` need not be sorted nor later than the stored ones."""
        n = t.size
        if n == 0:
            return
        if np.any(np.diff(t) < 0) or (len(self) and t[0] < self._t[self._end - 1]):
            # late samples (rare): merge them in time order
            old_t, old_v = self.view()
            t = np.concatenate([old_t, t])
            v = np.concatenate([old_v, v])
            order = np.argsort(t, kind='stable')  # stable: arrival order among equal stamps
            t, v = t[order], v[order]
            self.clear()
            n = t.size
        if self._end + n > self._t.size:
            self._compact(n)
        self._t[self._end:self._end + n] = t
        self._v[self._end:self._end + n] = v
        self._end += n

    def evict_until(self, t_min: float) -> None:
        """Drop the samples with ``t <= t_min``."""
        t, _ = self.view()
        self._start += int(np.searchsorted(t, t_min, side='right'))

    def _compact(self, extra: int) -> None:
        live = len(self)
        capacity = max(2 * (live + extra), 1024)
        t = np.empty(capacity)
        v = np.empty((capacity, self._v.shape[1]))
        t[:live] = self._t[self._start:self._end]
        v[:live] = self._v[self._start:self._end]
        self._t, self._v, self._start, self._end = t, v, 0, live


class _Sensor:
    def __init__(self, name: str) -> None:
        self.name = name
        self.buffer = _SampleBuffer(3)
        self.rejected = 0


class RollingVibrationStats:
    """Rolling vibration statistics over the last ``window`` seconds of stamped input.

    Parameters
    ----------
    window : float
        Window length (s), finite and > 0.
    sensors : iterable of str, optional
        Sensors to report from the start (also those without data yet); others are added
        by :meth:`add_samples` on first use.

    Examples
    --------
    >>> import numpy as np
    >>> stats = RollingVibrationStats(window=1.0, sensors=['tip'])
    >>> t = (np.arange(2000) + 0.5) / 1000.0                 # 2 s at 1 kHz (s)
    >>> a = np.zeros((t.size, 3))
    >>> a[:, 0] = 2 * G0 * np.sin(2 * np.pi * 40.0 * t)     # 2 g at 40 Hz (m/s^2)
    >>> stats.add_samples('tip', t, a)
    2000
    >>> stats.add_impacts([1.2, 1.5, 1.7])
    3
    >>> s = stats.report().sensors['tip']
    >>> round(s.rms_g, 6), round(s.dominant_hz, 6), s.samples
    (1.414214, 40.0, 1000)
    >>> stats.report().impacts_per_s
    3.0
    """

    def __init__(self, window: float, sensors: Iterable[str] = ()) -> None:
        self._window = self._checked_window(window)
        self._sensors: dict[str, _Sensor] = {}
        for name in sensors:
            self.add_sensor(name)
        self._impacts = _SampleBuffer(0)
        self._states: list[tuple[float, float]] = []   # [(t, stuck fraction)], time-sorted
        self._impactors = 0
        self._stuck_impactors = 0
        self._now: float | None = None       # latest stamp on any stream (s)
        self._first_t: float | None = None   # earliest stamp since the start or the last reset (s)
        self._rejected_impacts = 0
        self._rejected_states = 0
        self._time_resets = 0

    @staticmethod
    def _checked_window(window: float) -> float:
        window = float(window)
        if not (np.isfinite(window) and window > 0.0):
            raise ValueError(f'window must be finite and > 0 s, got {window!r}')
        return window

    @property
    def window(self) -> float:
        """Window length (s); setting it evicts what falls out of a shorter window."""
        return self._window

    @window.setter
    def window(self, value: float) -> None:
        self._window = self._checked_window(value)
        self._evict()

    @property
    def sensors(self) -> tuple[str, ...]:
        """Names of the sensors (tuple of str), in the order they were added."""
        return tuple(self._sensors)

    @property
    def now(self) -> float | None:
        """Latest stamp received on any stream (s), or None before any input."""
        return self._now

    def add_sensor(self, name: str) -> None:
        """Start reporting sensor ``name`` (str), even before it has data; idempotent."""
        if name not in self._sensors:
            self._sensors[name] = _Sensor(name)

    def reset(self) -> None:
        """Clear every history (sample, impact and stuck-state); keep the rejection counts."""
        for sensor in self._sensors.values():
            sensor.buffer.clear()
        self._impacts.clear()
        self._states.clear()
        self._impactors = self._stuck_impactors = 0
        self._now = self._first_t = None

    def add_samples(self, sensor: str, times: npt.ArrayLike, accelerations: npt.ArrayLike
                    ) -> int:
        """Add a batch of accelerometer samples.

        Parameters
        ----------
        sensor : str
            Sensor name.
        times : array_like, shape (n,)
            Sample stamps (s).
        accelerations : array_like, shape (n, 3)
            Accelerations along x, y, z (m/s^2).

        Returns
        -------
        int
            Samples kept: not rejected (a non-finite time or acceleration, or a component
            beyond ``MAX_ACCELERATION``) nor dropped as history from before a time reset.

        Raises
        ------
        ValueError
            If the shapes do not match.
        """
        t = np.asarray(times, dtype=float).reshape(-1)
        a = np.asarray(accelerations, dtype=float)
        if a.shape != (t.size, 3):
            raise ValueError(f'accelerations must have shape ({t.size}, 3), got {a.shape}')
        self.add_sensor(sensor)
        state = self._sensors[sensor]
        with np.errstate(invalid='ignore'):   # NaN compares False: rejected below
            good = np.isfinite(t) & np.all(np.abs(a) <= MAX_ACCELERATION, axis=1)
        state.rejected += int(t.size - np.count_nonzero(good))
        t, a = t[good], a[good]
        if t.size == 0:
            return 0
        while True:
            # a sample a window older than everything before it: the sender's clock went back
            before = np.maximum.accumulate(np.concatenate(
                [[-np.inf if self._now is None else self._now], t[:-1]]))
            went_back = np.flatnonzero(t <= before - self._window)
            if went_back.size == 0:
                break
            self._time_resets += 1
            self.reset()
            t, a = t[went_back[0]:], a[went_back[0]:]
        state.buffer.append(t, a)
        self._saw(float(t.min()), float(t.max()))
        return int(t.size)

    def add_impacts(self, times: npt.ArrayLike, start: float | None = None) -> int:
        """Add impacts.

        Parameters
        ----------
        times : array_like, shape (n,)
            Impact stamps (s); non-finite ones are rejected and counted.
        start : float, optional
            Start of the interval a batch of impacts covers (s): the batch says that nothing
            else hit from ``start`` to its last impact, so the interval counts in the span of
            the impact rate even when ``times`` is empty. None for impacts that come one by
            one (each covers only its own stamp).

        Returns
        -------
        int
            Impacts accepted.
        """
        t = np.asarray(times, dtype=float).reshape(-1)
        good = np.isfinite(t)
        self._rejected_impacts += int(t.size - np.count_nonzero(good))
        t = t[good]
        if t.size:
            self._impacts.append(t, np.empty((t.size, 0)))
        covered = t if start is None else np.append(t, float(start))
        covered = covered[np.isfinite(covered)]
        if covered.size:
            self._saw(float(covered.min()), float(covered.max()))
        return int(t.size)

    def reject_samples(self, sensor: str, count: int) -> None:
        """Count samples rejected before they reached :meth:`add_samples`.

        Parameters
        ----------
        sensor : str
            Sensor name.
        count : int
            Samples rejected (samples), e.g. the rows of a malformed batch message.
        """
        self.add_sensor(sensor)
        self._sensors[sensor].rejected += int(count)

    def reject_impacts(self, count: int) -> None:
        """Count impacts rejected before they reached :meth:`add_impacts`.

        Parameters
        ----------
        count : int
            Impacts rejected (impacts), e.g. the rows of a malformed batch message.
        """
        self._rejected_impacts += int(count)

    def clear_sensor(self, sensor: str) -> None:
        """Drop the sample history of a sensor whose source changed; keep its rejections.

        Parameters
        ----------
        sensor : str
            Sensor name.
        """
        self.add_sensor(sensor)
        self._sensors[sensor].buffer.clear()

    def update_stuck(self, time: float, stuck: npt.ArrayLike) -> bool:
        """Record the stuck/free state of every impactor from stamp ``time`` on.

        Parameters
        ----------
        time : float
            Stamp of the update (s).
        stuck : array_like of bool, shape (n_impactors,)
            True for each impactor that is stuck (n_impactors may be 0).

        Returns
        -------
        bool
            False if the update was rejected (non-finite time).
        """
        time = float(time)
        flags = np.asarray(stuck, dtype=bool).reshape(-1)
        if not np.isfinite(time):
            self._rejected_states += 1
            return False
        n_stuck = int(np.count_nonzero(flags))
        fraction = n_stuck / flags.size if flags.size else 0.0
        index = bisect.bisect_right([s[0] for s in self._states], time)
        self._states.insert(index, (time, fraction))
        if index == len(self._states) - 1:
            self._impactors, self._stuck_impactors = int(flags.size), n_stuck
        # an old stamp (a latched state) is no evidence of when the monitor started listening
        self._saw(time, time, covers=False)
        return True

    def reject_state(self) -> None:
        """Count a malformed stuck/free update that never reached :meth:`update_stuck`."""
        self._rejected_states += 1

    def _saw(self, t_min: float, t_max: float, covers: bool = True) -> None:
        """Advance ``now`` (and the start of the covered span if ``covers``), then evict."""
        if covers:
            self._first_t = t_min if self._first_t is None else min(self._first_t, t_min)
        if self._now is None or t_max > self._now:
            self._now = t_max
            self._evict()

    def _evict(self) -> None:
        if self._now is None:
            return
        start = self._now - self._window
        for sensor in self._sensors.values():
            sensor.buffer.evict_until(start + _BOUNDARY)
        self._impacts.evict_until(start + _BOUNDARY)
        # keep the last update at or before the window start: it is the state at the start
        times = [s[0] for s in self._states]
        drop = bisect.bisect_right(times, start) - 1
        if drop > 0:
            del self._states[:drop]

    def _stuck_fraction(self, start: float, end: float) -> float:
        if not self._states:
            return float('nan')
        start = max(start, self._states[0][0])
        if not end > start:
            return self._states[-1][1]
        total = 0.0
        for i, (t_i, fraction) in enumerate(self._states):
            t_next = self._states[i + 1][0] if i + 1 < len(self._states) else end
            overlap = min(t_next, end) - max(t_i, start)
            if overlap > 0.0:
                total += fraction * overlap
        return total / (end - start)

    def _sensor_stats(self, sensor: _Sensor, start: float) -> SensorStats:
        nan = float('nan')
        t, a = sensor.buffer.view()
        inside = t > start + _BOUNDARY
        t, a = t[inside], a[inside]
        n = int(t.size)
        if n == 0:
            return SensorStats(sensor.name, 0, nan, nan, nan, (nan,) * 3, (nan,) * 3, nan,
                               (nan,) * 3, nan, sensor.buffer.last_t, sensor.rejected)
        squares = a * a
        magnitude_sq = squares.sum(axis=1)
        rms_axes = np.sqrt(squares.mean(axis=0)) / G0
        peak_axes = np.abs(a).max(axis=0) / G0
        span = float(t[-1] - t[0])
        rate = (n - 1) / span if span > 0.0 else nan
        total_hz, axes_hz, resolution = dominant_frequencies(t, a)
        return SensorStats(
            name=sensor.name, samples=n, samples_per_s=rate,
            rms_g=float(np.sqrt(magnitude_sq.mean())) / G0,
            peak_g=float(np.sqrt(magnitude_sq.max())) / G0,
            rms_g_axes=tuple(float(v) for v in rms_axes),
            peak_g_axes=tuple(float(v) for v in peak_axes),
            dominant_hz=total_hz, dominant_hz_axes=tuple(float(v) for v in axes_hz),
            resolution_hz=resolution, last_sample_t=sensor.buffer.last_t,
            rejected_samples=sensor.rejected)

    def report(self) -> VibrationReport:

        """Return the statistics over ``(now - window, now]`` (a :class:`VibrationReport`)."""
        nan = float('nan')
        now = self._now if self._now is not None else nan
        start = now - self._window
        span = min(self._window, now - self._first_t) if self._first_t is not None else 0.0
        sensors = {name: self._sensor_stats(s, start) for name, s in self._sensors.items()}
        impact_t, _ = self._impacts.view()
        impacts = int(np.count_nonzero((impact_t > start + _BOUNDARY) & (impact_t <= now)))
        return VibrationReport(
            t=now, window=self._window, span=span, sensors=sensors, impacts=impacts,
            impacts_per_s=impacts / span if span > 0.0 else nan,
            stuck_fraction=self._stuck_fraction(start, now) if self._now is not None else nan,
            impactors=self._impactors, stuck_impactors=self._stuck_impactors,
            rejected_samples=sum(s.rejected for s in self._sensors.values()),
            rejected_impacts=self._rejected_impacts, rejected_states=self._rejected_states,
            time_resets=self._time_resets)


__all__ = ['AXES', 'MAX_ACCELERATION', 'RollingVibrationStats', 'SensorStats',
           'VibrationReport']
