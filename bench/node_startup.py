"""vibration_node start-up time, with a cold and with a warm Numba cache.

Each run is a fresh Python process that imports the node, builds it (scene load, finite
elements, modal reduction, Numba kernels) and publishes its first chunk of samples; the time is
from process start to that first publication (wall s). "Cold" points ``NUMBA_CACHE_DIR`` at
an empty directory, so every kernel is compiled; "warm" reuses the cache the cold run filled.

Usage::

    python bench/node_startup.py [--scene hpotp] [--repeat 3]
"""
from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time

CHILD = r'''
import sys, time
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
print(f'{t_import - t_start:.3f} {t_built - t_start:.3f} {t_first - t_start:.3f}')
node.destroy_node()
rclpy.try_shutdown()
'''


def run(scene, cache_dir):
    env = dict(os.environ, NUMBA_CACHE_DIR=cache_dir,
               ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    t0 = time.time()
    out = subprocess.run([sys.executable, '-c', CHILD, repr(t0), scene], env=env,
                         capture_output=True, text=True, check=True).stdout.split()
    return [float(x) for x in out[-3:]]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--scene', default='hpotp')
    parser.add_argument('--repeat', type=int, default=3)
    args = parser.parse_args(argv)
    print(f'load: {os.getloadavg()[0]:.2f} (1-min average, {os.cpu_count()} cores); '
          f'scene {args.scene}; times from process start (s): rclpy imported / node built / '
          'first samples published')
    cold, warm = [], []
    for _ in range(args.repeat):
        with tempfile.TemporaryDirectory() as cache:
            cold.append(run(args.scene, cache))
            warm.append(run(args.scene, cache))
    for name, rows in (('cold Numba cache', cold), ('warm Numba cache', warm)):
        med = [statistics.median(r[k] for r in rows) for k in range(3)]
        print(f'{name:18s} median of {len(rows)}: {med[0]:6.2f} / {med[1]:6.2f} / {med[2]:6.2f}')
    ratio = statistics.median(r[2] for r in cold) / statistics.median(r[2] for r in warm)
    print(f'cold / warm to first samples: {ratio:.1f}x')


if __name__ == '__main__':
    main()
