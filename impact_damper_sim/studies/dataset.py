"""``study dataset``: many labelled node logs from one spec, on a process pool or a Dask cluster.

::

    study dataset SPEC.yaml --out DIR [--executor process|serial|dask] [--workers N]
                  [--dask-address ADDR] [--retry-failed] [--progress | --no-progress] [--json]

A spec names a scene, a duration and either a grid or a seeded random sample over scene keys,
command schedules and noise seeds (units allowed wherever a scene takes them)::

    scene: hpotp
    duration: 2 s
    noise_std: 0.05 g            # optional, at start (m/s^2 or units)
    tick_period: 100 ms          # optional, the node's tick_period: 1 ms to 100 ms,
                                 # default 10 ms
    truth: true                  # optional, write each accelerometer's ground truth
                                 # (study record --truth); default false
    faults:                      # optional, sensor faults of every run (from sim time 0
                                 # unless onset; keys: docs/channel.md, "Sensor faults")
      - {kind: gain, accelerometer: hpotp_casing_bottom, gain: 20, onset: 1 s,
         duration: 0.5 s}
    overrides: [rotor.multiplier=2]   # optional, every run
    grid:                        # every combination ...
      impactors.0.clearance: [2 mil, 3 mil]
      impactors.0.cor: [0.5, 0.7]
    schedules: [ramp.yaml, dampers_off.yaml]   # ... with each schedule (paths: from the spec)
    seeds: [0, 1]                # ... and each noise seed

    # or, instead of grid/schedules/seeds:
    sample:
      n: 50
      seed: 7                    # the sample's own seed: the same spec draws the same runs
      keys:
        impactors.0.clearance: {low: 1.5, high: 4, unit: mil}   # uniform
        impactors.0.cor: [0.5, 0.6, 0.7]                        # one of
      schedules: [ramp.yaml, dampers_off.yaml]                  # one of (optional)

Each run is one ``study record`` (:func:`.record.record_log`) into ``DIR/runs/<id>.mcap``;
its id is a digest of everything that decides its bytes (scene, overrides, schedule text,
seed, noise, duration, tick period, ground truth when on, faults when given, software
version), so a run whose inputs are unchanged keeps its id.
``DIR/manifest.json`` and ``DIR/manifest.csv`` list every run: id, every parameter (the
spec's ``faults`` in SI), the summary labels (the accelerometer channel preset, impacts per
second, stuck fraction, peak and RMS acceleration in g, diverged or not, the sim time reached,
``fault_labels``: every sensor fault of the run, the spec's and its schedule's, with its
actual window), the file, its size and its sha256, and for a failed run its one-line
reason. Each log's metadata holds the run's full
labels (``labels``: every channel stage's values, unbalance, Kcc, dampers, seed). The
manifest is rewritten after every finished run, so a data set that is interrupted continues
where it stopped: a run already in the manifest whose file is there
with its recorded sha256 is skipped (a failed run too, unless ``--retry-failed``). A failing
run does not stop the others; a disk error does (a full disk fails every later run too): the
run is listed as failed, ``disk error: ...``, and recorded again by the next run of the
command, with the runs not started. Runs are written to ``<id>.mcap.part`` and renamed when
complete, so no half-written log carries a run's name; the ``.part`` of a run a disk error
or a signal stopped is removed. No worker outlives the command (:mod:`.dataset_pool`).

On a multi-machine Dask cluster every worker writes to ``DIR`` itself: give a directory that
all workers see at the same path (a shared file system), see docs/study.md. Without one, run
the parts on their machines and merge them with
:func:`.dataset_gather.gather_datasets` (``study dataset --gather DIR [DIR ...] --out OUT``).
"""
from __future__ import annotations

import contextlib
import csv
import hashlib
import io
import itertools
import json
import math
import os
import sys
import time

from ..scene.schema import SceneError

#: label columns of the manifest, from :func:`.record.record_log`'s result
LABELS = ('channel_preset', 'impacts_per_s', 'stuck_fraction', 'peak_g', 'rms_g', 'diverged',
          'failure', 'sim_time_s', 'wall_s', 'real_time_factor', 'messages', 'fault_labels')
SPEC_KEYS = ('scene', 'duration', 'noise_std', 'tick_period', 'truth', 'faults', 'overrides',
             'grid', 'schedules', 'seeds', 'sample')


#: How a manifest's ``error`` of a run failed by a disk error starts; such a run is recorded
#: again by the next ``study dataset`` without ``--retry-failed`` (the disk failed, not the run)
DISK_ERROR = 'disk error: '


class DatasetError(SceneError):
    """A data set spec is invalid; one line per problem, each naming its key."""

    def __init__(self, errors, source=None):
        super().__init__(errors, source)
        if source is not None and len(self.errors) > 1:
            self.args = ('\n'.join([f'invalid data set spec {source} ({len(self.errors)} '
                                    'errors):', *self.errors]),)


def _value_text(value):
    """A spec value as the text of a ``key=value`` override."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, float):
        return repr(value)
    return str(value)


def _file_sha256(path, block=1 << 20):
    digest = hashlib.sha256()
    with open(path, 'rb') as f:
        for chunk in iter(lambda: f.read(block), b''):
            digest.update(chunk)
    return digest.hexdigest()


def load_spec(path):
    """Read and check a data set spec; return the plan of its runs.

    Parameters
    ----------
    path : str or os.PathLike
        The spec (YAML).

    Returns
    -------
    list of dict
        One per run, in spec order: ``id``, ``scene``, ``overrides`` (the fixed ones, then
        the run's), ``keys`` (the run's own scene keys and values, as written), ``schedule``
        (absolute path or None), ``seed``, ``noise_std`` (m/s^2), ``duration`` (s),
        ``tick_period`` (s), ``truth`` (bool), ``faults`` (the sensor faults of every run,
        plain SI mappings; empty when none) and ``inputs_sha256`` (the digest of the inputs
        the id is made of).

    Raises
    ------
    DatasetError
        Every problem of the spec, each naming its key; a missing schedule file.
    """
    import pathlib

    import numpy as np

    import impact_damper_sim

    from ..recording.node_topics import TICK_PERIOD
    from ..scene.loading import load_yaml
    from ..scene.units import UnitError, parse_quantity
    from .tick_period import parse_tick_period
    path = os.fspath(path)
    raw = load_yaml(pathlib.Path(path), source=path)
    base = os.path.dirname(os.path.abspath(path))
    errors = []
    for key in raw:
        if key not in SPEC_KEYS:
            errors.append(f"key '{key}': unknown; expected one of {', '.join(SPEC_KEYS)}")

    def quantity(key, dimension, default=None, low=0.0, positive=False):
        value = raw.get(key, default)
        if value is None:
            errors.append(f"key '{key}': missing; expected a {dimension}")
            return None
        try:
            si = parse_quantity(value, dimension, key=key)
        except UnitError as exc:
            errors.append(f"key '{key}': {exc}")
            return None
        if si < low or (positive and si <= 0):
            errors.append(f"key '{key}': {value} must be {'>' if positive else '>='} {low:g}")
            return None
        return si

    def text_list(key, value):
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            errors.append(f"key '{key}': expected a list of strings, got {value!r}")
            return []
        return list(value)

    def schedule_files(key, value):
        files = []
        for i, name in enumerate(text_list(key, value)):
            full = os.path.join(base, name)
            if not os.path.isfile(full):
                errors.append(f"key '{key}[{i}]': schedule file {full} does not exist")
            files.append(full)
        return files

    scene = raw.get('scene')
    if not isinstance(scene, str) or not scene:
        errors.append("key 'scene': expected a scene name or file")
    elif scene.endswith(('.yaml', '.yml')) and not os.path.isabs(scene):
        scene = os.path.join(base, scene)   # a scene file next to the spec
    duration = quantity('duration', 'time', positive=True)
    noise_std = quantity('noise_std', 'acceleration', default=0.0)
    tick_period = None
    try:
        tick_period = parse_tick_period(raw.get('tick_period', TICK_PERIOD), "key 'tick_period'")
    except SceneError as exc:
        errors.append(str(exc))
    truth = raw.get('truth', False)
    if not isinstance(truth, bool):
        errors.append(f"key 'truth': expected true or false, got {truth!r}")
        truth = False
    faults = []
    if raw.get('faults') is not None:   # the accelerometers are checked when a run starts
        from ..live.fault_spec import parse_faults
        try:
            faults = [{k: v for k, v in spec.as_dict().items() if v is not None}
                      for spec in parse_faults(raw['faults'])]
        except SceneError as exc:
            errors += list(exc.errors)
    fixed = text_list('overrides', raw.get('overrides', []))
    runs = []   # (keys dict, schedule, seed)
    if 'sample' in raw:
        if any(k in raw for k in ('grid', 'schedules', 'seeds')):
            errors.append("key 'sample': give either sample or grid/schedules/seeds")
        sample = raw['sample'] if isinstance(raw['sample'], dict) else {}
        if not isinstance(raw['sample'], dict):
            errors.append("key 'sample': expected a mapping with n, seed, keys")
        n, seed = sample.get('n'), sample.get('seed', 0)
        if not (isinstance(n, int) and not isinstance(n, bool) and 1 <= n <= 1_000_000):
            errors.append(f"key 'sample.n': expected an integer in [1, 1000000], got {n!r}")
            n = 0
        if not (isinstance(seed, int) and not isinstance(seed, bool) and seed >= 0):
            errors.append(f"key 'sample.seed': expected an integer >= 0, got {seed!r}")
            seed = 0
        keys = sample.get('keys', {})
        if not isinstance(keys, dict) or not keys:
            errors.append("key 'sample.keys': expected a mapping of scene keys to ranges or "
                          'lists')
            keys = {}
        draws = {}
        for key, spec in keys.items():
            where = f"key 'sample.keys.{key}'"
            if isinstance(spec, list) and spec:
                draws[key] = ('choice', spec)
            elif isinstance(spec, dict) and set(spec) <= {'low', 'high', 'unit'} and all(
                    isinstance(spec.get(b), (int, float)) and not isinstance(spec.get(b), bool)
                    and math.isfinite(spec.get(b)) for b in ('low', 'high')) \
                    and spec['low'] <= spec['high']:
                draws[key] = ('uniform', spec)
            else:
                errors.append(f'{where}: expected a non-empty list, or {{low, high, unit}} '
                              f'with finite low <= high, got {spec!r}')
        schedules = schedule_files('sample.schedules', sample.get('schedules', []))
        rng = np.random.default_rng(seed)
        for _ in range(n):
            values = {}
            for key, (kind, spec) in draws.items():
                if kind == 'choice':
                    values[key] = spec[int(rng.integers(len(spec)))]
                else:
                    x = float(spec['low'] + (spec['high'] - spec['low']) * rng.random())
                    values[key] = f"{x!r} {spec['unit']}" if spec.get('unit') else x
            chosen = schedules[int(rng.integers(len(schedules)))] if schedules else None
            runs.append((values, chosen, int(rng.integers(2**31 - 1))))
    else:
        grid = raw.get('grid', {})
        if not isinstance(grid, dict) or not all(
                isinstance(v, list) and v and all(isinstance(x, (str, int, float, bool))
                                                  for x in v) for v in grid.values()):
            errors.append("key 'grid': expected a mapping of scene keys to non-empty lists of "
                          f'values, got {grid!r}')
            grid = {}
        schedules = schedule_files('schedules', raw.get('schedules', [])) or [None]
        seeds = raw.get('seeds', [0])
        if not (isinstance(seeds, list) and seeds and all(
                isinstance(s, int) and not isinstance(s, bool) and 0 <= s <= 2**31 - 1
                for s in seeds)):
            errors.append(f"key 'seeds': expected a list of integers in [0, 2147483647], "
                          f'got {seeds!r}')
            seeds = [0]
        for combo in itertools.product(*grid.values()):
            for schedule in schedules:
                for seed in seeds:
                    runs.append((dict(zip(grid, combo)), schedule, seed))
    if errors:
        raise DatasetError(errors, source=path)
    version = impact_damper_sim.__version__
    plan = []
    for keys, schedule, seed in runs:
        overrides = fixed + [f'{k}={_value_text(v)}' for k, v in keys.items()]
        schedule_sha = _file_sha256(schedule) if schedule else None
        inputs = {'scene': scene, 'scene_sha256': (_file_sha256(scene) if os.path.isfile(scene)
                                                   else None),
                  'overrides': overrides, 'schedule_sha256': schedule_sha, 'seed': seed,
                  'noise_std': noise_std, 'duration': duration, 'tick_period': tick_period,
                  'software_version': version}
        if truth:   # only when on: the ids of runs without it stay what they were
            inputs['truth'] = True
        if faults:   # likewise
            inputs['faults'] = faults
        digest = hashlib.sha256(json.dumps(inputs, sort_keys=True).encode()).hexdigest()
        plan.append({'id': 'r' + digest[:12], 'scene': scene, 'overrides': overrides,
                     'keys': keys, 'schedule': schedule, 'seed': seed, 'noise_std': noise_std,
                     'duration': duration, 'tick_period': tick_period, 'truth': truth,
                     'faults': faults, 'inputs_sha256': digest})
    ids = [run['id'] for run in plan]
    if len(set(ids)) != len(ids):
        dup = sorted({i for i in ids if ids.count(i) > 1})
        raise DatasetError(f'runs {", ".join(dup)} have the same inputs twice (a repeated '
                           'grid value?)', source=path)
    return plan


def record_run(run, out_dir):
    """Record one run of a plan (a top-level function: it runs on a worker).

    Parameters
    ----------
    run : dict
        One entry of :func:`load_spec`'s plan.
    out_dir : str
        The data set directory (``runs/`` is inside it).

    Returns
    -------
    dict
        The run's manifest row: ``status`` ``'ok'`` with the labels, file, size and sha256,
        or ``'failed'`` with ``error``, the one-line reason. A disk error (the log could not
        be created or written to its end: ENOSPC, EIO, a read-only or vanished directory)
        starts ``error`` with :data:`DISK_ERROR` and sets ``disk_error`` True (taken out by
        :func:`run_dataset`, which stops the data set); the unfinished log is removed (the
        run is recorded again by the next ``study dataset``).
    """
    from .log_errors import LogWriteError, error_reason
    from .record import record_log
    row = {'id': run['id'], 'status': 'failed', 'error': None}
    final = os.path.join(out_dir, 'runs', run['id'] + '.mcap')
    part = final + '.part'
    try:
        result = record_log(run['scene'], part, run['duration'], schedule=run['schedule'],
                            overrides=run['overrides'], seed=run['seed'],
                            noise_std=run['noise_std'], tick_period=run['tick_period'],
                            overwrite=True, progress=False, truth=bool(run.get('truth')),
                            faults=run.get('faults') or None)
        os.replace(part, final)
        size, digest = os.path.getsize(final), _file_sha256(final)
    except OSError as exc:   # the disk's failure, not the run's: the data set stops
        if isinstance(exc, LogWriteError):
            what = f'{exc.path}: {exc.reason}'
        else:   # LogOpenError names its file; the rename or the checksum may not
            reason = error_reason(exc)
            what = reason if part in reason or final in reason else f'{part}: {reason}'
        try:
            if os.path.lexists(part):
                os.remove(part)
                what += '; its unfinished log was removed'
        except OSError as removing:
            what += f'; its unfinished log is left ({error_reason(removing)})'
        row.update(error=f'{DISK_ERROR}{what}'[:500], disk_error=True)
        return row
    except Exception as exc:   # any other failure is this run's, never the data set's
        lines = str(exc).strip().splitlines()
        row['error'] = f'{type(exc).__name__}: ' + ('; '.join(lines)[:500] if lines else '')
        with contextlib.suppress(OSError):
            os.remove(part)
        return row
    row.update({k: result[k] for k in LABELS})
    row.update(status='ok', file=os.path.relpath(final, out_dir), bytes=size, sha256=digest)
    return row


#: a run's inputs in the manifest: (column, key of a :func:`load_spec` plan entry); the
#: grid or sample keys follow them, then the labels and the file. One table for writing the
#: manifest and for reading it back (:mod:`.dataset_gather`)
RUN_COLUMNS = (('id', 'id'), ('scene', 'scene'), ('duration_s', 'duration'),
               ('tick_period_s', 'tick_period'), ('noise_std', 'noise_std'), ('seed', 'seed'),
               ('schedule', 'schedule'), ('truth', 'truth'), ('faults', 'faults'),
               ('overrides', 'overrides'), ('inputs_sha256', 'inputs_sha256'))
#: the outcome columns of a run (the rest of a manifest row)
RESULT_COLUMNS = ('status', 'error', *LABELS, 'file', 'bytes', 'sha256')


def _columns(plan):
    """The CSV's columns: the inputs (the overrides stay in the JSON), the run's keys, the
    outcome, the inputs' digest last."""
    keys = []
    for run in plan:
        keys += [k for k in run['keys'] if k not in keys]
    inputs = [c for c, _ in RUN_COLUMNS if c not in ('id', 'overrides', 'inputs_sha256')]
    return (['id', 'status', 'error'] + inputs + keys + list(LABELS)
            + ['file', 'bytes', 'sha256', 'inputs_sha256'])


def _manifest_rows(plan, rows):
    out = []
    for run in plan:
        row = rows.get(run['id'])
        if row is None:
            continue
        out.append({**{column: run[key] for column, key in RUN_COLUMNS}, **run['keys'],
                    **row})
    return out


def _write_atomic(path, text):
    """Write ``path`` whole or not at all (on disk before it replaces the old one)."""
    tmp = path + '.tmp'
    try:
        with open(tmp, 'w', encoding='utf-8', newline='') as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:   # a full disk, say: no half-written .tmp left behind
        with contextlib.suppress(OSError):
            os.remove(tmp)
        raise


def write_manifest(out_dir, plan, rows, spec_path, gathered_from=None):
    """Write ``manifest.json`` and ``manifest.csv`` of the runs finished so far (atomic).

    ``spec_path`` may be None (a gathered data set whose parts name different specs);
    ``gathered_from``, the part directories of :func:`gather_datasets`, is written to the JSON.
    """
    import impact_damper_sim

    from .output import strict_json
    entries = _manifest_rows(plan, rows)
    doc = {'spec': None if spec_path is None else os.path.abspath(spec_path),
           'software_version': impact_damper_sim.__version__,
           'runs_planned': len(plan)}
    if gathered_from is not None:
        doc['gathered_from'] = list(gathered_from)
    doc['runs'] = entries
    _write_atomic(os.path.join(out_dir, 'manifest.json'),
                  json.dumps(strict_json(doc), indent=1) + '\n')
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=_columns(plan), extrasaction='ignore')
    writer.writeheader()
    for entry in entries:
        writer.writerow({k: _csv_text(k, v) for k, v in entry.items()})
    _write_atomic(os.path.join(out_dir, 'manifest.csv'), buf.getvalue())


def _csv_text(column, value):
    """A manifest value as its CSV cell: '' for None; the spec's faults as JSON; the fault
    labels as ``name kind accelerometer (onset_s, end_s]`` per fault, joined by ``; `` (the
    JSON holds every value and event)."""
    if value is None:
        return ''
    if column == 'fault_labels' and isinstance(value, list):
        return '; '.join(f"{f['name']} {f['kind']} {f['accelerometer']} ({f['onset_s']:g}, "
                         + ('end' if f['end_s'] is None else format(f['end_s'], 'g')) + ']'
                         for f in value)
    if isinstance(value, (list, dict)):
        return json.dumps(value, separators=(', ', ': '))
    return value


def _finished(out_dir, plan, retry_failed):
    """Rows of the manifest in ``out_dir`` that stand: their inputs and file unchanged."""
    path = os.path.join(out_dir, 'manifest.json')
    if not os.path.exists(path):
        return {}
    try:
        with open(path, encoding='utf-8') as f:
            old = {r['id']: r for r in json.load(f).get('runs', [])}
    except (OSError, ValueError, AttributeError, KeyError, TypeError):
        return {}   # unreadable: every run again
    keep = {}
    for run in plan:
        row = old.get(run['id'])
        if row is None or row.get('inputs_sha256') != run['inputs_sha256']:
            continue
        if row.get('status') == 'ok':
            file = os.path.join(out_dir, row.get('file') or '')
            if os.path.isfile(file) and _file_sha256(file) == row.get('sha256'):
                keep[run['id']] = {k: v for k, v in row.items()
                                   if k in ('id', 'status', 'error', 'file', 'bytes', 'sha256',
                                            *LABELS)}
        elif row.get('status') == 'failed' and not retry_failed \
                and not str(row.get('error') or '').startswith(DISK_ERROR):
            # a run the disk failed is recorded again: it was not the run's failure
            keep[run['id']] = {'id': run['id'], 'status': 'failed', 'error': row.get('error')}
    return keep


class DatasetProgress:
    """``dataset 12/40 runs (1 failed, 5 skipped)  0.42 runs/s  ~67 s left`` on one line."""

    def __init__(self, total, skipped, stream=None, enabled=None):
        self.total, self.skipped = total, skipped
        self.stream = sys.stderr if stream is None else stream
        if enabled is None:
            enabled = bool(getattr(self.stream, 'isatty', lambda: False)())
        self.enabled = enabled
        self.done = self.failed = 0
        self.start = time.perf_counter()

    def update(self, ok):
        self.done += 1
        self.failed += 0 if ok else 1
        if not self.enabled:
            return
        wall = time.perf_counter() - self.start
        rate = self.done / wall if wall > 0 else 0.0
        todo = self.total - self.skipped - self.done
        left = f'~{todo / rate:.0f} s left' if rate > 0 else ''
        failed = f', {self.failed} failed' if self.failed else ''
        skipped = f', {self.skipped} skipped' if self.skipped else ''
        self.stream.write(f'\rdataset {self.skipped + self.done}/{self.total} runs{failed}'
                          f'{skipped}  {rate:.2f} runs/s  {left} ')
        if todo == 0:
            self.stream.write('\n')
        self.stream.flush()


def run_dataset(spec_path, out_dir, *, executor='process', workers=None, dask_address=None,
                retry_failed=False, progress=None):
    """Record every run of a spec that is not finished yet, and write the manifest.

    A run that fails on its own (a bad override, a worker that died) is listed with its
    reason and the others go on. A disk error (a run's log or the manifest not written:
    ENOSPC, EIO, a read-only or vanished directory) stops the data set, as it would fail
    every later run too: no new run starts, the runs in progress finish, the failed run is
    listed with ``error`` starting :data:`DISK_ERROR` (its unfinished log removed) and
    ``stopped`` says why. SIGINT, SIGTERM, SIGHUP stop the workers at once (their logs
    removed) and raise :class:`.dataset_pool.Interrupted`; SIGKILL takes them with it. The
    manifest lists every run finished before; the same command records the rest.

    Parameters
    ----------
    spec_path : str
        The spec (YAML).
    out_dir : str
        The data set directory (made if missing; shared by every worker).
    executor : {'process', 'serial', 'dask'}
        Where runs go (see :mod:`.runner`; ``process`` here is :func:`.dataset_pool.
        process_pool`, whose workers end with this process).
    workers : int, optional
        Worker processes (or local Dask workers).
    dask_address : str, optional
        A running Dask scheduler (``tcp://host:8786``).
    retry_failed : bool
        Run again the runs the manifest records as failed (runs failed by a disk error
        always run again).
    progress : bool, optional
        Progress line on stderr; default when stderr is a terminal.

    Returns
    -------
    dict
        ``planned``, ``skipped``, ``recorded`` (runs finished now, ok or failed), ``failed``,
        ``not_started`` (run counts), ``manifest`` (path), ``stopped`` (None, or the
        one-line reason the data set stopped early) and ``rows`` (every manifest row, in plan
        order).

    Raises
    ------
    DatasetError
        A bad spec.
    SceneError
        The ROS message definitions are not found (nothing started).
    LogOpenError
        ``out_dir`` or its manifest cannot be written (an ``OSError``; nothing started).
    Interrupted
        SIGINT, SIGTERM or SIGHUP (a ``BaseException``); its ``detail`` says what the
        manifest holds.
    """
    from .dataset_pool import catch_signals, run_all
    from .log_errors import check_definitions, open_error
    plan = load_spec(spec_path)
    manifest = os.path.join(out_dir, 'manifest.json')
    check_definitions(os.path.join(out_dir, 'runs'))
    rows = _finished(out_dir, plan, retry_failed)
    todo = [run for run in plan if run['id'] not in rows]
    try:
        os.makedirs(os.path.join(out_dir, 'runs'), exist_ok=True)
        write_manifest(out_dir, plan, rows, spec_path)
    except OSError as exc:   # a read-only or full directory: nothing started
        raise open_error(exc, manifest if os.path.isdir(os.path.join(out_dir, 'runs'))
                         else os.path.join(out_dir, 'runs')) from None
    bar = DatasetProgress(len(plan), len(rows), enabled=progress)
    state = _DatasetState(out_dir, plan, rows, spec_path, bar)
    if todo:
        with catch_signals():
            run_all(record_run, os.path.abspath(out_dir), todo, state, executor=executor,
                    workers=workers, dask_address=dask_address)
    entries = _manifest_rows(plan, rows)
    stopped = None
    if state.stopped is not None:
        where = (f"run {state.stopped['id']}: {state.stopped['error'][len(DISK_ERROR):]}"
                 if 'id' in state.stopped else state.stopped['error'])
        kept = (f'{manifest} lists the {len(entries)} runs finished' if state.saved
                else f'{manifest} could not be updated ({state.manifest_error}); it lists '
                     'the runs finished before')
        stopped = (f'data set stopped by a disk error in {where}; {kept}; '
                   f'{state.not_started} of {len(plan)} runs not started: free space (or fix '
                   'the disk) and run the same command again to record the rest')
    return {'planned': len(plan), 'skipped': len(plan) - len(todo),
            'recorded': state.finished, 'not_started': state.not_started,
            'failed': sum(r['status'] != 'ok' for r in entries), 'stopped': stopped,
            'manifest': manifest, 'rows': entries}


class _DatasetState:
    """The rows of a data set as runs finish (the manifest rewritten after each), and what
    stopped it; :func:`.dataset_pool.run_all` reports to it."""

    def __init__(self, out_dir, plan, rows, spec_path, bar):
        self.out_dir, self.plan, self.rows, self.spec_path, self.bar = (out_dir, plan, rows,
                                                                         spec_path, bar)
        self.finished = self.not_started = 0
        self.stopped = None          # the row (or {'error': ...}) that stopped the data set
        self.saved = True            # the last manifest write succeeded
        self.manifest_error = None

    def add(self, run, row):
        disk = row.pop('disk_error', False)
        self.rows[run['id']] = row
        self.finished += 1
        self.save()
        self.bar.update(row['status'] == 'ok')
        if disk and self.stopped is None:
            self.stopped = row

    def save(self):
        from .log_errors import error_reason
        try:
            write_manifest(self.out_dir, self.plan, self.rows, self.spec_path)
            self.saved = True
        except OSError as exc:   # the data set cannot be listed: stop it
            self.saved = False
            self.manifest_error = error_reason(exc)
            if self.stopped is None:
                self.stopped = {'error': f"writing {os.path.join(self.out_dir, 'manifest.json')}"
                                         f': {self.manifest_error}'}

    def discard(self, run):
        """Remove the unfinished log of a run stopped by a signal (recorded again later)."""
        with contextlib.suppress(OSError):
            os.remove(os.path.join(self.out_dir, 'runs', run['id'] + '.mcap.part'))

    def interrupted(self, signum, in_progress):
        """The :class:`.dataset_pool.Interrupted` to raise: what the manifest holds."""
        from .dataset_pool import Interrupted
        return Interrupted(signum, (
            f"{os.path.join(self.out_dir, 'manifest.json')} lists {len(self.rows)} of "
            f'{len(self.plan)} runs; the {in_progress} in progress were stopped and their logs '
            'removed; run the same command again to record the rest'))


__all__ = ['DISK_ERROR', 'DatasetError', 'DatasetProgress', 'LABELS', 'load_spec', 'record_run',
           'run_dataset', 'write_manifest']
