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
import os
import sys
import time

from .dataset_manifest import (
    DISK_ERROR,
    LABELS,
    file_sha256,
    finished_rows,
    manifest_rows,
    write_manifest,
)
from .dataset_spec import load_spec


def record_run(run, out_dir):
    """Record one run of a plan (a top-level function: it runs on a worker).

    Parameters
    ----------
    run : dict
        One entry of :func:`.dataset_spec.load_spec`'s plan.
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
        size, digest = os.path.getsize(final), file_sha256(final)
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
    rows = finished_rows(out_dir, plan, retry_failed)
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
    entries = manifest_rows(plan, rows)
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


__all__ = ['DatasetProgress', 'record_run', 'run_dataset']
