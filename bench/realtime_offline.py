"""Real-time factor of every ready-made scene at its default accuracy, offline, one core.

Each scene runs from rest over its default ``simulation.duration`` with its default method,
dt, modes and energy ledger (what ``study simulate SCENE`` does), after a warm-up step that
compiles the kernels or loads them from the Numba cache. The real-time factor is simulated
time over the CPU time of this one process (one core; best of ``--repeat``). Also printed:
the same run without the energy ledger (``ledger=False``, what a node that does not report
energy could use), the impacts per simulated second and the kernel events per step.
Goal (issue 7): HPOTP at least 200 x real time. Usage::

    .venv/bin/python bench/realtime_offline.py [--repeat 3] [--scenes sdof,hpotp] [--duration S]
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np

from impact_damper_sim.scene.build import load

SCENES = ('sdof', 'cantilever', 'rbs', 'rbs_kcc', 'hpotp', 'hpotp_x10')


def measure(scene, duration, repeat, ledger):
    """Best CPU time (s) over ``repeat`` runs, the impacts and the largest impacts per step."""
    cfg = scene.scene['simulation']
    scene.make_simulation(ledger=ledger).advance(1)
    best, n_imp, per_step = np.inf, 0, 0
    for _ in range(repeat):
        sim = scene.make_simulation(ledger=ledger)
        n = int(round(duration / cfg['dt']))
        start = time.process_time()
        sim.advance(n)
        best = min(best, time.process_time() - start)
        n_imp = int(np.count_nonzero(sim.take_events()['kind'] == 0))
        per_step = sim.integrator.max_impacts_per_step
    return best, n_imp, per_step


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--repeat', type=int, default=3, help='best of N (default 3)')
    parser.add_argument('--scenes', default=','.join(SCENES), help='comma list of scenes')
    parser.add_argument('--duration', type=float,
                        help="simulated time (s); default each scene's simulation.duration")
    args = parser.parse_args(argv)
    print(f'offline real-time factor (simulated s / CPU s, one process), best of {args.repeat}; '
          f'load average {os.getloadavg()[0]:.2f}')
    print(f"{'scene':11s} {'method':7s} {'dt (s)':>8s} {'modes':>5s} {'sim (s)':>7s} "
          f"{'RTF':>9s} {'RTF no ledger':>13s} {'impacts/s':>10s} {'max/step':>8s}")
    for name in args.scenes.split(','):
        scene = load(name)
        cfg = scene.scene['simulation']
        duration = args.duration or cfg['duration']
        cpu, n_imp, per_step = measure(scene, duration, args.repeat, True)
        cpu_nl, _, _ = measure(scene, duration, args.repeat, False)
        print(f"{name:11s} {cfg['method']:7s} {cfg['dt']:8.2g} {scene.basis.n_modes:5d} "
              f'{duration:7.3g} {duration / cpu:9.1f} {duration / cpu_nl:13.1f} '
              f'{n_imp / duration:10.0f} {per_step:8d}', flush=True)
    print('goal: hpotp >= 200 x real time at default accuracy')


if __name__ == '__main__':
    main()
