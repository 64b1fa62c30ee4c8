"""Rotordynamics on the command line: ``study campbell`` and the whirl part of ``study modes``.

The computation is :mod:`impact_damper_sim.studies.campbell` (on
:mod:`impact_damper_sim.modal.whirl` and :mod:`impact_damper_sim.modal.tracking`); the plots
:mod:`impact_damper_sim.studies.campbell_plot`, imported only when ``--plot`` is given.
"""
from __future__ import annotations

from .._exit_status import EXIT_USAGE
from ..studies.output import OutputExists, refuse_existing
from ..studies.output import fmt as _g
from ..studies.output import print_error as _error
from ..studies.output import print_json as _print_json
from ..studies.output import table as _table


def add_campbell_parser(sub, scene_args):
    """Add the ``campbell`` sub-command to the ``study`` parser.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The sub-command registry.
    scene_args : callable
        Adds SCENE, ``--set`` and ``--json`` to a parser.
    """
    p = sub.add_parser(
        'campbell', help='Campbell diagram: whirl frequencies and log decrements over speed',
        description='Damped whirl modes of the rotating model (gyroscopic and cross-coupled '
                    'terms included) at each speed, tracked across speeds by shape (MAC), '
                    'forward/backward marked; critical speeds where a branch meets a harmonic '
                    'of the speed; the first speed where a log decrement turns negative. '
                    'Model: the scene\'s retained modes (--set modal.n_modes=N for more).')
    scene_args(p)
    p.add_argument('--speeds', required=True, metavar='START:STOP:N',
                   help='rotor speeds in rpm: N speeds from START to STOP (ends included), or '
                        'a comma list, e.g. 0:10000:101')
    p.add_argument('--harmonics', default='1', metavar='H1,H2',
                   help='orders of the excitation lines (default 1: the 1X unbalance line)')
    p.add_argument('--csv', metavar='PATH',
                   help='also write one row per speed and branch as CSV')
    p.add_argument('--plot', metavar='PATH.png', help='also draw the Campbell diagram')
    p.add_argument('--overwrite', action='store_true',
                   help='replace existing --csv/--plot files (default: refuse)')


def run_campbell(args):
    """Run ``study campbell``: compute, print or write the Campbell diagram.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed ``study campbell`` arguments.

    Returns
    -------
    int
        0 on success, 2 for bad input (message on stderr).
    """
    from ..studies.campbell import campbell_study
    from .studies import _Usage, _write_csv, parse_spec
    try:
        refuse_existing([args.csv, args.plot], args.overwrite)   # before the work
        speeds = parse_spec(args.speeds, '--speeds')
        harmonics = parse_spec(args.harmonics, '--harmonics')
        result = campbell_study(args.scene, speeds, harmonics, args.overrides)
    except (ValueError, OutputExists, _Usage) as exc:   # SceneError is a ValueError
        _error(str(exc))
        return EXIT_USAGE
    try:
        if args.csv:
            _write_csv(args.csv, result['rows'])
        if args.plot:
            from ..studies.campbell_plot import plot
            plot(result, args.plot)
    except OSError as exc:
        _error(f'cannot write output: {exc}')
        return EXIT_USAGE
    if args.json:
        _print_json(result)
    else:
        print_campbell(result)
    return 0


def print_campbell(r):
    """Print the text summary of a Campbell result (every value is in ``--csv``)."""
    speeds = r['speeds_rpm']
    model = r['model']
    print(f"Campbell diagram of {r['scene']} ({r['source']}), {len(speeds)} speeds from "
          f"{_g(speeds[0])} to {_g(speeds[-1])} rpm; {model['coordinates']}: "
          f"{model['selection_reason']}")
    gyro = model['gyroscopic_nodes']
    cc = model['cross_couplings']
    print('speed-dependent terms: '
          + (f"gyroscopic coupling of node(s) {', '.join(map(str, gyro))}" if gyro
             else 'none (no rotor.gyroscopic): the branches are flat')
          + ('; cross-coupled stiffness ' + ', '.join(f"{_g(c['kcc_N_m'])} N/m at node "
                                                      f"{c['node']}" for c in cc) if cc else ''))
    rows = []
    for b in r['branches']:
        f, d, ld = b['frequency_hz'], b['direction'], b['log_dec']
        finite = [(v, k) for k, v in enumerate(ld) if v is not None]
        low, at = min(finite) if finite else (None, None)
        rows.append([b['branch'], _g(f[0], 6), d[0] or '-', _g(f[-1], 6), d[-1] or '-',
                     _g(low, 4), _g(speeds[at], 6) if at is not None else 'n/a'])
    print(_table(['branch', f'f at {_g(speeds[0])} rpm (Hz)', 'whirl',
                  f'f at {_g(speeds[-1])} rpm (Hz)', 'whirl', 'min log dec', 'at rpm'], rows))
    crit = r['critical_speeds']
    harmonics = ', '.join(f'{h:g}X' for h in r['harmonics'])
    if crit:
        print(f'\ncritical speeds ({harmonics} lines crossing the branches):')
        print(_table(['speed (rpm)', 'harmonic', 'branch', 'frequency (Hz)', 'whirl',
                      'log dec'],
                     [[_g(c['speed_rpm'], 6), f"{c['harmonic']:g}X", c['branch'],
                       _g(c['frequency_hz'], 6), c['direction'], _g(c['log_dec'], 4)]
                      for c in crit]))
    else:
        print(f'\nno critical speed in the range ({harmonics})')
    o = r['onset']
    if o is None:
        print('stable over the range: every log decrement >= 0')
    elif o['branch'] is None:
        print(f"unstable from {_g(o['speed_rpm'], 6)} rpm: a real eigenvalue (divergence)")
    else:
        where = ('at the first speed of the range' if o['from_start']
                 else f"from {_g(o['speed_rpm'], 7)} rpm")
        print(f"unstable {where}: branch {o['branch']} ({o['direction']} whirl, "
              f"{_g(o['frequency_hz'], 6)} Hz) has a negative log decrement")
    print(f"eigen-analysis {_g(r['wall_time_s'], 3)} s")


def print_whirl(data):
    """Print the damped whirl modes of ``study modes`` (the ``whirl`` part of its data)."""
    speed = data['rotor_speed_rpm']
    if not data['spin_axis']:
        head = 'damped modes (no rotor: no spin axis, no whirl direction)'
    elif speed is None:
        head = ('damped whirl modes of the rotating model (no speed-dependent term: the same '
                'at every speed of the profile)')
    else:
        head = (f'damped whirl modes of the rotating model at {_g(speed, 6)} rpm (gyroscopic '
                'and cross-coupled terms included)')
    print(f'\n{head}; log dec = -2 pi Re(lambda)/Im(lambda), damping ratio = '
          '-Re(lambda)/|lambda|:')
    print(_table(['mode', 'frequency (Hz)', 'whirl', 'log dec', 'damping ratio'],
                 [(w['mode'], _g(w['frequency_hz'], 9), w['direction'], _g(w['log_dec'], 4),
                   _g(w['damping_ratio'], 4)) for w in data['whirl']]))
    if data['n_overdamped']:
        print(f"({data['n_overdamped']} real eigenvalue(s) left out: overdamped motion)")


def plot_modes(scene, args):
    """Write ``study modes --plot``: the orbit shapes of the asked whirl modes.

    Returns
    -------
    int or None
        An exit status on bad input, None when written.
    """
    from ..studies.campbell import whirl_shapes
    from .studies import _Usage, parse_spec
    try:
        numbers = ([int(v) for v in parse_spec(args.plot_modes, '--plot-modes')]
                   if args.plot_modes else None)
        shapes = whirl_shapes(scene, numbers)
    except (ValueError, _Usage) as exc:
        _error(str(exc))
        return EXIT_USAGE
    from ..studies.campbell_plot import plot_shapes
    try:
        plot_shapes(shapes, args.plot)
    except OSError as exc:
        _error(f'cannot write output: {exc}')
        return EXIT_USAGE
    return None


__all__ = ['add_campbell_parser', 'plot_modes', 'print_campbell', 'print_whirl',
           'run_campbell']
