"""Capture times onto the stable Masri-Caughey orbit from (nearly) rest, per method.

Each run starts from rest with the impactor displaced from the slot centre by
``k * 1e-12 * D`` (k = 0 .. n-1): perturbations far below any method's error. The time at
which a run settles on the orbit (every later per-period peak within 1e-3 of the closed
form) is then a random variable of the chaotic transient, and its spread, not one run,
is what methods can be compared on.

Usage: .venv/bin/python docs/fidelity/capture_times.py [n_starts] [periods]
Writes docs/fidelity/capture_times.json.
"""
import json
import sys
import time
from pathlib import Path

import numpy as np

from impact_damper_sim.studies.attractor import (FORCE, STIFFNESS, capture_period,
                                                   run_from_rest, stable_orbit)

POINT = (1.1, 0.0, 0.1, 0.6, 16.0)
METHODS = [('exact', 'exact', {}), ('exact, stick_rule none', 'exact', dict(stick_rule='none')),
           ('newmark T/400', 'newmark', {})]


def main(n_starts=12, periods=11000):
    orbit = stable_orbit(POINT)
    D = POINT[4] * FORCE / STIFFNESS
    out = dict(point=POINT, periods=periods, period_s=2 * np.pi / orbit.Omega,
               orbit_amplitude=orbit.amplitude, spectral_radius=orbit.spectral_radius,
               runs={})
    for label, method, kw in METHODS:
        caps = []
        t0 = time.time()
        for k in range(n_starts):
            run = run_from_rest(POINT, periods, method, offset=k * 1e-12 * D, **kw)
            caps.append(capture_period(run.amplitudes, orbit))
        out['runs'][label] = dict(capture_periods=caps, cpu_s=time.time() - t0)
        print(label, caps, f'{time.time() - t0:.0f} s', flush=True)
    Path(__file__).with_name('capture_times.json').write_text(json.dumps(out, indent=1))


if __name__ == '__main__':
    main(*(int(a) for a in sys.argv[1:3]))
