"""Whirl modes and Campbell data against closed forms (issue 26, item 6).

The rotors: a Jeffcott rotor (point mass on isotropic or anisotropic supports, with and
without a cross-coupled stiffness), a rigid disk on a massless shaft (tilt with polar
inertia: forward and backward branches), and an overhung disk on a massless cantilever
(translation and tilt coupled). Each is built through the ``modal.whirl`` API and through
the scene format (a tiny YAML), and the closed forms hold to rounding (stated per test).
The last tests measure what the scenes' modal subspace costs against every DOF, and check
that the Campbell model is the simulated one.
"""
import textwrap

import numpy as np
import pytest

from impact_damper_sim.modal.tracking import campbell, critical_speeds, instability_onset
from impact_damper_sim.modal.whirl import (
    OrbitStations,
    RotorModel,
    condensed_rotor,
    gyroscopic_matrix,
    orbit_radii,
    whirl_modes,
)
from impact_damper_sim.scene.build import load
from impact_damper_sim.studies.campbell import (
    RPM,
    campbell_study,
    describe_whirl,
    rotor_model,
    scene_speed,
)

M, K, KZ, C = 2.0, 1.5e5, 5.0e4, 40.0          # kg, N/m, N/m, N s/m
ID, IP, KT = 0.5, 0.35, 3.0e4                  # kg m^2, kg m^2, N m/rad


def translation(n_coords=2):
    """One station reading (y, z) = (q0, q1)."""
    y, z = np.zeros((1, n_coords)), np.zeros((1, n_coords))
    y[0, 0], z[0, 1] = 1.0, 1.0
    return OrbitStations(np.array([0]), ('translation',), y, z, np.array([M]))


def jeffcott(ky=K, kz=K, c=C, kcc=0.0):
    return RotorModel(M * np.eye(2), c * np.eye(2), np.array([[ky, kcc], [-kcc, kz]]),
                      np.zeros((2, 2)), translation())


def tilt_disk():
    """Tilts (theta_y, theta_z) of a disk: Id theta'' + Omega G theta' + k_t theta = 0."""
    stations = OrbitStations(np.array([0]), ('tilt',), np.array([[0.0, 1.0]]),
                             np.array([[-1.0, 0.0]]), np.array([ID]))
    return RotorModel(ID * np.eye(2), np.zeros((2, 2)), KT * np.eye(2),
                      np.array([[0.0, IP], [-IP, 0.0]]), stations)


def disk_branches(speed, ip=IP, idia=ID, kt=KT):
    """Closed form: Id w^2 -+ Ip Omega w - k_t = 0 (backward, forward), rad/s."""
    root = np.sqrt((ip * speed) ** 2 + 4 * idia * kt)
    return (root - ip * speed) / (2 * idia), (root + ip * speed) / (2 * idia)


# --- Jeffcott rotor --------------------------------------------------------------------------

@pytest.mark.parametrize('speed', [0.0, 500.0, 3000.0])
def test_isotropic_jeffcott_does_not_split(speed):
    # damped frequency sqrt(k/m - (c/2m)^2) for both members at every speed (1e-12), log
    # decrement 2 pi zeta / sqrt(1 - zeta^2); the degenerate pair is resolved into its
    # circular forward and backward members (whirl index +-1 to 1e-12)
    modes = whirl_modes(jeffcott(), speed)
    zeta = C / (2 * np.sqrt(K * M))
    wd = np.sqrt(K / M) * np.sqrt(1 - zeta ** 2)
    np.testing.assert_allclose(modes.eigenvalues.imag, [wd, wd], rtol=1e-12)
    np.testing.assert_allclose(modes.log_dec, 2 * np.pi * zeta / np.sqrt(1 - zeta ** 2),
                               rtol=1e-10)
    np.testing.assert_allclose(modes.damping_ratio, zeta, rtol=1e-10)
    assert sorted(modes.directions) == ['backward', 'forward']
    np.testing.assert_allclose(np.sort(modes.whirl_index), [-1.0, 1.0], atol=1e-12)


@pytest.mark.parametrize('speed', [0.0, 1000.0])
def test_anisotropic_jeffcott_has_the_two_support_frequencies(speed):
    # undamped: sqrt(kz/m) and sqrt(ky/m) to 1e-12; planar orbits along z and y: no whirl
    modes = whirl_modes(jeffcott(ky=K, kz=KZ, c=0.0), speed)
    np.testing.assert_allclose(modes.eigenvalues.imag, np.sqrt([KZ / M, K / M]), rtol=1e-12)
    assert modes.directions == ('none', 'none')
    np.testing.assert_allclose(modes.log_dec, 0.0, atol=1e-12)
    a_f, a_b = orbit_radii(translation(), modes.shapes)
    np.testing.assert_allclose(a_f, a_b, rtol=1e-12)   # a line: minor axis zero


@pytest.mark.parametrize('ratio', [0.0, 0.5, 0.99, 1.0, 1.01, 2.0])
def test_cross_coupled_jeffcott_against_its_characteristic_roots(ratio):
    # m lambda^2 + c lambda + (k - i Kcc) = 0 in r = y + i z: the root with Im > 0 whirls
    # forward, the other backward; eigenvalues to 1e-10, and the forward log decrement is
    # zero at Kcc = c omega_n (to 1e-9), negative above it
    wn = np.sqrt(K / M)
    kcc = ratio * C * wn
    modes = whirl_modes(jeffcott(kcc=kcc), 0.0)
    roots = np.roots([M, C, K - 1j * kcc])
    forward = roots[np.argmax(roots.imag)]
    backward = np.conj(roots[np.argmin(roots.imag)])
    got = dict(zip(modes.directions, modes.eigenvalues))
    if ratio == 0.0:   # degenerate: both members, one each way
        assert sorted(got) == ['backward', 'forward']
    np.testing.assert_allclose(got['forward'], forward, rtol=1e-10)
    np.testing.assert_allclose(got['backward'], backward, rtol=1e-10)
    log_dec = dict(zip(modes.directions, modes.log_dec))
    if ratio == 1.0:
        assert abs(log_dec['forward']) < 1e-9
    else:
        assert np.sign(log_dec['forward']) == np.sign(1.0 - ratio)
    assert log_dec['backward'] > 0


# --- rigid disk, polar inertia ------------------------------------------------------------------

def test_rigid_disk_forward_and_backward_branches():
    # Id w^2 -+ Ip Omega w - k_t = 0 over the speeds, to 1e-10; the rising branch is forward
    speeds = np.linspace(0.0, 3000.0, 31)
    data = campbell(tilt_disk(), speeds)
    back, fwd = disk_branches(speeds)
    b, f = (0, 1) if data.directions[-1, 0] == 'backward' else (1, 0)
    np.testing.assert_allclose(data.eigenvalues.imag[:, b], back, rtol=1e-10)
    np.testing.assert_allclose(data.eigenvalues.imag[:, f], fwd, rtol=1e-10)
    assert set(data.directions[:, b]) == {'backward'}   # at rest: the limit of the split
    assert set(data.directions[:, f]) == {'forward'}


# --- through the scene format -------------------------------------------------------------------

JEFFCOTT = textwrap.dedent(f"""
    name: jeffcott
    structure:
      kind: beam
      nodes:
        - {{id: 0, xyz: [0, 0, 0]}}
      point_masses:
        - {{node: 0, mass: {M} kg}}
      springs:
        - {{node: 0, dof: uy, stiffness: {K}}}
        - {{node: 0, dof: uz, stiffness: {K}}}
      dampers:
        - {{node: 0, dof: uy, damping: {C}}}
        - {{node: 0, dof: uz, damping: {C}}}
      cross_couplings:
        - {{node: 0, kcc: 0}}
      clamps:
        - {{node: 0, dofs: [ux, rx, ry, rz]}}
    modal: {{n_modes: 2}}
    rotor:
      speed: {{kind: constant, speed: 3000 rpm}}
    """)

# A rigid disk on springs (translation k, tilt k_t) spinning at node 0
DISK = textwrap.dedent(f"""
    name: disk
    structure:
      kind: beam
      nodes:
        - {{id: 0, xyz: [0, 0, 0]}}
      point_masses:
        - {{node: 0, mass: {M} kg, inertia: [{IP}, {ID}, {ID}]}}
      springs:
        - {{node: 0, dof: uy, stiffness: {K}}}
        - {{node: 0, dof: uz, stiffness: {K}}}
        - {{node: 0, dof: ry, rotational_stiffness: {KT}}}
        - {{node: 0, dof: rz, rotational_stiffness: {KT}}}
      clamps:
        - {{node: 0, dofs: [ux, rx]}}
    modal: {{n_modes: 4}}
    rotor:
      speed: {{kind: constant, speed: 2000 rpm}}
      gyroscopic: {{nodes: [0]}}
    """)


@pytest.fixture
def scene_file(tmp_path):
    def write(text, name):
        path = tmp_path / f'{name}.yaml'
        path.write_text(text)
        return str(path)
    return write


def test_jeffcott_scene_onset_is_c_omega_and_campbell_agrees_with_stability(scene_file):
    # The scene's whirl modes are the closed form's (1e-10); study stability --onset finds
    # Kcc = c omega_n (1e-5, its bisection tolerance 1e-6); the Campbell study calls a Kcc
    # 0.1 % above it unstable from the first speed (the forward branch, at the onset's whirl
    # frequency to 1e-4) and 0.1 % below it stable over the range.
    from impact_damper_sim.studies.stability import onset
    path = scene_file(JEFFCOTT, 'jeffcott')
    key = 'structure.cross_couplings.0.kcc'
    wn = np.sqrt(K / M)
    kcc = 0.4 * C * wn
    data = describe_whirl(load(path, [f'{key}={float(kcc)!r}']))
    roots = np.roots([M, C, K - 1j * kcc])
    fwd = roots[np.argmax(roots.imag)]
    by_dir = {w['direction']: w for w in data['whirl']}
    assert by_dir['forward']['frequency_hz'] == pytest.approx(fwd.imag / (2 * np.pi), rel=1e-10)
    assert by_dir['forward']['log_dec'] == pytest.approx(-2 * np.pi * fwd.real / fwd.imag,
                                                         rel=1e-10)
    found = onset(path, key)
    assert found['onset_kcc_N_m'] == pytest.approx(C * wn, rel=1e-5)
    speeds = [0.0, 1500.0, 3000.0]

    def at(factor):
        kcc = float(found['onset_kcc_N_m'] * factor)
        return campbell_study(path, speeds, overrides=[f'{key}={kcc!r}'])['onset']

    above = at(1.001)
    assert above['from_start'] and above['direction'] == 'forward'
    assert above['frequency_hz'] == pytest.approx(found['whirl_frequency_hz'], rel=1e-4)
    assert at(0.999) is None


def test_disk_scene_campbell_branches_and_critical_speeds(scene_file):
    # Branches over 0..6000 rpm: the translation pair stays at sqrt(k/m) (no split), the tilt
    # pair follows the closed forms (1e-9); the rising forward tilt branch crosses the flat
    # translation pair and keeps its identity (tracked by shape, not by sorting). Critical
    # speeds (1X): translation at sqrt(k/m), backward tilt at sqrt(k_t/(Id + Ip)), forward
    # tilt at sqrt(k_t/(Id - Ip)) (Id > Ip), each to 1e-9.
    path = scene_file(DISK, 'disk')
    speeds_rpm = np.linspace(0.0, 6000.0, 61)
    r = campbell_study(path, speeds_rpm, [1])
    freq = np.array([b['frequency_hz'] for b in r['branches']]) * 2 * np.pi
    speeds = speeds_rpm * RPM
    back, fwd = disk_branches(speeds)
    wt = np.sqrt(K / M)
    rows = {b: freq[b] for b in range(4)}
    tilt_back = [b for b in rows if abs(rows[b][-1] - back[-1]) < 1e-6 * back[-1]]
    tilt_fwd = [b for b in rows if abs(rows[b][-1] - fwd[-1]) < 1e-6 * fwd[-1]]
    trans = [b for b in rows if b not in tilt_back + tilt_fwd]
    assert len(tilt_back) == len(tilt_fwd) == 1 and len(trans) == 2
    np.testing.assert_allclose(rows[tilt_back[0]], back, rtol=1e-9)
    np.testing.assert_allclose(rows[tilt_fwd[0]], fwd, rtol=1e-9)
    for b in trans:
        np.testing.assert_allclose(rows[b], wt, rtol=1e-9)
    assert fwd[0] < wt < fwd[-1]   # the forward tilt branch does cross the translation pair
    dirs = r['branches'][tilt_fwd[0]]['direction']
    assert set(dirs[1:]) == {'forward'}
    got = sorted((c['speed_rpm'] * RPM, c['direction']) for c in r['critical_speeds'])
    want = sorted([(wt, 'forward'), (wt, 'backward'),
                   (np.sqrt(KT / (ID + IP)), 'backward'), (np.sqrt(KT / (ID - IP)), 'forward')])
    assert [d for _, d in got] == [d for _, d in want]
    np.testing.assert_allclose([s for s, _ in got], [s for s, _ in want], rtol=1e-9)


# Overhung disk on a massless cantilever of length L (Euler-Bernoulli), the disk at the tip:
# per plane K = [[12 EI/L^3, -6 EI/L^2], [-6 EI/L^2, 4 EI/L]] on (u, theta)
E, D_SHAFT, L = 2.0e11, 0.02, 0.3
EI = E * np.pi * D_SHAFT ** 4 / 64
OVERHUNG = textwrap.dedent(f"""
    name: overhung
    structure:
      kind: beam
      material: {{E: {E}, nu: 0.3, rho: 1e-3}}
      sections:
        shaft: {{shape: solid_circular, diameter: {D_SHAFT}}}
      lines:
        - {{from: [0, 0, 0], to: [{L}, 0, 0], n_elements: 1, section: shaft, shear: false}}
      point_masses:
        - {{node: 1, mass: {M} kg, inertia: [{IP}, {ID}, {ID}]}}
      clamps:
        - {{node: 0}}
        - {{node: 1, dofs: [ux, rx]}}
    modal: {{n_modes: 4}}
    rotor:
      speed: {{kind: constant, speed: 3000 rpm}}
      gyroscopic: {{nodes: [1]}}
    """)


def overhung_frequencies(speed):
    """Closed form: det([[k11 - m w^2, k12], [k12, k22 - Id w^2 + Ip Omega w]]) = 0, rad/s.

    The roots w > 0 are forward whirl, w < 0 backward (in the complex coordinates
    u + i v and theta_z - i theta_y).
    """
    k11, k12, k22 = 12 * EI / L ** 3, -6 * EI / L ** 2, 4 * EI / L
    poly = np.polysub(np.polymul([-M, 0, k11], [-ID, IP * speed, k22]), [k12 ** 2])
    roots = np.roots(poly).real
    return np.sort(-roots[roots < 0]), np.sort(roots[roots > 0])


def test_overhung_disk_scene_matches_its_frequency_equation(scene_file):
    # Through a beam element of the scene format (rho 1e-3 kg/m^3: the shaft's mass is 1e-7 of
    # the disk's), backward and forward branches within 1e-6 of the closed form
    path = scene_file(OVERHUNG, 'overhung')
    speeds_rpm = [0.0, 3000.0, 9000.0]
    r = campbell_study(path, speeds_rpm)
    for k, s in enumerate(speeds_rpm):
        back, fwd = overhung_frequencies(s * RPM)
        got = {'backward': [], 'forward': []}
        for b in r['branches']:
            if b['direction'][k] in got:
                got[b['direction'][k]].append(b['frequency_hz'][k] * 2 * np.pi)
        if s == 0.0:
            np.testing.assert_allclose(sorted(got['backward'] + got['forward']),
                                       np.sort(np.r_[back, fwd]), rtol=1e-6)
            continue
        np.testing.assert_allclose(sorted(got['backward']), back, rtol=1e-6)
        np.testing.assert_allclose(sorted(got['forward']), fwd, rtol=1e-6)


def test_speed_dependent_onset_agrees_with_stability(scene_file):
    # A negative Kcc feeds backward whirl, whose frequency falls with speed: at a fixed Kcc
    # the overhung rotor is stable at low speed and unstable above some speed. The Campbell
    # onset speed there, and study stability --onset at that speed, give back the same Kcc
    # (1e-5), the same branch direction and whirl frequency (1e-4). 0.5 % tare damping.
    from impact_damper_sim.studies.stability import onset
    text = OVERHUNG.replace('  clamps:', '  cross_couplings:\n    - {node: 1, kcc: 0}\n'
                            '  clamps:')
    text = text.replace('modal: {n_modes: 4}', 'modal: {n_modes: 4, damping: {default: 0.005}}')
    path = scene_file(text, 'overhung_kcc')
    key = 'structure.cross_couplings.0.kcc'
    at_rpm = 6000.0
    found = onset(path, key, [f'rotor.speed.speed={at_rpm} rpm'],
                  bracket=(-5e4, 0.0), rtol=1e-9)
    kcc = found['onset_kcc_N_m']
    assert kcc < 0
    r = campbell_study(path, [0.0, 3000.0, 9000.0], overrides=[f'{key}={float(kcc)!r}'])
    o = r['onset']
    assert not o['from_start'] and o['direction'] == 'backward'
    assert o['speed_rpm'] == pytest.approx(at_rpm, rel=1e-5)
    assert o['frequency_hz'] == pytest.approx(found['whirl_frequency_hz'], rel=1e-4)


# --- the scenes' model: simulated, and what the modal subspace costs -----------------------------

def test_campbell_model_is_the_simulated_model(scene_file):
    # C + Omega G of the Campbell model equals the simulated model's C at the scene's speed
    # (to 1e-12 of its largest entry), on the disk scene and on ross_rotor
    for scene in (load(scene_file(DISK, 'disk')), load('ross_rotor')):
        rotor = rotor_model(scene)
        speed = scene_speed(scene)
        assert scene.polar_inertia() and speed > 0
        scale = np.abs(scene.model.C).max()
        assert np.abs(rotor.C + speed * rotor.G - scene.model.C).max() <= 1e-12 * scale
        assert np.abs(rotor.K - scene.model.K).max() == 0.0


def test_ross_rotor_modal_subspace_against_every_dof():
    # The Campbell study runs on the scene's 16 retained modes; against the condensed model
    # of all 196 DOFs (state matrix 392 x 392) the 8 lowest whirl frequencies differ by at
    # most 2e-4 up to 10,000 rpm (measured 8e-5, the 4th pair's forward whirl at 10,000
    # rpm; 0 at rest), and the directions are the same.
    scene = load('ross_rotor')
    reduced = rotor_model(scene)
    full = condensed_rotor(scene.system,
                           gyroscopic_matrix(scene.system, scene.polar_inertia()))
    worst = 0.0
    for rpm in (0.0, 5000.0, 10000.0):
        a, b = whirl_modes(reduced, rpm * RPM), whirl_modes(full, rpm * RPM)
        err = np.abs(a.frequency_hz[:8] / b.frequency_hz[:8] - 1)
        worst = max(worst, err.max())
        if rpm:
            assert a.directions[:8] == b.directions[:8]
    assert worst < 2e-4


def test_instability_onset_bisects_between_speeds():
    # A rotor whose backward tilt branch is destabilized by a skew stiffness: the onset found
    # between two coarse speeds is where the largest real part crosses zero (1e-8)
    rotor = tilt_disk()
    rotor = RotorModel(rotor.M, 0.5 * np.eye(2), rotor.K + np.array([[0.0, -40.0],
                                                                   [40.0, 0.0]]),
                       rotor.G, rotor.stations)
    data = campbell(rotor, np.linspace(0.0, 4000.0, 5))
    o = instability_onset(data)
    assert o is not None and not o.from_start and o.direction == 'backward'
    lam = np.linalg.eigvals(rotor.state_matrix(o.speed))
    assert abs(lam.real.max()) < 1e-8 * np.abs(lam).max()
    assert critical_speeds(data, [1.0])   # the 1X line crosses the backward branch
