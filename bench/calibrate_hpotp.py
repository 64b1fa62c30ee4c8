"""Calibrate the HPOTP casing scene (config/scenes/hpotp.yaml) to the paper's frequencies.

NASA's finite-element data for the SSME HPOTP (paper section 4.3) is not public, so the
scene is a representative casing whose boundary is tuned. Three numbers are solved for,
everything else is fixed in the scene file:

``k_r``
    HGM rocking stiffness (lbf in/rad, about y and z at the HGM elastic centre): sets the
    first bending pair (the paper's "first mode at 77 Hz ... (78 Hz)").
``k_t``
    HGM lateral stiffness (lbf/in, y and z at the elastic centre): sets the second bending
    pair, placed (our choice) at F_PAIR2 Hz, below full speed so the ramp crosses it.
``k_pipe``
    Axial stiffness (lbf/in) of the two pipe ducts, which run along global y: it makes the
    y pair stiffer than the z pair; tuned to the paper's 77 Hz / 78 Hz split.

The HGM super element is the 6x6 stiffness of springs at the HGM elastic centre, a distance
``E_OFFSET`` above the flange node 17, transformed to node 17 (a rigid offset along x):
``u_c = u + theta x (e, 0, 0)``, so the (uy, rz) block is [[k_t, e k_t], [e k_t,
k_r + e^2 k_t]] and the (uz, ry) block the same with -e k_t off the diagonal.

Usage::

    .venv/bin/python bench/calibrate_hpotp.py          # solve, print modes and YAML rows
    .venv/bin/python bench/calibrate_hpotp.py --check  # modes of the scene file as it is
    .venv/bin/python bench/calibrate_hpotp.py --reduction 1,10 [--set KEY=VALUE ...] [--ledger]

Run time: about two seconds (``--reduction``: seconds at X = 1, about a minute at X = 10).

``--reduction`` measures the impact damper at the 240 Hz criticals (modes 3 and 4) on a
ramp *window* instead of the whole 6 s run: the speed rises linearly from 1150 to 1850 rad/s
at the paper's rate, 480 rad/s^2 (2400 rad/s in 5 s), with and without impactors, for each
unbalance multiple X. It prints the worst-case node-1 acceleration (800 Hz low-pass, 4 kHz
sampling, as in ``test/test_hpotp_unbalance.py``) and displacement, their reductions and the
amplitude the damper removes (without - with, mil). With ``--ledger`` it also prints, per
50 ms, the energy dissipated by impacts and sticking next to the tare damping's. The window
reproduces the whole run at X = 10 (52.71 g with impactors in both); at X = 1 the whole run
reads 4.03 g, the window 3.84 g (the impactors enter the 240 Hz critical with the motion left
by the 77 Hz one). The motion of twelve impactors is chaotic: round-off differences (another
initial spread, or advancing in 50 ms chunks as ``--ledger`` does) move the levels with
impactors by a few percent (X = 3: 14.3 to 15.1 g). docs/hpotp-model.md, "Why the reduction
falls with X", uses it.
"""
from __future__ import annotations

import argparse
import sys

import numpy as np
from scipy.optimize import least_squares

from impact_damper_sim.scene.build import build
from impact_damper_sim.scene.catalog import resolve_scene
from impact_damper_sim.scene.loading import load_yaml
from impact_damper_sim.scene.schema import validate
from impact_damper_sim.scene.spec import SCHEMA

#: Targets (Hz): the paper's first pair (section 4.3: "first mode at 77 Hz", "first mode
#: (78 Hz)"), and our second pair, between the first pair and full speed (381 Hz).
F1_Z, F1_Y, F_PAIR2 = 77.0, 78.0, 240.0

#: Fixed by us (see docs/hpotp-model.md).
E_OFFSET = 4.0          # in, HGM elastic centre above the flange node
K_AXIAL = 2.0e7         # lbf/in, HGM axial
K_TORSION = 2.0e9       # lbf in/rad, HGM torsion about the pump axis
K_PIPE_LATERAL = 2000.0  # lbf/in, each duct across its own axis (ux and uz)
PIPE_NODES = (2, 5)     # inlet and discharge ducts
HGM_NODE = 17
START = (5.0e9, 8.0e5, 5.0e3)   # k_r, k_t, k_pipe first guesses
BOUNDS = ((1.0e8, 1.0e5, 1.0e2), (1.0e11, 1.0e7, 1.0e5))   # lower, upper

COMPONENTS = ('ux', 'uy', 'uz', 'rx', 'ry', 'rz')


def hgm_matrix(k_r, k_t, e=E_OFFSET, k_a=K_AXIAL, k_tor=K_TORSION):
    """6x6 HGM stiffness at the flange node in (ux, uy, uz, rx, ry, rz), lbf and in."""
    K = np.zeros((6, 6))
    K[0, 0] = k_a
    K[3, 3] = k_tor
    for u, r, sign in ((1, 5, 1.0), (2, 4, -1.0)):   # (uy, rz) and (uz, ry)
        K[u, u] = k_t
        K[u, r] = K[r, u] = sign * e * k_t
        K[r, r] = k_r + e * e * k_t
    return K


def with_parameters(raw, k_r, k_t, k_pipe):
    """Return a copy of the raw scene with the calibrated entries replaced."""
    import copy
    raw = copy.deepcopy(raw)
    st = raw['structure']
    se = st['super_elements'][0]
    assert [d['node'] for d in se['dofs']] == [HGM_NODE] * 6
    assert [d['dof'] for d in se['dofs']] == list(COMPONENTS)
    se['stiffness'] = [[float(f'{v:.6g}') for v in row] for row in hgm_matrix(k_r, k_t)]
    springs = []
    for node in PIPE_NODES:
        for dof, k in (('ux', K_PIPE_LATERAL), ('uy', k_pipe), ('uz', K_PIPE_LATERAL)):
            springs.append({'node': node, 'dof': dof, 'stiffness': f'{k:.6g} lb/in'})
    st['springs'] = springs
    return raw


def build_raw(raw, n_modes=None):
    """Build a raw scene dict; ``n_modes`` overrides the retained count."""
    if n_modes is not None:
        raw = dict(raw, modal=dict(raw['modal'], n_modes=n_modes))
    return build(validate(SCHEMA, raw, source='hpotp'), source='hpotp')


def classify(scene):
    """Per mode: kinetic-energy fraction by component class and a short label."""
    system, basis = scene.system, scene.basis
    phi = basis.rows(list(range(system.n_dof)))          # (n_dof, n_modes)
    m = system.M.diagonal()
    comp = system.dofs[:, 1]
    out = []
    for k in range(basis.n_modes):
        ke = m * phi[:, k] ** 2
        frac = {c: float(ke[comp == i].sum() / ke.sum()) for i, c in enumerate(COMPONENTS)}
        lateral_y = frac['uy'] + frac['rz']
        lateral_z = frac['uz'] + frac['ry']
        kind = max((('bending y', lateral_y), ('bending z', lateral_z),
                    ('axial', frac['ux']), ('torsion', frac['rx'])), key=lambda p: p[1])[0]
        out.append((kind, frac))
    return out


def pair_frequencies(scene):
    """(f of 1st z pair, 1st y, 2nd z, 2nd y) in Hz, from the mode labels."""
    f = scene.basis.frequencies_hz
    kinds = [k for k, _ in classify(scene)]
    z = [f[i] for i, k in enumerate(kinds) if k == 'bending z']
    y = [f[i] for i, k in enumerate(kinds) if k == 'bending y']
    return z[0], y[0], z[1], y[1]


def solve(raw):
    """Solve (k_r, k_t, k_pipe) for the three targets; return them and the built scene."""
    def residual(logp):
        p = np.exp(logp)
        fz1, fy1, fz2, fy2 = pair_frequencies(build_raw(with_parameters(raw, *p), 12))
        return [fz1 / F1_Z - 1.0, fy1 / F1_Y - 1.0, 0.5 * (fz2 + fy2) / F_PAIR2 - 1.0]

    res = least_squares(residual, np.log(START), bounds=np.log(BOUNDS), xtol=1e-12,
                        ftol=1e-12, gtol=1e-12, diff_step=1e-4)
    if np.max(np.abs(res.fun)) > 1e-5:
        raise RuntimeError(f'calibration did not converge: {res.message} (residual {res.fun})')
    p = np.exp(res.x)
    # round to 4 significant digits, the precision written to the scene file
    p = np.array([float(f'{v:.4g}') for v in p])
    return p, build_raw(with_parameters(raw, *p))


def report(scene):
    """Print masses, the retained modes and their labels."""
    m = scene.system.M.diagonal()
    ux = scene.system.dofs[:, 1] == 0
    beam = scene.scene['structure']
    lumped = sum(pm['mass'] for pm in beam['point_masses'])
    total = float(m[ux].sum())
    print(f'mass: total {total:.1f} kg ({total / 0.45359237:.0f} lb), lumped {lumped:.1f} kg, '
          f'casing tube {total - lumped:.1f} kg')
    print(f'{"mode":>4} {"f (Hz)":>10} {"below 381 Hz":>12}  kind       node-1 uy / uz')
    iy, iz = scene.system.index(1, 'uy'), scene.system.index(1, 'uz')
    for k, (kind, _) in enumerate(classify(scene)):
        f = scene.basis.frequencies_hz[k]
        rows = scene.basis.rows([iy, iz])[:, k]
        print(f'{k + 1:>4} {f:>10.2f} {"yes" if f < 381.0 else "no":>12}  {kind:<10} '
              f'{rows[0]: .4f} / {rows[1]: .4f}')


def reduction(multipliers, overrides=(), omega=(1150.0, 1850.0), rate=480.0, ledger=False):
    """Ramp-window damper measurement at the 240 Hz criticals (see the module docstring)."""
    from impact_damper_sim.live.filters import scene_lowpass
    from impact_damper_sim.scene.build import load
    from impact_damper_sim.studies.analysis import G0
    dt, mil = 2.5e-4, 2.54e-5
    duration = (omega[1] - omega[0]) / rate
    speed = (f'rotor.speed={{kind: piecewise, times: [0 s, {duration!r} s], '
             f'speeds: [{omega[0]!r} rad/s, {omega[1]!r} rad/s]}}')
    base = [speed] + [o for o in overrides if not o.startswith('impactors')]

    def worst(scene_overrides, with_ledger):
        scene = load('hpotp', scene_overrides)
        sim = scene.make_simulation('exact', dt, ledger=with_ledger)
        lowpass = scene_lowpass(scene, dt)
        v0 = sim.integrator.model.sensors @ sim.integrator.state()[1]
        rows, acc, disp = [], [], []
        t, prev = 0.0, (sim.energy() if with_ledger else None)
        chunk = 0.05 if with_ledger else duration   # chunking perturbs the chaotic impacts
        while t < duration - 1e-9:
            t = min(t + chunk, duration)
            samples = sim.advance_to(t)
            acc.append(np.abs(lowpass.apply(sim.mean_acceleration(samples, v0))).max() / G0)
            disp.append(np.abs(samples.displacement).max() / mil)
            v0 = samples.velocity[-1]
            if with_ledger:
                e = sim.energy()
                rows.append((t, disp[-1], e.impacts + e.sticking - prev.impacts - prev.sticking,
                             e.damping - prev.damping))
                prev = e
        return max(acc), max(disp), rows

    print(f'ramp window {omega[0]:g} -> {omega[1]:g} rad/s at {rate:g} rad/s^2 '
          f'({duration:.3f} s); overrides {list(overrides)}')
    print(f'{"X":>4} {"without (g)":>11} {"with (g)":>9} {"reduct":>6} {"without (mil)":>13} '
          f'{"with (mil)":>10} {"reduct":>6} {"removed (mil)":>13}')
    for x in multipliers:
        mult = [f'rotor.multiplier={x!r}']
        a0, d0, _ = worst(['impactors=[]'] + base + mult, False)
        a1, d1, rows = worst([speed] + list(overrides) + mult, ledger)
        print(f'{x:>4g} {a0:>11.3f} {a1:>9.3f} {a0 / a1:>6.3f} {d0:>13.3f} {d1:>10.3f} '
              f'{d0 / d1:>6.3f} {d0 - d1:>13.3f}', flush=True)
        for t, d, e_imp, e_damp in rows:
            print(f'       t {t:5.2f} s  max disp {d:6.3f} mil  impacts+sticking {e_imp:9.4g} J'
                  f'  tare damping {e_damp:9.4g} J')


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--check', action='store_true',
                        help='report the scene file as it is, do not calibrate')
    parser.add_argument('--reduction', metavar='X,...',
                        help='measure the damper on a ramp window through the 240 Hz criticals '
                             'for these unbalance multiples (see the module docstring)')
    parser.add_argument('--set', action='append', default=[], metavar='KEY=VALUE',
                        help='(--reduction) scene override, repeatable')
    parser.add_argument('--rate', type=float, default=480.0,
                        help='(--reduction) ramp rate, rad/s^2 (default 480, the paper\'s)')
    parser.add_argument('--ledger', action='store_true',
                        help='(--reduction) print impact vs tare dissipation per 50 ms')
    args = parser.parse_args(argv)
    if args.reduction:
        reduction([float(x) for x in args.reduction.split(',')], args.set, rate=args.rate,
                  ledger=args.ledger)
        return 0
    raw = load_yaml(resolve_scene('hpotp'))
    if args.check:
        report(build_raw(raw))
        return 0
    p, scene = solve(raw)
    k_r, k_t, k_pipe = p
    print(f'k_r = {k_r:.4g} lbf in/rad, k_t = {k_t:.4g} lbf/in, k_pipe = {k_pipe:.4g} lbf/in '
          f'(e = {E_OFFSET} in, k_axial = {K_AXIAL:.4g} lbf/in, '
          f'k_torsion = {K_TORSION:.4g} lbf in/rad)')
    report(scene)
    print('\nsuper_elements[0].stiffness (lbf, in):')
    for row in hgm_matrix(k_r, k_t):
        print('        - [' + ', '.join(f'{v:.6g}' for v in row) + ']')
    print('springs:')
    for s in with_parameters(raw, *p)['structure']['springs']:
        print(f"    - {{node: {s['node']}, dof: {s['dof']}, stiffness: {s['stiffness']}}}")
    return 0


if __name__ == '__main__':
    sys.exit(main())
