"""Long-run state from rest over a grid of Masri-Caughey SDOF cases, per method.

For every grid point with a stable symmetric two-impact orbit (closed form,
:mod:`impact_damper_sim.dampers.analytic`), run from rest: our exact method (paper's stick
rule and none), located-impact Newmark at T/400, and, when ``/usr/bin/python3`` has Siconos,
Siconos Moreau-Jean (theta = 1/2, T/400; its event-driven scheme stops at the first
accumulation of impacts, see transient.py), on the undamped
points, through
``bench/siconos_sdof.py``. Record each run's last-10-period peak over the orbit amplitude,
its impacts and sticks, and the Floquet spectral radius of the orbit.

Usage: .venv/bin/python docs/fidelity/attractor_grid.py [periods]
Writes docs/fidelity/attractor_grid.json and prints a Markdown table.
"""
import itertools
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from impact_damper_sim.studies.attractor import (capture_period, classify, run_from_rest,
                                                   stable_orbit)

HERE = Path(__file__).resolve().parent
SICONOS = HERE.parent.parent / 'bench' / 'siconos_sdof.py'
GRID = dict(r=(0.8, 0.9, 1.1, 1.2), zeta=(0.0, 0.005, 0.02), mu=(0.1, 0.2), e=(0.3, 0.6),
            d=(8.0, 16.0))
METHODS = [('exact', 'exact', {}), ('exact/none', 'exact', dict(stick_rule='none')),
           ('newmark', 'newmark', {})]


def siconos(point, periods, scheme):
    try:
        res = subprocess.run(['/usr/bin/python3', str(SICONOS), *map(str, point), str(periods),
                              scheme, '400'], capture_output=True, text=True, timeout=900)
        return json.loads(res.stdout)
    except Exception as exc:  # Siconos absent or crashed: say so, keep the rest
        return dict(failure=f'{type(exc).__name__}: {exc}', amps=[], impacts=[])


def summarize(amps, n_impacts, n_sticks, orbit, periods):
    amps = np.asarray(amps)
    row = dict(periods_run=int(amps.size), impacts=int(n_impacts), sticks=int(n_sticks))
    if amps.size < periods:
        row['state'] = 'failed'
        return row
    row['late_max'] = float(amps[-10:].max() / orbit.amplitude)
    row['late_min'] = float(amps[-10:].min() / orbit.amplitude)
    row['state'] = classify(amps, orbit) if n_impacts else 'no_impacts'
    row['capture_period'] = capture_period(amps, orbit)
    return row


def main(periods=1000):
    rows = []
    for r, zeta, mu, e, d in itertools.product(*GRID.values()):
        point = (r, zeta, mu, e, d)
        orbit = stable_orbit(point)
        if orbit is None:
            continue
        row = dict(point=point, orbit_amplitude=orbit.amplitude,
                   linear_amplitude=orbit.linear_amplitude,
                   spectral_radius=orbit.spectral_radius, methods={})
        for label, method, kw in METHODS:
            t0 = time.time()
            run = run_from_rest(point, periods, method, **kw)
            row['methods'][label] = summarize(run.amplitudes, len(run.impacts), len(run.sticks),
                                              orbit, periods)
            row['methods'][label]['cpu_s'] = time.time() - t0
        for scheme in (('mj',) if zeta == 0.0 else ()):   # the peer on the undamped cases
            out = siconos(point, periods, scheme)
            s = summarize(out['amps'], len(out['impacts']), 0, orbit, periods)
            s.pop('sticks')
            if out.get('failure'):
                s['failure'] = out['failure']
            row['methods']['siconos ' + scheme] = s
        rows.append(row)
        print(json.dumps(row), flush=True)
    (HERE / 'attractor_grid.json').write_text(json.dumps(dict(periods=periods, rows=rows),
                                                          indent=1))


if __name__ == '__main__':
    main(*(int(a) for a in sys.argv[1:2]))
