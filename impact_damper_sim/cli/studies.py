"""The ``study frf|sweep|stability|convergence|validate`` subcommands: arguments and output.

The studies themselves are in :mod:`impact_damper_sim.studies`; Matplotlib is imported only
when ``--plot`` is given.
"""
from __future__ import annotations

import csv
import os
import sys

from .._exit_status import EXIT_DIVERGED, EXIT_USAGE
from ..integrate.divergence import StudyDiverged
from ..studies.output import QUICK_VALIDATION_OUT, OutputExists, refuse_existing
from ..studies.output import fmt as _g
from ..studies.output import print_error as _error
from ..studies.output import print_json as _print_json
from ..studies.output import table as _table

_SHORTHANDS = ('duration', 'method', 'dt', 'window')


class _Usage(Exception):
    """Bad command-line input (exit 2)."""


def run_study(args):
    """Run the study named by ``args.command`` and print/write its results.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed ``study`` arguments.

    Returns
    -------
    int
        0 if every point (or at least one) succeeded, 1 if all failed, 2 for bad input, 3 if
        a point's run diverged (its one-line reason on stderr; the other points are kept).
    """
    try:
        refuse_existing([args.csv, args.plot], args.overwrite)   # before the runs, not after
        result = {'frf': _frf, 'sweep': _sweep, 'stability': _stability,
                  'convergence': _convergence}[args.command](args)
    except (_Usage, ValueError, OutputExists) as exc:   # UnitError, TooLarge: ValueErrors
        _error(str(exc))
        return EXIT_USAGE
    except StudyDiverged as exc:
        _error(str(exc))
        return EXIT_DIVERGED
    module = _module(args.command)
    try:
        if args.csv:
            _write_csv(args.csv, result['rows'])
        if args.plot:
            module.plot(result, args.plot)
    except OSError as exc:
        _error(f'cannot write output: {exc}')
        return EXIT_USAGE
    if args.json:
        _print_json(result)
    else:
        {'frf': _print_frf, 'sweep': _print_sweep, 'stability': _print_stability,
         'convergence': _print_convergence}[args.command](result)
    for f in result['failures']:
        labels = ', '.join(f'{k}={v}' for k, v in f['labels'].items())
        print(f'study: warning: point failed ({labels}): {f["error"]}', file=sys.stderr)
    n_points = len(result['points'])
    if any(f.get('diverged') for f in result['failures']):
        return EXIT_DIVERGED
    return 1 if n_points and len(result['failures']) == n_points else 0


def run_validate(args):
    """Run ``study validate``: write the validation document and its plots.

    Returns
    -------
    int
        0 if every run succeeded, 1 if some failed (the document says which), 2 for bad input.
    """
    if args.workers is not None and args.workers < 1:
        _error(f'--workers must be >= 1, got {args.workers}')
        return EXIT_USAGE
    from ..studies.validation import validate
    out = args.out or (QUICK_VALIDATION_OUT if args.quick else 'docs/validation.md')
    plot_dir = os.path.splitext(out)[0]
    plots = ([os.path.join(plot_dir, f) for f in sorted(os.listdir(plot_dir))
              if f.endswith('.png')] if os.path.isdir(plot_dir) else [])
    try:
        refuse_existing([out] + plots, args.overwrite)
    except OutputExists as exc:
        _error(str(exc))
        return EXIT_USAGE
    try:
        r = validate(out, quick=args.quick, workers=args.workers, seed=args.seed,
                     progress=args.progress)
    except OSError as exc:
        _error(f'cannot write output: {exc}')
        return EXIT_USAGE
    print(f"wrote {r['path']} and {len(r['plots'])} plot(s) in "
          f"{os.path.dirname(next(iter(r['plots'].values()))) or '.'}; "
          f"{r['n_points']} runs in {_g(r['wall_time_s'], 3)} s")
    for f in r['failures']:
        print(f"study: warning: run failed ({f['labels']}): {f['error']}", file=sys.stderr)
    return 1 if r['failures'] else 0


def _module(command):
    from ..studies import convergence, frf, stability, sweep
    return {'frf': frf, 'sweep': sweep, 'stability': stability,
            'convergence': convergence}[command]


def _overrides(args):
    out = list(args.overrides)
    for key in _SHORTHANDS:
        value = getattr(args, key)
        if value is not None:
            out.append(f'simulation.{key}={value}')
    return out


def _runner(args):
    if args.workers is not None and args.workers < 1:
        raise _Usage(f'--workers must be >= 1, got {args.workers}')
    if args.dask_address and args.executor != 'dask':
        raise _Usage('--dask-address needs --executor dask')
    return dict(seed=args.seed, executor=args.executor, workers=args.workers,
                dask_address=args.dask_address, progress=args.progress)


def _length(text, option):
    from ..scene.units import parse_quantity
    try:
        return parse_quantity(text, 'length')
    except ValueError as exc:
        raise _Usage(f'{option}: {exc}') from None


def parse_spec(text, option):
    """Read ``START:STOP:N`` (N points, ends included) or a comma list of numbers.

    Parameters
    ----------
    text : str
        The specification.
    option : str
        Option name for messages.

    Returns
    -------
    list of float
    """
    try:
        if ':' in text:
            a, b, n = text.split(':')
            a, b, n = float(a), float(b), int(n)
            if n < 1:
                raise ValueError
            # rounded so that 0.9:1.1:5 gives 0.95, not 0.9500000000000001
            return [a] if n == 1 else [float(f"{a + (b - a) * k / (n - 1):.12g}")
                                       for k in range(n)]
        values = [float(v) for v in text.split(',') if v.strip()]
    except ValueError:
        raise _Usage(f'{option} {text!r}: expected START:STOP:N (N >= 1) or a comma list of '
                     'numbers') from None
    if not values:
        raise _Usage(f'{option}: no values')
    return values


# --- frf ----------------------------------------------------------------------------------

def _frf(args):
    from ..studies.frf import frf
    unit = 'ratio' if args.ratio is not None else 'hz'
    values = parse_spec(args.ratio if unit == 'ratio' else args.hz, f'--{unit}')
    if any(not v > 0 for v in values):
        raise _Usage(f'--{unit}: frequencies must be > 0')
    max_duration = None
    if args.max_duration is not None:
        from ..scene.units import parse_quantity
        max_duration = parse_quantity(args.max_duration, 'time', key='--max-duration')
    if not args.tol >= 0:
        raise _Usage(f'--tol must be >= 0, got {args.tol}')
    return frf(args.scene, values, unit, _overrides(args), tol=args.tol,
               max_duration=max_duration, **_runner(args))


def _print_frf(r):
    col = 'frequency_ratio' if r['unit'] == 'ratio' else 'frequency_hz'
    header = ['r' if r['unit'] == 'ratio' else 'f (Hz)'] + (
        ['f (Hz)'] if r['unit'] == 'ratio' else [])
    for s in r['sensors']:
        header += [f'{s} with (m)', f'{s} without (m)', f'{s} without/with']
    header.append('settled')
    rows = []
    for row in r['rows']:
        cells = [_g(row[col])] + ([_g(row['frequency_hz'])] if r['unit'] == 'ratio' else [])
        for s in r['sensors']:
            cells += [_g(row[f'{s}_with_m'], 4), _g(row[f'{s}_without_m'], 4),
                      _g(row[f'{s}_reduction'], 3)]
        cells.append('yes' if row['settled'] else 'no')
        rows.append(cells)
    print(f"frequency response of {r['scene']} ({r['source']}); steady amplitude = peak over "
          'the trailing window')
    print(_table(header, rows))
    for s, cases in r['peaks'].items():
        for case, peak in cases.items():
            print(f"peak {s} {case} impactors: {_g(peak['amplitude_m'], 5)} m at "
                  f"{col.replace('_', ' ')} {_g(peak[col])}")
    print(f"{len(r['points'])} runs in {_g(r['wall_time_s'], 3)} s")


# --- sweep --------------------------------------------------------------------------------

def _sweep(args):
    from ..studies.sweep import DEFAULT_PHASES, split_values, sweep
    if not args.grid:
        raise _Usage('sweep needs at least one --grid KEY=V1,V2,...')
    grid = []
    for text in args.grid:
        key, sep, values = text.partition('=')
        vals = split_values(values)
        if not sep or not key.strip() or not vals:
            raise _Usage(f'--grid {text!r}: expected KEY=V1,V2,...')
        grid.append((key.strip(), vals))
    _check_grid_keys(args.scene, grid, _overrides(args))
    phases = DEFAULT_PHASES
    if args.phase:
        phases = []
        for text in args.phase:
            name, sep, span = text.partition('=')
            t0, sep2, t1 = span.partition(':')
            try:
                phases.append((name.strip(), float(t0) if t0.strip() else 0.0,
                               float(t1) if t1.strip() else None))
            except ValueError:
                sep = ''
            if not sep or not sep2 or not name.strip():
                raise _Usage(f'--phase {text!r}: expected NAME=T0:T1 (s; T1 may be empty)')
    return sweep(args.scene, grid, _overrides(args), phases=phases, best_over=args.best_over,
                 objective=args.objective, **_runner(args))


def _check_grid_keys(scene, grid, overrides):
    """Refuse, before any run, a grid key the scene cannot take (exit 2, one line)."""
    from ..scene.catalog import validated
    from ..scene.schema import SceneError
    from ..studies.sweep import expand_key
    base, _ = validated(scene, overrides)   # the scene and the other options: their own error
    for key, vals in grid:
        # 'impactors.*.mass': every impactor must take it (ValueError: '*' matches nothing)
        lines = [f'{k}={vals[0]}' for k in expand_key(key, base)]
        try:
            validated(scene, list(overrides) + lines)
        except SceneError as exc:
            first = str(exc).strip().splitlines()[-1].strip()
            raise _Usage(f'--grid {key}: does not apply to scene {scene!r} ({first})') from exc


def _print_sweep(r):
    keys = [g['key'] for g in r['grid']]
    phases = [p['name'] for p in r['phases']]
    header = list(keys)
    for p in phases:
        header += [f'{p} displacement (m)', 'reduction', f'{p} acceleration (g)', 'reduction',
                   f'{p} impacts/s']
    rows = []
    for row in r['rows']:
        cells = [row[k] for k in keys]
        for p in phases:
            cells += [_g(row[f'{p}_worst_displacement_m'], 4),
                      _g(row[f'{p}_displacement_reduction'], 3),
                      _g(row[f'{p}_worst_acceleration_g'], 4),
                      _g(row[f'{p}_acceleration_reduction'], 3),
                      _g(row[f'{p}_impacts_per_second'], 4)]
        rows.append(cells)
    print(f"sweep of {r['scene']} ({r['source']}); worst case over the sensors; reduction = "
          'worst case without impactors / with them (> 1: the impactors help)')
    print(_table(header, rows))
    diverged = sorted({row['without_diverged_at_s'] for row in r['rows']
                       if row.get('without_diverged_at_s') is not None})
    if diverged:
        print(f"without impactors the run diverged (at t = {_g(diverged[0], 4)} s first): the "
              "structure is unbounded without them, so the reduction is n/a (unbounded)")
    if r['best']:
        from ..studies.analysis import G0
        disp = r['objective'] == 'displacement'
        field = f"worst_{r['objective']}_{'m' if disp else 'm_s2'}"
        scale = 1.0 if disp else 1.0 / G0   # in the table's units: m, or g
        others = [k for k in keys if k != r['best_over']]
        print(f"\nbest {r['best_over']} (least worst-case {r['objective']} over the phases):")
        print(_table(others + [r['best_over'],
                               f"worst {r['objective']} ({'m' if disp else 'g'})"],
                     [[b[k] for k in others] + [b[r['best_over']], _g(b[field] * scale, 4)]
                      for b in r['best']]))
    print(f"{len(r['points'])} runs in {_g(r['wall_time_s'], 3)} s")


# --- stability ----------------------------------------------------------------------------

def _stability(args):
    from ..scene.units import parse_quantity
    from ..studies.stability import stability
    from ..studies.sweep import split_values
    kccs = split_values(args.kcc)
    if not kccs and not args.onset:
        raise _Usage('stability needs --kcc values, --onset, or both')
    weights, clearances = split_values(args.weights), split_values(args.clearances)
    if weights and not args.weight_key:
        raise _Usage('--weights needs --weight-key (e.g. impactors.0.mass)')
    if clearances and not args.clearance_key:
        raise _Usage('--clearances needs --clearance-key (e.g. impactors.0.clearance)')
    bracket = None
    if args.onset_bracket:
        parts = split_values(args.onset_bracket)
        if len(parts) != 2:
            raise _Usage(f'--onset-bracket {args.onset_bracket!r}: expected LO,HI')
        bracket = [parse_quantity(v, 'stiffness', key='--onset-bracket') for v in parts]
    max_amp = (_length(args.max_amplitude, '--max-amplitude')
               if args.max_amplitude is not None else None)
    return stability(args.scene, args.kcc_key, kccs, _overrides(args),
                     weight_keys=args.weight_key, weights=weights,
                     clearance_keys=args.clearance_key, clearances=clearances,
                     baseline=not args.no_baseline,
                     sensors=split_values(args.sensors) or None,
                     perturbation=_length(args.perturbation, '--perturbation'),
                     growth_tol=args.growth_tol, max_amplitude=max_amp,
                     find_onset=args.onset, onset_bracket=bracket, verify=args.verify,
                     **_runner(args))


def _print_stability(r):
    print(f"stability of {r['scene']} ({r['source']}); {r['criterion']} "
          f"(window {_g(r['window_s'])} s, duration {_g(r['duration_s'])} s)")
    if r['rows']:
        verify = r.get('verification')

        def scene_value(value, key):
            # rows that keep the scene's impactors show them, not None
            return value if value is not None else (r.get(key) or 'scene')

        rows = [[row['kcc'], _g(row['kcc_N_m']),
                 scene_value(row['weight'], 'scene_weight') if row['impactors'] else '-',
                 scene_value(row['clearance'], 'scene_clearance') if row['impactors'] else '-',
                 (f"unstable (diverged at {_g(row['diverged_at_s'], 3)} s)"
                  if row.get('diverged_at_s') is not None else row['verdict']),
                 _g(row['rms_radial_m'], 4), _g(row['growth_ratio'], 4),
                 _g(row['growth_rate_1_s'], 3), _g(row['impacts_per_second'], 4)]
                + ([row['verdict_half_dt'], row['verdict_other_method'],
                    'yes' if row['verified'] else 'NO'] if verify else [])
                for row in r['rows']]
        print(_table(['Kcc', 'Kcc (N/m)', 'weight', 'gap', 'verdict', 'rms radial (m)',
                      'R_last/R_prev', 'growth (1/s)', 'impacts/s']
                     + (['dt/2', verify['other_method']['method'], 'same verdict']
                        if verify else []), rows))
        if verify:
            h, o = verify['half_dt'], verify['other_method']
            print(f"verification: {h['method']} at dt {_g(h['dt_s'])} s and {o['method']} at "
                  f"dt {_g(o['dt_s'])} s from the same perturbation; "
                  f"{sum(row['verified'] for row in r['rows'])}/{len(r['rows'])} verdicts "
                  'unchanged')
    if r['onset']:
        o = r['onset']
        from ..studies.display import axis_unit
        unit, factor = axis_unit(o['kcc_key'], [row['kcc'] for row in r['rows']])
        given = (f" = {_g(o['onset_kcc_N_m'] / factor, 7)} {unit}"
                 if unit and unit != 'N/m' else '')   # also in the unit of --kcc
        print(f"linear onset without impactors: {o['kcc_key']} = {_g(o['onset_kcc_N_m'], 7)} "
              f"N/m{given} (whirl {_g(o['whirl_frequency_hz'], 6)} Hz, {o['evaluations']} "
              'eigenvalue evaluations)')
    print(f"{len(r['points'])} runs in {_g(r['wall_time_s'], 3)} s")


# --- convergence --------------------------------------------------------------------------

def _convergence(args):
    from ..scene.units import parse_quantity
    from ..studies.convergence import convergence
    from ..studies.sweep import split_values

    def times(text, option):
        return [parse_quantity(v, 'time', key=option) for v in split_values(text)]

    methods = split_values(args.methods)
    try:
        modes = [int(m) for m in split_values(args.modes)]
    except ValueError:
        raise _Usage(f'--modes {args.modes!r}: expected integers N1,N2,...') from None
    ref_dt = times(args.ref_dt, '--ref-dt')[0] if args.ref_dt else None
    isolation = times(args.isolation, '--isolation')[0]
    if args.n_impacts < 1:
        raise _Usage(f'--n-impacts must be >= 1, got {args.n_impacts}')
    return convergence(args.scene, methods, times(args.dts, '--dts') or None, modes or None,
                       _overrides(args), ref_dt=ref_dt, ref_modes=args.ref_modes,
                       n_impacts=args.n_impacts, isolation=isolation, **_runner(args))


def _print_convergence(r):
    ref = r['reference']
    print(f"speed/accuracy of {r['scene']} ({r['source']}): {_g(r['duration_s'])} s from rest; "
          f"reference exact, dt {_g(ref['dt_s'])} s, {ref['modes']} modes "
          f"({ref['isolated_impacts']} isolated impacts compared); errors relative unless "
          'stated, RMS acceleration per '
          f"{_g(r['coarse_dt_s'])} s period over the last {_g(r['window_s'])} s")
    rows = []
    for row in r['rows']:
        if row['status'] != 'ok':
            rows.append([row['method'], _g(row['dt_s']), row['modes'], row['status']]
                        + ['-'] * 6)
            continue
        rows.append([row['method'], _g(row['dt_s']), row['modes'], 'ok',
                     _g(row['cpu_per_simulated_s'], 3), _g(row['real_time_factor'], 3),
                     _g(row['amplitude_error'], 2), _g(row['rms_acceleration_error'], 2),
                     f"{_g(row['impact_time_error_s'], 2)} ({row['impacts_matched']})",
                     _g(row['energy_residual'], 2)])
    print(_table(['method', 'dt (s)', 'modes', 'status', 'CPU s/s', 'RTF', 'amplitude',
                  'rms acc', 'impact t (s) (matched)', 'energy res'], rows))
    for row in r['rows']:
        if row['status'] != 'ok':
            print(f"{row['method']} dt {_g(row['dt_s'])} s, {row['modes']} modes: {row['error']}")
    print(f"{len(r['points'])} runs in {_g(r['wall_time_s'], 3)} s")


def _write_csv(path, rows):
    fields = []
    for row in rows:
        fields += [k for k in row if k not in fields]
    with open(path, 'w', newline='') as fh:
        writer = csv.DictWriter(fh, fieldnames=fields)
        writer.writeheader()
        for row in rows:
            writer.writerow({k: '' if v is None else v for k, v in row.items()})
