"""How the ``monitor`` reads ``impactor_state`` and words what it sees: ROS-free.

* :func:`impactor_stuck_flags` and :func:`dampers_off` read the node's
  ``impactor_state`` efforts (1 stuck, 0 free, -1 dampers off);
* :func:`waiting_text`, :func:`impacts_text` and :func:`sensor_text` are the monitor's log
  lines, in words where a number is not known (never ``nan``); :func:`sensor_values`,
  :func:`impact_values` and :func:`value_text` are the ``/diagnostics`` values.

The statistics themselves are :class:`.monitoring.RollingVibrationStats`'s.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from .monitoring import AXES, SensorStats, VibrationReport

#: JointState effort at or above which an impactor counts as stuck (the node sends 1.0 / 0.0).
STUCK_EFFORT = 0.5
#: JointState effort below which an entry says the dampers are off (the node sends -1.0).
DAMPERS_OFF_EFFORT = -0.5
#: Node-clock seconds the monitor waits for a sensor's first sample before it warns.
FIRST_SAMPLE_GRACE_S = 5.0


def dampers_off(efforts: Sequence[float] | np.ndarray) -> bool:
    """bool: an ``impactor_state`` that says the dampers are off (every effort -1).

    Parameters
    ----------
    efforts : sequence of float
        The JointState efforts (dimensionless: 1 stuck, 0 free, -1 dampers off).
    """
    flat = np.asarray(efforts, dtype=float).reshape(-1)
    return bool(flat.size) and bool(np.all(flat <= DAMPERS_OFF_EFFORT))


def waiting_text(topic: str, waited_s: float,
                 grace_s: float = FIRST_SAMPLE_GRACE_S) -> tuple[bool, str]:
    """What the monitor says about a sensor without a valid sample yet.

    Parameters
    ----------
    topic : str
        The sensor's topic.
    waited_s : float
        Node-clock time since the monitor started watching it (s).
    grace_s : float
        Time a start-up may take before the silence is a problem (s).

    Returns
    -------
    warn : bool
        True once ``waited_s`` exceeds ``grace_s``: a WARN, not an INFO.
    text : str
        ``'waiting for the first sample on <topic>'`` within the grace period, else
        ``'no valid sample received on <topic> in <waited> s'``.
    """
    if not waited_s > grace_s:
        return False, f'waiting for the first sample on {topic}'
    return True, f'no valid sample received on {topic} in {waited_s:.3g} s'


def impacts_text(impacts_per_s: float | None, stuck_fraction: float | None,
                 stuck_impactors: int, impactors: int, off: bool = False) -> str:
    """The monitor's impacts line, in words where a number is not known.

    Parameters
    ----------
    impacts_per_s : float
        Impact rate over the window (1/s); NaN before any impact batch.
    stuck_fraction : float
        Time-weighted stuck fraction (0..1); NaN before any ``impactor_state``.
    stuck_impactors, impactors : int
        Impactors stuck in the latest state, and how many there are.
    off : bool
        The latest ``impactor_state`` says the dampers are off.

    Returns
    -------
    str
        e.g. ``'impacts: 1.2e+04 /s, stuck fraction 0.02 (1 of 12 impactors stuck now)'``,
        ``'impacts: 0 /s, dampers off: no impactor can stick'`` or
        ``'impacts: no impacts received yet, no impactor_state received yet'``; never ``nan``.
    """
    rate = ('no impacts received yet' if impacts_per_s is None or math.isnan(impacts_per_s)
            else f'{impacts_per_s:.4g} /s')
    if off:
        state = 'dampers off: no impactor can stick'
    elif stuck_fraction is None or math.isnan(stuck_fraction):
        state = 'no impactor_state received yet'
    else:
        state = (f'stuck fraction {stuck_fraction:.3g} ({stuck_impactors} of {impactors} '
                 'impactors stuck now)')
    return f'impacts: {rate}, {state}'


def impactor_stuck_flags(names: Sequence[str], efforts: Sequence[float] | np.ndarray
                         ) -> tuple[tuple[str, ...], np.ndarray]:
    """Group ``impactor_state`` JointState entries into one stuck flag per impactor.

    Parameters
    ----------
    names : sequence of str
        Joint names, ``<impactor>/<dof>`` (a name without ``/`` is its own impactor).
    efforts : sequence of float
        Stuck flags (1.0 stuck, 0.0 free; dimensionless), one per name.

    Returns
    -------
    impactors : tuple of str
        Impactor names in order of first appearance.
    stuck : ndarray of bool, shape (len(impactors),)
        True if any entry of the impactor has ``effort >= STUCK_EFFORT``.

    Raises
    ------
    ValueError
        If the lengths differ or an effort is not finite.
    """
    flat = np.asarray(efforts, dtype=float).reshape(-1)
    if flat.size != len(names):
        raise ValueError(f'{len(names)} names but {flat.size} efforts')
    if not np.all(np.isfinite(flat)):
        raise ValueError('non-finite effort')
    flags: dict[str, bool] = {}
    for name, effort in zip(names, flat):
        impactor = name.rsplit('/', 1)[0] if '/' in name else name
        flags[impactor] = flags.get(impactor, False) or bool(effort >= STUCK_EFFORT)
    return tuple(flags), np.array(list(flags.values()), dtype=bool)


def sensor_text(topic: str, stats: SensorStats) -> str:
    """The monitor's line for one accelerometer with samples in its window.

    Parameters
    ----------
    topic : str
        The sensor's topic.
    stats : SensorStats
        Its statistics (g, Hz, samples/s).

    Returns
    -------
    str
        e.g. ``'accel/s1: rms 0.81 g (x 0.0013, y 0.62, z 0.52), peak 3.1 g, dominant 382
        Hz (resolution 0.5 Hz), 2000 samples/s'``.
    """
    x, y, z = stats.rms_g_axes
    return (f'{topic}: rms {stats.rms_g:.4g} g (x {x:.3g}, y {y:.3g}, z {z:.3g}), '
            f'peak {stats.peak_g:.4g} g, dominant {stats.dominant_hz:.5g} Hz '
            f'(resolution {stats.resolution_hz:.3g} Hz), {stats.samples_per_s:.5g} samples/s')


def value_text(value: float | None) -> str:
    """A diagnostic value as text: an int as it is, else 6 significant digits, ``nan`` for
    unknown (``diagnostic_msgs/KeyValue`` values are strings)."""
    if isinstance(value, int):
        return str(value)
    return 'nan' if value is None or math.isnan(value) else f'{value:.6g}'


def sensor_values(stats: SensorStats, lag: float, age: float, window: float,
                  t: float) -> list[tuple[str, float]]:
    """The ``/diagnostics`` values of one accelerometer, in their order.

    Parameters
    ----------
    stats : SensorStats
        Its statistics (g, Hz, samples/s).
    lag : float
        Newest stamp on any topic minus the sensor's newest (sim s); NaN before a sample.
    age : float
        Node-clock time since a valid sample last arrived (s); NaN before one.
    window, t : float
        The report's window length and end (sim s).

    Returns
    -------
    list of (str, number)
        Key (unit in the name) and value.
    """
    values: list[tuple[str, float]] = [('rms_g', stats.rms_g), ('peak_g', stats.peak_g)]
    values += [(f'rms_g_{axis}', v) for axis, v in zip(AXES, stats.rms_g_axes)]
    values += [(f'peak_g_{axis}', v) for axis, v in zip(AXES, stats.peak_g_axes)]
    values.append(('dominant_hz', stats.dominant_hz))
    values += [(f'dominant_hz_{axis}', v) for axis, v in zip(AXES, stats.dominant_hz_axes)]
    return values + [('resolution_hz', stats.resolution_hz),
                     ('samples_per_s', stats.samples_per_s),
                     ('samples_in_window', stats.samples),
                     ('rejected_samples', stats.rejected_samples),
                     ('stamp_lag_s', lag), ('last_sample_age_s', age),
                     ('window_s', window), ('window_end_s', t)]


def impact_values(report: VibrationReport) -> list[tuple[str, float]]:

    """The ``/diagnostics`` values of the impacts status (a :class:`VibrationReport`), in
    their order: list of (key with its unit, value)."""
    return [('impacts_per_s', report.impacts_per_s), ('impacts_in_window', report.impacts),
            ('stuck_fraction', report.stuck_fraction), ('impactors', report.impactors),
            ('stuck_impactors', report.stuck_impactors),
            ('rejected_impacts', report.rejected_impacts),
            ('rejected_states', report.rejected_states), ('time_resets', report.time_resets),
            ('span_s', report.span), ('window_s', report.window), ('window_end_s', report.t)]


__all__ = ['DAMPERS_OFF_EFFORT', 'FIRST_SAMPLE_GRACE_S', 'STUCK_EFFORT', 'dampers_off',
           'impact_values', 'impactor_stuck_flags', 'impacts_text', 'sensor_text', 'sensor_values',
           'value_text', 'waiting_text']
