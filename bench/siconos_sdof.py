#!/usr/bin/python3
"""Siconos 4.4 peer for the SDOF impact damper (Masri-Caughey), from rest.

Runs under the *system* Python with the Debian package ``python3-siconos`` (not the venv;
Siconos is never a dependency of impact_damper_sim). Prints one JSON line per run: the
per-forcing-period peak housing displacement and the impact times, so that
``docs/fidelity/attractor.py`` can compare them with our methods impact by impact.

Model: housing mass M on spring K (dashpot c), impactor m = mu M in a slot of travel D,
coordinates q = (x, z, y). The harmonic force F0 cos(Omega t) is produced by an exciter
coordinate y, an undamped oscillator of frequency Omega started at y = 1, y' = 0 and coupled
into the housing row of K (K[0, 2] = -F0): the system stays linear time-invariant, so
Siconos' event-driven LSODAR integrates it without a compiled plugin, and the force is exact.
Walls: y1 = D/2 - (z - x) >= 0 and y2 = D/2 + (z - x) >= 0, Newton impact law with e.

Usage: siconos_sdof.py r zeta mu e d periods [ed|mj] [steps_per_period]
(d is the clearance D in units of F0/K; mass, stiffness and F0 as in test_analytic_sdof).
"""
import json
import sys
import time

import numpy as np
import siconos.kernel as sk

M, K, F0 = 2.0, 5.0e4, 10.0


def build(r, zeta, mu, e, d):
    wn = np.sqrt(K / M)
    omega = r * wn
    D = d * F0 / K
    Mm = np.diag([M, mu * M, 1.0])
    Km = np.zeros((3, 3))
    Km[0, 0] = K
    Km[0, 2] = -F0             # force on the housing: +F0 y(t) = F0 cos(Omega t)
    Km[2, 2] = omega ** 2
    Cm = np.zeros((3, 3))
    Cm[0, 0] = 2.0 * zeta * np.sqrt(K * M)
    ds = sk.LagrangianLinearTIDS([0.0, 0.0, 1.0], [0.0, 0.0, 0.0], Mm)
    ds.setKPtr(Km)
    ds.setCPtr(Cm)
    return ds, omega, D


def run(r, zeta, mu, e, d, periods, scheme='ed', per=400):
    ds, omega, D = build(r, zeta, mu, e, d)
    P = 2.0 * np.pi / omega
    T = periods * P
    nsds = sk.NonSmoothDynamicalSystem(0.0, T)
    nsds.insertDynamicalSystem(ds)
    walls = []
    for sign in (+1.0, -1.0):
        # y = H q + b >= 0: sign=+1 the + wall (z - x <= D/2), sign=-1 the - wall
        H = np.array([[sign, -sign, 0.0]])
        rel = sk.LagrangianLinearTIR(H, [D / 2.0])
        inter = sk.Interaction(sk.NewtonImpactNSL(e), rel)
        nsds.link(inter, ds)
        walls.append(inter)
    h = P / per
    td = sk.TimeDiscretisation(0.0, h)
    if scheme == 'ed':
        osi = sk.LsodarOSI()
        sim = sk.EventDriven(nsds, td)
        sim.insertIntegrator(osi)
        sim.insertNonSmoothProblem(sk.LCP(), sk.SICONOS_OSNSP_ED_IMPACT)
        sim.insertNonSmoothProblem(sk.LCP(), sk.SICONOS_OSNSP_ED_SMOOTH_ACC)
        osi.setTol(1, 1e-12, 1e-16)   # itol, rtol, atol of LSODAR
    else:
        osi = sk.MoreauJeanOSI(0.5)
        sim = sk.TimeStepping(nsds, td, osi, sk.LCP())
    q = ds.q()
    v = ds.velocity()
    t_out, x_out, impacts = [], [], []
    t0 = time.time()
    failure = None
    while sim.hasNextEvent():
        if scheme == 'ed':
            sim.advanceToEvent()
        else:
            sim.computeOneStep()
        t = sim.nextTime()
        pre = v[1] - v[0]
        if scheme == 'ed':
            try:
                sim.processEvents()
            except Exception as exc:  # LSODAR/LCP failure (e.g. an accumulation of impacts)
                failure = f'{type(exc).__name__} {exc} at t = {t:.9g} s'
                break
            jump = (v[1] - v[0]) - pre
            if abs(jump) > 1e-12 * (1.0 + abs(pre)):
                # impact: wall from the sign of z - x, approach speed before
                impacts.append((t, float(np.sign(q[1] - q[0])), abs(pre)))
        else:
            lam = [w.lambda_(1)[0] for w in walls]
            for k, lam_k in enumerate(lam):
                if lam_k > 0.0:
                    impacts.append((t, 1.0 if k == 0 else -1.0, float('nan')))
        t_out.append(t)
        x_out.append(q[0])
        if scheme != 'ed':
            sim.nextStep()
    t_out, x_out = np.array(t_out), np.array(x_out)
    cycle = np.floor(t_out / P).astype(int)
    done = int(cycle.max()) if failure else periods  # complete periods only
    amps = np.zeros(periods)
    np.maximum.at(amps, np.clip(cycle, 0, periods - 1), np.abs(x_out))
    amps = amps[:done]
    return dict(point=[r, zeta, mu, e, d], scheme=scheme, per=per, periods=periods,
                wall_s=time.time() - t0, failure=failure, amps=amps.tolist(), impacts=impacts)


if __name__ == '__main__':
    a = sys.argv[1:]
    scheme = a[6] if len(a) > 6 else 'ed'
    per = int(a[7]) if len(a) > 7 else 400
    out = run(*(float(s) for s in a[:5]), int(a[5]), scheme, per)
    print(json.dumps(out))
