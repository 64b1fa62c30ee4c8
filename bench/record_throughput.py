"""Throughput of offline node logs (``study record``, ``study dataset``), as ratios of one run.

1. **One log, one core.** HPOTP (its impactors, the paper's ramp) stepped for ``--duration``
   of sim time three ways in this process: the bare live engine (``LiveSimulation.step`` in
   the node's 10 ms chunks, nothing packed), the engine plus the node's message packing
   (``NodeMessages``: CDR bytes of every topic, nothing written), and ``study record``'s
   whole path (packing and the rosbag2 MCAP writer, to a file). Printed: sim seconds per CPU
   second of this process (x real time per core) for each, the log's share of the cost as
   a ratio against the bare engine, the log's bytes per sim second, and the cost per GB of
   log (CPU s/GB, and the sim time a GB holds). The same record with the node's largest
   ``tick_period`` (``study record --tick-period 100ms``: a tenth of the per-chunk overhead,
   100 ms batches) is timed too. Issue 28's goal: logs at >= 10 x real time per core
   including serialization and MCAP writing.
2. **A data set on Dask.** ``--runs`` HPOTP runs of ``--run-duration`` each through
   ``study dataset`` on a Dask ``LocalCluster`` of 1 worker, then of 2 workers (one process
   each, one thread: the engine holds the GIL), same spec, fresh directories. Printed: runs
   per wall second of each, and the 2-worker speed-up (goal >= 1.8 x one worker; it needs 2
   idle cores, and the load average of this shared machine is printed beside it).

Usage::

    .venv/bin/python bench/record_throughput.py [--duration 10] [--runs 8]
                                                [--run-duration 2] [--skip-dask]
"""
from __future__ import annotations

import argparse
import os
import tempfile
import time

SCENE = 'hpotp'


def _load():
    return '/'.join(f'{x:.2f}' for x in os.getloadavg())


def engine_only(duration, pack):
    """CPU s of stepping ``duration`` s of HPOTP in 10 ms chunks (with the packing if asked)."""
    from impact_damper_sim.live.realtime import LiveSimulation
    from impact_damper_sim.live.streams import live_scene
    from impact_damper_sim.recording.node_messages import NodeMessages
    model, target = live_scene(SCENE)
    live = LiveSimulation(model, initial_target=target)
    messages = NodeMessages(live, model) if pack else None
    chunk = int(round(0.01 * live.sample_rate))
    total = int(round(duration * live.sample_rate))
    live.step(chunk)   # kernels loaded before the clock starts
    done, size = chunk, 0
    t0 = time.process_time()
    while done < total:
        batch = live.step(chunk)
        done += chunk
        if messages is not None:
            size += sum(len(d) for _, _, d in messages.batch_items(batch))
            size += sum(len(d) for _, _, d in messages.time_items())
    return time.process_time() - t0, size


def record(duration, directory, tick_period=0.01):
    """CPU s and bytes of ``study record`` writing ``duration`` s of HPOTP."""
    from impact_damper_sim.studies.record import record_log
    record_log(SCENE, os.path.join(directory, 'warm.mcap'), 0.02, overwrite=True)
    t0 = time.process_time()
    result = record_log(SCENE, os.path.join(directory, 'bench.mcap'), duration,
                        tick_period=tick_period, overwrite=True)
    return time.process_time() - t0, result['bytes'], result


def dataset(workers, runs, run_duration, directory):
    """Wall s of a ``runs``-run data set on a Dask LocalCluster of ``workers`` processes."""
    from dask.distributed import LocalCluster

    from impact_damper_sim.studies.dataset import run_dataset
    spec = os.path.join(directory, 'spec.yaml')
    with open(spec, 'w') as f:   # distinct runs: one noise seed each
        f.write(f'scene: {SCENE}\nduration: {run_duration}\nnoise_std: 0.1\n'
                f'seeds: {list(range(runs))}\n')
    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster:
        # warm each worker (imports, compiled kernels) outside the timed data set
        warm = os.path.join(directory, f'warm{workers}')
        with open(spec + '.warm', 'w') as f:
            f.write(f'scene: {SCENE}\nduration: 0.02\nseeds: {list(range(workers))}\n')
        run_dataset(spec + '.warm', warm, executor='dask', dask_address=cluster.scheduler_address)
        out = os.path.join(directory, f'data{workers}')
        t0 = time.perf_counter()
        result = run_dataset(spec, out, executor='dask', dask_address=cluster.scheduler_address)
        wall = time.perf_counter() - t0
    assert result['failed'] == 0 and result['recorded'] == runs, result
    return wall


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--duration', type=float, default=10.0, help='sim s of the one log')
    parser.add_argument('--runs', type=int, default=8, help='runs of the data set')
    parser.add_argument('--run-duration', type=float, default=2.0, help='sim s per run')
    parser.add_argument('--skip-dask', action='store_true', help='only the one-log part')
    args = parser.parse_args(argv)
    d = args.duration
    with tempfile.TemporaryDirectory() as tmp:
        bare, _ = engine_only(d, pack=False)
        packed, packed_bytes = engine_only(d, pack=True)
        rec, size, result = record(d, tmp)
        print(f'one HPOTP log, {d:g} s of sim time, CPU of this process (load {_load()}):')
        print(f'  bare live engine       {d / bare:7.1f} x real time per core')
        print(f'  + message packing      {d / packed:7.1f} x real time per core '
              f'({packed / bare:.2f} x the engine, {packed_bytes / d / 1e6:.2f} MB of CDR '
              'per sim s)')
        print(f'  + MCAP writing (record){d / rec:7.1f} x real time per core '
              f'({rec / bare:.2f} x the engine; goal >= 10 x real time)')
        coarse, _, _ = record(d, tmp, tick_period=0.1)
        print(f'  study record --tick-period 100ms {d / coarse:6.1f} x real time per core '
              f'({coarse / bare:.2f} x the engine in 10 ms chunks, {rec / coarse:.2f} x faster '
              'than the default 10 ms: 100 ms batches, as the node with tick_period:=0.1)')
        gb = size / 1e9
        print(f'  log: {size / d / 1e6:.2f} MB per sim s, {result["messages"] / d:.0f} messages '
              f'per sim s; a GB of log holds {d / gb / 60:.1f} sim min and costs '
              f'{rec / gb:.0f} CPU s ({rec / gb / 3600:.2f} core hours)')
        if args.skip_dask:
            return 0
        one = dataset(1, args.runs, args.run_duration, tmp)
        two = dataset(2, args.runs, args.run_duration, tmp)
        print(f'data set of {args.runs} HPOTP runs x {args.run_duration:g} s on a Dask '
              f'LocalCluster (load {_load()}):')
        print(f'  1 worker   {args.runs / one:6.2f} runs/s ({one:.1f} s)')
        print(f'  2 workers  {args.runs / two:6.2f} runs/s ({two:.1f} s): {one / two:.2f} x one '
              'worker (goal >= 1.8; needs 2 idle cores)')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
