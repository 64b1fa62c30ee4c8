"""Frequency response by transient runs to a steady amplitude (paper Figs. 4.1.2, 4.1.3).

For each forcing frequency the scene is run from rest, with its impactors and without them
(``impactors=[]``, the linear path), and the steady amplitude of each sensor is the refined
peak ``|x|`` over the trailing ``simulation.window``. A run is *settled* when that peak and
the one of the window before differ by at most ``tol`` (relative); an unsettled run can be
continued window by window up to ``max_duration``. Near the centre frequency the impact
damper's response beats (paper section 4.1): the trailing peak is then the beat maximum when
the window is longer than the beat period, and the run may never settle.
"""
from __future__ import annotations

import time

from .runner import Point, point_seed, run_points

UNITS = ('ratio', 'hz')
_COLUMN = {'ratio': 'frequency_ratio', 'hz': 'frequency_hz'}


def frequency_overrides(n_forcing, value, unit):
    """Overrides that set every forcing entry's frequency.

    Parameters
    ----------
    n_forcing : int
        Number of ``forcing`` entries of the scene.
    value : float
        Frequency ratio (dimensionless, to the first retained mode) or frequency (Hz).
    unit : {'ratio', 'hz'}
        Meaning of ``value``.

    Returns
    -------
    list of str
        ``key=value`` overrides (the other frequency key is cleared: a forcing entry takes
        exactly one).
    """
    out = []
    for k in range(n_forcing):
        if unit == 'ratio':
            out += [f'forcing.{k}.frequency=', f'forcing.{k}.frequency_ratio={value!r}']
        else:
            out += [f'forcing.{k}.frequency_ratio=', f'forcing.{k}.frequency={value!r} Hz']
    return out


def steady_amplitude(point):
    """Task: run a point to a steady amplitude.

    Parameters
    ----------
    point : Point
        ``params``: ``tol`` (relative settling tolerance, dimensionless) and
        ``max_duration`` (s, None = the scene's ``simulation.duration``).

    Returns
    -------
    dict
        ``amplitude_m`` and ``previous_amplitude_m`` (per sensor, m: refined peak over the
        last and the previous window), ``change`` (largest relative difference), ``settled``,
        ``t_end_s``, ``forcing_hz`` (distinct forcing frequencies, Hz) and
        ``impacts_per_second`` (per impactor, over the last window, 1/s).
    """
    import numpy as np

    from .analysis import refined_peak
    from .measure import load_point, start, window_impact_rates
    scene = load_point(point)
    cfg = scene.scene['simulation']
    window, dt = cfg['window'], cfg['dt']
    t_max = max(cfg['duration'], point.params.get('max_duration') or 0.0)
    tol = point.params.get('tol', 0.005)
    sim = start(scene)
    first = sim.advance_to(cfg['duration'])
    t, x = first.t, first.displacement
    names = sim.sensor_names
    while True:
        last = t > t[-1] - window
        prev = (t > t[-1] - 2 * window) & ~last
        amp = np.array([refined_peak(x[last, s]) for s in range(len(names))])
        before = np.array([refined_peak(x[prev, s]) for s in range(len(names))])
        scale = np.maximum(amp, 1e-300)
        change = float(np.max(np.abs(amp - before) / scale)) if amp.size else 0.0
        settled = change <= tol
        if settled or sim.t + window > t_max + 0.5 * dt:
            break
        more = sim.advance(int(round(window / dt)))
        keep = t > t[-1] - 2 * window   # only the last two windows are ever needed
        t = np.concatenate([t[keep], more.t])
        x = np.vstack([x[keep], more.displacement])
    events = sim.take_events()
    omegas, _ = scene.forcing.harmonic_table()
    return {'amplitude_m': dict(zip(names, map(float, amp))),
            'previous_amplitude_m': dict(zip(names, map(float, before))),
            'change': change, 'settled': bool(settled), 't_end_s': float(sim.t),
            'forcing_hz': [float(w / (2 * np.pi)) for w in omegas],
            'impacts_per_second': window_impact_rates(events, sim.impactor_names,
                                                      sim.t - window, sim.t)}


def make_points(scene, values, unit='ratio', overrides=(), *, n_forcing, has_impactors=True,
                tol=0.005, max_duration=None, seed=0):
    """Points of a frequency response: each value with and without impactors.

    Parameters
    ----------
    scene : str
        Scene name or path.
    values : sequence of float
        Frequency ratios or frequencies (Hz), see ``unit``.
    unit : {'ratio', 'hz'}
        Meaning of ``values``.
    overrides : sequence of str
        Base overrides (applied first).
    n_forcing : int
        Number of forcing entries (all are set to each frequency).
    has_impactors : bool
        False skips the runs with impactors (the scene has none).
    tol : float
        Relative settling tolerance (dimensionless).
    max_duration : float, optional
        Longest run (s) when continuing unsettled runs.
    seed : int
        Study seed.

    Returns
    -------
    list of Point
    """
    if unit not in UNITS:
        raise ValueError(f"unit must be one of {', '.join(UNITS)}, got {unit!r}")
    points = []
    for v in values:
        for with_imp in ((True, False) if has_impactors else (False,)):
            ov = list(overrides) + frequency_overrides(n_forcing, float(v), unit)
            if not with_imp:
                ov.append('impactors=[]')
            points.append(Point(steady_amplitude, scene, tuple(ov),
                                point_seed(seed, '\n'.join([scene] + ov)),
                                {'tol': tol, 'max_duration': max_duration},
                                {'value': float(v), 'impactors': with_imp}))
    return points


def frf(scene, values, unit='ratio', overrides=(), *, tol=0.005, max_duration=None, seed=0,
        executor='process', workers=None, dask_address=None, progress=None):
    """Frequency response with and without impactors.

    Parameters
    ----------
    scene : str
        Scene name or path.
    values : sequence of float
        Frequency ratios (dimensionless) or frequencies (Hz).
    unit : {'ratio', 'hz'}
        Meaning of ``values``.
    overrides : sequence of str
        Base ``key=value`` overrides.
    tol, max_duration, seed
        See :func:`make_points`.
    executor, workers, dask_address, progress
        See :func:`.runner.run_points`.

    Returns
    -------
    dict
        ``study``, ``scene``, ``overrides``, ``unit``, ``sensors``, ``rows`` (one flat dict
        per frequency: the frequency, then per sensor ``<sensor>_with_m``,
        ``<sensor>_without_m`` and ``<sensor>_reduction`` = without/with, and whether both
        runs settled), ``peaks`` (per sensor and case: largest amplitude (m) and where),
        ``points`` (every point's full result), ``failures`` and ``wall_time_s``.

    Raises
    ------
    SceneError
        If the scene or the base overrides are invalid, or the scene has no forcing.
    """
    from ..scene.build import load
    from ..scene.schema import SceneError
    base = load(scene, list(overrides))
    from .measure import check_memory
    check_memory(base, max(base.scene['simulation']['duration'], max_duration or 0.0))
    if not base.scene['forcing']:
        raise SceneError("scene key 'forcing': the scene has no forcing to sweep", base.source)
    points = make_points(scene, values, unit, overrides, n_forcing=len(base.scene['forcing']),
                         has_impactors=bool(base.scene['impactors']), tol=tol,
                         max_duration=max_duration, seed=seed)
    start = time.perf_counter()
    results = run_points(points, executor, workers=workers, dask_address=dask_address,
                         progress=progress)
    wall = time.perf_counter() - start
    return assemble(base, list(overrides), unit, values, results, wall)


def assemble(base, overrides, unit, values, results, wall):
    """Tabulate point results (see :func:`frf`)."""
    sensors = [s['name'] for s in base.scene['sensors']]
    col = _COLUMN[unit]
    by = {(r.point.labels['value'], r.point.labels['impactors']): r for r in results}
    rows = []
    for v in values:
        row = {col: float(v)}
        w, wo = by.get((float(v), True)), by.get((float(v), False))
        ok = [r for r in (w, wo) if r is not None and r.ok]
        if unit == 'ratio':
            row['frequency_hz'] = ok[0].value['forcing_hz'][0] if ok else None
        for s in sensors:
            a_w = w.value['amplitude_m'][s] if w is not None and w.ok else None
            a_wo = wo.value['amplitude_m'][s] if wo is not None and wo.ok else None
            row[f'{s}_with_m'] = a_w
            row[f'{s}_without_m'] = a_wo
            row[f'{s}_reduction'] = a_wo / a_w if a_w and a_wo is not None else None
        row['settled'] = all(r.value['settled'] for r in ok) and len(ok) == len(
            [r for r in (w, wo) if r is not None])
        rows.append(row)
    peaks = {}
    for s in sensors:
        peaks[s] = {}
        for case in ('with', 'without'):
            vals = [(r[f'{s}_{case}_m'], r[col]) for r in rows if r[f'{s}_{case}_m'] is not None]
            if vals:
                amp, at = max(vals)
                peaks[s][case] = {'amplitude_m': amp, col: at}
    return {'study': 'frf', 'scene': base.name, 'source': base.source, 'overrides': overrides,
            'unit': unit, 'sensors': sensors, 'rows': rows, 'peaks': peaks,
            'points': [point_record(r) for r in results],
            'failures': [failure(r) for r in results if not r.ok], 'wall_time_s': wall}


def point_record(r):
    """JSON-ready record of one point result."""
    return {'labels': r.point.labels, 'overrides': list(r.point.overrides),
            'seed': r.point.seed, 'ok': r.ok, 'error': r.error, 'result': r.value,
            'wall_time_s': r.wall_time}


def failure(r):
    """JSON-ready record of a failed point."""
    return {'labels': r.point.labels, 'overrides': list(r.point.overrides), 'error': r.error,
            'diverged': r.diverged}


def plot(result, path):
    """Plot amplitude versus frequency with and without impactors (PNG via Agg).

    Parameters
    ----------
    result : dict
        Output of :func:`frf`.
    path : str or os.PathLike
        Image file.
    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    col = _COLUMN[result['unit']]
    fig, ax = plt.subplots(figsize=(7, 4.5))
    xs = [r[col] for r in result['rows']]
    unsettled = False
    for s in result['sensors']:
        for case, style in (('without', '--'), ('with', '-o')):
            ys = [r[f'{s}_{case}_m'] for r in result['rows']]
            if any(y is not None for y in ys):
                ax.plot(xs, [float('nan') if y is None else y for y in ys], style, ms=3,
                        label=f'{s}, {case} impactors')
        # points whose amplitude had not settled: the value is the last window's peak
        bad = [(x, r[f'{s}_with_m']) for x, r in zip(xs, result['rows'])
               if not r['settled'] and r[f'{s}_with_m'] is not None]
        if bad:
            ax.plot(*zip(*bad), 'o', ms=9, mfc='none', mec='r', mew=1.2,
                    label=None if unsettled else 'not settled (last window peak)')
            unsettled = True
    ax.set_xlabel('frequency ratio r' if result['unit'] == 'ratio' else 'frequency (Hz)')
    ax.set_ylabel('steady amplitude (m)')
    ax.set_title(f"frequency response: {result['scene']}")
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
