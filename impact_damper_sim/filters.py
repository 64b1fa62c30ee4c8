"""Streaming Butterworth low-pass filters for the accelerometer outputs.

The simulators report, per sensor, the *mean acceleration over each sample period*
(:meth:`~impact_damper_sim.simulation.Simulation.mean_acceleration`). A sensor with a
``lowpass`` cutoff (scene key ``sensors[].lowpass``, Hz) reports that signal passed through a
digital Butterworth low-pass (second-order sections, zero initial state: the structure starts
at rest, so the acceleration history before t = 0 is zero). The filter carries its state
between calls, so a run advanced chunk by chunk gives the same output as one advanced in a
single call.
"""
from __future__ import annotations

import numpy as np


def butter_lowpass_sos(order, cutoff_hz, sample_rate_hz):
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

    def __init__(self, cutoff_hz, sample_rate_hz, n_channels, order=4):
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

    def reset(self):
        """Zero the filter state (a signal at rest before the next sample)."""
        self.zi = np.zeros((self.sos.shape[0], 2, self.n_channels))

    def apply(self, x):
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
        from .integrate.kernels.filters import sosfilt
        x = np.asarray(x, dtype=float)
        flat = x.ndim == 1
        x2 = x[:, None] if flat else x
        if x2.ndim != 2 or x2.shape[1] != self.n_channels:
            raise ValueError(f'expected shape (k, {self.n_channels}), got {x.shape}')
        if x2.shape[0] == 0:
            return x.copy()
        y = np.empty_like(x2)
        sosfilt(self.sos, np.ascontiguousarray(x2), self.zi, y)
        return y[:, 0] if flat else y


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

    def __init__(self, sensors, dt, order=4, source=None):
        from .scene.schema import SceneError
        rate = 1.0 / float(dt)
        groups, errors = {}, []
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
    def active(self):
        """bool: at least one sensor is filtered."""
        return bool(self.groups)

    def apply(self, acc):
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


def scene_lowpass(scene, dt=None, order=4):
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
