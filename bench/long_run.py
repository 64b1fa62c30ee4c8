"""One hour of simulated time at full speed (no ROS, no pacing): nothing drifts, nothing hangs.

Runs a scene from rest for ``--hours`` (default 1) of simulated time in chunks of
``--chunk`` seconds, as fast as the CPU allows (a node's ``real_time_factor`` 0), and checks
after every chunk:

* every sensor output is finite;
* events per output step stay bounded: the integrator's largest impacts of one impactor in
  one step is at most its ``max_events_per_step`` (the chatter cap);
* the energy ledger closes: ``|relative residual| < 1e-9`` (the exact propagator's stated
  bound; Newmark's is 1e-10).

Prints the CPU time, the real-time factor, the impacts and the worst ledger residual; exits
with status 1 if a check fails. Usage::

    .venv/bin/python bench/long_run.py [--scene sdof] [--hours 1] [--method exact]

The default ``sdof`` scene (steady two-impacts-per-cycle orbit, 25 Hz) takes about a minute
of CPU. ``rbs_kcc`` (limit cycle at about 4,400 impacts/s) takes about an hour.
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

from impact_damper_sim.scene.build import load

LEDGER_BOUND = {'exact': 1e-9}
NEWMARK_BOUND = 1e-10


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--scene', default='sdof')
    parser.add_argument('--hours', type=float, default=1.0, help='simulated hours (default 1)')
    parser.add_argument('--method', help="integration method (default: the scene's)")
    parser.add_argument('--chunk', type=float, default=10.0, help='seconds per check (10)')
    args = parser.parse_args(argv)
    scene = load(args.scene)
    sim = scene.make_simulation(args.method)
    method = sim.method
    bound = LEDGER_BOUND.get(method, NEWMARK_BOUND)
    duration = 3600.0 * args.hours
    print(f'{args.scene}: {method}, dt {sim.dt:g} s, {duration:g} s simulated in chunks of '
          f'{args.chunk:g} s (load average {os.getloadavg()[0]:.2f})', flush=True)
    scene.make_simulation(args.method).advance(1)          # compile / load the kernels
    cpu0, wall0 = time.process_time(), time.perf_counter()
    n_impacts, worst, problems = 0, 0.0, []
    while sim.t < duration - 0.5 * sim.dt and not problems:
        s = sim.advance_to(min(sim.t + args.chunk, duration))
        ev = sim.take_events()
        n_impacts += int(np.count_nonzero(ev['kind'] == 0))
        if not (np.all(np.isfinite(s.displacement)) and np.all(np.isfinite(s.velocity))):
            problems.append(f'non-finite output before t = {sim.t:g} s')
        integ = sim.integrator
        if integ.max_impacts_per_step > integ.max_events_per_step:
            problems.append(f'{integ.max_impacts_per_step} impacts in one step (cap '
                            f'{integ.max_events_per_step}) before t = {sim.t:g} s')
        res = abs(sim.energy().relative_residual)
        worst = max(worst, res)
        if not res < bound:
            problems.append(f'ledger residual {res:.3g} >= {bound:g} at t = {sim.t:g} s')
    cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
    led = sim.energy()
    print(f'simulated {sim.t:g} s in {cpu:.1f} s CPU ({wall:.1f} s wall): real-time factor '
          f'{sim.t / cpu:.1f}')
    print(f'impacts {n_impacts} ({n_impacts / max(sim.t, 1e-300):.1f}/s), largest impacts of '
          f'one impactor in one step {sim.integrator.max_impacts_per_step} (cap '
          f'{sim.integrator.max_events_per_step})')
    print(f'energy (J): forcing work {led.forcing:.6g}, damping {led.damping:.6g}, impacts '
          f'{led.impacts:.6g}, sticking {led.sticking:.6g}, final {led.total:.6g}; worst '
          f'relative residual {worst:.2e} (bound {bound:g})')
    for p in problems:
        print(f'FAILED: {p}')
    print('all checks passed' if not problems else 'checks FAILED')
    return 1 if problems else 0


if __name__ == '__main__':
    sys.exit(main())
