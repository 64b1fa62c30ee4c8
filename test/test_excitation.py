"""Rotor speed profiles and unbalance forcing (``impact_damper_sim.scene.excitation``).

Tolerances are stated per test; the closed forms are exact, so they are round-off bounds.
"""
import numpy as np
import pytest
from scipy.integrate import quad

from impact_damper_sim.integrate.exact import ExactPropagator
from impact_damper_sim.integrate.forcing import Forcing
from impact_damper_sim.integrate.model import LinearModel
from impact_damper_sim.scene.excitation import (
    CommandedSpeed,
    ConstantSpeed,
    PaperRamp,
    PiecewiseLinearSpeed,
    UnbalanceForce,
    unbalance_forcing,
)


def _commanded():
    prof = CommandedSpeed(initial=100.0, max_rate=400.0, t0=0.5)
    prof.command(1.0, 1500.0)     # ramp up, reaches 1500 at 4.5 s ...
    prof.command(2.0, 300.0)      # ... but is turned down mid-ramp (500 rad/s at 2 s)
    prof.command(6.0, 800.0)
    return prof


PROFILES = {
    'paper': (PaperRamp(), [0.0, 5.0]),
    'table': (PiecewiseLinearSpeed([0.3, 1.0, 2.5, 4.0], [50.0, 900.0, 900.0, 120.0]),
              [0.3, 1.0, 2.5, 4.0]),
    'commanded': (_commanded(), [0.5, 1.0, 2.0, 2.5, 6.0, 7.25]),
    'constant': (ConstantSpeed(377.0), []),
}


def _quad_angle(profile, t, knots):
    # integral_0^t omega ds, split at the knots so quad integrates polynomials only
    lo, hi = sorted((0.0, t))
    pts = [k for k in knots if lo < k < hi]
    val = quad(profile.speed, lo, hi, points=pts or None, epsabs=0.0, epsrel=1e-13,
               limit=200)[0]
    return val if t >= 0 else -val


@pytest.mark.parametrize('name', sorted(PROFILES))
def test_angle_is_exact_integral_of_speed(name):
    # phi(t) = integral_0^t omega: |phi - quad| <= 1e-10 max(1, |phi|) rad at random times.
    profile, knots = PROFILES[name]
    rng = np.random.default_rng(1)
    times = np.concatenate([rng.uniform(-1.0, 9.0, 40), knots])
    phi = profile.angle(times)
    for t, p in zip(times, phi):
        ref = _quad_angle(profile, t, knots)
        assert abs(p - ref) <= 1e-10 * max(1.0, abs(ref)), (t, p, ref)
    assert profile.angle(0.0) == 0.0


@pytest.mark.parametrize('name', sorted(PROFILES))
def test_acceleration_is_derivative_of_speed(name):
    # Central differences of omega (h = 1e-5 s) away from knots: |alpha - cd| <= 1e-6
    # max(1, |alpha|) rad/s^2 (speed is linear between knots, so only round-off remains).
    profile, knots = PROFILES[name]
    h = 1e-5
    rng = np.random.default_rng(2)
    t = rng.uniform(-1.0, 9.0, 200)
    if knots:
        t = t[np.min(np.abs(t[:, None] - np.asarray(knots)[None, :]), axis=1) > 10 * h]
    cd = (profile.speed(t + h) - profile.speed(t - h)) / (2 * h)
    alpha = profile.acceleration(t)
    assert np.all(np.abs(alpha - cd) <= 1e-6 * np.maximum(1.0, np.abs(alpha)))
    # and the angle's second difference is the acceleration too (same bound, looser h)
    H = 1e-3
    phi_dd = (profile.angle(t + H) - 2 * profile.angle(t) + profile.angle(t - H)) / H ** 2
    near = np.min(np.abs(t[:, None] - np.asarray(knots + [1e9])[None, :]), axis=1) > 2 * H
    assert np.all(np.abs(phi_dd - alpha)[near] <= 1e-3 * np.maximum(1.0, np.abs(alpha[near])))


def test_paper_ramp_eq_4_3_1():
    # Eq. (4.3.1): omega = 2400 t/5 for t < 5 s, 2400 rad/s after (exact equality).
    ramp = PaperRamp()
    t = np.array([0.0, 1.0, 2.5, 4.999, 5.0, 5.001, 30.0])
    expected = np.where(t < 5.0, 2400.0 * t / 5.0, 2400.0)
    assert np.allclose(ramp.speed(t), expected, rtol=1e-15, atol=0.0)
    assert ramp.speed(5.0) == 2400.0 and ramp.speed(100.0) == 2400.0
    assert ramp.acceleration(2.0) == 480.0 and ramp.acceleration(5.0) == 0.0
    assert ramp.angle(5.0) == pytest.approx(0.5 * 2400.0 * 5.0, rel=1e-15)
    assert ramp.speed(-1.0) == 0.0   # at rest before the start


def test_commanded_speed_rate_limit_target_and_history():
    prof = CommandedSpeed(initial=200.0, max_rate=100.0)
    prof.command(1.0, 700.0)
    # reaches 700 rad/s exactly at 1 + 500/100 = 6 s and holds it
    assert prof.t_reached == 6.0
    assert prof.speed(6.0) == 700.0 and prof.speed(50.0) == 700.0
    t = np.linspace(0.0, 10.0, 10001)
    w = prof.speed(t)
    assert np.max(np.abs(np.diff(w) / np.diff(t))) <= 100.0 * (1 + 1e-9)
    assert np.max(np.abs(prof.acceleration(t))) == 100.0
    # the history before a command is unchanged by it, bit for bit
    # (strictly before: alpha is right-continuous, so at the command time it is the new rate)
    before = np.linspace(-1.0, 3.5, 777, endpoint=False)
    state_before = prof.state(before)
    at_command = prof.angle(3.5), prof.speed(3.5)
    prof.command(3.5, 0.0)            # mid-ramp: 450 rad/s at 3.5 s, down to 0 at 8 s
    for old, new in zip(state_before, prof.state(before)):
        assert np.array_equal(old, new)
    assert (prof.angle(3.5), prof.speed(3.5)) == at_command
    assert prof.acceleration(3.5) == -100.0
    assert prof.speed(3.5) == pytest.approx(450.0, rel=1e-15)
    assert prof.t_reached == pytest.approx(8.0, rel=1e-15)
    assert prof.speed(8.0) == 0.0 and prof.speed(9.0) == 0.0
    t = np.linspace(3.0, 10.0, 7001)
    assert np.max(np.abs(np.diff(prof.speed(t)) / np.diff(t))) <= 100.0 * (1 + 1e-9)
    # a command equal to the current speed just holds
    prof.command(9.0, 0.0)
    assert prof.speed(20.0) == 0.0 and prof.acceleration(20.0) == 0.0


M_E = 2.5e-4      # kg m
X = 3.0           # multiplier


def test_constant_speed_force_magnitude_rotation_and_harmonics():
    omega = 377.0
    force = UnbalanceForce(ConstantSpeed(omega), [(M_E, 0.4), (0.5 * M_E, -2.0)],
                           [(0, 1), (3, 2)], multiplier=X, n_inputs=5)
    amp = X * M_E * omega ** 2
    t = np.random.default_rng(3).uniform(0.0, 2.0, 500)
    F = force(t)
    assert F.shape == (t.size, 5) and np.all(F[:, 4] == 0.0)
    # |F| = X m_e omega^2 per bearing, to 1e-12 relative
    assert np.allclose(np.hypot(F[:, 0], F[:, 1]), amp, rtol=1e-12, atol=0)
    assert np.allclose(np.hypot(F[:, 3], F[:, 2]), 0.5 * amp, rtol=1e-12, atol=0)
    # forward rotation: z lags y by a quarter period, F_z(t) = F_y(t - pi/(2 omega))
    Fq = force(t - 0.5 * np.pi / omega)
    assert np.max(np.abs(F[:, 1] - Fq[:, 0])) <= 1e-12 * amp
    assert np.max(np.abs(F[:, 2] - Fq[:, 3])) <= 1e-12 * amp
    # the exact harmonic terms reproduce the callable to 1e-12 of the amplitude
    harmonic = Forcing(5, force.harmonic_terms())
    assert np.max(np.abs(harmonic.evaluate(t) - F)) <= 1e-12 * amp
    forcing = unbalance_forcing(5, force)
    assert len(forcing.harmonics) == 4 and not forcing.has_sampled


def test_ramp_force_has_angular_acceleration_term():
    ramp = PaperRamp()
    force = UnbalanceForce(ramp, [(M_E, 0.7)], [(0, 1)], multiplier=X)
    t = 2.5                                 # phi = 1500 rad, omega = 1200 rad/s, 480 rad/s^2
    phi, w, a = 0.5 * 480.0 * t * t, 480.0 * t, 480.0
    Fy, Fz = force([t])[0]
    expect_y = X * M_E * (w * w * np.cos(phi + 0.7) + a * np.sin(phi + 0.7))
    expect_z = X * M_E * (w * w * np.sin(phi + 0.7) - a * np.cos(phi + 0.7))
    scale = X * M_E * w * w
    assert abs(Fy - expect_y) <= 1e-12 * scale and abs(Fz - expect_z) <= 1e-12 * scale
    # |F| = X m_e sqrt(omega^4 + alpha^2): the alpha term is there (it is 1.6e-7 of |F|^2)
    assert np.hypot(Fy, Fz) == pytest.approx(X * M_E * np.hypot(w * w, a), rel=1e-13)
    forcing = unbalance_forcing(2, force)
    assert forcing.has_sampled and not forcing.harmonics
    with pytest.raises(ValueError, match='ConstantSpeed'):
        force.harmonic_terms()


def _planar(wn=100.0, zeta=0.05):
    eye = np.eye(2)
    return LinearModel(M=eye, C=2 * zeta * wn * eye, K=wn * wn * eye, B=eye, sensors=eye)


def test_exact_propagator_steady_whirl_matches_frequency_response():
    # Isotropic 2-mode model (y, z), wn = 100 rad/s, zeta = 0.05, driven at 150 rad/s from
    # rest. After 6 s the transient is e^{-30} ~ 1e-13 of its start: the whirl radius is
    # |H(omega)| X m_e omega^2 and the waveform Re(H F e^{i(omega t + p)}), both within 1e-6.
    wn, zeta, omega, p = 100.0, 0.05, 150.0, 0.3
    force = UnbalanceForce(ConstantSpeed(omega), [(M_E, p)], [(0, 1)], multiplier=X)
    prop = ExactPropagator(_planar(wn, zeta), unbalance_forcing(2, force), dt=1e-3)
    s = prop.advance(7000)
    last = s.t >= 6.0
    H = 1.0 / (wn ** 2 - omega ** 2 + 2j * zeta * wn * omega)
    radius = abs(H) * X * M_E * omega ** 2
    r = np.hypot(s.displacement[last, 0], s.displacement[last, 1])
    assert np.max(np.abs(r / radius - 1.0)) < 1e-6
    z = H * X * M_E * omega ** 2 * np.exp(1j * (omega * s.t[last] + p))
    assert np.max(np.abs(s.displacement[last, 0] - z.real)) < 1e-6 * radius
    assert np.max(np.abs(s.displacement[last, 1] - z.imag)) < 1e-6 * radius


def test_sampled_unbalance_converges_to_harmonic_and_follows_multiplier():
    # The same run through the sampled (first-order-hold) path: linear interpolation of a
    # cosine shrinks it by about (omega dt)^2/12 on average, so the error is O((omega dt)^2):
    # bounded here by (omega dt)^2/8 of the response, and halving dt divides it by 4 +- 0.5.
    wn, zeta, omega = 100.0, 0.05, 150.0
    force = UnbalanceForce(ConstantSpeed(omega), [(M_E, 0.0)], [(0, 1)], multiplier=X)
    ref = ExactPropagator(_planar(wn, zeta), unbalance_forcing(2, force), dt=1e-3)
    y_ref = ref.advance(3000).displacement
    errors = []
    for dt in (1e-3, 5e-4):
        prop = ExactPropagator(_planar(wn, zeta),
                               unbalance_forcing(2, force, exact_harmonics=False), dt=dt)
        y = prop.advance(int(round(3.0 / dt))).displacement[int(round(1e-3 / dt)) - 1::
                                                             int(round(1e-3 / dt))]
        errors.append(np.max(np.abs(y - y_ref)) / np.max(np.abs(y_ref)))
    assert errors[0] < (omega * 1e-3) ** 2 / 8 and 3.5 < errors[0] / errors[1] < 4.5
    # the sampled path reads the multiplier at run time: doubling X doubles the later response
    prop = ExactPropagator(_planar(wn, zeta), unbalance_forcing(2, force, exact_harmonics=False),
                           dt=1e-3)
    force.multiplier = 0.0
    assert np.all(prop.advance(100).displacement == 0.0)
    force.multiplier = X
    assert np.any(prop.advance(100).displacement != 0.0)


@pytest.mark.parametrize('make, match', [
    (lambda: CommandedSpeed(100.0, 0.0), r'max_rate must be finite and > 0 rad/s\^2'),
    (lambda: CommandedSpeed(100.0, -5.0), r'max_rate must be finite and > 0'),
    (lambda: CommandedSpeed(100.0, np.nan), r'max_rate must be finite and > 0'),
    (lambda: CommandedSpeed(-1.0, 5.0), r'initial must be finite and >= 0 rad/s'),
    (lambda: CommandedSpeed(1.0, 5.0).command(1.0, np.nan), r'target must be finite and >= 0'),
    (lambda: CommandedSpeed(1.0, 5.0).command(1.0, np.inf), r'target must be finite and >= 0'),
    (lambda: CommandedSpeed(1.0, 5.0).command(1.0, -3.0), r'target must be finite and >= 0'),
    (lambda: CommandedSpeed(1.0, 5.0).command(2.0, 3.0).command(1.0, 3.0),
     r't_now must be >= 2.0 s'),
    (lambda: CommandedSpeed(1.0, 5.0).command(np.nan, 3.0), r't_now must be finite'),
    (lambda: PaperRamp(omega_f=0.0), r'omega_f must be finite and > 0 rad/s'),
    (lambda: PaperRamp(t_ramp=-1.0), r't_ramp must be finite and > 0 s'),
    (lambda: ConstantSpeed(np.inf), r'omega must be finite and >= 0 rad/s'),
    (lambda: PiecewiseLinearSpeed([0.0, 1.0, 1.0], [0.0, 1.0, 2.0]), 'strictly increasing'),
    (lambda: PiecewiseLinearSpeed([0.0, 1.0], [0.0, -1.0]), r'speeds must be finite and >= 0'),
    (lambda: PiecewiseLinearSpeed([0.0, 1.0], [0.0]), 'equal length'),
    (lambda: UnbalanceForce(ConstantSpeed(1.0), [(1e-3, 0.0)], [(0, 1)], multiplier=-1.0),
     r'multiplier must be finite and >= 0'),
    (lambda: UnbalanceForce(ConstantSpeed(1.0), [(-1e-3, 0.0)], [(0, 1)]),
     r'm_e must be finite and >= 0 kg m'),
    (lambda: UnbalanceForce(ConstantSpeed(1.0), [(1e-3, 0.0)], [(1, 1)]), 'different inputs'),
    (lambda: UnbalanceForce(ConstantSpeed(1.0), [(1e-3, 0.0)], [(0, 1), (2, 3)]),
     'per bearing'),
    (lambda: UnbalanceForce(ConstantSpeed(1.0), [(1e-3, 0.0)], [(0, 3)], n_inputs=3),
     r'n_inputs must be an integer >= 4'),
    (lambda: unbalance_forcing(1, UnbalanceForce(ConstantSpeed(1.0), [(1e-3, 0.0)], [(0, 1)])),
     r'n_inputs must be >= 2'),
])
def test_bad_inputs_raise(make, match):
    with pytest.raises(ValueError, match=match):
        make()


def test_multiplier_setter_validates():
    force = UnbalanceForce(PaperRamp(), [(M_E, 0.0)], [(0, 1)])
    force.multiplier = 7.0
    assert force.multiplier == 7.0
    for bad in (-0.1, np.nan, np.inf):
        with pytest.raises(ValueError, match=r'multiplier must be finite and >= 0'):
            force.multiplier = bad
    assert force.multiplier == 7.0
