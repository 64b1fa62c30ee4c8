"""The paper's stuck formulation (``simulation.stuck_model: basis_switch``) on rotor scenes.

A rotor adds two things to a scene that every stuck basis must carry as well as the free
one: the unbalance force inputs (two per ``rotor.unbalance`` entry, after the ``forcing``
inputs) and the gyroscopic coupling ``Omega Phi^T G Phi`` of ``rotor.gyroscopic``. Both are
checked in closed form on a rigid spinning disk with a ring damper, where the translations
and the tilts do not couple: sticking adds the ring's mass to the translations only, and the
tilts keep their forward and backward whirl. Each test states its tolerance.
"""
import numpy as np
import pytest

from impact_damper_sim.integrate.basis_switch import BasisSwitch
from impact_damper_sim.modal.stability import state_matrix
from impact_damper_sim.scene.build import load

MASS, IP, ID = 5.0, 0.4, 0.25          # disk: kg, polar and diametral inertia (kg m^2)
K_T, K_R = 2.0e5, 2.0e4                # translational (N/m) and tilt (N m/rad) springs
SPEED = 300.0                          # rad/s
RING = 0.5                             # ring damper mass (kg)

DISK = f"""
name: disk
description: a rigid spinning disk on springs, a ring damper at its centre
structure:
  kind: beam
  material: {{E: 200 GPa, nu: 0.3, rho: 7850 kg/m^3}}
  nodes: [{{id: 0, xyz: [0, 0, 0]}}]
  point_masses:
    - {{node: 0, mass: {MASS} kg, inertia: [{IP} kg*m^2, {ID} kg*m^2, {ID} kg*m^2]}}
  springs:
    - {{node: 0, dof: uy, stiffness: {K_T} N/m}}
    - {{node: 0, dof: uz, stiffness: {K_T} N/m}}
    - {{node: 0, dof: ry, rotational_stiffness: {K_R} N*m/rad}}
    - {{node: 0, dof: rz, rotational_stiffness: {K_R} N*m/rad}}
  clamps:
    - {{node: 0, dofs: [ux, rx]}}
modal:
  n_modes: 4
  damping: {{default: 0}}
sensors:
  - {{name: y, node: 0, dof: uy}}
  - {{name: tilt_y, node: 0, dof: ry}}
rotor:
  speed: {{kind: constant, speed: {SPEED} rad/s}}
  gyroscopic: {{nodes: [0]}}
  unbalance:
    - {{node: 0, amount: 1e-3 kg*m, phase: 0 deg}}
impactors:
  - {{name: ring, kind: planar, node: 0, plane: [uy, uz], mass: {RING} kg, cor: 0.5,
     clearance: 0.1 mm}}
simulation:
  method: exact
  dt: 1 ms
  duration: 0.5 s
  window: 0.25 s
"""

ROTOR_SCENES = ('hpotp', 'hpotp_x10', 'rbs', 'rbs_kcc', 'ross_rotor')


@pytest.fixture
def disk(tmp_path):
    path = tmp_path / 'disk.yaml'
    path.write_text(DISK)
    return load(str(path))


def whirl_rad_s(model):
    """Damped natural frequencies of a modal model, each once (rad/s), ascending."""
    lam = np.linalg.eigvals(state_matrix(model.K, model.C))
    return np.sort(np.abs(lam.imag))[::2]


def test_stuck_basis_keeps_the_gyroscopic_coupling_and_the_unbalance_inputs(disk):
    # Stuck: translations sqrt(K_T/(MASS + RING)) twice; tilts Id w^2 -+ Ip W w - k = 0,
    # w = (-+ Ip W + sqrt(Ip^2 W^2 + 4 Id k))/(2 Id), as free. 1e-9 relative.
    stuck, masses, carried = disk.basis_switch().model((1,))
    assert masses == (0.0,) and carried == (RING,)
    root = np.sqrt(IP ** 2 * SPEED ** 2 + 4 * ID * K_R)
    expected = np.sort([(root - IP * SPEED) / (2 * ID), (root + IP * SPEED) / (2 * ID),
                        np.sqrt(K_T / (MASS + RING)), np.sqrt(K_T / (MASS + RING))])
    np.testing.assert_allclose(whirl_rad_s(stuck), expected, rtol=1e-9)
    # the two unbalance inputs (uy, uz) on the stuck basis: static compliance 1/K_T at the
    # translation sensor, none at the tilt sensor, whatever the mass. 1e-12 relative.
    assert stuck.input_names == ('unbalance0_uy', 'unbalance0_uz')
    static = stuck.sensors @ np.linalg.solve(stuck.K, stuck.B)
    np.testing.assert_allclose(static, [[1.0 / K_T, 0.0], [0.0, 0.0]], rtol=0,
                               atol=1e-12 / K_T)


def test_complete_basis_equals_mass_update_on_a_spinning_disk(disk):
    # A complete basis without tare damping: the two formulations are the same model, so
    # the same events (to 1e-8 s) and responses (1e-7 of the peak; measured 8.7e-9 and 2.2e-9
    # s over 1278 impacts and 236 sticks), and both ledgers close (1e-12; measured 6e-14).
    runs = {}
    for stuck_model in ('mass_update', 'basis_switch'):
        sim = disk.make_simulation(stuck_model=stuck_model)
        runs[stuck_model] = (sim.advance_to(0.5), sim.take_events(), sim.energy())
    (s_mu, ev_mu, led_mu), (s_bs, ev_bs, led_bs) = runs['mass_update'], runs['basis_switch']
    assert np.sum(ev_mu['kind'] == 1) >= 100
    assert ev_bs.size == ev_mu.size
    np.testing.assert_array_equal(ev_bs['kind'], ev_mu['kind'])
    assert np.max(np.abs(ev_bs['t'] - ev_mu['t'])) < 1e-8
    peak = np.max(np.abs(s_mu.displacement), axis=0)
    assert np.all(np.abs(s_bs.displacement - s_mu.displacement) <= 1e-7 * peak)
    for led in (led_mu, led_bs):
        assert abs(led.relative_residual) < 1e-12


def test_a_model_with_gyroscopic_damping_needs_its_terms(disk):
    # without the gyroscopic terms the stuck bases would lose the coupling: refused up front
    args = (disk.system, disk.basis, disk.model, disk.impactor_dofs)
    with pytest.raises(ValueError, match='gyroscopic'):
        BasisSwitch(*args, force_indices=disk.input_dofs)
    switch = BasisSwitch(*args, force_indices=disk.input_dofs,
                         gyroscopic=disk.gyroscopic_terms())
    assert switch.gyroscopic == ((disk.system.index(0, 'ry'), disk.system.index(0, 'rz'),
                                  IP * SPEED),)


@pytest.mark.parametrize('name', ROTOR_SCENES)
def test_every_rotor_scene_runs_with_basis_switch(name):
    # Until the first stick both formulations integrate the same free model with the same
    # unbalance inputs: identical sensor outputs over 20 ms (measured: equal to the bit).
    scene = load(name)
    runs = [scene.make_simulation(stuck_model=m) for m in ('mass_update', 'basis_switch')]
    samples = [sim.advance_to(0.02) for sim in runs]
    assert not any(np.any(sim.take_events()['kind'] == 1) for sim in runs)
    assert runs[1].model.n_inputs == len(scene.input_dofs) >= 2
    np.testing.assert_array_equal(samples[1].displacement, samples[0].displacement)
