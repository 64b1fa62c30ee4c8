"""SDOF impact damper: every integrator against the scipy solve_ivp baseline, same run.

Prints, for each method and setting, the CPU time per simulated second, the real-time factor,
and the errors against a reference (the exact propagator sampled finely): the state at
``t_end`` and the largest impact-time error. Then the cost ratios at equal accuracy, measured
in this same run. Usage::

    .venv/bin/python bench/sdof_methods.py [--t-end 10] [--repeat 3]

The case is the baseline's: f_n = 10 Hz, zeta = 0.01, r = 1, mu = 0.05, e = 0.6,
D = 30 F0/K, started on the stable symmetric two-impact orbit (Masri & Caughey).
"""
from __future__ import annotations

import argparse
import importlib.util
import time
from pathlib import Path

import numpy as np

from impact_damper_sim.dampers.analytic import symmetric_two_impact_orbit
from impact_damper_sim.dampers.analytic_flow import orbit_state
from impact_damper_sim.dampers.impactors import Impactor
from impact_damper_sim.integrate.exact import ExactPropagator
from impact_damper_sim.integrate.forcing import Forcing, Harmonic
from impact_damper_sim.integrate.model import LinearModel


def _load_baseline():
    path = Path(__file__).with_name('ivp_baseline.py')
    spec = importlib.util.spec_from_file_location('ivp_baseline', path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


M, F0 = 1.0, 1.0
F_N, ZETA, R, MU, COR, D_REL = 10.0, 0.01, 1.0, 0.05, 0.6, 30.0
WN = 2 * np.pi * F_N
K = M * WN ** 2
C = 2 * ZETA * np.sqrt(K * M)
OMEGA = R * WN
D = D_REL * F0 / K
PERIOD = 2 * np.pi / OMEGA


def initial_state():
    """Post-impact-free point on the analytic orbit at t = 0: x, x', z, z' (m, m/s)."""
    orbit = symmetric_two_impact_orbit(M, K, C, F0, OMEGA, MU, COR, D)
    return orbit_state(orbit, 0.0)


def modal_model(x, z, zd):
    r = 1.0 / np.sqrt(M)
    imp = Impactor('i', 'sdof', mass=MU * M, cor=COR, clearance=D, rows=[[r]], housing_mass=M,
                   position=[z - x], velocity=[zd])
    return LinearModel(M=[[1.0]], C=[[C / M]], K=[[K / M]], B=[[r]], sensors=[[r]],
                       impactors=[imp])


def run_ours(cls, t_end, dt, **options):
    x, xd, z, zd = initial_state()
    model = modal_model(x, z, zd)
    prop = cls(model, Forcing(1, [Harmonic(0, F0, OMEGA)]), dt, q0=[np.sqrt(M) * x],
               qd0=[np.sqrt(M) * xd], **options)
    prop.advance(2)  # compile outside the timing (cache=True makes this cheap after the first)
    prop = cls(model, Forcing(1, [Harmonic(0, F0, OMEGA)]), dt, q0=[np.sqrt(M) * x],
               qd0=[np.sqrt(M) * xd], **options)
    start = time.process_time()
    samples = prop.advance(int(round(t_end / dt)))
    cpu = time.process_time() - start
    ev = prop.take_events()
    return cpu, samples.displacement[-1, 0], ev['t'][ev['kind'] == 0]


def run_baseline(base, t_end, rtol):
    x, xd, z, zd = initial_state()
    params = base.Params(M=M, K=K, c=C, F0=F0, Omega=OMEGA, mu=MU, e=COR, D=D)
    res = base.simulate(params, t_end, rtol=rtol, x0=(x, xd, z, zd), ledger=False)
    return res.cpu_time, res.y_end[0], res.impact_times


def errors(x_end, times, ref_x, ref_times):
    n = min(len(times), len(ref_times))
    dt_err = np.max(np.abs(np.asarray(times[:n]) - ref_times[:n])) if n else np.nan
    if len(times) != len(ref_times):
        dt_err = np.inf
    return abs(x_end - ref_x) / (D / 2), dt_err


def best_of(repeat, fn, *args, **kwargs):
    results = [fn(*args, **kwargs) for _ in range(repeat)]
    return min(results, key=lambda r: r[0])


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--t-end', type=float, default=10.0, help='simulated time (s)')
    parser.add_argument('--repeat', type=int, default=3, help='runs per setting (best kept)')
    args = parser.parse_args(argv)
    t_end = args.t_end
    base = _load_baseline()
    _, ref_x, ref_times = run_ours(ExactPropagator, t_end, PERIOD / 200, ledger=False)
    rows = []
    for rtol in (1e-6, 1e-8, 1e-10, 1e-12):
        cpu, x_end, times = best_of(args.repeat, run_baseline, base, t_end, rtol)
        rows.append((f'solve_ivp DOP853 rtol={rtol:g}', cpu, *errors(x_end, times, ref_x,
                                                                      ref_times)))
    for per_cycle in (20, 50):
        for ledger in (False, True):
            cpu, x_end, times = best_of(args.repeat, run_ours, ExactPropagator, t_end,
                                        PERIOD / per_cycle, ledger=ledger)
            rows.append((f'exact dt=T/{per_cycle} ledger={ledger}', cpu,
                         *errors(x_end, times, ref_x, ref_times)))
    try:
        from impact_damper_sim.integrate.newmark import NewmarkIntegrator
    except ImportError:
        NewmarkIntegrator = None
    if NewmarkIntegrator is not None:
        for impacts in ('located', 'step_end'):
            for per_cycle in (200, 2000, 20000):
                cpu, x_end, times = best_of(args.repeat, run_ours, NewmarkIntegrator, t_end,
                                            PERIOD / per_cycle, impacts=impacts, ledger=False)
                rows.append((f'newmark {impacts} dt=T/{per_cycle}', cpu,
                             *errors(x_end, times, ref_x, ref_times)))
    print(f'SDOF impact damper, {t_end:g} s simulated, f_n = {F_N} Hz, r = {R}, mu = {MU}, '
          f'e = {COR}, D = {D_REL} F0/K; reference: exact, dt = T/200')
    print(f'{"method":40s} {"CPU ms/sim s":>13s} {"RTF":>9s} {"x(t_end) err/(D/2)":>19s} '
          f'{"impact-time err (s)":>20s}')
    for name, cpu, ex, et in rows:
        print(f'{name:40s} {1e3 * cpu / t_end:13.3f} {t_end / cpu:9.0f} {ex:19.2e} {et:20.2e}')
    exact_cost = min(cpu for name, cpu, ex, et in rows if name.startswith('exact')
                     and 'ledger=False' in name)
    exact_err = max(ex for name, cpu, ex, et in rows if name.startswith('exact'))
    print(f'\nexact propagator: worst state error {exact_err:.1e} of D/2 at any setting above')
    for name, cpu, ex, _ in rows:
        if name.startswith('solve_ivp'):
            print(f'  {name}: error {ex:.1e}, cost ratio baseline/exact = '
                  f'{cpu / exact_cost:6.1f}')
    accurate = [cpu for name, cpu, ex, et in rows if name.startswith('solve_ivp') and ex < 1e-8]
    if accurate:
        print(f'cheapest baseline with error < 1e-8: ratio {min(accurate) / exact_cost:.1f} '
              f'(the exact propagator is more accurate still)')


if __name__ == '__main__':
    main()
