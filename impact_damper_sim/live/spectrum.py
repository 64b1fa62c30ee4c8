"""The dominant frequency of sampled signals: resampled, Hann-windowed FFT, refined peak.

:func:`dominant_frequencies` puts possibly uneven samples on a uniform grid at their median
spacing, removes the mean, applies a periodic Hann window, zero-pads the FFT to a 5-smooth
length (:func:`_fast_length`) and refines the peak bin by a parabola through the log-power
of it and its neighbours (QIFFT, Smith & Serra), per column and for the power summed over
the columns. It is the spectral estimate behind the ``monitor`` node's dominant frequencies
(:mod:`.monitoring`), kept apart because it is a pure function of arrays, with none of the
rolling window's bookkeeping (test/test_monitoring.py checks it through the reports).
"""
from __future__ import annotations

import numpy as np
import numpy.typing as npt

#: Fewest uniformly spaced samples for which a dominant frequency is reported.
MIN_FFT_SAMPLES = 8


def _quadratic_peak(log_mag: np.ndarray, k: int) -> float:
    """Offset (bins, within -0.5..0.5) of the vertex of the parabola through ``k-1, k, k+1``."""
    a, b, c = log_mag[k - 1], log_mag[k], log_mag[k + 1]
    denom = a - 2.0 * b + c
    if not denom < 0.0:
        return 0.0
    return float(np.clip(0.5 * (a - c) / denom, -0.5, 0.5))


def _dominant_from_power(power: np.ndarray, bin_hz: float) -> float:
    """Dominant frequency (Hz) from a one-sided power spectrum, bin 0 (DC) excluded."""
    if power.size < 3:
        return float('nan')
    k = 1 + int(np.argmax(power[1:]))
    if not power[k] > 0.0:
        return float('nan')   # a constant signal has no dominant frequency
    offset = 0.0
    if k < power.size - 1:
        # floor the neighbours so that log stays finite next to an exact zero
        log_p = np.log(np.maximum(power[k - 1:k + 2], np.finfo(float).tiny))
        offset = _quadratic_peak(log_p, 1)
    return (k + offset) * bin_hz


def _fast_length(n: int) -> int:
    """Smallest ``2^a 3^b 5^c >= n`` (int), a length the FFT handles at full speed."""
    best = 1 << max(int(n - 1).bit_length(), 0)
    power5 = 1
    while power5 < best:
        power35 = power5
        while power35 < best:
            length = power35 << max(int(-(-n // power35) - 1).bit_length(), 0)
            best = min(best, length)
            power35 *= 3
        power5 *= 5
    return best


def dominant_frequencies(t: np.ndarray, values: np.ndarray
                         ) -> tuple[float, npt.NDArray[np.float64], float]:
    """Dominant frequency of each column and of their summed power.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Sample times (s), sorted.
    values : ndarray, shape (n, m)
        Signals (any unit), one per column.

    Returns
    -------
    total_hz : float
        Dominant frequency of the power summed over the columns (Hz).
    column_hz : ndarray, shape (m,)
        Dominant frequency of each column (Hz).
    resolution_hz : float
        Frequency resolution of the samples, ``1 / (n dt)`` (Hz), ``n`` grid points of spacing
        ``dt``; the FFT bins are this or finer (zero padding to a fast length).

    Notes
    -----
    The samples are resampled by linear interpolation onto a uniform grid ending at ``t[-1]``
    with the median positive spacing, the mean is removed, a periodic Hann window applied,
    the FFT zero-padded to the next 5-smooth length, and the peak bin refined by a parabola
    through the log-power of it and its neighbours.
    NaN is returned when fewer than ``MIN_FFT_SAMPLES`` grid points fit.
    """
    m = values.shape[1]
    nan = float('nan')
    steps = np.diff(t)
    steps = steps[steps > 0.0]
    if steps.size == 0:
        return nan, np.full(m, nan), nan
    dt = float(np.median(steps))
    # samples on the grid; the margin keeps a whole number of steps from rounding down
    n = int(np.floor((t[-1] - t[0]) / dt + 1e-6)) + 1
    if n < MIN_FFT_SAMPLES:
        return nan, np.full(m, nan), nan
    grid = t[-1] - dt * np.arange(n - 1, -1, -1)
    # one row per signal: the FFT runs along contiguous memory (several times faster)
    uniform = np.array([np.interp(grid, t, values[:, j]) for j in range(m)])
    uniform -= uniform.mean(axis=1, keepdims=True)
    uniform *= 0.5 - 0.5 * np.cos(2.0 * np.pi * np.arange(n) / n)    # periodic Hann
    # zero-pad to a 5-smooth length: a large prime factor makes the FFT many times slower
    n_fft = _fast_length(n)
    spectrum = np.fft.rfft(uniform, n=n_fft, axis=1)
    power = spectrum.real ** 2 + spectrum.imag ** 2
    bin_hz = 1.0 / (n_fft * dt)
    column_hz = np.array([_dominant_from_power(row, bin_hz) for row in power])
    return _dominant_from_power(power.sum(axis=0), bin_hz), column_hz, 1.0 / (n * dt)


__all__ = ['MIN_FFT_SAMPLES', 'dominant_frequencies']
