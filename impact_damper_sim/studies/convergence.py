"""Speed/accuracy trade: method x time step x retained modes against a tight reference.

Every combination of a method (``exact``, ``newmark``, ``newmark_step_end``, ``direct``), a
time step ``dt`` and a number of retained modes runs the scene from rest over
``simulation.duration``. The reference is the exact propagator with the most modes of the
study at a step ``ref_dt`` (default: the smallest ``dt`` / 2; its error does not depend on the
step except through the first-order hold of sampled forcing). ``direct`` integrates the full
physical model, so it runs once per ``dt`` (its modes column is ``all``).

Errors against the reference (dimensionless unless stated):

* ``amplitude_error``: the steady amplitude (peak ``|x|`` over the trailing
  ``simulation.window`` of the run's own samples), relative, worst sensor;
* ``rms_acceleration_error``: the RMS over the trailing window of the mean acceleration per
  period of the *coarsest* step of the study (``(v(t_k) - v(t_{k-1}))/dt_c``, through the
  sensor's low-pass if it has one), relative, worst sensor. A common period makes runs with
  different steps comparable: the mean acceleration per sample period depends on the period;
* ``impact_time_error_s`` (s): the median timing error of the first ``n_impacts`` isolated
  reference impacts (no other event of the same impactor within ``isolation`` s), each
  matched to the run's nearest impact of the same impactor (``impact_time_error_max_s`` the
  largest); ``impacts_matched`` counts those found within ``isolation``. Isolated impacts are
  well defined; counts in chatter are not. In a chaotic response (rattling limit cycles)
  trajectories that differ by round-off part after a while, and then every error below
  measures that parting, not the method;
* ``energy_residual``: the run's own ledger residual relative to its largest entry.

Cost: ``cpu_per_simulated_s`` is the CPU time of the run (one process, after a warm-up that
compiles the kernels) over the simulated time. A combination the integrator refuses (for
example a Newmark step above a tenth of the highest retained mode's period) is reported with
its error message and no numbers.
"""
from __future__ import annotations

import time

import numpy as np

from ..integrate.simulation import METHODS
from .frf import failure, point_record
from .runner import Point, point_seed, run_points


def run_case(point):
    """Task: run one combination and return what the comparison needs.

    Parameters
    ----------
    point : Point
        ``params``: ``method``, ``dt`` (s), ``coarse_dt`` (s, the common grid), ``window``
        (s) and ``duration`` (s).

    Returns
    -------
    dict
        ``cpu_s`` (s), ``peak_m`` (per sensor, m), ``velocity_coarse`` (m/s on the common
        grid, list of rows), ``impacts`` (``[t, impactor]`` pairs), ``events`` (``[t,
        impactor]`` of every event), ``energy_residual``, ``n_modes``,
        ``max_impacts_per_step``.
    """
    from .measure import load_point
    p = point.params
    scene = load_point(point)
    method, dt = p['method'], p['dt']
    duration, window, coarse = p['duration'], p['window'], p['coarse_dt']
    stride = int(round(coarse / dt))
    if abs(stride * dt - coarse) > 1e-9 * coarse:
        raise ValueError(f'dt = {dt:g} s does not divide the coarsest step {coarse:g} s')
    scene.make_simulation(method, dt).advance(1)       # compile or load the kernels
    sim = scene.make_simulation(method, dt)
    n = int(round(duration / dt))
    start = time.process_time()
    samples = sim.advance(n)
    cpu = time.process_time() - start
    ev = sim.take_events()
    last = samples.t > samples.t[-1] - window
    peak = np.abs(samples.displacement[last]).max(axis=0)
    v = samples.velocity[stride - 1::stride]
    return {'cpu_s': cpu, 'peak_m': peak.tolist(), 'velocity_coarse': v.tolist(),
            'impacts': [[float(t), int(j)] for t, j in zip(ev['t'][ev['kind'] == 0],
                                                            ev['impactor'][ev['kind'] == 0])],
            'events': [[float(t), int(j)] for t, j in zip(ev['t'], ev['impactor'])],
            'energy_residual': float(sim.energy().relative_residual),
            'n_modes': int(scene.basis.n_modes),
            'max_impacts_per_step': int(sim.integrator.max_impacts_per_step)}


def _rms_acceleration(value, scene, coarse, window, duration):
    """RMS over the trailing window of the mean acceleration per coarse period (m/s^2)."""
    from ..live.filters import scene_lowpass
    v = np.asarray(value['velocity_coarse'], dtype=float)
    v = np.vstack([np.zeros((1, v.shape[1])), v])       # from rest
    acc = scene_lowpass(scene, coarse).apply(np.diff(v, axis=0) / coarse)
    t = coarse * np.arange(1, acc.shape[0] + 1)
    tail = t > duration - window
    return np.sqrt(np.mean(acc[tail] ** 2, axis=0))


def _isolated(events, impacts, isolation, n_max):
    """The first ``n_max`` impacts with no other event of their impactor within ``isolation``."""
    ev = np.asarray(events, dtype=float).reshape(-1, 2)
    out = []
    for t, j in impacts:
        mine = ev[ev[:, 1] == j, 0]
        if np.count_nonzero(np.abs(mine - t) < isolation) == 1:
            out.append((t, int(j)))
            if len(out) == n_max:
                break
    return out


def _impact_errors(ref_isolated, impacts, isolation):
    """Median and largest timing error (s) of the matched isolated impacts, and how many
    matched."""
    imp = np.asarray(impacts, dtype=float).reshape(-1, 2)
    errs = []
    for t, j in ref_isolated:
        mine = imp[imp[:, 1] == j, 0]
        if mine.size:
            d = float(np.min(np.abs(mine - t)))
            if d < isolation:
                errs.append(d)
    if not errs:
        return None, None, 0
    return float(np.median(errs)), max(errs), len(errs)


def make_points(scene, methods, dts, modes, overrides, params, ref_dt, ref_modes, seed=0):
    """The study's points: the reference first, then every valid combination.

    Returns
    -------
    list of Point
        ``labels``: ``method``, ``dt`` (s), ``modes`` (int or ``'all'``), ``reference``.
    """
    points = []

    def add(method, dt, n_modes, reference=False):
        ov = list(overrides) + ([f'modal.n_modes={n_modes}'] if n_modes != 'all' else [])
        key = '\n'.join([scene, method, repr(dt), str(n_modes)] + ov)
        points.append(Point(run_case, scene, tuple(ov), point_seed(seed, key),
                            dict(params, method=method, dt=dt),
                            {'method': method, 'dt': dt, 'modes': n_modes,
                             'reference': reference}))

    add('exact', ref_dt, ref_modes, True)
    for method in methods:
        for dt in dts:
            # direct integrates every DOF: the retained modes only set its sticking time
            for n_modes in (['all'] if method == 'direct' else modes):
                add(method, dt, n_modes)
    return points


def _available_modes(scene):
    """Modes of the condensed system of a built scene (the most a basis can retain)."""
    condensation = getattr(scene.basis, 'condensation', None)
    master = getattr(condensation, 'master', None)
    return int(master.size) if master is not None else int(scene.basis.n_modes)


def convergence(scene, methods=METHODS, dts=None, modes=None, overrides=(), *, ref_dt=None,
                ref_modes=None, n_impacts=20, isolation=2e-3, seed=0, executor='process',
                workers=None, dask_address=None, progress=None):
    """Run the speed/accuracy study of a scene.

    Parameters
    ----------
    scene : str
        Scene name or path.
    methods : sequence of str
        Methods to cross (see :data:`METHODS`).
    dts : sequence of float, optional
        Time steps (s); each must divide the largest. Default: the scene's ``simulation.dt``
        times 2, 1, 1/2 and 1/4 (1, 1/2, 1/4, 1/8 when twice the step would put Nyquist at
        or below a sensor's low-pass).
    modes : sequence of int, optional
        Retained mode counts (dimensionless); default the scene's count and twice it (at
        most the condensed system's mode count: the SDOF has one).
    overrides : sequence of str
        Scene overrides (``simulation.duration``, ``simulation.window``, ...).
    ref_dt : float, optional
        Step of the reference (s); default the smallest ``dt`` / 2.
    ref_modes : int, optional
        Modes of the reference; default the largest of ``modes``.
    n_impacts : int
        Isolated reference impacts whose times are compared (dimensionless).
    isolation : float
        An impact is isolated without another event of its impactor within this time (s);
        also the largest timing error that still counts as a match.
    seed, executor, workers, dask_address, progress
        See :func:`.runner.run_points`.

    Returns
    -------
    dict
        ``study``, ``scene``, ``reference`` (its settings, CPU and energy residual),
        ``rows`` (one per combination: ``method``, ``dt_s``, ``modes``, ``status``,
        ``cpu_per_simulated_s``, ``real_time_factor``, ``amplitude_error``,
        ``rms_acceleration_error``, ``impact_time_error_s``, ``impact_time_error_max_s``,
        ``impacts_matched``,
        ``energy_residual``, ``max_impacts_per_step``, ``error``), ``points``,
        ``failures``, ``wall_time_s``.
    """
    from ..scene.build import load
    base = load(scene, list(overrides))
    cfg = base.scene['simulation']
    unknown = [m for m in methods if m not in METHODS]
    if unknown:
        raise ValueError(f"unknown method(s) {', '.join(unknown)}; expected {METHODS}")
    cutoffs = [s['lowpass'] for s in base.scene['sensors'] if s.get('lowpass')]
    if not dts:
        # the scene dt x 2, 1, 1/2, 1/4; x 2 only where the sensors' low-pass stays below
        # Nyquist (the RMS acceleration is filtered at the coarsest step)
        factors = [2, 1, 0.5, 0.25]
        if cutoffs and max(cutoffs) >= 0.5 / (2 * cfg['dt']):
            factors = [1, 0.5, 0.25, 0.125]
        dts = [cfg['dt'] * f for f in factors]
    dts = sorted({float(d) for d in dts}, reverse=True)
    if any(not d > 0 for d in dts):
        raise ValueError('time steps must be > 0 s')
    if cutoffs and max(cutoffs) >= 0.5 / dts[0]:
        raise ValueError(f'the largest step {dts[0]:g} s puts Nyquist ({0.5 / dts[0]:g} Hz) at '
                         f'or below the sensor low-pass {max(cutoffs):g} Hz; use smaller '
                         '--dts')
    coarse = dts[0]
    for d in dts:
        if abs(coarse / d - round(coarse / d)) > 1e-9 * coarse / d:
            raise ValueError(f'dt = {d:g} s does not divide the largest step {coarse:g} s')
    n0 = int(base.basis.n_modes)
    n_max = _available_modes(base)
    # default: the scene's count and twice it, as far as the condensed system has modes
    modes = sorted({int(m) for m in (modes or [n0, min(2 * n0, n_max)])})
    if any(m < 1 for m in modes):
        raise ValueError('mode counts must be >= 1')
    ref_modes = int(ref_modes or modes[-1])
    ref_dt = float(ref_dt or dts[-1] / 2)
    if abs(coarse / ref_dt - round(coarse / ref_dt)) > 1e-9 * coarse / ref_dt:
        raise ValueError(f'ref_dt = {ref_dt:g} s does not divide the largest step {coarse:g} s')
    duration = round(cfg['duration'] / coarse) * coarse
    from .measure import check_memory
    check_memory(base, duration, min(ref_dt, dts[-1]))
    params = {'coarse_dt': coarse, 'window': cfg['window'], 'duration': duration}
    start = time.perf_counter()
    points = make_points(scene, list(methods), dts, modes, overrides, params, ref_dt, ref_modes,
                         seed)
    results = run_points(points, executor, workers=workers, dask_address=dask_address,
                         progress=progress)
    wall = time.perf_counter() - start
    ref = results[0]
    if ref.diverged:
        from ..integrate.divergence import StudyDiverged
        raise StudyDiverged(f'the reference run diverged: {ref.error}')
    if not ref.ok:
        raise ValueError(f'the reference run failed: {ref.error}')
    rv = ref.value
    rms_ref = _rms_acceleration(rv, base, coarse, cfg['window'], duration)
    peak_ref = np.asarray(rv['peak_m'])
    iso = _isolated(rv['events'], rv['impacts'], isolation, n_impacts)
    rows = []
    for r in results[1:]:
        lab = r.point.labels
        row = {'method': lab['method'], 'dt_s': lab['dt'], 'modes': lab['modes']}
        if not r.ok:
            row.update(status='refused' if r.error.startswith('ValueError') else 'failed',
                       error=r.error)
            rows.append(row)
            continue
        v = r.value
        with np.errstate(divide='ignore', invalid='ignore'):
            amp = np.abs(np.asarray(v['peak_m']) - peak_ref) / peak_ref
            rms = np.abs(_rms_acceleration(v, base, coarse, cfg['window'], duration)
                         - rms_ref) / rms_ref
        t_err, t_max, matched = _impact_errors(iso, v['impacts'], isolation)
        row.update(status='ok', modes=v['n_modes'] if lab['modes'] != 'all' else 'all',
                   cpu_per_simulated_s=v['cpu_s'] / duration,
                   real_time_factor=duration / v['cpu_s'] if v['cpu_s'] > 0 else None,
                   amplitude_error=_finite(np.max(amp)),
                   rms_acceleration_error=_finite(np.max(rms)),
                   impact_time_error_s=t_err, impact_time_error_max_s=t_max,
                   impacts_matched=matched,
                   energy_residual=v['energy_residual'],
                   max_impacts_per_step=v['max_impacts_per_step'], error=None)
        rows.append(row)
    return {'study': 'convergence', 'scene': base.name, 'source': base.source,
            'overrides': list(overrides), 'duration_s': duration, 'window_s': cfg['window'],
            'coarse_dt_s': coarse,
            'reference': {'method': 'exact', 'dt_s': ref_dt, 'modes': rv['n_modes'],
                          'cpu_per_simulated_s': rv['cpu_s'] / duration,
                          'energy_residual': rv['energy_residual'],
                          'isolated_impacts': len(iso), 'peak_m': rv['peak_m'],
                          'rms_acceleration_m_s2': rms_ref.tolist()},
            'rows': rows, 'points': [_light(point_record(r)) for r in results],
            'failures': [failure(r) for r in results if not r.ok], 'wall_time_s': wall}


def _finite(x):
    x = float(x)
    return x if np.isfinite(x) else None


def _light(record):
    """A point record without the bulky time series."""
    value = record.get('result')
    if value:
        record = dict(record, result={k: v for k, v in value.items()
                                      if k not in ('velocity_coarse', 'impacts', 'events')})
    return record


def pareto(rows, key):
    """Rows on the Pareto front of ``key`` error against CPU time (both minimized).

    Parameters
    ----------
    rows : list of dict
        Study rows.
    key : str
        Error column, e.g. ``'amplitude_error'``.

    Returns
    -------
    list of dict
        Rows no other row beats in both cost and error, by increasing cost.
    """
    ok = sorted((r for r in rows if r.get('status') == 'ok' and r.get(key) is not None),
                key=lambda r: (r['cpu_per_simulated_s'], r[key]))
    front, best = [], np.inf
    for r in ok:
        if r[key] < best:
            front.append(r)
            best = r[key]
    return front


def plot(result, path):
    """Pareto plot: each error against CPU time per simulated second (PNG, Agg).

    Parameters
    ----------
    result : dict
        Output of :func:`convergence`.
    path : str or os.PathLike
        Image file.
    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    keys = (('amplitude_error', 'steady amplitude error (relative)'),
            ('rms_acceleration_error', 'RMS acceleration error (relative)'),
            ('impact_time_error_s', 'isolated impact-time error (s)'))
    from .plot_style import log_ticks, place_labels
    markers = {'exact': 'o', 'newmark': 's', 'newmark_step_end': '^', 'direct': 'D'}
    # one panel per error, stacked: 990 px wide at 110 dpi, shown at its size on a docs page
    fig, axes = plt.subplots(3, 1, figsize=(9, 12.5), dpi=110)
    ok = [r for r in result['rows'] if r.get('status') == 'ok']
    costs = [r['cpu_per_simulated_s'] for r in ok if r.get('cpu_per_simulated_s')]
    labels = {}
    for ax, (key, label) in zip(axes, keys):
        labels[key] = []
        for method, marker in markers.items():
            rows = [r for r in ok if r['method'] == method and r.get(key) is not None]
            if not rows:
                continue
            ax.scatter([r['cpu_per_simulated_s'] for r in rows],
                       [max(r[key], 1e-16) for r in rows], marker=marker, label=method)
            labels[key] += [(r['cpu_per_simulated_s'], max(r[key], 1e-16),
                             f"{r['dt_s'] * 1e6:g}us/{r['modes']}",
                             f'C{list(markers).index(method)}') for r in rows]
        front = pareto(result['rows'], key)
        if front:
            ax.step([r['cpu_per_simulated_s'] for r in front], [max(r[key], 1e-16)
                                                                  for r in front],
                    'k:', where='post', lw=1, label='Pareto front')
            # the front's points are labelled first: they are the ones to read
            on_front = {(r['cpu_per_simulated_s'], max(r[key], 1e-16)) for r in front}
            labels[key].sort(key=lambda item: (item[0], item[1]) not in on_front)
        ax.set_xscale('log')
        ax.set_yscale('log')
        if costs:
            log_ticks(ax.xaxis, min(costs) / 1.1, max(costs) * 1.1)
        ax.set_xlabel('CPU s per simulated s')
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=8)
    modes = result['reference']['modes']
    fig.suptitle(f"speed/accuracy: {result['scene']} (labels: dt/modes where they fit; "
                 f"reference exact {result['reference']['dt_s'] * 1e6:g} us, {modes} "
                 f"mode{'' if modes == 1 else 's'})")
    fig.tight_layout()
    # labels last, in pixels of the final layout: none on another, a marker or the legend
    fig.canvas.draw()
    legend = axes[0].get_legend()
    for ax, (key, _) in zip(axes, keys):
        place_labels(ax, labels[key], avoid=[legend.get_window_extent()] if ax is axes[0]
                     else [])
    fig.savefig(path, dpi=110)
    plt.close(fig)


#: The studies of ``docs/convergence.md`` (``make convergence``): scene, overrides, dts (s),
#: modes. Spans are short where direct and Newmark runs are slow; rbs_kcc and hpotp are cut
#: to where their impactors rattle (the HPOTP ramp reaches them at about 0.86 s).
DOC_STUDIES = (
    ('sdof', ['simulation.duration=5 s'], [1e-3, 5e-4, 2.5e-4, 1e-4, 5e-5], [1]),
    ('cantilever', ['simulation.duration=5 s'], [1e-3, 5e-4, 2.5e-4, 1e-4], [1, 2, 4]),
    ('rbs_kcc', ['simulation.duration=0.2 s', 'simulation.window=0.05 s',
                 'simulation.law=effective_mass'], [5e-5, 2.5e-5, 1.25e-5], [6, 10, 20]),
    ('hpotp', ['simulation.duration=1.2 s', 'simulation.window=0.3 s'], [1e-4, 5e-5, 2.5e-5],
     [6, 10, 16]),
)


def _cell(x, digits=2):
    return '-' if x is None else f'{x:.{digits}g}'


def document(md_path='docs/convergence.md', workers=1, scenes=None, progress=None):
    """Run :data:`DOC_STUDIES` and write the markdown, CSV, JSON and Pareto plots.

    Parameters
    ----------
    md_path : str
        Markdown file; tables and plots go to the directory of the same name without ``.md``.
    workers : int
        Worker processes (dimensionless); 1 runs serially in this process.
    scenes : sequence of str, optional
        Only these scenes of :data:`DOC_STUDIES`.
    progress : bool, optional
        Progress bars on stderr.

    Returns
    -------
    dict of str to dict
        The study result of each scene (read back from its JSON file for scenes not run).
    """
    import csv
    import json
    import os
    md_path = str(md_path)
    out_dir = md_path[:-3] if md_path.endswith('.md') else md_path + '_files'
    os.makedirs(out_dir, exist_ok=True)
    rel = os.path.basename(out_dir)
    executor = 'serial' if workers == 1 else 'process'
    lines = ['# Speed/accuracy trade', '',
             'Generated by `make convergence` (`python -m impact_damper_sim.studies.convergence`'
             ' docs/convergence.md); do not edit by hand. Each scene runs from rest with every '
             'combination of method, time step and retained modes; errors are against the '
             'exact propagator at the smallest step / 2 with the most modes (see '
             '`impact_damper_sim/studies/convergence.py` for the definitions). CPU time is '
             'one process on this shared 2-core machine: compare within a table, not across '
             'runs on different days. The rattling limit cycles of `rbs_kcc` and of `hpotp` '
             'are chaotic: runs that differ by round-off part after a while, and their errors '
             'then measure that parting as much as the method (compare the spread of one '
             'method over the steps).', '']
    results = {}
    for scene, overrides, dts, modes in DOC_STUDIES:
        json_path = os.path.join(out_dir, f'{scene}.json')
        if scenes and scene not in scenes:
            if os.path.exists(json_path):     # not re-run: keep the committed result
                with open(json_path) as fh:
                    results[scene] = (json.load(fh), overrides)
            continue
        r = convergence(scene, METHODS, dts, modes, overrides, executor=executor,
                        workers=workers, progress=progress)
        results[scene] = (r, overrides)
        fields = ['method', 'dt_s', 'modes', 'status', 'cpu_per_simulated_s',
                  'real_time_factor', 'amplitude_error', 'rms_acceleration_error',
                  'impact_time_error_s', 'impact_time_error_max_s', 'impacts_matched',
                  'energy_residual',
                  'max_impacts_per_step', 'error']
        with open(os.path.join(out_dir, f'{scene}.csv'), 'w', newline='') as fh:
            w = csv.DictWriter(fh, fieldnames=fields, extrasaction='ignore')
            w.writeheader()
            for row in r['rows']:
                w.writerow({k: '' if row.get(k) is None else row.get(k) for k in fields})
        with open(json_path, 'w') as fh:
            json.dump({k: v for k, v in r.items() if k != 'points'}, fh, indent=1)
        plot(r, os.path.join(out_dir, f'{scene}.png'))
    for scene, (r, overrides) in results.items():
        ref = r['reference']
        lines += [f"## {scene}", '',
                  f"{_cell(r['duration_s'], 3)} s from rest, overrides "
                  f"`{' '.join(overrides)}`; reference: exact, dt {ref['dt_s'] * 1e6:g} us, "
                  f"{ref['modes']} modes, {ref['isolated_impacts']} isolated impacts; RMS "
                  f"acceleration per {r['coarse_dt_s'] * 1e6:g} us over the last "
                  f"{_cell(r['window_s'], 3)} s. Wall time {r['wall_time_s']:.0f} s.", '',
                  f'![Pareto plot]({rel}/{scene}.png)', '',
                  '| method | dt (us) | modes | CPU s per s | real-time factor | amplitude '
                  '| RMS acc | impact time, median (s) | matched | energy residual |',
                  '|---|---|---|---|---|---|---|---|---|---|']
        for row in r['rows']:
            if row['status'] != 'ok':
                lines.append(f"| {row['method']} | {row['dt_s'] * 1e6:g} | {row['modes']} | "
                             f"{row['status']}: {row['error'].split(':', 1)[-1].strip()[:60]}"
                             '... | | | | | | |')
                continue
            lines.append(
                f"| {row['method']} | {row['dt_s'] * 1e6:g} | {row['modes']} | "
                f"{_cell(row['cpu_per_simulated_s'], 3)} | {_cell(row['real_time_factor'], 3)} | "
                f"{_cell(row['amplitude_error'])} | {_cell(row['rms_acceleration_error'])} | "
                f"{_cell(row['impact_time_error_s'])} | {row['impacts_matched']} | "
                f"{_cell(row['energy_residual'])} |")
        front = pareto(r['rows'], 'amplitude_error')
        lines += ['', 'Pareto front (amplitude error against cost): '
                  + ', '.join(f"{x['method']} {x['dt_s'] * 1e6:g} us/{x['modes']} "
                              f"({_cell(x['cpu_per_simulated_s'], 2)} s/s, "
                              f"{_cell(x['amplitude_error'])})" for x in front) + '.', '']
    with open(md_path, 'w') as fh:
        fh.write('\n'.join(lines) + '\n')
    return {scene: r for scene, (r, _) in results.items()}


def main(argv=None):
    """``python -m impact_damper_sim.studies.convergence [MD] [--workers N] [--scenes A,B]``."""
    import argparse
    parser = argparse.ArgumentParser(description='Write docs/convergence.md and its files.')
    parser.add_argument('md', nargs='?', default='docs/convergence.md')
    parser.add_argument('--workers', type=int, default=1)
    parser.add_argument('--scenes', default='')
    args = parser.parse_args(argv)
    document(args.md, args.workers, [s for s in args.scenes.split(',') if s] or None)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
