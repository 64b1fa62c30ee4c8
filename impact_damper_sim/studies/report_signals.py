"""The estimates of ``study report`` from arrays: peak and RMS of an accelerometer, its Welch
spectrum and, over a rotor-speed range, its waterfall; the impact rate in bins; the
time-weighted stuck fraction of each impactor. Functions of stamps (ns) and values only, with
no knowledge of the log format or of ROS messages: :mod:`.report` reads a log into these arrays
and :mod:`.report_output` prints and plots what they return. Apart so that each estimate reads,
and is tested, on arrays alone.
"""
from __future__ import annotations

import math

import numpy as np

from ..live.monitor_text import STUCK_EFFORT, dampers_off

#: An impactor's state in the report's stuck-state lanes (``impactor_state`` efforts 0, 1, -1).
LANE_FREE, LANE_STUCK, LANE_DAMPERS_OFF = 0, 1, -1

#: a rotor speed range wider than this fraction of the top speed is plotted against speed,
#: if the speed also sweeps through most of the log (see :func:`waterfall_axis`)
WATERFALL_MIN_SPAN = 0.1
#: a slice sweeps when its speed changes by more than this fraction of the top speed in it
SWEEPING_SLICE_CHANGE = 0.005
#: the waterfall is against speed when at least this fraction of the slices sweep
SWEEPING_FRACTION = 0.5
#: slices per waterfall (fewer when the record is short)
WATERFALL_SLICES = 40
BIN_S = 1.0   # impact-rate bin width (s)


def sensor_report(t_ns, a_g, origin_ns=0, speed=None):
    """Peak, RMS, spectrum and (over a speed range) waterfall of one accelerometer.

    Parameters
    ----------
    t_ns : numpy.ndarray of int, shape (n,)
        Sample stamps (ns), sorted.
    a_g : numpy.ndarray, shape (n, 3)
        Linear acceleration along x, y, z (g).
    origin_ns : int
        Time origin of the slice times (ns).
    speed : tuple of numpy.ndarray, optional
        Rotor speed stamps (ns, sorted) and speeds (rad/s); with it a waterfall (a spectrum
        per slice of time) is computed, to be read against the speed where the speed sweeps
        and against time where it is held (:func:`waterfall_axis`).

    Returns
    -------
    entry : dict
        ``samples``, ``sample_rate_hz``, ``gaps``, ``duration_s``, ``peak_g`` and ``rms_g``
        (``x``, ``y``, ``z``, ``magnitude``; g), ``spectrum`` (``method``,
        ``segment_samples``, ``resolution_hz``, ``dominant_hz`` per axis and ``total``; None
        with fewer than 16 samples) and ``waterfall`` (None, or ``slices``,
        ``segment_samples``, ``resolution_hz``, ``axis`` ('speed' or 'time'),
        ``sweeping_fraction`` and per slice ``time_s``, ``speed_rad_s``, ``speed_rpm``,
        ``dominant_hz``, ``amplitude_g``).
    arrays : dict
        Spectrum (``freq_hz``, ``psd_g2_hz`` shape (3, m)) and waterfall arrays for the plot.
    """
    n = t_ns.size
    axes = ('x', 'y', 'z')
    a_g = np.asarray(a_g, dtype=float)
    bad = ~np.isfinite(a_g)
    nonfinite = {k: int(bad[:, i].sum()) for i, k in enumerate(axes)}
    if bad.any():
        # NaN or inf samples: left out of peak and RMS (None for an axis without a finite
        # one), the magnitude over the finite components, and the spectra with each such
        # sample replaced by its axis' finite mean (no power added)
        finite_mean = [float(np.mean(a_g[~bad[:, i], i])) if (~bad[:, i]).any() else 0.0
                       for i in range(3)]
        a_g = np.where(bad, np.asarray(finite_mean)[None, :], a_g)
    mag_rows = ~bad.all(axis=1)
    mag = np.sqrt(np.sum(np.where(bad, 0.0, a_g) ** 2, axis=1))[mag_rows]

    def stat(values, ok, fn):
        return float(fn(values[ok])) if ok.any() else None

    peak = {k: stat(np.abs(a_g[:, i]), ~bad[:, i], np.max) for i, k in enumerate(axes)}
    peak['magnitude'] = float(mag.max()) if mag.size else None
    rms = {k: stat(a_g[:, i] ** 2, ~bad[:, i], lambda v: np.sqrt(np.mean(v)))
           for i, k in enumerate(axes)}
    rms['magnitude'] = float(np.sqrt(np.mean(mag ** 2))) if mag.size else None
    dt = np.diff(t_ns) * 1e-9
    step = float(np.median(dt)) if n > 1 else 0.0
    fs = 1.0 / step if step > 0 else None
    entry = {'samples': int(n), 'sample_rate_hz': fs,
             'gaps': int(np.sum(dt > 1.5 * step)) if step > 0 else 0,
             'duration_s': (int(t_ns[-1]) - int(t_ns[0])) * 1e-9, 'peak_g': peak, 'rms_g': rms,
             'nonfinite_samples': nonfinite, 'spectrum': None, 'waterfall': None}
    arrays = {}
    if fs is None or n < 16:
        return entry, arrays
    seg = _segment(n)
    freq, psd = welch(a_g, fs, seg)
    total = psd.sum(axis=0)
    dom = {k: float(freq[1 + np.argmax(psd[i, 1:])]) for i, k in enumerate(axes)}
    dom['total'] = float(freq[1 + np.argmax(total[1:])])
    entry['spectrum'] = {'method': 'welch, hann, 50% overlap', 'segment_samples': int(seg),
                         'resolution_hz': float(fs / seg), 'dominant_hz': dom}
    arrays.update(freq_hz=freq, psd_g2_hz=psd)
    if speed is not None:
        entry['waterfall'], more = _waterfall(t_ns, a_g, fs, speed, origin_ns)
        arrays.update(more)
    return entry, arrays


def nonfinite_text(entry):
    """``'non-finite samples (NaN or inf): x 10 of 2000, ...'`` of a sensor entry."""
    bad = entry['nonfinite_samples']
    return ('non-finite samples (NaN or inf): '
            + ', '.join(f"{axis} {count} of {entry['samples']}"
                        for axis, count in bad.items() if count))


def welch(x, fs, nperseg):
    """One-sided Welch PSD: periodic Hann window, 50 % overlap, mean removed per segment.

    NumPy only (SciPy's import costs seconds on the command's start-up path); the same
    estimate as ``scipy.signal.welch(x, fs, 'hann', nperseg, axis=0)``.

    Parameters
    ----------
    x : numpy.ndarray, shape (n, k)
        Evenly sampled signals in columns (any unit U).
    fs : float
        Sample rate (Hz).
    nperseg : int
        Segment length (samples), <= n.

    Returns
    -------
    freq : numpy.ndarray, shape (m,)
        Frequencies (Hz), m = nperseg // 2 + 1.
    psd : numpy.ndarray, shape (k, m)
        Power spectral density (U^2/Hz).
    """
    window = 0.5 - 0.5 * np.cos(2 * np.pi * np.arange(nperseg) / nperseg)
    starts = range(0, x.shape[0] - nperseg + 1, nperseg - nperseg // 2)
    psd = 0.0
    for start in starts:
        seg = x[start:start + nperseg]
        spec = np.fft.rfft((seg - seg.mean(axis=0)) * window[:, None], axis=0)
        psd = psd + np.abs(spec) ** 2
    psd = psd / (len(starts) * fs * np.sum(window ** 2))
    psd[1:-1 if nperseg % 2 == 0 else None] *= 2   # one-sided: fold negative frequencies
    return np.fft.rfftfreq(nperseg, 1.0 / fs), psd.T


def _segment(n):
    """Welch segment length: about a quarter of the record as a power of two, >= 256."""
    return int(min(n, max(256, 2 ** int(math.floor(math.log2(max(n / 4, 1)))))))


def waterfall_axis(start_speeds, end_speeds):
    """What a waterfall is read against: ``'speed'`` while the rotor sweeps, else ``'time'``.

    A log that holds the speed for most of its length (a run-up, then 26 s at two speeds)
    plotted against speed shrinks those stretches to thin bands and hides what happened in
    them (an unbalance step); against time every second keeps its height.

    Parameters
    ----------
    start_speeds, end_speeds : numpy.ndarray
        Rotor speed at the start and at the end of each slice (rad/s).

    Returns
    -------
    axis : str
        ``'speed'`` when the speed spans more than ``WATERFALL_MIN_SPAN`` of its top and at
        least ``SWEEPING_FRACTION`` of the slices sweep, else ``'time'``.
    fraction : float
        The fraction of slices whose speed changes by more than ``SWEEPING_SLICE_CHANGE`` of
        the top speed.
    """
    start, end = np.asarray(start_speeds, float), np.asarray(end_speeds, float)
    both = np.concatenate([start, end])
    top = float(np.max(np.abs(both))) if both.size else 0.0
    if top <= 0 or start.size == 0:
        return 'time', 0.0
    fraction = float(np.mean(np.abs(end - start) > SWEEPING_SLICE_CHANGE * top))
    span = float(both.max() - both.min())
    sweeps = span > WATERFALL_MIN_SPAN * top and fraction >= SWEEPING_FRACTION
    return ('speed' if sweeps else 'time'), fraction


def _waterfall(t_ns, a_g, fs, speed, origin_ns):
    st, w = speed
    if w.size < 1:
        return None, {}
    # up to WATERFALL_SLICES slices, but not shorter than 256 samples while 4 slices fit
    seg = max(min(256, t_ns.size // 4), t_ns.size // WATERFALL_SLICES, 16)
    n_slices = t_ns.size // seg
    if n_slices < 2:
        return None, {}
    window = np.hanning(seg)
    freq = np.fft.rfftfreq(seg, 1.0 / fs)
    rows, times, speeds, ends = [], [], [], []
    for k in range(n_slices):
        part = slice(k * seg, (k + 1) * seg)
        x = a_g[part] - a_g[part].mean(axis=0)
        spec = np.fft.rfft(x * window[:, None], axis=0)
        # single-sided amplitude (g) of a sine, Hann-corrected; axes summed in power
        rows.append(np.sqrt(np.sum(np.abs(spec) ** 2, axis=1)) * 2 / window.sum())
        ts = t_ns[part]
        times.append((float(ts.mean()) - origin_ns) * 1e-9)
        inside = np.interp(ts.astype(float), st.astype(float), w)
        speeds.append(float(np.mean(inside)))
        ends.append((float(inside[0]), float(inside[-1])))
    amp = np.array(rows)
    dom = freq[1 + np.argmax(amp[:, 1:], axis=1)]
    axis, fraction = waterfall_axis([a for a, _ in ends], [b for _, b in ends])
    entry = {'slices': n_slices, 'segment_samples': int(seg), 'resolution_hz': fs / seg,
             'axis': axis, 'sweeping_fraction': fraction,
             'time_s': times, 'speed_rad_s': speeds,
             'speed_rpm': [s * 30 / math.pi for s in speeds],
             'dominant_hz': [float(f) for f in dom],
             'amplitude_g': [float(a) for a in amp[:, 1:].max(axis=1)]}
    return entry, {'waterfall_freq_hz': freq, 'waterfall_amp_g': amp,
                   'waterfall_speed_rad_s': np.array(speeds),
                   'waterfall_time_s': np.array(times)}


def impact_rate(t_ns, impactors, origin_ns, end_ns):
    """Impacts per second in bins of ``BIN_S`` from the time origin.

    Parameters
    ----------
    t_ns : sequence of int
        Impact stamps (ns).
    impactors : sequence of str
        Impactor name of each impact (the last component of a WrenchStamped's
        ``frame_id``, or named from a batch row's impactor index).
    origin_ns, end_ns : int
        Start and end of the log's stamped time (ns); the last bin ends at ``end_ns``.

    Returns
    -------
    entry : dict
        ``count``, ``mean_rate_hz`` (count over the stamped span), ``peak_rate_hz`` (the
        largest full bin), ``bin_s``, ``bins`` (``start_s`` from the origin, ``width_s``,
        ``count``, ``rate_hz``) and ``per_impactor`` counts.
    arrays : dict
        ``start_s``, ``width_s``, ``rate_hz`` for the plot.
    """
    t = np.asarray(t_ns, dtype=np.int64)
    span = max(0, int(end_ns) - int(origin_ns)) * 1e-9
    n_bins = max(1, math.ceil(span / BIN_S))
    width = np.full(n_bins, BIN_S)
    width[-1] = span - (n_bins - 1) * BIN_S
    index = np.minimum(((t - origin_ns) * 1e-9 // BIN_S).astype(int), n_bins - 1)
    count = np.bincount(np.maximum(index, 0), minlength=n_bins)
    with np.errstate(divide='ignore', invalid='ignore'):
        rate = np.where(width > 0, count / np.where(width > 0, width, 1.0), np.nan)
    full = width >= BIN_S - 1e-12
    peak = rate[full].max() if full.any() else (np.nanmax(rate) if np.isfinite(rate).any()
                                                  else None)
    per = {}
    for name in impactors:
        per[name] = per.get(name, 0) + 1
    starts = np.arange(n_bins) * BIN_S
    entry = {'count': int(t.size), 'mean_rate_hz': t.size / span if span > 0 else None,
             'peak_rate_hz': None if peak is None else float(peak), 'bin_s': BIN_S,
             'bins': [{'start_s': float(s), 'width_s': float(w), 'count': int(c),
                       'rate_hz': float(r) if np.isfinite(r) else None}
                      for s, w, c, r in zip(starts, width, count, rate)],
             'per_impactor': dict(sorted(per.items()))}
    return entry, {'start_s': starts, 'width_s': width, 'rate_hz': rate}


def stuck_fractions(t_ns, names, efforts, end_ns):
    """Time-weighted stuck fraction of each impactor from ``JointState`` effort flags.

    Parameters
    ----------
    t_ns : list of int
        Message stamps (ns).
    names : list of list of str
        Joint names per message, ``<impactor>/<dof>``.
    efforts : list of list of float
        Effort per joint (dimensionless): 1.0 while stuck, 0.0 while free, -1.0 while the
        dampers are off.
    end_ns : int
        End of the log's stamped time (ns); the last state holds until then.

    Returns
    -------
    impactors : dict
        Per impactor: ``stuck_fraction`` (stuck time over observed time), ``stuck_s``,
        ``dampers_off_s``, ``observed_s`` (from its first state to the end) and
        ``stick_events`` (transitions into stuck, a first state that is stuck included).
    steps : dict
        Per impactor ``(t_ns, state)`` arrays for the plot, ``state`` one of
        :data:`LANE_FREE`, :data:`LANE_STUCK` and :data:`LANE_DAMPERS_OFF`.
    """
    order = sorted(range(len(t_ns)), key=lambda i: t_ns[i])
    states = {}
    for i in order:
        joints = {}
        for name, effort in zip(names[i], efforts[i]):
            joints.setdefault(name.rsplit('/', 1)[0], []).append(effort)
        for imp, values in joints.items():
            state = (LANE_DAMPERS_OFF if dampers_off(values)
                     else LANE_STUCK if max(values) >= STUCK_EFFORT else LANE_FREE)
            states.setdefault(imp, ([], []))
            states[imp][0].append(int(t_ns[i]))
            states[imp][1].append(state)
    out, steps = {}, {}
    for imp, (t, state) in sorted(states.items()):
        t = np.asarray(t, dtype=np.int64)
        state = np.asarray(state, dtype=np.int8)
        stuck = state == LANE_STUCK
        stop = max(int(end_ns), int(t[-1]))
        held = np.diff(np.append(t, stop)) * 1e-9
        observed = (stop - int(t[0])) * 1e-9
        stuck_s = float(held[stuck].sum())
        entries = int(stuck[0]) + int(np.sum(stuck[1:] & ~stuck[:-1]))
        out[imp] = {'stuck_fraction': stuck_s / observed if observed > 0 else None,
                    'stuck_s': stuck_s,
                    'dampers_off_s': float(held[state == LANE_DAMPERS_OFF].sum()),
                    'observed_s': observed, 'stick_events': entries}
        steps[imp] = (np.append(t, stop), np.append(state, state[-1]))
    return out, steps


__all__ = ['LANE_DAMPERS_OFF', 'LANE_FREE', 'LANE_STUCK', 'impact_rate', 'sensor_report',
           'stuck_fractions']
