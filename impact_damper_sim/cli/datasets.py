"""``study record`` and ``study dataset``: node logs offline, one or a labelled data set.

::

    study record SCENE --duration S --out F.mcap [--schedule F.yaml] [--seed N]
                 [--noise-std A] [--tick-period T] [--truth] [--fault YAML ...]
                 [--set KEY=VALUE ...] [--overwrite] [--progress] [--json]
    study dataset SPEC.yaml --out DIR [--executor process|serial|dask] [--workers N]
                  [--dask-address ADDR] [--retry-failed] [--progress] [--json]
    study dataset --gather DIR [DIR ...] --out OUT [--json]

``record`` (:mod:`..studies.record`): exit status 0 with a one-line summary on stdout (or
JSON); 2 with one message per problem on stderr for a bad scene, override, duration,
schedule or tick period, an existing ``--out`` without ``--overwrite``, or an ``--out`` that
cannot be created (missing or read-only directory; nothing written); 3 when the simulation
diverged (the log holds everything up to it, and the summary says so); 4
(:data:`..studies.log_errors.EXIT_WRITE_FAILED`) when the log was not written to its end (disk
full, I/O error, file or directory removed): one line on stderr naming the file, the error
and what is on disk, no summary (``--json``: the run so far, ``finished`` false).

``dataset`` (:mod:`..studies.dataset`): exit status 0 when every run is recorded (diverged
runs are labelled, not failed), 1 when some failed (each with its reason in the manifest),
2 for a bad spec or an ``--out`` that cannot be written, 4 when a disk error stopped the data
set (one line on stderr; the run failed in the manifest, ``disk error: ...``), 128 + the
signal number (130, 143, 129) when SIGINT, SIGTERM or SIGHUP stopped it (its workers killed,
one line on stderr). No worker outlives the command, SIGKILL included
(:mod:`..studies.dataset_pool`).
``dataset --gather`` (:func:`..studies.dataset_gather.gather_datasets`): 0 when every
finished run was gathered, 1 when a log did not match its sha256 (or was missing) or two parts
hold the same run with other bytes, 2 for a part without a readable manifest (nothing
written), 4 when a disk error in ``--out`` stopped it (one line). Importing this module is
cheap: the engine is imported when a command runs.
"""
from __future__ import annotations

import argparse

from .._exit_status import EXIT_DIVERGED, EXIT_USAGE
from ..studies.output import fmt as _g
from ..studies.output import print_error as _error
from ..studies.output import print_json as _print_json
from ..studies.output import refuse_existing


def add_record_parser(sub, scene_args):
    """Add the ``record`` subcommand to the ``study`` command's sub-parsers.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The sub-parser collection.
    scene_args : callable
        Adds SCENE, ``--set`` and ``--json`` to a parser.
    """
    p = sub.add_parser(
        'record', help="write the node's log of a scripted run, as fast as the engine goes",
        description="Step a scene without the wall clock and write the MCAP log "
                    'vibration_node would record (same topics, types, CDR bytes, QoS '
                    'metadata and rosbag2 layout; log time = sim time), playing a command '
                    'schedule in sim time. Deterministic: the same scene, overrides, '
                    'schedule, seed and version give the same message bytes. No '
                    '/diagnostics (there is no wall-clock run to report).')
    scene_args(p)
    p.add_argument('--duration', required=True, metavar='S',
                   help="sim time to record (s; units allowed, e.g. '500 ms')")
    p.add_argument('--out', required=True, metavar='F.mcap', help='the log to write')
    p.add_argument('--schedule', metavar='F.yaml',
                   help='command schedule (speed, speed_rate, unbalance, dampers, noise_std, '
                        'noise_seed, fault, clear_fault at sim times; docs/node.md)')
    p.add_argument('--seed', type=int, default=0,
                   help="noise seed, the node's noise_seed (default 0)")
    p.add_argument('--noise-std', default='0', metavar='A',
                   help="accelerometer noise at start (m/s^2; units allowed, e.g. '0.05 g'); "
                        'default 0')
    p.add_argument('--tick-period', default='10 ms', metavar='T',
                   help="sim time stepped per chunk, the node's tick_period (s; units allowed, "
                        "e.g. '100 ms'; 1 ms to 100 ms). The full-rate batch, impact batch, "
                        '/clock and rotor topics are published once per tick, so it sets '
                        'their message size and rate; the per-sample Imu stream keeps its '
                        'messages and times. '
                        "Default 10 ms, the node's default; 100 ms writes HPOTP logs about "
                        '1.5 x faster')
    p.add_argument('--truth', action='store_true',
                   help="also write each accelerometer's ground truth accel/<name>/truth: the "
                        "model's acceleration before the channel (the node's publish_truth)")
    p.add_argument('--fault', action='append', default=[], metavar='YAML',
                   help="a sensor fault from the start, as accel/fault_command takes it, e.g. "
                        "'{kind: dropout, accelerometer: hpotp_casing_bottom, onset: 1 s, "
                        "duration: 50 ms}' (repeat for more; docs/channel.md, Sensor faults)")
    p.add_argument('--overwrite', action='store_true', help='replace --out if it exists')
    p.add_argument('--progress', action=argparse.BooleanOptionalAction, default=None,
                   help='progress line on stderr (default: when stderr is a terminal)')


def run_record(args):
    """Run ``study record``.

    Parameters
    ----------
    args : argparse.Namespace
        ``scene``, ``overrides``, ``json``, ``duration``, ``out``, ``schedule``, ``seed``,
        ``noise_std``, ``tick_period``, ``truth``, ``fault``, ``overwrite``, ``progress``.

    Returns
    -------
    int
        Exit status: 0, 3 when the run diverged, 2 when ``--out`` cannot be created (one
        line naming it; nothing written), 4 when writing failed (one line: the file, the
        error, what is on disk and how to recover it; ``--json`` prints the run so far with
        ``finished`` false and ``write_error``); other bad input raises ``SceneError`` or
        ``OutputExists`` for :func:`.study.main` to report (exit 2).
    """
    from ..scene.schema import SceneError
    from ..scene.units import UnitError, parse_quantity
    from ..studies.log_errors import EXIT_WRITE_FAILED, LogOpenError, LogWriteError
    from ..studies.record import record_log
    from ..studies.tick_period import parse_tick_period
    try:
        duration = parse_quantity(args.duration, 'time', key='--duration')
        noise_std = parse_quantity(args.noise_std, 'acceleration', key='--noise-std')
    except UnitError as exc:
        raise SceneError(str(exc)) from None
    tick_period = parse_tick_period(args.tick_period, '--tick-period')
    if not duration > 0:
        raise SceneError(f'--duration: must be > 0 s, got {args.duration}')
    if not noise_std >= 0:
        raise SceneError(f'--noise-std: must be >= 0 m/s^2, got {args.noise_std}')
    if not 0 <= args.seed <= 2**31 - 1:
        raise SceneError(f'--seed: must be in [0, 2147483647], got {args.seed}')
    refuse_existing([args.out], args.overwrite)
    try:
        result = record_log(args.scene, args.out, duration, schedule=args.schedule,
                            overrides=args.overrides, seed=args.seed, noise_std=noise_std,
                            tick_period=tick_period, overwrite=args.overwrite,
                            progress=args.progress, truth=args.truth,
                            faults=getattr(args, 'fault', None) or None)
    except FileExistsError as exc:   # created between the check and the open
        raise SceneError(str(exc)) from None
    except LogOpenError as exc:   # nothing written: like bad input
        _error(str(exc))
        return EXIT_USAGE
    except LogWriteError as exc:   # no summary of a run whose log is not (all) there
        if args.json and exc.result is not None:
            _print_json(dict(exc.result))
        _error(str(exc))
        return EXIT_WRITE_FAILED
    if args.json:
        _print_json(dict(result))
    else:
        stuck = result['stuck_fraction']
        print(f"{result['path']}: {_g(result['sim_time_s'])} s of sim time in "
              f"{result['wall_s']:.2f} s ({result['real_time_factor']:.1f} x real time), "
              f"{result['messages']} messages, {result['bytes'] / 1e6:.2f} MB; "
              f"{result['commands']} schedule commands; {result['impacts_per_s']:.1f} "
              f"impacts/s, stuck {'-' if stuck is None else f'{100 * stuck:.1f} %'}, "
              f"peak {_g(result['peak_g'])} g, RMS {_g(result['rms_g'])} g")
    if result['diverged']:
        _error(f"the simulation stopped at {_g(result['sim_time_s'])} s: {result['failure']}"
               f" (the log holds everything before)")
        return EXIT_DIVERGED
    return 0


def add_dataset_parser(sub):
    """Add the ``dataset`` subcommand to the ``study`` command's sub-parsers.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The sub-parser collection.
    """
    p = sub.add_parser(
        'dataset', help='a labelled data set of node logs: a grid or a seeded sample of runs',
        usage='%(prog)s SPEC.yaml --out DIR [--executor process|serial|dask] [--workers N]\n'
              '                     [--dask-address ADDR] [--retry-failed] [--progress] [--json]\n'
              '       %(prog)s --gather DIR [DIR ...] --out OUT [--json]',
        description='Record one node log per run of a spec (a grid or a seeded random sample '
                    'over scene keys, command schedules and noise seeds) on a process pool or '
                    'a Dask cluster, and write DIR/manifest.json and DIR/manifest.csv (run id, '
                    'every parameter, impacts/s, stuck fraction, peak and RMS g, diverged, '
                    'file and sha256; a failed run with its reason). Resumable: runs whose '
                    'inputs and file are unchanged are skipped. With --gather, merge data '
                    'sets recorded part by part (one per machine) into OUT instead: every '
                    'finished log copied after checking its sha256, one manifest.')
    p.add_argument('spec', metavar='SPEC.yaml', nargs='?',
                   help='the data set spec (docs/study.md); not with --gather')
    p.add_argument('--out', required=True, metavar='DIR',
                   help='data set directory (logs in DIR/runs; shared by every worker); with '
                        '--gather, the merged data set')
    p.add_argument('--gather', nargs='+', metavar='DIR',
                   help='merge these data set directories (each with its manifest.json) into '
                        '--out: logs copied, not moved, each checked against its sha256; runs '
                        'already in --out are not copied again')
    p.add_argument('--executor', choices=('process', 'serial', 'dask'),
                   help='where runs go (default process)')
    p.add_argument('--workers', type=int, metavar='N',
                   help='worker processes or local Dask workers (default: CPU count)')
    p.add_argument('--dask-address', metavar='ADDR',
                   help='Dask scheduler, e.g. tcp://host:8786 (default: a local cluster)')
    p.add_argument('--retry-failed', action='store_true',
                   help='run again the runs the manifest records as failed')
    p.add_argument('--progress', action=argparse.BooleanOptionalAction, default=None,
                   help='progress line on stderr (default: when stderr is a terminal)')
    p.add_argument('--json', action='store_true', help='print the summary as JSON')


def run_dataset(args):
    """Run ``study dataset``; return the exit status: 0 all recorded, 1 some failed, 2 for
    a bad spec or an ``--out`` that cannot be written (nothing started), 4 stopped by a
    disk error (one line: the run and the error, what the manifest lists, what to do), 128
    + the signal for SIGINT, SIGTERM, SIGHUP (one line: what the manifest lists).

    Parameters
    ----------
    args : argparse.Namespace
        ``spec``, ``out``, ``executor``, ``workers``, ``dask_address``, ``retry_failed``,
        ``progress``, ``json``.
    """
    from ..scene.schema import SceneError
    from ..studies.dataset import run_dataset as run
    from ..studies.dataset_pool import Interrupted
    from ..studies.log_errors import EXIT_WRITE_FAILED, LogOpenError
    if args.gather is not None:
        return run_gather(args)
    if args.spec is None:
        raise SceneError('dataset: give SPEC.yaml, or --gather DIR [DIR ...]')
    try:
        result = run(args.spec, args.out, executor=args.executor or 'process',
                     workers=args.workers,
                     dask_address=args.dask_address, retry_failed=args.retry_failed,
                     progress=args.progress)
    except ValueError as exc:   # a bad executor option (SceneError is reported by main)
        if isinstance(exc, SceneError):
            raise
        raise SceneError(str(exc)) from None
    except LogOpenError as exc:   # --out not writable: nothing started
        _error(str(exc))
        return EXIT_USAGE
    except Interrupted as exc:   # workers stopped, manifest saved: say what is kept
        _error(str(exc))
        return exc.exit_status
    if args.json:
        _print_json({k: v for k, v in result.items() if k != 'rows'})
    if result['stopped']:   # one line: the disk error, what is kept, what to do
        _error(result['stopped'])
        return EXIT_WRITE_FAILED
    if not args.json:
        print(f"{result['planned']} runs planned: {result['skipped']} already done, "
              f"{result['recorded']} recorded now, {result['failed']} failed; "
              f"manifest {result['manifest']}")
    for row in result['rows']:
        if row['status'] != 'ok':
            _error(f"run {row['id']} ({', '.join(row['overrides']) or 'no overrides'}): "
                   f"{row['error']}")
    return 1 if result['failed'] else 0


def run_gather(args):
    """Run ``study dataset --gather``; return the exit status (0 all gathered, 1 a log that
    did not match its sha256 or a conflict, 4 stopped by a disk error in ``--out``, one
    line); a part without a readable manifest raises ``SceneError`` (exit 2, nothing
    written).

    Parameters
    ----------
    args : argparse.Namespace
        ``gather``, ``out``, ``json``; ``spec``, ``executor``, ``workers``, ``dask_address``,
        ``retry_failed`` and ``progress`` must be unset.
    """
    from ..scene.schema import SceneError
    from ..studies.dataset_gather import gather_datasets
    given = [name for name, value in (
        ('SPEC.yaml', args.spec), ('--executor', args.executor), ('--workers', args.workers),
        ('--dask-address', args.dask_address), ('--retry-failed', args.retry_failed or None),
        ('--progress', args.progress)) if value is not None]
    if given:
        raise SceneError(f"dataset --gather: {', '.join(given)} cannot be given with --gather "
                         '(it records nothing; run `study dataset SPEC.yaml --out OUT` after '
                         'it to record what is missing)')
    from ..studies.log_errors import EXIT_WRITE_FAILED, LogWriteError
    try:
        result = gather_datasets(args.gather, args.out)
    except LogWriteError as exc:   # a disk error in --out: stopped, what is kept
        _error(f'dataset --gather stopped by a disk error: {exc}; the logs copied before '
               f'are kept in {args.out}/runs (checked against their sha256): free space and '
               'run the same command again to go on from them')
        return EXIT_WRITE_FAILED
    except OSError as exc:   # --out not writable, say
        raise SceneError(f'dataset --gather: {exc}') from None
    if args.json:
        _print_json({k: v for k, v in result.items() if k != 'runs'})
    else:
        print(f"{result['ok'] + result['failed']} runs gathered from {len(args.gather)} "
              f"directories: {result['copied']} copied, {result['already_there']} already "
              f"there, {len(result['conflicts'])} conflicts, {len(result['bad'])} bad logs "
              f"skipped, {result['failed']} failed; manifest {result['manifest']}")
    for bad in result['bad']:
        _error(f"run {bad['id']} in {bad['dir']}: {bad['reason']}; skipped")
    for c in result['conflicts']:
        _error(f"run {c['id']}: {c['kept']} and {c['other']} hold different logs (sha256); "
               f"kept the one from {c['kept']}")
    return 1 if result['bad'] or result['conflicts'] else 0


__all__ = ['add_dataset_parser', 'add_record_parser', 'run_dataset', 'run_gather',
           'run_record']
