"""Modal against direct (physical-coordinate) integration on HPOTP and RBS, same run, same dt.

The paper's Table 2.2.1: 4.5 min for the direct Newmark run against 4.2 s for the modal one,
about 64:1, at dt = 50 us. Here, at that dt, every case runs the scene with the three methods
(``direct``: Newmark on the full condensed FE model; ``newmark``: Newmark on the retained
modes, the paper's modal method; ``exact``: our exact modal propagator) and prints the CPU
time per simulated second and the ratios direct/newmark and direct/exact, all measured in this
run (best of ``--repeat``, after a warm-up that compiles the kernels). Usage::

    .venv/bin/python bench/modal_vs_direct.py [--repeat 3] [--dt 5e-5]

Cases (short spans, since direct is slow):

* ``rbs``: 7878 rpm, X = 1 (the response stays inside the clearances: no impacts), 0.2 s;
* ``rbs X=10``: impacts on every impactor, 0.05 s;
* ``hpotp ramp``: the first 0.4 s of the speed ramp (no impacts yet), 0.4 s;
* ``hpotp impacts``: from 1.0 s, when the impactors rattle (about 4,000 impacts/s), 0.05 s
  (state reached by the exact propagator, then handed to each method as its initial state).
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np

from impact_damper_sim.scene.build import load

CASES = (
    ('rbs', 'rbs', [], 0.0, 0.2),
    ('rbs X=10', 'rbs', ['rotor.multiplier=10'], 0.0, 0.05),
    ('hpotp ramp', 'hpotp', [], 0.0, 0.4),
    ('hpotp impacts', 'hpotp', [], 1.0, 0.05),
)
METHODS = ('direct', 'newmark', 'exact')


def _start_state(scene, method, t0, dt):
    """Options that start ``method`` at ``t0`` (s) from the exact run's state (at rest for 0).

    Impactors restart centred, moving with their housing: the same start for every method.
    """
    if t0 == 0.0:
        return {}
    sim = scene.make_simulation('exact', dt)
    sim.advance_to(t0)
    q, qd = sim.integrator.state()
    if method == 'direct':
        Phi = scene.basis.shapes          # physical = Phi q (the retained modes' part)
        q, qd = Phi @ q, Phi @ qd
    return {'q0': q, 'qd0': qd, 't0': t0}


def measure(scene, method, t0, span, dt, repeat):
    """Best CPU time (s) of ``span`` simulated seconds from ``t0`` and the impacts counted."""
    opts = _start_state(scene, method, t0, dt)
    scene.make_simulation(method, dt, **opts).advance(2)      # compile / load the cache
    best, n_imp = np.inf, 0
    for _ in range(repeat):
        sim = scene.make_simulation(method, dt, **opts)
        start = time.process_time()
        sim.advance(int(round(span / dt)))
        best = min(best, time.process_time() - start)
        ev = sim.take_events()
        n_imp = int(np.count_nonzero(ev['kind'] == 0))
    return best, n_imp


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--repeat', type=int, default=3, help='best of N (default 3)')
    parser.add_argument('--dt', type=float, default=5e-5, help='time step (s), default 50 us')
    args = parser.parse_args(argv)
    print(f'modal vs direct at dt = {args.dt * 1e6:g} us, CPU s per simulated s, best of '
          f'{args.repeat} (load average {os.getloadavg()[0]:.2f})')
    header = (f"{'case':15s} {'DOF':>5s} {'modes':>5s} " + ' '.join(f'{m:>12s}' for m in METHODS)
              + f" {'impacts':>8s} {'direct/newmark':>15s} {'direct/exact':>13s}")
    print(header)
    ratios = []
    for label, name, overrides, t0, span in CASES:
        scene = load(name, overrides)
        cpu, imps = {}, {}
        for m in METHODS:
            c, n = measure(scene, m, t0, span, args.dt, args.repeat)
            cpu[m], imps[m] = c / span, n
        r_nm, r_ex = cpu['direct'] / cpu['newmark'], cpu['direct'] / cpu['exact']
        ratios.append((label, r_nm, r_ex))
        print(f'{label:15s} {scene.physical_model.n:5d} {scene.basis.n_modes:5d} '
              + ' '.join(f'{cpu[m]:12.4g}' for m in METHODS)
              + f" {'/'.join(str(imps[m]) for m in METHODS):>8s} {r_nm:15.1f} {r_ex:13.1f}")
    print('\nimpacts: direct/newmark/exact over the span. Paper (Table 2.2.1): about 64:1.')
    for label, r_nm, r_ex in ratios:
        print(f'{label}: direct is {r_nm:.0f} x the modal Newmark and {r_ex:.0f} x the exact '
              'propagator')


if __name__ == '__main__':
    main()
