"""``study``: inspect and run scenes offline.

::

    study modes SCENE [--set KEY=VALUE ...] [--json] [--plot PATH.png] [--plot-modes N1,N2]
                      [--overwrite]
    study campbell SCENE --speeds START:STOP:N [--harmonics H1,H2] [--set KEY=VALUE ...]
                         [--json] [--csv PATH] [--plot PATH.png] [--overwrite]
    study simulate SCENE [--set KEY=VALUE ...] [--duration S] [--method M] [--dt S]
                         [--window S] [--json]
    study keys [--markdown]
    study frf SCENE (--ratio SPEC | --hz SPEC) [--tol X] [--max-duration S] [study options]
    study sweep SCENE --grid KEY=V1,V2,... [--grid ...] [--phase NAME=T0:T1 ...]
                      [--best-over KEY] [--objective acceleration|displacement] [study options]
    study stability SCENE --kcc-key KEY [--kcc V1,V2,...] [--weight-key KEY --weights ...]
                          [--clearance-key KEY --clearances ...] [--onset] [study options]
    study validate [--out docs/validation.md] [--quick] [--workers N] [--overwrite]
    study convergence SCENE [--methods M1,M2] [--dts DT1,DT2] [--modes N1,N2] [--ref-dt S]
                            [--ref-modes N] [study options]
    study report FILE.mcap [--json] [--plot PATH.png] [--csv PATH] [--overwrite]
    study recover CRASHED.mcap OUT.mcap [--overwrite] [--json]
    study record SCENE --duration S --out F.mcap [--schedule F.yaml] [--seed N]
                 [--noise-std A] [--set KEY=VALUE ...] [--overwrite] [--progress] [--json]
    study dataset SPEC.yaml --out DIR [--executor process|serial|dask] [--workers N]
                  [--dask-address ADDR] [--retry-failed] [--progress] [--json]

study options: [--set KEY=VALUE ...] [--duration S] [--method M] [--dt S] [--window S]
[--json] [--csv PATH] [--plot PATH.png] [--overwrite] [--workers N]
[--executor process|serial|dask] [--dask-address ADDR] [--seed N] [--progress | --no-progress]

SCENE is a ready-made scene name (``config/scenes/<name>.yaml``) or a path to a YAML file.
``--duration``, ``--method``, ``--dt`` and ``--window`` are shorthands for
``--set simulation.<key>=VALUE``, so they accept units (``--dt '50 us'``) and are checked
like scene values. Bad input prints one message per problem to stderr and exits with 2; so
does a run whose samples would not fit in memory (refused up front, with the estimate). A run
that diverges (non-finite or absurd state, unresolved chatter) ends in one line on stderr,
what diverged, when, and which setting to change, and exits with 3.

The studies (``frf``, ``sweep``, ``stability``; :mod:`impact_damper_sim.studies`) run their
points in parallel; a point that fails is reported on stderr and the others are kept (exit
status 0 if any point succeeded, 1 if none did, 3 if a point diverged).

Importing this module is cheap: NumPy, SciPy, Numba, Dask and Matplotlib are imported by the
subcommands that need them.
"""
from __future__ import annotations

import argparse
import sys
import time

from .._exit_status import EXIT_DIVERGED, EXIT_USAGE
from ..studies.output import QUICK_VALIDATION_OUT, OutputExists, refuse_existing
from ..studies.output import fmt as _g
from ..studies.output import print_error as _error
from ..studies.output import print_json as _print_json
from ..studies.output import table as _table

_METHODS_HELP = 'exact, newmark, newmark_step_end or direct'


def _parser():
    parser = argparse.ArgumentParser(
        prog='study', description='Inspect and run impact-damper scenes offline (SI units).')
    sub = parser.add_subparsers(dest='command', required=True, metavar='COMMAND')

    def scene_args(p):
        p.add_argument('scene', metavar='SCENE',
                       help='scene name (config/scenes/<name>.yaml) or path to a .yaml file')
        p.add_argument('--set', dest='overrides', action='append', default=[],
                       metavar='KEY=VALUE',
                       help="override a scene key, e.g. impactors.0.cor=0.6 or "
                            "'impactors[0].clearance=2 mil' (repeatable)")
        p.add_argument('--json', action='store_true', help='print JSON instead of text')

    modes = sub.add_parser('modes', help='DOF counts, modal basis, damped whirl modes at speed',
                           description='DOF counts, retained modes and why, the undamped '
                                       'modal basis (natural frequencies, damping ratios, the '
                                       'mode shapes at sensor, impactor and force DOFs) and '
                                       'the damped whirl modes of the rotating model at the '
                                       "scene's speed (frequency, forward/backward whirl, log "
                                       'decrement, damping ratio).')
    scene_args(modes)
    modes.add_argument('--plot', metavar='PATH.png',
                       help='also draw the whirl modes\' orbit shapes along the shaft')
    modes.add_argument('--plot-modes', metavar='N1,N2',
                       help='whirl modes to draw (numbers of the whirl table; default the '
                            'first six)')
    modes.add_argument('--overwrite', action='store_true',
                       help='replace an existing --plot file (default: refuse)')
    simulate = sub.add_parser('simulate', help='run a scene and summarize it',
                              description='Run a scene from rest and print per-sensor peak, '
                                          'RMS and steady-state amplitudes, accelerations '
                                          '(mean per sample period, impacts included), impact '
                                          'rates, stuck fractions, the energy balance and the '
                                          'real-time factor.')
    scene_args(simulate)
    simulate.add_argument('--duration', metavar='S',
                          help='simulated time (s, or with a unit: "500 ms")')
    simulate.add_argument('--method', metavar='M', help=f'integration method: {_METHODS_HELP}')
    simulate.add_argument('--dt', metavar='S', help='output sample period (s)')
    simulate.add_argument('--window', metavar='S',
                          help='trailing window of the steady-state amplitude (s)')
    keys = sub.add_parser('keys', help='every scene key with unit, default and range',
                          description='Every scene key with its type or unit, default, '
                                      'allowed range and meaning.')
    keys.add_argument('--markdown', action='store_true', help='print a Markdown table')
    report = sub.add_parser(
        'report', help='summarize a recorded MCAP log (rosbag2 layout)',
        description='Per-topic counts and rates; per accelerometer (sensor_msgs/Imu) peak and '
                    'RMS acceleration in g, spectrum and dominant frequency (a waterfall over '
                    'rotor speed when rotor/speed spans a range); impacts per second; '
                    'time-weighted stuck fraction per impactor; metadata records.')
    report.add_argument('file', metavar='FILE.mcap', help='MCAP log with profile ros2')
    report.add_argument('--json', action='store_true', help='print JSON instead of text')
    report.add_argument('--plot', metavar='PATH.png',
                        help='also plot spectra or waterfalls, impact rate and stuck state')
    report.add_argument('--csv', metavar='PATH',
                        help='also write the summary as CSV (section,name,quantity,value,unit)')
    report.add_argument('--overwrite', action='store_true',
                        help='replace existing --plot/--csv files (default: refuse)')
    _study_parsers(sub, scene_args)
    from .rotor import add_campbell_parser
    add_campbell_parser(sub, scene_args)
    from ..recording.cli import add_recover_parser
    add_recover_parser(sub)
    from .datasets import add_dataset_parser, add_record_parser
    add_record_parser(sub, scene_args)
    add_dataset_parser(sub)
    return parser


def _study_parsers(sub, scene_args):
    def common(p):
        scene_args(p)
        for key, meta, text in (('duration', 'S', 'simulated time of each point (s)'),
                                ('method', 'M', f'integration method: {_METHODS_HELP}'),
                                ('dt', 'S', 'output sample period (s)'),
                                ('window', 'S', 'trailing window (s)')):
            p.add_argument(f'--{key}', metavar=meta, help=text)
        p.add_argument('--csv', metavar='PATH', help='also write the table as CSV')
        p.add_argument('--plot', metavar='PATH.png', help='also write a plot (PNG)')
        p.add_argument('--overwrite', action='store_true',
                       help='replace existing --csv/--plot files (default: refuse)')
        p.add_argument('--workers', type=int, metavar='N',
                       help='parallel workers (default: CPU count)')
        p.add_argument('--executor', choices=('process', 'serial', 'dask'), default='process',
                       help='where points run (default process; serial for debugging)')
        p.add_argument('--dask-address', metavar='ADDR',
                       help='Dask scheduler, e.g. tcp://host:8786 (default: a local cluster)')
        p.add_argument('--seed', type=int, default=0, help='study seed (default 0)')
        p.add_argument('--progress', action=argparse.BooleanOptionalAction, default=None,
                       help='progress bar on stderr (default: when stderr is a terminal)')

    frf = sub.add_parser(
        'frf', help='frequency response with and without impactors',
        description='For each forcing frequency run the scene to a steady amplitude (peak '
                    'over the trailing window) with its impactors and without them '
                    '(impactors=[]). SPEC is START:STOP:N (N points, ends included) or a '
                    'comma list. Every forcing entry gets the frequency.')
    common(frf)
    which = frf.add_mutually_exclusive_group(required=True)
    which.add_argument('--ratio', metavar='SPEC',
                       help='frequency ratios to the first retained mode, e.g. 0.8:1.2:21')
    which.add_argument('--hz', metavar='SPEC', help='frequencies (Hz), e.g. 20:30:11')
    frf.add_argument('--tol', type=float, default=0.005,
                     help='settled when the last two window peaks differ by <= tol '
                          '(relative, default 0.005)')
    frf.add_argument('--max-duration', metavar='S',
                     help='continue unsettled runs window by window up to this time (s)')

    sweep = sub.add_parser(
        'sweep', help='grid sweep with worst-case responses and reductions',
        description='Run every combination of the --grid values with impactors, and each '
                    'combination of the non-impactor keys without impactors as reference; '
                    'report per phase the worst-case displacement and acceleration over the '
                    'sensors, the reductions (without/with) and the best value of '
                    '--best-over per combination of the other keys.')
    common(sweep)
    sweep.add_argument('--grid', action='append', default=[], metavar='KEY=V1,V2,...',
                       help="scene key and values, e.g. 'impactors.0.clearance=1 mil,2 mil' "
                            '(repeatable; commas inside [..] and {..} are kept)')
    sweep.add_argument('--phase', action='append', default=[], metavar='NAME=T0:T1',
                       help='time window (s) to report separately; T1 may be empty (end); '
                            'default run=0: and steady = the trailing window (repeatable)')
    sweep.add_argument('--best-over', metavar='KEY',
                       help='grid key to optimize (default: the first with "clearance")')
    sweep.add_argument('--objective', choices=('acceleration', 'displacement'),
                       default='acceleration', help='what the best value minimizes')

    stab = sub.add_parser(
        'stability', help='stable/unstable map over Kcc, weight and clearance',
        description='From a small seeded perturbation, run each Kcc (and weight, clearance) '
                    'and classify: unstable when the RMS radial amplitude over the last '
                    'window exceeds (1 + growth tol) times that of the previous window. '
                    '--onset finds the linear onset Kcc without impactors by bisection on '
                    'the least-damped eigenvalue.')
    common(stab)
    stab.add_argument('--kcc-key', required=True, metavar='KEY',
                      help='scene key of the cross-coupling, e.g. '
                           'structure.cross_couplings.0.kcc')
    stab.add_argument('--kcc', default='', metavar='V1,V2,...',
                      help="values, e.g. '8500 lb/in,11250 lb/in' (plain numbers: N/m)")
    stab.add_argument('--weight-key', action='append', default=[], metavar='KEY',
                      help='key(s) set to each weight, e.g. impactors.0.mass (repeatable; '
                           'impactors.*.mass: every impactor)')
    stab.add_argument('--weights', default='', metavar='V1,V2,...', help="e.g. '1.5 lb,3 lb'")
    stab.add_argument('--clearance-key', action='append', default=[], metavar='KEY',
                      help='key(s) set to each clearance, e.g. impactors.0.clearance '
                           '(repeatable; impactors.*.clearance: every impactor)')
    stab.add_argument('--clearances', default='', metavar='V1,V2,...',
                      help="e.g. '6.9 mil,1 mil'")
    stab.add_argument('--sensors', default='', metavar='S1,S2',
                      help='sensors of the radial amplitude (default: all)')
    stab.add_argument('--perturbation', default='1 um', metavar='LENGTH',
                      help='initial displacement at the sensors (default 1 um)')
    stab.add_argument('--growth-tol', type=float, default=0.05,
                      help='unstable when R_last/R_previous > 1 + tol (default 0.05)')
    stab.add_argument('--max-amplitude', metavar='LENGTH',
                      help='also unstable above this RMS radial amplitude')
    stab.add_argument('--no-baseline', action='store_true',
                      help='skip the runs without impactors')
    stab.add_argument('--onset', action='store_true',
                      help='also find the linear onset Kcc without impactors')
    stab.add_argument('--onset-bracket', metavar='LO,HI',
                      help='onset bracket (N/m or with units; default: 0 and doubling)')
    stab.add_argument('--verify', action='store_true',
                      help='re-run every verdict with dt halved and with the other method '
                           '(exact <-> newmark) and report whether it changes')

    conv = sub.add_parser(
        'convergence', help='speed/accuracy trade: method x dt x modes against a reference',
        description='Cross the methods, time steps and retained mode counts; measure each '
                    "combination's errors against a tight exact reference (steady amplitude, "
                    'RMS acceleration, isolated impact times, energy residual) and its CPU '
                    'time per simulated second. Table (--csv, --json) and Pareto plot (--plot).')
    common(conv)
    conv.add_argument('--methods', default='exact,newmark,newmark_step_end,direct',
                      metavar='M1,M2', help='methods to cross (default: all four)')
    conv.add_argument('--dts', default='', metavar='DT1,DT2',
                      help="time steps, each dividing the largest, e.g. '100 us,50 us' "
                           '(default: the scene dt x 2, 1, 1/2, 1/4; x 1 to 1/8 when a '
                           "sensor's low-pass would reach Nyquist at twice dt)")
    conv.add_argument('--modes', default='', metavar='N1,N2',
                      help="retained mode counts (default: the scene's and twice it)")
    conv.add_argument('--ref-dt', metavar='S', help='step of the reference (default: smallest/2)')
    conv.add_argument('--ref-modes', type=int, metavar='N',
                      help='modes of the reference (default: the largest of --modes)')
    conv.add_argument('--n-impacts', type=int, default=20,
                      help='isolated reference impacts whose times are compared (default 20)')
    conv.add_argument('--isolation', default='2 ms', metavar='S',
                      help='isolation (and matching) time of impacts (default 2 ms)')

    val = sub.add_parser(
        'validate', help="validation document: the paper's results next to ours",
        description="Run the paper's result studies (Figs. 4.1.2/4.1.3 FRFs, Tables 4.3.1, "
                    '4.3.2 HPOTP sweep, Table 4.4.1 RBS stability, Table 4.4.2 HPOTP onset) '
                    'in parallel and write a markdown document with the paper columns next to '
                    'ours, plots next to it (OUT without .md, e.g. docs/validation/*.png).')
    val.add_argument('--out', metavar='PATH.md',
                     help='markdown file (default docs/validation.md; with --quick, '
                          f'{QUICK_VALIDATION_OUT}, never the full document)')
    val.add_argument('--quick', action='store_true',
                     help='small subset, short runs, no HPOTP runs (well under a minute)')
    val.add_argument('--overwrite', action='store_true',
                     help='replace an existing document and its plots (default: refuse)')
    val.add_argument('--workers', type=int, metavar='N',
                     help='parallel workers (default: CPU count; 1 runs serially in-process)')
    val.add_argument('--seed', type=int, default=0, help='study seed (default 0)')
    val.add_argument('--progress', action=argparse.BooleanOptionalAction, default=None,
                     help='progress bar on stderr (default: when stderr is a terminal)')


def main(argv=None):
    """Run the ``study`` command.

    Parameters
    ----------
    argv : sequence of str, optional
        Arguments without the program name; default ``sys.argv[1:]``.

    Returns
    -------
    int
        Exit status: 0 on success, 1 when every study point failed, 2 for bad input
        (message on stderr), 3 when a run diverged.
    """
    try:
        args = _parser().parse_args(argv)
    except SystemExit as exc:   # argparse has printed usage and the problem
        return exc.code if isinstance(exc.code, int) else EXIT_USAGE
    from ..integrate.divergence import Divergence
    from ..integrate.memory import TooLarge
    from ..scene.schema import SceneError
    try:
        if getattr(args, 'scene', None) is not None:
            _check_scene_file(args.scene)
        _check_plot_format(getattr(args, 'plot', None))
        if args.command == 'keys':
            return _keys(args)
        if args.command == 'modes':
            return _modes(args)
        if args.command == 'campbell':
            from .rotor import run_campbell
            return run_campbell(args)
        if args.command in ('frf', 'sweep', 'stability', 'convergence'):
            from .studies import run_study
            return run_study(args)
        if args.command == 'validate':
            from .studies import run_validate
            return run_validate(args)
        if args.command == 'report':
            from ..studies.report import run_report
            refuse_existing([args.plot, args.csv], args.overwrite)
            return run_report(args)
        if args.command == 'recover':
            from ..recording.cli import run_recover
            return run_recover(args)
        if args.command == 'record':
            from .datasets import run_record
            return run_record(args)
        if args.command == 'dataset':
            from .datasets import run_dataset
            return run_dataset(args)
        return _simulate(args)
    except (SceneError, TooLarge, OutputExists) as exc:
        _error(str(exc))
        return EXIT_USAGE
    except Divergence as exc:
        _error(str(exc))
        return EXIT_DIVERGED
    except BrokenPipeError:   # e.g. `study keys | head`
        sys.stderr.close()
        return 0


#: What Matplotlib's savefig writes (its file-type registry), so that a --plot name is
#: checked before the computation it would follow, without importing Matplotlib.
PLOT_FORMATS = ('avif', 'eps', 'gif', 'jpeg', 'jpg', 'pdf', 'pgf', 'png', 'ps', 'raw', 'rgba',
                'svg', 'svgz', 'tif', 'tiff', 'webp')


def _check_plot_format(path):
    """Refuse a ``--plot`` path whose suffix Matplotlib cannot write (before any work)."""
    import os

    from ..scene.schema import SceneError
    if not path:
        return
    suffix = os.path.splitext(path)[1].lower().lstrip('.')
    if suffix not in PLOT_FORMATS:
        raise SceneError(f"--plot {path}: cannot write a '.{suffix}' plot; use one of "
                         f"{', '.join('.' + f for f in PLOT_FORMATS)}")


def _check_scene_file(scene):
    """Refuse a SCENE path that is not a scene file without echoing its contents.

    A path (with a directory separator or a YAML suffix) must name a ``.yaml``/``.yml``
    file; its size, kind and encoding are the loader's budgets
    (:func:`impact_damper_sim.scene.loading.load_yaml`), which the node shares.
    """
    import os

    from ..scene.schema import SceneError
    if not ('/' in scene or os.sep in scene or scene.endswith(('.yaml', '.yml'))):
        return
    if not os.path.isfile(scene):
        return   # the loader says what it is instead (missing, a directory, a FIFO)
    if not scene.endswith(('.yaml', '.yml')):
        raise SceneError(f'{scene}: not a scene file (a scene is a .yaml or .yml file)')


# --- keys -------------------------------------------------------------------------------------

def _keys(args):
    from ..scene.keytable import describe, markdown_table
    from ..scene.spec import SCHEMA
    if args.markdown:
        sys.stdout.write(markdown_table(SCHEMA))
        return 0
    rows = [(r.key, r.kind, r.default, r.range, r.doc) for r in describe(SCHEMA)]
    print(_table(['key', 'type', 'default', 'range (SI)', 'description'], rows))
    return 0


# --- modes ------------------------------------------------------------------------------------

def _modes(args):
    from ..scene.build import load
    from ..studies.campbell import describe_whirl
    from .rotor import plot_modes, print_whirl
    refuse_existing([args.plot], args.overwrite)
    scene = load(args.scene, args.overrides)
    data = scene.describe_modes()
    data.update(describe_whirl(scene))   # 'coupled' too: gyroscopic coupling included
    if args.plot:
        status = plot_modes(scene, args)
        if status is not None:
            return status
    if args.json:
        _print_json(data)
        return 0
    dofs = data['dofs']
    print(f"scene {data['scene']} ({data['source']})")
    print(f"DOFs: {dofs['total']} total, {dofs['active']} active ({dofs['clamped']} clamped), "
          f"{dofs['after_condensation']} after condensation ({dofs['condensed']} massless "
          'condensed)')
    print(f"retained: {data['selection_reason']}")
    if data['coupled']:
        print('modal matrices are coupled (cross-coupled stiffness, physical dampers or '
              'gyroscopic coupling)')
    print('\nundamped modal basis (modes of the non-rotating structure, symmetric stiffness: '
          "the simulation's coordinates):")
    print(_table(['mode', 'frequency (Hz)', 'tare zeta', 'damping ratio'],
                 [(m['mode'], _g(m['frequency_hz'], 9), _g(m['tare_damping_ratio']),
                   _g(m['damping_ratio'])) for m in data['modes']]))
    if data['shapes']:
        print('\nmode shapes (mass-normalized, 1/sqrt(kg)):')
        header = ['role', 'name', 'node', 'dof'] + [f"mode {m['mode']}" for m in data['modes']]
        print(_table(header, [[s['role'], s['name'], s['node'], s['dof']]
                              + [_g(v) for v in s['values']] for s in data['shapes']]))
    for imp in data['impactors']:
        eff = ', '.join(_g(m, 9) for m in imp['effective_mass_kg'])
        print(f"\nimpactor {imp['name']} ({imp['kind']}): mass {_g(imp['mass_kg'])} kg, "
              f"housing mass {_g(imp['housing_mass_kg'])} kg, effective mass of the retained "
              f'modes {eff} kg')
    print_whirl(data)
    return 0


# --- simulate ---------------------------------------------------------------------------------

def _simulate(args):
    from ..scene.build import load
    from ..scene.schema import SceneError
    overrides = list(args.overrides)
    for key in ('duration', 'method', 'dt', 'window'):
        value = getattr(args, key)
        if value is not None:
            overrides.append(f'simulation.{key}={value}')
    shorthands = [f'--{k}' for k in ('duration', 'method', 'dt', 'window')
                  if getattr(args, k) is not None]
    try:
        scene = load(args.scene, overrides)
    except SceneError as exc:
        if not shorthands:
            raise
        note = f' (given as {", ".join(shorthands)})'
        raise SceneError([e + note if "'simulation" in e else e for e in exc.errors],
                         exc.source) from None
    try:
        result = run(scene)
    except ModuleNotFoundError as exc:
        if not (exc.name or '').startswith('impact_damper_sim'):
            raise
        _error(f"method {scene.scene['simulation']['method']!r} is not available in this "
               f'installation ({exc})')
        return EXIT_USAGE
    if args.json:
        _print_json(result)
    else:
        _print_summary(result)
    return 0


def run(scene):
    """Run a built scene with its ``simulation`` settings and summarize it.

    Parameters
    ----------
    scene : SceneModel
        The scene (``scene.scene['simulation']`` gives method, dt (s), duration (s) and
        window (s)).

    Returns
    -------
    dict
        The ``study simulate --json`` data (see the README). Accelerations are the mean
        acceleration per sample period (impacts included) passed through the sensor's
        ``lowpass`` (4th-order Butterworth, :mod:`impact_damper_sim.live.filters`) if it has one:
        the model's signal. The scene's accelerometer ``channel`` (sensor and DAQ,
        :mod:`impact_damper_sim.live.channel`) is what the node and ``study record`` publish; it
        is not applied here, so design studies and the paper comparisons see the structure.

    Raises
    ------
    SceneError
        A sensor's ``lowpass`` at or above the Nyquist frequency of ``simulation.dt``.
    TooLarge
        Before running, if ``duration / dt`` samples would not fit in memory.
    Divergence
        If the run diverges; its ``setting`` names the scene keys to change.
    """
    from ..integrate.divergence import Divergence
    from ..integrate.events import EVENT_KINDS
    from ..integrate.memory import TooLarge, check_allocation
    from ..live.filters import scene_lowpass
    from ..scene.advice import scene_advice
    from ..scene.model_budget import model_estimate
    from ..scene.schema import SceneError
    from ..studies.analysis import summarize
    cfg = scene.scene['simulation']
    method, dt = cfg['method'], cfg['dt']
    scene_lowpass(scene, dt)   # reject a cutoff at or above Nyquist before running
    try:   # refuse up front what would not fit in memory: the samples with the model
        check_allocation(round(cfg['duration'] / dt), len(scene.model.sensor_names),
                         model_bytes=model_estimate(scene.scene).total)
    except TooLarge as exc:
        raise TooLarge(exc.n_steps, exc.n_bytes, exc.limit,
                       context=f"simulation.dt = {dt:g} s over simulation.duration = "
                               f"{cfg['duration']:g} s", model_bytes=exc.model_bytes,
                       advice='raise simulation.dt (--dt) or shorten simulation.duration '
                              '(--duration)') from None
    try:
        # JIT compilation or cache loading is not simulation time: warm up on one step first
        try:
            warm = scene.make_simulation(method, dt)
        except ValueError as exc:   # e.g. a defective state matrix at an extreme setting
            raise SceneError(f'cannot build the {method} integrator of this scene: {exc}; '
                             f'{scene_advice(scene)}') from None
        warm.advance(1)
        sim = scene.make_simulation(method, dt)
        _, qd = sim.integrator.state()
        v0 = sim.integrator.model.sensors @ qd
        start = time.perf_counter()
        samples = sim.advance_to(cfg['duration'])
        wall = time.perf_counter() - start
    except Divergence as exc:
        raise exc.with_setting(scene_advice(scene, exc)) from None
    events = sim.take_events()
    # accelerations: mean per sample period, through each sensor's low-pass (if it has one)
    acc = scene_lowpass(scene, dt).apply(sim.mean_acceleration(samples, v0))
    summary = summarize(samples, acc, events,
                        sim.sensor_names, sim.impactor_names, sim.energy(),
                        window=cfg['window'], wall_time=wall)
    # the paper's tables give steady-state impact rates: count over the trailing window too
    impact = EVENT_KINDS.index('impact')
    late = events[(events['kind'] == impact) & (events['t'] > sim.t - cfg['window'])]
    for j, name in enumerate(sim.impactor_names):
        count = int((late['impactor'] == j).sum())
        summary['impactors'][name]['steady_impacts_per_second'] = count / cfg['window']
    head = {'scene': scene.name, 'source': scene.source, 'overrides': list(scene.overrides),
            'method': method, 'dt_s': dt, 'window_s': cfg['window'],
            'n_modes': int(scene.basis.n_modes), 'n_samples': int(samples.t.size)}
    return {**head, **summary}


def _print_summary(r):
    print(f"scene {r['scene']} ({r['source']})")
    print(f"method {r['method']}, dt {_g(r['dt_s'])} s, duration {_g(r['duration_s'])} s, "
          f"{r['n_modes']} mode(s); steady state over the last {_g(r['window_s'])} s")
    if r['sensors']:
        print('\naccelerations are mean accelerations per sample period (impacts included), '
              "through the sensor's low-pass where it has one: the model's signal (the scene's "
              "accelerometer channel applies to the node and study record)")
        rows = [(name, _g(s['peak_displacement_m']), _g(s['rms_displacement_m']),
                 _g(s['steady_amplitude_m']), _g(s['peak_acceleration_m_s2']),
                 _g(s['peak_acceleration_g']), _g(s['rms_acceleration_m_s2']),
                 _g(s['rms_acceleration_g']))
                for name, s in r['sensors'].items()]
        print(_table(['sensor', 'peak (m)', 'rms (m)', 'steady amp (m)', 'peak acc (m/s^2)',
                      'peak acc (g)', 'rms acc (m/s^2)', 'rms acc (g)'], rows))
    if r['impactors']:
        print()
        print(_table(['impactor', 'impacts', 'impacts/s', 'steady impacts/s', 'stuck fraction'],
                     [(name, i['impacts'], _g(i['impacts_per_second']),
                       _g(i['steady_impacts_per_second']), _g(i['stuck_fraction']))
                      for name, i in r['impactors'].items()]))
    e = r['energy_J']
    print(f"\nenergy (J): forcing work {_g(e['work_forcing'])}, damping "
          f"{_g(e['dissipated_damping'])}, impacts {_g(e['dissipated_impacts'])}, sticking "
          f"{_g(e['dissipated_sticking'])}, final {_g(e['structure'] + e['impactors'])}")
    print(f"energy balance residual {_g(e['residual'], 3)} J "
          f"(relative {_g(e['relative_residual'], 3)})")
    print(f"wall time {_g(r['wall_time_s'], 3)} s, real-time factor "
          f"{_g(r['real_time_factor'], 3)}")


if __name__ == '__main__':
    sys.exit(main())
