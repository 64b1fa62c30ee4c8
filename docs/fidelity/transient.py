"""Impact-by-impact comparison of the transient from rest (issue 14, undamped chaotic case).

Methods, same rest start, point (r, zeta, mu, e, d) = (1.1, 0, 0.1, 0.6, 16):
exact (stick rule none, so that no rule separates them), Newmark with located impacts at
T/400 .. T/20000, scipy DOP853 (rtol 1e-12, event-located, restarted at each impact) and,
if the system python3 has Siconos, Siconos event-driven (LSODAR, tol 1e-12) and
Moreau-Jean (theta 1/2, T/400 and T/4000). For each: the index and time of the first impact
that differs from the exact method's (wall, or time by more than 1 % of the period), and
the largest impact-time difference over the first 40 impacts.
Then the 240 s runs from rest (6,640 periods), with their late per-period peaks.

Usage: .venv/bin/python docs/fidelity/transient.py
Writes docs/fidelity/transient.json.
"""
import json
import subprocess
import time
from pathlib import Path

import numpy as np

from impact_damper_sim.studies.attractor import (AttractorRun, first_divergence,
                                                   min_wall_distance, reference_impacts,
                                                   run_from_rest, stable_orbit)

HERE = Path(__file__).resolve().parent
SICONOS = HERE.parent.parent / 'bench' / 'siconos_sdof.py'
POINT = (1.1, 0.0, 0.1, 0.6, 16.0)


def siconos(periods, scheme, per):
    try:
        res = subprocess.run(['/usr/bin/python3', str(SICONOS), *map(str, POINT),
                              str(periods), scheme, str(per)], capture_output=True, text=True,
                             timeout=1800)
        return json.loads(res.stdout)
    except Exception as exc:
        return dict(failure=f'{type(exc).__name__}: {exc}', amps=[], impacts=[])


def as_run(label, period, impacts, amps=()):
    imp = np.array([row[:3] for row in impacts], dtype=float).reshape(-1, 3)
    return AttractorRun(POINT, label, period, np.asarray(amps, float), imp, np.zeros(0))


def main():
    orbit = stable_orbit(POINT)
    period = 2 * np.pi / orbit.Omega
    out = dict(point=POINT, period_s=period, orbit_amplitude_m=orbit.amplitude,
               multipliers_abs=[abs(m) for m in orbit.multipliers], short={}, long={})
    ex = run_from_rest(POINT, 60, 'exact', stick_rule='none')
    ref = reference_impacts(POINT, 60)
    k52 = 52
    depth, t_min = min_wall_distance(POINT, ref[k52, 3:], ref[k52, 0], ref[k52 + 1, 0]
                                     - ref[k52, 0], wall=-1.0)
    out['graze'] = dict(index=53, exact_t=ex.impacts[53, 0], exact_v_n=ex.impacts[53, 2],
                        median_v_n=float(np.median(ex.impacts[:53, 2])),
                        dop853_next_wall=ref[53, 1], dop853_flight_depth_m=depth,
                        dop853_flight_depth_t=t_min)
    others = {'dop853 rtol 1e-12': as_run('dop853', period, ref)}
    for per in (400, 1000, 2000, 5000, 10000, 20000):
        others[f'newmark T/{per}'] = run_from_rest(POINT, 60, 'newmark', per_cycle=per,
                                                   stick_rule='none')
    for scheme, per in (('ed', 400), ('mj', 400), ('mj', 4000)):
        s = siconos(60, scheme, per)
        if s.get('impacts'):
            others[f'siconos {scheme} T/{per}' if scheme == 'mj' else 'siconos ed'] = as_run(
                scheme, period, s['impacts'])
    for label, run in others.items():
        k, t = first_divergence(ex, run, rel=1e-2)
        n = min(40, len(run.impacts))
        err = float(np.max(np.abs(run.impacts[:n, 0] - ex.impacts[:n, 0])))
        out['short'][label] = dict(first_divergence=k, at_s=t, max_dt_first_40_s=err)
        print(f'{label:22s} parts from exact at impact {k} (t = {t:.4f} s); '
              f'max |dt| over impacts 0..39: {err:.2e} s', flush=True)
    periods = 6640
    for label, method, kw in [('exact', 'exact', {}), ('exact, stick rule none', 'exact',
                                                       dict(stick_rule='none')),
                              ('newmark T/400', 'newmark', {}),
                              ('newmark T/2000', 'newmark', dict(per_cycle=2000))]:
        t0 = time.time()
        run = run_from_rest(POINT, periods, method, **kw)
        a = run.amplitudes / orbit.amplitude
        out['long'][label] = dict(late_min=float(a[-10:].min()), late_max=float(a[-10:].max()),
                                  impacts=len(run.impacts), sticks=len(run.sticks),
                                  cpu_s=time.time() - t0)
        print(label, out['long'][label], flush=True)
    for scheme in ('mj', 'ed'):
        s = siconos(periods, scheme, 400)
        a = np.asarray(s.get('amps', []), float) / orbit.amplitude
        out['long'][f'siconos {scheme} T/400'] = dict(
            periods_done=int(a.size), late_min=float(a[-10:].min()) if a.size else None,
            late_max=float(a[-10:].max()) if a.size else None, impacts=len(s['impacts']),
            failure=s.get('failure'))
        print(scheme, out['long'][f'siconos {scheme} T/400'], flush=True)
    (HERE / 'transient.json').write_text(json.dumps(out, indent=1, default=float))


if __name__ == '__main__':
    main()
