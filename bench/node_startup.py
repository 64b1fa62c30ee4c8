"""Start-up time of ``study simulate`` and of vibration_node, with a cold and a warm Numba cache.

Each run is a fresh Python process of this interpreter (the project's venv; nothing outside
it is called), timed from just before it is started (wall s):

* ``study simulate SCENE --duration 0.5`` (``python -m impact_damper_sim.cli.study``): to
  its exit, after it printed its result; the real-time factor it reports for its own timed
  run is printed too;
* the node: the process imports rclpy, builds the node (scene load, finite elements, modal
  reduction, Numba kernels) and publishes its first chunk of samples; times to each of
  those. It then steps and publishes one simulated second flat out, whose real-time factor
  shows that nothing is left to compile after the first samples.

Each run also reports its CPU time (user + system s of the process and of the compile helpers
it waited for, :mod:`impact_damper_sim.integrate.kernels`): on a shared machine the wall time
of a cold start depends on the other jobs, its CPU time much less. A cold start compiles in
up to as many processes as there are cores, so its wall time on an idle machine is about
its CPU time divided by the cores it could use, plus the serial parts.

"Cold" points ``NUMBA_CACHE_DIR`` at a fresh empty directory, so every kernel the run calls is
compiled; "warm" runs again with the cache the cold run filled. Each tool gets its own
directories (the node runs without the energy ledger, ``study simulate`` with it: they
compile different kernels). Medians and ranges (min-max) over ``--repeat`` runs.

Usage::

    python bench/node_startup.py [--scene hpotp] [--repeat 3] [--only study|node]
"""
from __future__ import annotations

import argparse
import math
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time

NODE_CHILD = r'''
import math, sys, time
t_start = float(sys.argv[1])
import rclpy
from rclpy.parameter import Parameter
t_import = time.time()
from impact_damper_sim.ros.vibration_node import VibrationNode
rclpy.init()
node = VibrationNode(start_stepping=False, parameter_overrides=[
    Parameter('scene', value=sys.argv[2])])
t_built = time.time()
node._wall = lambda: time.monotonic() + 1.0   # one chunk is due at once
node.tick()
t_first = time.time()
live = node.live
t_sim = live.t
wall = time.perf_counter()
while live.t < t_sim + 1.0 and node._step(node._chunk):
    node._flush()
rtf = (live.t - t_sim) / (time.perf_counter() - wall)
print(f'{t_import - t_start:.3f} {t_built - t_start:.3f} {t_first - t_start:.3f} {rtf:.2f}')
node.destroy_node()
rclpy.try_shutdown()
'''


def children_cpu():
    """CPU time (user + system s) of the finished child processes so far, theirs included."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def run_node(scene, cache_dir):
    """One node process: ``[rclpy imported, node built, first samples published]`` (wall s
    from the start), the real-time factor of the next simulated second (dimensionless) and
    the process's CPU time (s; it runs about a second more after its first samples)."""
    env = dict(os.environ, NUMBA_CACHE_DIR=cache_dir,
               ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    cpu = children_cpu()
    t0 = time.time()
    out = subprocess.run([sys.executable, '-c', NODE_CHILD, repr(t0), scene], env=env,
                         capture_output=True, text=True, check=True).stdout.split()
    return [float(x) for x in out[-4:]] + [children_cpu() - cpu]


def run_study(scene, duration, cache_dir):
    """One ``study simulate`` process: ``[wall s to its exit, real-time factor it reports,
    CPU s]``."""
    env = dict(os.environ, NUMBA_CACHE_DIR=cache_dir)
    cpu = children_cpu()
    t0 = time.perf_counter()
    out = subprocess.run([sys.executable, '-m', 'impact_damper_sim.cli.study', 'simulate',
                          scene, '--duration', str(duration)], env=env, capture_output=True,
                         text=True, check=True).stdout
    wall = time.perf_counter() - t0
    rtf = re.search(r'real-time factor ([0-9.eE+-]+)', out)
    return [wall, float(rtf.group(1)) if rtf else math.nan, children_cpu() - cpu]


def cold_and_warm(run, repeat):
    """``repeat`` pairs of runs, each pair in a fresh cache directory: (cold rows, warm rows)."""
    cold, warm = [], []
    for _ in range(repeat):
        with tempfile.TemporaryDirectory(prefix='numba-cache-') as cache:
            cold.append(run(cache))
            warm.append(run(cache))
    return cold, warm


def spread(values, fmt='{:.2f}'):
    """``'median (min-max)'`` of ``values``."""
    return (f'{fmt.format(statistics.median(values))} '
            f'({fmt.format(min(values))}-{fmt.format(max(values))})')


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--scene', default='hpotp')
    parser.add_argument('--repeat', type=int, default=3)
    parser.add_argument('--duration', type=float, default=0.5,
                        help='simulated time of study simulate (s)')
    parser.add_argument('--only', choices=('study', 'node'))
    args = parser.parse_args(argv)
    print(f'load: {os.getloadavg()[0]:.2f} (1-min average, {os.cpu_count()} cores); '
          f'scene {args.scene}; wall s from process start, median (min-max) of {args.repeat}')
    if args.only != 'node':
        cold, warm = cold_and_warm(lambda c: run_study(args.scene, args.duration, c),
                                   args.repeat)
        print(f'study simulate {args.scene} --duration {args.duration:g}, to its result:')
        for name, rows in (('cold', cold), ('warm', warm)):
            print(f'  {name} Numba cache  {spread([r[0] for r in rows])} s; its run '
                  f'{spread([r[1] for r in rows], "{:.1f}")} x real time; CPU '
                  f'{spread([r[2] for r in rows], "{:.1f}")} s')
    if args.only != 'study':
        cold, warm = cold_and_warm(lambda c: run_node(args.scene, c), args.repeat)
        print('vibration_node: rclpy imported / node built / first samples published; the next '
              'simulated second, flat out:')
        for name, rows in (('cold', cold), ('warm', warm)):
            print(f'  {name} Numba cache  {spread([r[0] for r in rows])} / '
                  f'{spread([r[1] for r in rows])} / {spread([r[2] for r in rows])} s; '
                  f'{spread([r[3] for r in rows], "{:.1f}")} x real time; CPU '
                  f'{spread([r[4] for r in rows], "{:.1f}")} s')
        ratio = statistics.median(r[2] for r in cold) / statistics.median(r[2] for r in warm)
        print(f'  cold / warm to first samples: {ratio:.1f}x')


if __name__ == '__main__':
    main()
