"""Streaming Butterworth low-pass filters for the accelerometer outputs.

The simulators report, per sensor, the *mean acceleration over each sample period*
(:meth:`~impact_damper_sim.integrate.simulation.Simulation.mean_acceleration`). A sensor with a
``lowpass`` cutoff (scene key ``sensors[].lowpass``, Hz) reports that signal passed through a
digital Butterworth low-pass (second-order sections, zero initial state: the structure starts
at rest, so the acceleration history before t = 0 is zero). The filter carries its state
between calls, so a run advanced chunk by chunk gives the same output as one advanced in a
single call.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:
    from ..scene.build import SceneModel


def butter_lowpass_sos(order: int, cutoff_hz: float,
                       sample_rate_hz: float) -> npt.NDArray[np.float64]:
    """Digital Butterworth low-pass in second-order sections (bilinear, prewarped).

    The same transfer function as ``scipy.signal.butter(order, cutoff_hz, output='sos',
    fs=sample_rate_hz)`` (outputs agree to round-off, ``test/test_filters.py``; the gain is
    spread as unit DC gain per section), without importing ``scipy.signal``: its import
    took 2.8 to 7.3 s (``python -X importtime``, 2 loaded cores, warm and cold disk cache),
    a few tenths of a second on a quiet machine, and the node needs only this filter.

    Parameters
    ----------
    order : int
        Filter order (dimensionless), >= 1.
    cutoff_hz : float
        -3 dB cutoff (Hz), in ``(0, sample_rate_hz / 2)``.
    sample_rate_hz : float
        Sample rate (Hz).

    Returns
    -------
    ndarray, shape (ceil(order / 2), 6)
        Rows ``[b0, b1, b2, 1, a1, a2]``, unit gain at DC.
    """
    fs2 = 2.0 * float(sample_rate_hz)
    warped = fs2 * np.tan(np.pi * float(cutoff_hz) / float(sample_rate_hz))
    k = np.arange(1, order + 1)
    poles_s = warped * np.exp(1j * np.pi * (2 * k + order - 1) / (2 * order))
    poles_z = (fs2 + poles_s) / (fs2 - poles_s)
    # conjugate pairs (upper half plane) first, a real pole last, as scipy orders them
    upper = sorted((p for p in poles_z if p.imag > 1e-12), key=lambda p: -abs(p))
    sections = []
    for p in upper:
        sections.append([1.0, 2.0, 1.0, 1.0, -2.0 * p.real, abs(p) ** 2])
    if order % 2:
        p = float(poles_z[np.argmin(np.abs(poles_z.imag))].real)
        sections.append([1.0, 1.0, 0.0, 1.0, -p, 0.0])
    sos = np.array(sections[::-1])   # poles nearest the unit circle last, as scipy does
    for row in sos:                  # unit DC gain per section
        row[:3] *= (1.0 + row[4] + row[5]) / (row[0] + row[1] + row[2])
    return sos


class StreamingLowpass:
    """Digital Butterworth low-pass that keeps its state between chunks.

    Parameters
    ----------
    cutoff_hz : float
        -3 dB cutoff frequency (Hz), ``0 < cutoff_hz < sample_rate_hz / 2``.
    sample_rate_hz : float
        Sample rate of the signal (Hz).
    n_channels : int
        Number of channels (columns of the signal).
    order : int
        Filter order (default 4; 2 and 4 are the usual accelerometer filters).

    Raises
    ------
    ValueError
        A cutoff that is not positive or not below the Nyquist frequency.
    """

    def __init__(self, cutoff_hz: float, sample_rate_hz: float, n_channels: int,
                 order: int = 4) -> None:
        self.cutoff_hz = float(cutoff_hz)
        self.sample_rate_hz = float(sample_rate_hz)
        self.n_channels = int(n_channels)
        self.order = int(order)
        nyquist = 0.5 * self.sample_rate_hz
        if not 0.0 < self.cutoff_hz < nyquist:
            raise ValueError(f'low-pass cutoff {self.cutoff_hz:g} Hz must lie in (0, '
                             f'{nyquist:g}) Hz, the Nyquist frequency of the sample rate '
                             f'{self.sample_rate_hz:g} Hz')
        if self.order < 1:
            raise ValueError(f'filter order must be >= 1, got {self.order}')
        self.sos = butter_lowpass_sos(self.order, self.cutoff_hz, self.sample_rate_hz)
        self.reset()

    def reset(self) -> None:
        """Zero the filter state (a signal at rest before the next sample)."""
        self.zi = np.zeros((self.sos.shape[0], 2, self.n_channels))

    def apply(self, x: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """Filter the next chunk of the signal.

        Parameters
        ----------
        x : array_like, shape (k, n_channels) or (k,) when ``n_channels == 1``
            Next ``k`` samples (any unit).

        Returns
        -------
        ndarray
            Filtered samples, same shape and unit as ``x``.
        """
        from ..integrate.kernels.filters import sosfilt
        x = np.asarray(x, dtype=float)
        flat = x.ndim == 1
        x2 = x[:, None] if flat else x
        if x2.ndim != 2 or x2.shape[1] != self.n_channels:
            raise ValueError(f'expected shape (k, {self.n_channels}), got {x.shape}')
        # no early return for k = 0: that call compiles the kernel where the node warms up
        # (LiveSimulation.step(0)), not in its first paced tick (1.4 s on a cold cache)
        y = np.empty_like(x2)
        sosfilt(self.sos, np.ascontiguousarray(x2), self.zi, y)
        return y[:, 0] if flat else y


#: Stopband attenuation of the decimation filter (dB): 80 dB puts an alias below a 24-bit
#: vibration DAQ's noise floor relative to full scale of the band.
DECIMATION_STOPBAND_DB = 80.0
#: Passband edge of the decimation filter, times the output rate: flat (ripple 1e-4) to
#: 0.4 x the output rate, stopband from the output Nyquist frequency on (as delta-sigma DAQ
#: decimators are specified), so nothing above it folds back below it.
DECIMATION_PASSBAND_FRACTION = 0.4
#: Largest decimation factor (dimensionless). The anti-alias FIR is ~52 x factor taps
#: (delay ~26 output periods) and each chunk copies its history: at 2000 (1 Hz from 2 kHz)
#: 1e5 taps, +0.5 ms per 10 ms chunk of hpotp; at 2e6 (1 mHz) 1e8 taps, GBs a chunk.
MAX_DECIMATION_FACTOR = 2000


def kaiser_lowpass_fir(cutoff_hz: float, transition_hz: float, sample_rate_hz: float,
                       stopband_db: float = DECIMATION_STOPBAND_DB) -> npt.NDArray[np.float64]:
    """Linear-phase FIR low-pass by the Kaiser window method (odd length, unit DC gain).

    The window's beta and the length follow Kaiser's formulas (as ``scipy.signal.kaiserord``
    and ``firwin``), without importing ``scipy.signal`` (seconds on a loaded machine).

    Parameters
    ----------
    cutoff_hz : float
        Centre of the transition band (Hz), where the gain is 1/2.
    transition_hz : float
        Width of the transition band (Hz), > 0.
    sample_rate_hz : float
        Sample rate (Hz).
    stopband_db : float
        Attenuation outside ``cutoff_hz +- transition_hz / 2`` (dB, > 21); the passband
        ripple is the same fraction, ``10**(-stopband_db / 20)``.

    Returns
    -------
    ndarray, shape (n,)
        Taps, ``n`` odd: the delay is ``(n - 1) / 2`` samples.
    """
    fs = float(sample_rate_hz)
    a = float(stopband_db)
    beta = 0.1102 * (a - 8.7) if a > 50 else 0.5842 * (a - 21) ** 0.4 + 0.07886 * (a - 21)
    width = 2.0 * np.pi * float(transition_hz) / fs   # rad per sample
    n = int(np.ceil((a - 7.95) / (2.285 * width))) + 1
    n += 1 - n % 2                                      # odd: a whole-sample delay
    m = np.arange(n) - (n - 1) / 2.0
    fc = 2.0 * float(cutoff_hz) / fs                    # of the Nyquist frequency
    taps = fc * np.sinc(fc * m) * np.kaiser(n, beta)
    return taps / taps.sum()


class StreamingDecimator:
    """Anti-alias FIR filter and decimation by an integer factor, kept across chunks.

    Output sample ``k`` is the filtered signal at input sample ``k * factor``: the filter's
    delay is compensated in the time it is given for, not hidden (a linear-phase filter
    delays every frequency by the same ``(n - 1) / 2`` input samples, so an output is ready
    that many samples after its time). The signal is taken as zero before the first input
    sample (the structure at rest).

    Parameters
    ----------
    factor : int
        Decimation factor (dimensionless), >= 1; 1 passes the signal through unchanged.
    sample_rate_hz : float
        Input sample rate (Hz).
    n_channels : int
        Number of channels (columns of the signal).

    Attributes
    ----------
    taps : ndarray
        The FIR filter (``[1.0]`` for factor 1).
    delay : int
        Filter delay (input samples).
    """

    def __init__(self, factor: int, sample_rate_hz: float, n_channels: int) -> None:
        self.factor = int(factor)
        if self.factor < 1:
            raise ValueError(f'decimation factor must be >= 1, got {factor}')
        self.sample_rate_hz = float(sample_rate_hz)
        self.n_channels = int(n_channels)
        if self.factor == 1:
            self.taps = np.ones(1)
        else:
            rate_out = self.sample_rate_hz / self.factor
            edge = DECIMATION_PASSBAND_FRACTION * rate_out
            # Kaiser's length formula falls up to ~1 dB short: design 2 dB deeper
            self.taps = kaiser_lowpass_fir(0.5 * (edge + 0.5 * rate_out), 0.5 * rate_out - edge,
                                           self.sample_rate_hz, DECIMATION_STOPBAND_DB + 2.0)
        self.delay = (len(self.taps) - 1) // 2
        self._kernel = self.taps[::-1].copy()
        self._none = np.empty((0, 0, 0))   # apply's second group of columns: none
        self._gather: Any = None           # the compiled gather, imported on first use
        #: fraction of a white input's variance an output keeps: sum(taps^2) (0.44 at
        #: 2 -> 1 kHz, 0.044 at 20 -> 1 kHz; 1 without decimation)
        self.white_noise_gain = float(np.sum(self.taps ** 2))
        self.reset()

    def reset(self) -> None:
        """Forget the history (a signal at rest before the next sample)."""
        # the last len(taps) - 1 inputs, channel-major (updated in place)
        self._history = np.zeros((self.n_channels, len(self.taps) - 1))
        self._consumed = 0   # input samples taken so far
        # _filter's scratch per chunk length and output count: the history and the chunk
        # channel-major, and the windows
        self._work: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}

    def apply(self, x: npt.ArrayLike) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.float64]]:
        """Take the next chunk; return the outputs that are now complete.

        Parameters
        ----------
        x : array_like, shape (k, n_channels)
            Next ``k`` input samples (any unit).

        Returns
        -------
        index : ndarray of int, shape (j,)
            Input sample index (0 = the first sample ever given) each output stands for:
            multiples of ``factor``, ``delay`` samples behind the newest input at most.
        y : ndarray, shape (j, n_channels)
            The filtered, decimated signal at those samples (unit of ``x``).
        """
        x = np.asarray(x, dtype=float)
        if x.ndim != 2 or x.shape[1] != self.n_channels:
            raise ValueError(f'expected shape (k, {self.n_channels}), got {x.shape}')
        if self.factor == 1:
            index = np.arange(self._consumed, self._consumed + len(x), dtype=np.int64)
            self._consumed += len(x)
            return index, x.copy()
        return self._filter(np.ascontiguousarray(x).reshape(len(x), self.n_channels, 1),
                            self._none)

    def _apply_groups(self, a: np.ndarray, b: np.ndarray
                      ) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.float64]]:
        """:meth:`apply` of the chunk ``concatenate([a, b], axis=2).reshape(k, n_channels)``
        without making it: ``a`` and ``b`` C-contiguous float ``(k, g, w_a)`` and ``(k, g,
        w_b)``, ``g (w_a + w_b) = n_channels`` (``LiveSimulation.step``'s linear and angular
        accelerations)."""
        if self.factor == 1:
            return self.apply(np.concatenate([a, b], axis=2).reshape(len(a), self.n_channels))
        return self._filter(a, b)

    def _filter(self, a: np.ndarray, b: np.ndarray
                ) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.float64]]:
        """:meth:`apply` (factor > 1) of a chunk given as :meth:`_apply_groups` takes it."""
        gather = self._gather
        if gather is None:
            from ..integrate.kernels.channel_chunk import decimator_gather as gather
            self._gather = gather
        hist = self._history.shape[1]
        k = a.shape[0]
        start = self._consumed - hist   # the input index of the history's first column
        self._consumed += k
        # outputs at input index c need inputs up to c + delay, all taken by now
        last = self._consumed - 1 - self.delay
        first = max(0, -(-(self._consumed - k - self.delay) // self.factor) * self.factor)
        index = np.arange(first, last + 1, self.factor, dtype=np.int64)
        n = len(self.taps)
        # window of output c: inputs c + delay - n + 1 .. c + delay (before t = 0: zeros),
        # gathered channel-major into the layout a sliding_window_view indexed by lo has
        # (outputs, channels, taps): the product then rounds alike, bit for bit
        work = self._work.get((k, index.size))
        if work is None:
            if len(self._work) >= 8:   # chunk lengths vary (a paced run catching up)
                self._work.clear()
            work = self._work[k, index.size] = (np.empty((self.n_channels, hist + k)),
                                                 np.empty((index.size, self.n_channels, n)))
        buf, windows = work
        # also with no output: the history moves on (and the node's warm-up, a chunk of
        # none, compiles the kernel)
        gather(self._history, a, b, first + self.delay - (n - 1) - start, self.factor, buf,
               windows)
        if index.size == 0:
            return index, np.empty((0, self.n_channels))
        return index, (windows.transpose(1, 0, 2) @ self._kernel).T


class SensorLowpass:
    """Per-sensor low-pass of a scene's sensor outputs (``sensors[].lowpass``).

    Sensors without a cutoff pass unchanged; sensors sharing a cutoff share one
    :class:`StreamingLowpass`.

    Parameters
    ----------
    sensors : sequence of dict
        The scene's validated ``sensors`` (``lowpass`` in Hz or None).
    dt : float
        Sample period (s).
    order : int
        Filter order (default 4).

    Raises
    ------
    SceneError
        A cutoff at or above the Nyquist frequency ``1 / (2 dt)``; the message names the
        sensor key (``sensors[i].lowpass``).
    """

    def __init__(self, sensors: Sequence[Mapping[str, Any]], dt: float, order: int = 4,
                 source: str | None = None) -> None:
        from ..scene.schema import SceneError
        rate = 1.0 / float(dt)
        groups: dict[float, list[int]] = {}
        errors: list[str] = []
        for i, s in enumerate(sensors):
            fc = s.get('lowpass')
            if fc is None:
                continue
            if not fc < 0.5 * rate:
                errors.append(f"scene key 'sensors[{i}].lowpass': cutoff {fc:g} Hz must be "
                              f'below the Nyquist frequency {0.5 * rate:g} Hz of the sample '
                              f'period dt = {dt:g} s (lower the cutoff or dt)')
                continue
            groups.setdefault(float(fc), []).append(i)
        if errors:
            raise SceneError(errors, source)
        self.groups = [(np.array(idx), StreamingLowpass(fc, rate, len(idx), order))
                       for fc, idx in groups.items()]

    @property
    def active(self) -> bool:
        """bool: at least one sensor is filtered."""
        return bool(self.groups)

    def apply(self, acc: np.ndarray) -> npt.NDArray[np.float64]:
        """Filter the next chunk of sensor accelerations.

        Parameters
        ----------
        acc : ndarray, shape (k, n_sensors)
            Mean acceleration per sample period (m/s^2).

        Returns
        -------
        ndarray, shape (k, n_sensors)
            The same, each filtered sensor through its low-pass (m/s^2).
        """
        out = np.array(acc, dtype=float, copy=True)
        for idx, filt in self.groups:
            out[:, idx] = filt.apply(out[:, idx])
        return out


def scene_lowpass(scene: SceneModel, dt: float | None = None, order: int = 4) -> SensorLowpass:
    """:class:`SensorLowpass` of a built scene at sample period ``dt``.

    Parameters
    ----------
    scene : SceneModel
        Built scene.
    dt : float, optional
        Sample period (s); default the scene's ``simulation.dt``.
    order : int
        Filter order (default 4).

    Returns
    -------
    SensorLowpass
    """
    dt = scene.scene['simulation']['dt'] if dt is None else dt
    return SensorLowpass(scene.scene['sensors'], dt, order, source=scene.source)


__all__ = ['SensorLowpass', 'StreamingLowpass', 'butter_lowpass_sos', 'scene_lowpass']
