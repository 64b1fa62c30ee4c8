"""Gyroscopic coupling of a spinning disk: forward and backward whirl in closed form."""
import numpy as np
import pytest

from impact_damper_sim.modal.stability import state_matrix
from impact_damper_sim.scene.build import load
from impact_damper_sim.scene.schema import SceneError

SCENE = """
name: disk
description: a rigid disk on a rotational spring (conical whirl only)
structure:
  kind: beam
  material: {{E: 200 GPa, nu: 0.3, rho: 7850 kg/m^3}}
  nodes:
    - {{id: 0, xyz: [0, 0, 0]}}
  point_masses:
    - {{node: 0, mass: 5 kg, inertia: [{ip}, {id}, {id}]}}
  springs:
    - {{node: 0, dof: ry, rotational_stiffness: {k} N*m/rad}}
    - {{node: 0, dof: rz, rotational_stiffness: {k} N*m/rad}}
  clamps:
    - {{node: 0, dofs: [ux, uy, uz, rx]}}
sensors:
  - {{name: tilt_y, node: 0, dof: ry}}
rotor:
  speed: {speed_line}
  gyroscopic: {{nodes: [0]}}
"""


def _scene(tmp_path, ip=0.4, id_=0.25, k=2.0e4, speed=300.0, speed_line=None):
    path = tmp_path / 'disk.yaml'
    line = speed_line or f'{{kind: constant, speed: {speed} rad/s}}'
    path.write_text(SCENE.format(ip=ip, id=id_, k=k, speed_line=line))
    return load(str(path))


@pytest.mark.parametrize('speed', [0.0, 150.0, 600.0])
def test_forward_and_backward_whirl_match_closed_form(tmp_path, speed):
    # Id th'' + Ip W th_z' + k th_y = 0, Id th_z'' - Ip W th_y' + k th_z = 0 gives
    # Id w^2 -+ Ip W w - k = 0: w_b,f = (-+ Ip W + sqrt(Ip^2 W^2 + 4 Id k))/(2 Id). 1e-9.
    ip, id_, k = 0.4, 0.25, 2.0e4
    scene = _scene(tmp_path, ip, id_, k, speed)
    lam = np.linalg.eigvals(state_matrix(scene.model.K, scene.model.C))
    whirl = np.sort(np.abs(lam.imag))[::2]
    root = np.sqrt(ip ** 2 * speed ** 2 + 4 * id_ * k)
    expected = np.sort([(-ip * speed + root) / (2 * id_), (ip * speed + root) / (2 * id_)])
    np.testing.assert_allclose(whirl, expected, rtol=1e-9)
    assert np.max(np.abs(lam.real)) < 1e-9 * np.max(np.abs(lam))  # no work done: undamped
    # the coupling is skew-symmetric and proportional to the speed
    C = scene.model.C
    np.testing.assert_allclose(C, -C.T, atol=1e-12 * max(np.abs(C).max(), 1.0))


def test_gyroscopic_needs_constant_speed_and_a_polar_inertia(tmp_path):
    with pytest.raises(SceneError, match='rotor.gyroscopic'):
        _scene(tmp_path, speed_line='{kind: paper_ramp}')
    with pytest.raises(SceneError, match=r'rotor\.gyroscopic\.nodes\[0\]'):
        _scene(tmp_path, ip=0.0)
