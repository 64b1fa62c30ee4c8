"""ROSS reference for the rotor scene config/scenes/ross_rotor.yaml (issue 14).

ROSS (petrobras/ross, package ross-rotordynamics) is not a dependency of
impact_damper_sim: it needs Python >= 3.13, so this script runs in its own environment,
e.g.

    python3.13 -m venv /tmp/ross && /tmp/ross/bin/pip install ross-rotordynamics
    /tmp/ross/bin/python docs/fidelity/ross_rotor.py

and writes docs/fidelity/ross_rotor.json, which test/test_fidelity_rotor.py reads.

Rotor: a steel shaft 1.5 m long, 50 mm diameter, Timoshenko elements (shear, rotary
inertia, gyroscopics: ROSS' ShaftElement defaults), one disk (width 70 mm, bore 50 mm,
outer diameter 280 mm) at mid-span, bearings at both ends with kxx = 1e6 N/m and
kyy = 8e5 N/m, no damping. Meshes of 6 and 24 elements (the 24-element one is the
converged reference). Damped natural frequencies (Hz) and whirl directions at 0, 2500,
5000 and 10000 rpm, plus the same rotor with the shaft's gyroscopic terms switched off
(to measure what they contribute).
"""
import json
import sys
from pathlib import Path

import numpy as np
import ross as rs

RPMS = (0.0, 2500.0, 5000.0, 10000.0)
N_MODES = 8


def rotor(n_el, shaft_gyroscopic=True):
    steel = rs.Material(name='Steel_ross_rotor', rho=7810.0, E=211e9, G_s=81.2e9)
    L = 1.5 / n_el
    shaft = [rs.ShaftElement(L=L, idl=0.0, odl=0.05, material=steel, shear_effects=True,
                             rotary_inertia=True, gyroscopic=shaft_gyroscopic)
             for _ in range(n_el)]
    disk = rs.DiskElement.from_geometry(n=n_el // 2, material=steel, width=0.07, i_d=0.05,
                                        o_d=0.28)
    bearings = [rs.BearingElement(n=0, kxx=1e6, kyy=8e5, cxx=0.0),
                rs.BearingElement(n=n_el, kxx=1e6, kyy=8e5, cxx=0.0)]
    return rs.Rotor(shaft, [disk], bearings), disk, steel


def main():
    out = dict(ross_version=rs.__version__, python=sys.version.split()[0], meshes={})
    for n_el in (6, 24):
        for gyro in (True, False):
            r, disk, steel = rotor(n_el, gyro)
            key = f'{n_el} elements' + ('' if gyro else ', no shaft gyroscopics')
            rows = {}
            for rpm in RPMS:
                m = r.run_modal(speed=rpm * np.pi / 30.0, num_modes=2 * N_MODES)
                rows[f'{rpm:g}'] = dict(wd_hz=(m.wd[:N_MODES] / (2 * np.pi)).tolist(),
                                        whirl=list(m.whirl_direction()[:N_MODES]))
            out['meshes'][key] = rows
            out['disk'] = dict(m=disk.m, Ip=disk.Ip, Id=disk.Id)
            out['material'] = dict(rho=steel.rho, E=steel.E, G_s=steel.G_s, Poisson=steel.Poisson)
            print(key, {k: np.round(v['wd_hz'], 3).tolist() for k, v in rows.items()})
    Path(__file__).with_name('ross_rotor.json').write_text(json.dumps(out, indent=1))


if __name__ == '__main__':
    main()
