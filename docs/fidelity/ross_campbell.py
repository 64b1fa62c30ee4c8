"""ROSS reference for the rotordynamics output (issue 26, item 4): whirl at speed, critical speeds.

ROSS (petrobras/ross, package ross-rotordynamics) is not a dependency of impact_damper_sim:
it needs Python >= 3.13, so this script runs in its own environment:

    /root/.pyenv/versions/3.13.0/bin/python3.13 -m venv /tmp/ross313
    /tmp/ross313/bin/pip install ross-rotordynamics        # ROSS 3.1.0
    /tmp/ross313/bin/python docs/fidelity/ross_campbell.py

and writes docs/fidelity/ross_campbell.json, which test/test_fidelity_campbell.py reads.

Two rotors, each at two meshes (the finer one is the reference, the coarser bounds ROSS' own
discretization error):

* ``ross_rotor_damped``: the rotor of config/scenes/ross_rotor.yaml (docs/fidelity/
  ross_rotor.py), its bearings damped, 1000 N s/m along x and 800 N s/m along y (our y, z);
  meshes of 12 and 24 elements.
* ``overhung``: docs/fidelity/ross_overhung.yaml: a 1.0 m shaft of 50 mm on two bearings at
  0 and 0.7 m (kxx 5e6, kyy 3e6 N/m, cxx 2000, cyy 1500 N s/m), a heavy disk (width 80 mm,
  bore 50 mm, OD 350 mm) overhung at the free end; meshes of 10 and 20 elements.

Per rotor and mesh: at 0, 2500, 5000, 7500 and 10000 rpm the 8 lowest damped natural
frequencies (Hz), log decrements, whirl directions (Forward, Backward, Mixed: every node
one way, or not) and ROSS' amplitude-weighted whirl ratio (its sign where the direction is
Mixed); and the critical speeds (run_critical_speed: speed = damped frequency, 1X) of the 8
lowest modes with their log decrement and direction.
"""
import json
import sys
from pathlib import Path

import numpy as np
import ross as rs

RPMS = (0.0, 2500.0, 5000.0, 7500.0, 10000.0)
N_MODES = 8


def steel():
    return rs.Material(name='Steel_ross_campbell', rho=7810.0, E=211e9, G_s=81.2e9)


def shaft(n_el, length):
    return [rs.ShaftElement(L=length / n_el, idl=0.0, odl=0.05, material=steel(),
                            shear_effects=True, rotary_inertia=True, gyroscopic=True)
            for _ in range(n_el)]


def ross_rotor_damped(n_el):
    disk = rs.DiskElement.from_geometry(n=n_el // 2, material=steel(), width=0.07, i_d=0.05,
                                        o_d=0.28)
    bearings = [rs.BearingElement(n=n, kxx=1e6, kyy=8e5, cxx=1000.0, cyy=800.0)
                for n in (0, n_el)]
    return rs.Rotor(shaft(n_el, 1.5), [disk], bearings), disk


def overhung(n_el):
    # bearing at 0.7 of the length: node 0.7 n_el (n_el a multiple of 10)
    disk = rs.DiskElement.from_geometry(n=n_el, material=steel(), width=0.08, i_d=0.05,
                                        o_d=0.35)
    bearings = [rs.BearingElement(n=n, kxx=5e6, kyy=3e6, cxx=2000.0, cyy=1500.0)
                for n in (0, 7 * n_el // 10)]
    return rs.Rotor(shaft(n_el, 1.0), [disk], bearings), disk


def record(rotor):
    rows = {}
    for rpm in RPMS:
        m = rotor.run_modal(speed=rpm * np.pi / 30.0, num_modes=2 * N_MODES)
        rows[f'{rpm:g}'] = dict(
            wd_hz=(m.wd[:N_MODES] / (2 * np.pi)).tolist(),
            log_dec=np.asarray(m.log_dec[:N_MODES], dtype=float).tolist(),
            whirl=[str(w) for w in m.whirl_direction()[:N_MODES]],
            whirl_ratio=[float(rs.Rotor._whirl_ratio(s)) for s in m.shapes[:N_MODES]])
    crit = rotor.run_critical_speed(num_modes=2 * N_MODES, rtol=1e-10)
    critical = dict(speed_rpm=np.asarray(crit.wd('rpm'), dtype=float).tolist(),
                    log_dec=np.asarray(crit.log_dec, dtype=float).tolist(),
                    whirl=[str(w) for w in crit.whirl_direction])
    return dict(modal=rows, critical=critical)


def main():
    out = dict(ross_version=rs.__version__, python=sys.version.split()[0], rotors={})
    for name, build, meshes in (('ross_rotor_damped', ross_rotor_damped, (12, 24)),
                                ('overhung', overhung, (10, 20))):
        out['rotors'][name] = {}
        for n_el in meshes:
            rotor, disk = build(n_el)
            out['rotors'][name][f'{n_el} elements'] = record(rotor)
            out['rotors'][name]['disk'] = dict(m=disk.m, Ip=disk.Ip, Id=disk.Id)
            print(name, n_el, {k: np.round(v['wd_hz'], 3).tolist()
                               for k, v in out['rotors'][name][f'{n_el} elements']['modal']
                               .items()}, flush=True)
    Path(__file__).with_name('ross_campbell.json').write_text(json.dumps(out, indent=1))


if __name__ == '__main__':
    main()
