"""Extreme settings: the simulator neither blows up nor hangs, and refuses what cannot work.

Every run checks the same three things (:func:`assert_sane`): the sensor outputs are finite;
no output step holds more impacts of one impactor than ``max_events_per_step`` (above it a
bounce-down is completed plastically, so a run cannot hang in chatter); the energy ledger
closes within its stated bound. The bounds: the exact propagator integrates damping, forcing
and circulatory work by Gauss quadrature accurate to about 1e-10 relative (1e-9 here); Newmark
matches its own discrete energy balance to round-off (1e-10 here). Runs with the paper's
``lumped_mass`` law (the ``rbs`` scenes) use ``effective_mass`` here: the lumped law does not
conserve the simulated model's momentum (its ledger books what the model loses, so it closes
all the same; test/test_energy_balance.py).

Each extreme also asserts the physics that must hold there (restitution of every impact,
a linear response when nothing can impact, step-independent impact times of the exact
propagator, ...). Settings that cannot work raise a ``ValueError`` naming the setting. The
fast subset runs in CI; ``@pytest.mark.slow`` cases run with ``make test-slow``.
"""
import numpy as np
import pytest

from impact_damper_sim.integrate.events import EVENT_KINDS
from impact_damper_sim.scene.build import load
from impact_damper_sim.scene.schema import SceneError

IMPACT = EVENT_KINDS.index('impact')
EXACT_LEDGER = 1e-9      # relative ledger residual, exact propagator
NEWMARK_LEDGER = 1e-10   # relative ledger residual, Newmark (modal and direct)
METHODS = ('exact', 'newmark', 'newmark_step_end', 'direct')
EFFECTIVE = 'simulation.law=effective_mass'


def run(scene, overrides=(), method='exact', dt=None, t_end=1.0, chunk=None):
    """Run ``scene`` to ``t_end`` (s) in chunks; return the simulation, samples and events."""
    sc = load(scene, list(overrides))
    sim = sc.make_simulation(method, dt)
    chunk = chunk or t_end
    parts = []
    while sim.t < t_end - 0.5 * sim.dt:
        parts.append(sim.advance_to(min(sim.t + chunk, t_end)))
    disp = np.vstack([p.displacement for p in parts])
    vel = np.vstack([p.velocity for p in parts])
    return sim, disp, vel, sim.take_events()


def assert_sane(sim, disp, vel, method):
    """Finite outputs, bounded events per step, closed energy ledger (module docstring)."""
    assert np.all(np.isfinite(disp)) and np.all(np.isfinite(vel))
    integ = sim.integrator
    assert integ.max_impacts_per_step <= integ.max_events_per_step
    led = sim.energy()
    assert np.isfinite(led.total)
    bound = EXACT_LEDGER if method == 'exact' else NEWMARK_LEDGER
    assert abs(led.relative_residual) < bound, led


def impacts(events):
    return events[events['kind'] == IMPACT]


# ------------------------------------------------------------------ restitution 0 and 1
@pytest.mark.parametrize('method', METHODS)
@pytest.mark.parametrize('cor', [0.0, 1.0])
def test_cor_extremes(method, cor):
    """e = 0: every impact leaves zero normal relative velocity (plastic), e = 1: it reverses
    it exactly (1e-9 of v_n) and dissipates nothing (impact loss exactly 0 J)."""
    sim, disp, vel, ev = run('sdof', [f'impactors.0.cor={cor}'], method)
    assert_sane(sim, disp, vel, method)
    imp = impacts(ev)
    assert imp.size >= 20
    np.testing.assert_allclose(imp['v_n_after'], -cor * imp['v_n'], rtol=0,
                               atol=1e-9 * np.abs(imp['v_n']).max())
    if cor == 1.0:
        assert sim.energy().impacts == 0.0
    else:
        assert sim.energy().impacts > 0.0


# ------------------------------------------------------------------ mass ratio 1e-4 and 1
@pytest.mark.parametrize('method', METHODS)
def test_tiny_mass_ratio_leaves_the_linear_response(method):
    """mu = 1e-4: impacts happen but hardly matter: the peak is the linear one within 1 %."""
    sim, disp, vel, ev = run('sdof', ['impactors.0.mass_ratio=1e-4'], method)
    assert_sane(sim, disp, vel, method)
    assert impacts(ev).size > 0
    _, lin, _, _ = run('sdof', ['impactors=[]'], method)
    assert np.abs(disp).max() == pytest.approx(np.abs(lin).max(), rel=1e-2)


@pytest.mark.parametrize('method', METHODS)
def test_unit_mass_ratio(method):
    """mu = 1: restitution holds at every impact (1e-9 of v_n) with the effective mass."""
    sim, disp, vel, ev = run('sdof', ['impactors.0.mass_ratio=1'], method)
    assert_sane(sim, disp, vel, method)
    imp = impacts(ev)
    assert imp.size >= 10
    cor = load('sdof').scene['impactors'][0]['cor']
    np.testing.assert_allclose(imp['v_n_after'], -cor * imp['v_n'], rtol=0,
                               atol=1e-9 * np.abs(imp['v_n']).max())


# ------------------------------------------------------------------ clearances
@pytest.mark.parametrize('method', METHODS)
def test_smallest_clearance(method):
    """D = 1e-8 m (the schema's smallest): many impacts or a stuck impactor, never a hang,
    and the impactor never leaves its slot by more than 1e-9 of the clearance (step-end
    impacts, the paper's baseline, leave it where the step ended: up to one step of relative
    motion, < 1 m/s x dt, outside)."""
    sim, disp, vel, ev = run('sdof', ['impactors.0.clearance=1e-8'], method, chunk=0.05)
    assert_sane(sim, disp, vel, method)
    assert impacts(ev).size >= 20
    rel = sim.impactor_states()[0]['position'][0]
    slack = 1.0 * sim.dt if method == 'newmark_step_end' else 0.5e-8 * 1e-9
    assert abs(rel) <= 0.5e-8 + slack


@pytest.mark.parametrize('method', METHODS)
def test_clearance_larger_than_any_motion_is_the_linear_structure(method):
    """D = 0.1 m (the schema's largest) against 5 mm of motion: no event at all, and the
    response equals the run without impactors to 1e-12 of its peak."""
    sim, disp, vel, ev = run('sdof', ['impactors.0.clearance=0.1'], method)
    assert_sane(sim, disp, vel, method)
    assert ev.size == 0
    _, lin, _, _ = run('sdof', ['impactors=[]'], method)
    np.testing.assert_allclose(disp, lin, rtol=0, atol=1e-12 * np.abs(lin).max())


# ------------------------------------------------------------------ time steps
def test_exact_impact_times_do_not_depend_on_the_step():
    """Exact propagator from dt = 1e-7 s to the schema's largest dt = 1 s: the impact times
    of the first 1 s agree with the dt = 1e-4 s run to 1e-9 s (the harmonic forcing is exact
    at any dt; only the sampling changes). dt = 1e-7 s runs the first 0.24 s (3 impacts)."""
    ref = impacts(run('sdof', [], 'exact', 1e-4, 1.0)[3])['t']
    assert ref.size >= 20
    for dt, t_end in ((1e-7, 0.24), (1e-5, 1.0), (1e-3, 1.0), (0.1, 1.0), (1.0, 1.0)):
        sim, disp, vel, ev = run('sdof', [], 'exact', dt, t_end)
        assert_sane(sim, disp, vel, 'exact')
        t = impacts(ev)['t']
        expected = ref[ref <= t_end - 1e-3]
        assert expected.size >= 3 and t.size >= expected.size
        np.testing.assert_allclose(t[:expected.size], expected, rtol=0, atol=1e-9)


@pytest.mark.parametrize('method', ['newmark', 'newmark_step_end', 'direct'])
def test_newmark_smallest_and_largest_allowed_steps(method):
    """Newmark at dt = 1e-7 s (0.02 s) and at the largest allowed step, T_min/10 (3.97 ms on
    the 25.2 Hz SDOF, 1 s): sane, and at T_min/10 the impacts are still there (located:
    within 15 % of the exact count of the same second)."""
    sim, disp, vel, _ = run('sdof', [], method, 1e-7, 0.02)
    assert_sane(sim, disp, vel, method)
    h_max = 1.0 / (10 * 25.1646)
    dt = 1.0 / np.ceil(1.0 / h_max)          # largest step <= T/10 that divides 1 s
    sim, disp, vel, ev = run('sdof', [], method, dt, 1.0)
    assert_sane(sim, disp, vel, method)
    n_ref = impacts(run('sdof', [], 'exact', 1e-4, 1.0)[3]).size
    n = impacts(ev).size
    assert n > 0
    if method != 'newmark_step_end':
        assert n == pytest.approx(n_ref, rel=0.15)


@pytest.mark.parametrize('method', ['newmark', 'newmark_step_end', 'direct'])
def test_newmark_step_too_large_for_event_tracking_is_refused(method):
    """Above T_min/10 of the highest retained mode: a ValueError naming simulation.dt (at
    T/6.3 the SDOF at resonance would silently lose every impact)."""
    with pytest.raises(ValueError, match=r'simulation\.dt .* too large to track impacts'):
        load('sdof').make_simulation(method, 1.0 / (6.3 * 25.1646))


def test_newmark_step_rule_needs_impactors_only():
    """Without impactors there is nothing to track: a long Newmark step is accepted."""
    sim = load('sdof', ['impactors=[]']).make_simulation('newmark', 0.01)
    sim.advance(10)
    assert np.isfinite(sim.energy().total)


def test_dt_beyond_the_schema_is_refused():
    with pytest.raises(SceneError, match=r"simulation\.dt"):
        load('sdof', ['simulation.dt=2 s'])


def test_sampled_unbalance_needs_ten_samples_per_revolution():
    """HPOTP ramp to 2400 rad/s (382 rev/s): dt = 1 ms would alias the unbalance force; a
    SceneError names simulation.dt. 0.26 ms (10.02 samples per revolution) is accepted."""
    scene = load('hpotp')
    with pytest.raises(SceneError, match=r"simulation\.dt.*per revolution"):
        scene.make_simulation('exact', 1e-3)
    scene.make_simulation('exact', 2.6e-4)


# ------------------------------------------------------------------ rotor extremes
def test_rotor_at_rest_does_nothing():
    """Speed 0: no unbalance force, the structure stays at rest exactly, no event."""
    sim, disp, vel, ev = run('rbs', ['rotor.speed.speed=0 rpm', EFFECTIVE], 'exact', 5e-5, 0.1)
    assert_sane(sim, disp, vel, 'exact')
    assert ev.size == 0 and np.all(disp == 0.0)


@pytest.mark.parametrize('method', ['exact', pytest.param('newmark', marks=pytest.mark.slow)])
def test_rotor_at_twice_full_speed(method):
    """7878 rpm x 2 on rbs: sane, and the impactors work (impacts happen)."""
    sim, disp, vel, ev = run('rbs', ['rotor.speed.speed=15756 rpm', EFFECTIVE], method, 5e-5,
                             0.1)
    assert_sane(sim, disp, vel, method)
    assert impacts(ev).size > 0


@pytest.mark.slow
def test_hpotp_ramp_to_twice_full_speed():
    sim, disp, vel, ev = run('hpotp', ['rotor.speed.final_speed=4800 rad/s'], 'exact', 1e-4,
                             1.0, chunk=0.25)
    assert_sane(sim, disp, vel, 'exact')
    assert impacts(ev).size > 0


@pytest.mark.parametrize('method', ['exact', pytest.param('newmark', marks=pytest.mark.slow)])
def test_unbalance_times_100(method):
    """X = 100 on rbs: violent rattling (about 40,000 impacts/s over six impactors), still
    sane. Without impactors the structure is linear: 100 times the X = 1 response to 1e-9."""
    sim, disp, vel, ev = run('rbs', ['rotor.multiplier=100', EFFECTIVE], method, 5e-5, 0.1)
    assert_sane(sim, disp, vel, method)
    assert impacts(ev).size > 500
    _, lin100, _, _ = run('rbs', ['rotor.multiplier=100', 'impactors=[]'], method, 5e-5, 0.1)
    _, lin1, _, _ = run('rbs', ['impactors=[]'], method, 5e-5, 0.1)
    np.testing.assert_allclose(lin100, 100 * lin1, rtol=0, atol=1e-9 * np.abs(lin100).max())


@pytest.mark.slow
def test_hpotp_unbalance_times_100():
    sim, disp, vel, ev = run('hpotp', ['rotor.multiplier=100'], 'exact', 1e-4, 0.5, chunk=0.25)
    assert_sane(sim, disp, vel, 'exact')
    assert impacts(ev).size > 500


@pytest.mark.slow
def test_direct_unbalance_times_100():
    """The physical-coordinate model (227 DOF) under the same violent rattling, 20 ms."""
    sim, disp, vel, ev = run('rbs', ['rotor.multiplier=100', EFFECTIVE], 'direct', 5e-5, 0.02)
    assert_sane(sim, disp, vel, 'direct')
    assert impacts(ev).size > 50


# ------------------------------------------------------------------ Kcc at the onset
def _rbs_onset():
    """Linear onset Kcc of rbs_kcc without impactors (N/m): the modal basis does not depend
    on the skew stiffness, so the modal matrices are affine in Kcc."""
    from impact_damper_sim.modal.stability import onset_cross_coupling
    key = 'structure.cross_couplings.0.kcc'
    mats = [load('rbs_kcc', ['impactors=[]', f'{key}={k}']).basis for k in (0.0, 1.0)]
    K0, K1 = (b.stiffness_matrix() for b in mats)
    C = mats[0].damping_matrix()
    return onset_cross_coupling(lambda k: (K0 + k * (K1 - K0), C), 1e5, 1e7, rtol=1e-9), key


def test_onset_is_the_linear_stability_limit():
    """At 0.99 x onset every eigenvalue decays, at 1.01 x one grows (the onset is 8,275 lb/in
    to 0.1 %, README)."""
    from impact_damper_sim.modal.stability import least_damped_eigenvalue
    kcc, key = _rbs_onset()
    assert kcc / 175.126835 == pytest.approx(8275, rel=1e-3)   # N/m per lb/in
    for f, sign in ((0.99, -1), (1.01, 1)):
        b = load('rbs_kcc', ['impactors=[]', f'{key}={kcc * f!r}']).basis
        assert np.sign(least_damped_eigenvalue(b.stiffness_matrix(),
                                               b.damping_matrix()).real) == sign


@pytest.mark.slow
@pytest.mark.parametrize('factor', [0.99, 1.01])
@pytest.mark.parametrize('method', ['exact', 'newmark'])
def test_kcc_at_the_onset_with_impactors(factor, method):
    """Kcc = onset x (1 +- 1 %), with impactors and a 10 um push: sane, circulatory work in
    the ledger; without impactors the last 0.25 s grow (1.01) or decay (0.99) against the
    previous 0.25 s, as the eigenvalue says."""
    kcc, key = _rbs_onset()
    ov = [f'{key}={kcc * factor!r}', EFFECTIVE]
    for extra in ([], ['impactors=[]']):
        sc = load('rbs_kcc', ov + extra)
        q0 = np.full(sc.model.n, 1e-5 / np.sqrt(sc.model.n))
        sim = sc.make_simulation(method, 5e-5, q0=q0)
        s = sim.advance_to(1.0)
        assert_sane(sim, s.displacement, s.velocity, method)
        if extra:
            r2 = np.sum(s.displacement ** 2, axis=1)
            last, prev = r2[-5000:].mean(), r2[-10000:-5000].mean()
            assert (last > prev) == (factor > 1)


# ------------------------------------------------------------------ modes up to 20 kHz
def test_modes_up_to_20_khz_refuse_a_coarse_newmark_step():
    """rbs with every mode up to 20 kHz (60 modes): Newmark at the paper's 50 us is refused
    (T_min/10 is about 5 us); the exact propagator takes any step."""
    scene = load('rbs', ['modal.n_modes=null', 'modal.f_max=20 kHz'])
    assert scene.basis.frequencies_hz.max() > 10e3
    with pytest.raises(ValueError, match=r'simulation\.dt'):
        scene.make_simulation('newmark', 5e-5)


@pytest.mark.slow
@pytest.mark.parametrize('scene', ['rbs', 'hpotp'])
def test_modes_up_to_20_khz_exact(scene):
    """Every mode up to 20 kHz (rbs 60, hpotp 88), unbalance x 10 so that impacts happen."""
    ov = ['modal.n_modes=null', 'modal.f_max=20 kHz', 'rotor.multiplier=10']
    ov += [EFFECTIVE] if scene == 'rbs' else []
    sim, disp, vel, ev = run(scene, ov, 'exact', 5e-5, 0.1)
    assert_sane(sim, disp, vel, 'exact')


@pytest.mark.slow
def test_modes_up_to_20_khz_newmark_at_the_largest_allowed_step():
    ov = ['modal.n_modes=null', 'modal.f_max=20 kHz', 'rotor.multiplier=10', EFFECTIVE]
    scene = load('rbs', ov)
    dt = 1.0 / np.ceil(10 * scene.basis.frequencies_hz.max())
    sim = scene.make_simulation('newmark', dt)
    s = sim.advance_to(0.02)
    assert_sane(sim, s.displacement, s.velocity, 'newmark')
