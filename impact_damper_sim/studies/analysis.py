"""Post-processing of simulated signals: amplitudes, RMS, impact rates, stuck fractions."""
from __future__ import annotations

import numpy as np

from ..scene.units import G0  # standard gravity (m/s^2)


def refined_peak(signal):
    """Peak of ``|signal|`` refined by a parabola through the largest sample and its neighbours.

    For a smooth signal sampled ``N`` times per cycle the error of the raw sample maximum is
    ``O(1/N^2)``; the parabola makes it ``O(1/N^4)``.

    Parameters
    ----------
    signal : ndarray, shape (k,)
        Samples (any unit).

    Returns
    -------
    float
        Refined peak of ``|signal|`` (same unit).
    """
    a = np.abs(np.asarray(signal, dtype=float))
    if a.size == 0:
        return 0.0
    k = int(np.argmax(a))
    if 0 < k < a.size - 1:
        s = np.sign(signal[k]) * np.asarray(signal[k - 1:k + 2], dtype=float)
        denom = s[0] - 2 * s[1] + s[2]
        if denom < 0:
            return float(s[1] - 0.125 * (s[2] - s[0]) ** 2 / denom)
    return float(a[k])


def stuck_fraction(events, n_impactors, t_start, t_end, stuck_at_start=None):
    """Fraction of ``[t_start, t_end]`` each impactor spent stuck.

    Parameters
    ----------
    events : ndarray of EVENT_DTYPE
        Events in time order.
    n_impactors : int
        Number of impactors.
    t_start, t_end : float
        Window (s).
    stuck_at_start : array_like of bool, optional
        Stuck flags at ``t_start``.

    Returns
    -------
    ndarray, shape (n_impactors,)
        Stuck time fraction (dimensionless).
    """
    from ..integrate.events import EVENT_KINDS
    stick = EVENT_KINDS.index('stick')
    release = EVENT_KINDS.index('release')
    total = np.zeros(n_impactors)
    since = np.full(n_impactors, np.nan)
    if stuck_at_start is not None:
        since[np.asarray(stuck_at_start, dtype=bool)] = t_start
    for ev in events:
        j = int(ev['impactor'])
        if ev['kind'] == stick and np.isnan(since[j]):
            since[j] = ev['t']
        elif ev['kind'] == release and not np.isnan(since[j]):
            total[j] += max(ev['t'] - max(since[j], t_start), 0.0)
            since[j] = np.nan
    open_ = ~np.isnan(since)
    total[open_] += t_end - np.maximum(since[open_], t_start)
    span = max(t_end - t_start, 1e-300)
    return total / span


def summarize(samples, mean_acc, events, sensor_names, impactor_names, energy, *, window,
              wall_time, stuck_at_start=None):
    """Summary of a run, as plain JSON-ready data.

    Parameters
    ----------
    samples : Samples
        Sensor outputs.
    mean_acc : ndarray, shape (k, n_s)
        Mean acceleration per sample period (m/s^2), impacts included.
    events : ndarray of EVENT_DTYPE
        Events of the run.
    sensor_names : sequence of str
        Names of the sensors.
    impactor_names : sequence of str
        Names of the impactors.
    energy : EnergyLedger
        Ledger at the end (J).
    window : float
        Trailing window for the steady-state amplitude (s).
    wall_time : float
        Wall-clock time of the run (s).

    Returns
    -------
    dict
        See the README ("study simulate --json") for the schema.
    """
    from ..integrate.events import EVENT_KINDS
    t = samples.t
    duration = float(t[-1] - t[0] + (t[1] - t[0])) if t.size > 1 else 0.0
    t0 = float(t[0] - (t[1] - t[0])) if t.size > 1 else 0.0
    tail = t >= (t[-1] - window) if t.size else np.zeros(0, bool)
    sensors = {}
    for s, name in enumerate(sensor_names):
        x = samples.displacement[:, s]
        a = mean_acc[:, s]
        sensors[name] = {
            'peak_displacement_m': refined_peak(x),
            'rms_displacement_m': float(np.sqrt(np.mean(x * x))) if x.size else 0.0,
            'steady_amplitude_m': refined_peak(x[tail]),
            'peak_acceleration_m_s2': float(np.max(np.abs(a))) if a.size else 0.0,
            'rms_acceleration_m_s2': float(np.sqrt(np.mean(a * a))) if a.size else 0.0,
            'steady_peak_acceleration_m_s2': float(np.max(np.abs(a[tail]))) if a.size else 0.0,
        }
        for key in ('peak_acceleration', 'rms_acceleration', 'steady_peak_acceleration'):
            sensors[name][key + '_g'] = sensors[name][key + '_m_s2'] / G0
    impact = EVENT_KINDS.index('impact')
    fractions = stuck_fraction(events, len(impactor_names), t0, t0 + duration, stuck_at_start)
    impactors = {}
    for j, name in enumerate(impactor_names):
        mine = events[events['impactor'] == j]
        n_imp = int(np.sum(mine['kind'] == impact))
        impactors[name] = {
            'impacts': n_imp,
            'impacts_per_second': n_imp / duration if duration > 0 else 0.0,
            'stuck_fraction': float(fractions[j]),
        }
    return {
        'duration_s': duration,
        'sensors': sensors,
        'impactors': impactors,
        'energy_J': {
            'structure': float(energy.structure), 'impactors': float(energy.impactors),
            'dissipated_impacts': float(energy.impacts),
            'dissipated_sticking': float(energy.sticking),
            'dissipated_damping': float(energy.damping), 'work_forcing': float(energy.forcing),
            'work_circulatory': float(energy.circulatory), 'initial': float(energy.initial),
            'residual': float(energy.residual),
            'relative_residual': float(energy.relative_residual),
        },
        'wall_time_s': float(wall_time),
        'real_time_factor': duration / wall_time if wall_time > 0 else float('inf'),
    }

