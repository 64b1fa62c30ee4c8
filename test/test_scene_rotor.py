"""Scene ``rotor`` section: validation messages, builder wiring and the exact unbalance response."""
import textwrap

import numpy as np
import pytest

from impact_damper_sim.modal.basis import harmonic_response
from impact_damper_sim.scene.build import load
from impact_damper_sim.scene.excitation import CommandedSpeed, ConstantSpeed, PaperRamp
from impact_damper_sim.scene.schema import SceneError
from impact_damper_sim.scene.units import parse_quantity

# A clamped-free steel shaft along X with a disk at the tip: a few well-separated modes.
BEAM = textwrap.dedent("""
    name: rotor_beam
    structure:
      kind: beam
      material: {E: 200 GPa, nu: 0.3, rho: 7850}
      sections:
        shaft: {shape: solid_circular, diameter: 30 mm}
      lines:
        - {from: [0, 0, 0], to: [0.6, 0, 0], n_elements: 4, section: shaft}
      point_masses:
        - {node: 4, mass: 5 kg}
      springs:
        - {node: 4, dof: uz, stiffness: 2e5}    # makes y and z differ
      clamps:
        - {node: 0}
    modal:
      n_modes: 4
      damping: {default: 0.2}
    sensors:
      - {name: tip_y, node: 4, dof: uy, lowpass: 2 kHz}
      - {name: tip_z, node: 4, dof: uz}
    rotor:
      speed: {kind: constant, speed: 600 rpm}
      unbalance:
        - {node: 4, amount: 2 oz*in, phase: 30 deg}
        - {node: 2, amount: 1e-4, phase: 0}
      multiplier: 1.5
    """)


@pytest.fixture
def beam_file(tmp_path):
    path = tmp_path / 'rotor_beam.yaml'
    path.write_text(BEAM)
    return path


def problem(path, overrides=()):
    with pytest.raises(SceneError) as info:
        load(path, overrides)
    return str(info.value)


@pytest.mark.parametrize('override, key, words', [
    ('rotor.speed.kind=spinning', 'rotor.speed.kind', 'constant'),
    ('rotor.speed.speed=-5 rpm', 'rotor.speed.speed', 'out of range'),
    ('rotor.speed.speed=5 Hz', 'rotor.speed.speed', 'rpm'),
    ('rotor.speed.max_rate=10 rpm/s', 'rotor.speed', "key 'max_rate' does not apply"),
    ('rotor.speed.kind=commanded', 'rotor.speed', "kind commanded needs key 'max_rate'"),
    ('rotor.speed={kind: piecewise, times: [0, 1], speeds: [0]}', 'rotor.speed',
     'same length'),
    ('rotor.speed={kind: piecewise, times: [1, 1], speeds: [0, 1]}', 'rotor.speed',
     'strictly increasing'),
    ('rotor.speed={kind: paper_ramp, ramp_time: 0 s}', 'rotor.speed.ramp_time',
     'out of range'),
    ('rotor.multiplier=-1', 'rotor.multiplier', 'out of range'),
    ('rotor.unbalance.0.amount=2 oz', 'rotor.unbalance[0].amount', 'oz*in'),
    ('rotor.unbalance.0.amount=-1 g*mm', 'rotor.unbalance[0].amount', 'out of range'),
    ('rotor.unbalance.0.node=99', 'rotor.unbalance[0].node', 'not defined'),
    ('rotor.unbalance.1.node=0', 'rotor.unbalance[1]', 'clamped'),
    ('rotor.unbalance.0.spin=1', 'rotor.unbalance[0]', 'spin'),
    ('sensors.0.lowpass=0 Hz', 'sensors[0].lowpass', 'out of range'),
    ('sensors.0.lowpass=2 rpm', 'sensors[0].lowpass', 'Hz'),
])
def test_bad_rotor_inputs_name_the_key(beam_file, override, key, words):
    message = problem(beam_file, [override])
    assert f"'{key}" in message and words in message, message


def test_profiles_and_units(beam_file):
    scene = load(beam_file)
    assert isinstance(scene.speed_profile, ConstantSpeed)
    assert scene.speed_profile.omega == pytest.approx(20 * np.pi, rel=1e-15)
    assert scene.input_names == ('unbalance0_uy', 'unbalance0_uz', 'unbalance1_uy',
                                 'unbalance1_uz')
    assert scene.unbalance.m_e[0] == pytest.approx(parse_quantity('2 oz*in', 'unbalance'))
    assert scene.unbalance.multiplier == 1.5
    ramp = load(beam_file, ['rotor.speed={kind: paper_ramp, final_speed: 3000 rpm}'])
    assert isinstance(ramp.speed_profile, PaperRamp) and ramp.speed_profile.t_ramp == 5.0
    cmd = load(beam_file, ['rotor.speed={kind: commanded, speed: 100 rad/s, '
                           'max_rate: 600 rpm/s}'])
    assert isinstance(cmd.speed_profile, CommandedSpeed)
    assert cmd.speed_profile.max_rate == pytest.approx(20 * np.pi, rel=1e-15)
    assert not cmd.forcing.harmonics and cmd.forcing.sampled   # follows commands
    # the scene forcing carries the live profile: a command changes later forces
    cmd.speed_profile.command(0.0, 200.0)
    t = np.array([10.0])
    np.testing.assert_allclose(cmd.forcing.evaluate(t), cmd.unbalance.forces(t), rtol=1e-15)
    assert cmd.speed_profile.speed(10.0) == 200.0
    sensors = [s for s in scene.describe_modes()['shapes'] if s['role'] == 'sensor']
    assert [s['lowpass_hz'] for s in sensors] == [2000.0, None]


def test_forcing_entries_come_first(beam_file):
    scene = load(beam_file, ['forcing=[{node: 3, dof: uy, amplitude: 1 N, frequency: 5 Hz}]'])
    assert scene.input_names[0] == 'force0' and len(scene.input_names) == 5
    assert scene.model.B.shape == (scene.basis.n_modes, 5)
    assert {h.input_index for h in scene.forcing.harmonics} == {0, 1, 2, 3, 4}


def test_scene_without_rotor_is_unchanged():
    scene = load('cantilever')
    assert scene.speed_profile is None and scene.unbalance is None
    assert scene.input_names == ('force0',) and scene.model.B.shape == (1, 1)


def test_constant_speed_unbalance_response_is_the_harmonic_response(beam_file):
    """Tolerance 1e-6 of the amplitude: the exact method driven by the scene's unbalance
    equals the closed-form steady state output_rows (K - W^2 + i W C)^-1 B F once the
    transient (zeta = 0.2, decay e^-40 by t = 1.2 s) has died out."""
    scene = load(beam_file)
    basis = scene.basis
    omega = scene.speed_profile.omega
    H = harmonic_response(basis, basis.rows(list(scene.input_dofs)),
                          basis.rows(list(scene.sensor_dofs)), omega)
    # F_y = A cos(W t + p), F_z = A sin(W t + p) = Re(-i A e^{i(W t + p)})
    amps = []
    for m_e, p in zip(scene.unbalance.m_e, scene.unbalance.phase):
        a = 1.5 * m_e * omega ** 2 * np.exp(1j * p)
        amps += [a, -1j * a]
    sim = scene.make_simulation(method='exact', dt=1e-3)
    samples = sim.advance_to(1.5)
    keep = samples.t >= 1.2
    t = samples.t[keep]
    expected = np.real((H @ np.array(amps))[None, :] * np.exp(1j * omega * t)[:, None])
    scale = np.abs(expected).max()
    assert scale > 1e-6   # a response worth comparing (m)
    np.testing.assert_allclose(samples.displacement[keep], expected, rtol=0, atol=1e-6 * scale)
