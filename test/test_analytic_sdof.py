"""Checks of the exact symmetric two-impact orbit of the SDOF impact damper.

The reference integration here is deliberately independent of the module under test: scipy's
DOP853 at rtol = 1e-12 with terminal wall events, the impact law applied by hand and a restart
after every impact. It only borrows the orbit's post-impact state as its initial condition.
"""
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from impact_damper_sim.dampers.analytic import (
    phase_equation_roots,
    symmetric_two_impact_orbit,
    symmetric_two_impact_orbits,
)
from impact_damper_sim.dampers.analytic_checks import (
    orbit_residuals,
    symmetric_half_map,
    symmetric_half_map_jacobian,
)
from impact_damper_sim.dampers.analytic_flow import (
    NoSymmetricOrbit,
    linear_steady_amplitude,
    orbit_state,
)

# Non-unit SI values so that unit or scaling slips show up.
M = 2.0          # kg
K = 5.0e4        # N/m
F0 = 10.0        # N
WN = np.sqrt(K / M)   # rad/s
XS = F0 / K      # static deflection, m


def params(r, zeta, mu, e, d):
    """Arguments of symmetric_two_impact_orbit from (Omega/omega_n, zeta, mu, e, D K/F0)."""
    return dict(M=M, K=K, c=2.0 * zeta * np.sqrt(K * M), F0=F0, Omega=r * WN,
                mass_ratio=mu, cor=e, clearance=d * XS)


# (r = Omega/omega_n, zeta, mu, e, D in units of F0/K): stable orbits for the integrator tests.
STABLE_POINTS = [
    (0.8, 0.02, 0.02, 0.5, 24.0),
    (0.8, 0.02, 0.05, 0.8, 16.0),
    (0.9, 0.02, 0.05, 0.3, 24.0),
    (1.0, 0.02, 0.10, 0.5, 24.0),
    (1.0, 0.05, 0.20, 0.3, 10.0),
    (1.1, 0.02, 0.20, 0.3, 8.0),
    (1.2, 0.02, 0.10, 0.6, 8.0),
    (1.1, 0.00, 0.20, 0.3, 10.0),   # undamped primary, as in Masri & Caughey (1966)
]


def simulate(p, t0, y0, n_impacts):
    """Event-located reference run; returns [(t_impact, wall, pre, post)] and the segments."""
    Mh, Kh, c, F, Om = p['M'], p['K'], p['c'], p['F0'], p['Omega']
    mu, e, D = p['mass_ratio'], p['cor'], p['clearance']
    T = 2.0 * np.pi / Om

    def rhs(t, y):
        return [y[1], (F * np.cos(Om * t) - c * y[1] - Kh * y[0]) / Mh, y[3], 0.0]

    def upper(t, y):
        return y[2] - y[0] - D / 2.0
    upper.terminal, upper.direction = True, 1.0

    def lower(t, y):
        return y[2] - y[0] + D / 2.0
    lower.terminal, lower.direction = True, -1.0

    xs = max(abs(y0[0]), D)
    atol = 1e-16 * np.array([xs, xs * Om, xs, xs * Om])
    t, y, out, segments = t0, np.array(y0, float), [], []
    while len(out) < n_impacts:
        sol = solve_ivp(rhs, (t, t + 2.0 * T), y, method='DOP853', rtol=1e-12, atol=atol,
                        events=(upper, lower), dense_output=True)
        if sol.status != 1:
            break  # no impact within two periods
        k = 0 if sol.t_events[0].size else 1
        te, pre = sol.t_events[k][0], sol.y_events[k][0].copy()
        wall = 1 if k == 0 else -1
        xd = ((1 - mu * e) * pre[1] + mu * (1 + e) * pre[3]) / (1 + mu)
        zd = ((1 + e) * pre[1] + (mu - e) * pre[3]) / (1 + mu)
        y = np.array([pre[0], xd, pre[0] + wall * D / 2.0, zd])
        out.append((te, wall, pre, y.copy()))
        segments.append((t, te, sol.sol))
        if len(out) > 1 and te - out[-2][0] < 1e-6 * T:
            break  # chatter: the orbit has been left
        t = te
    return out, segments


def start_on(orbit, perturb=(0.0, 0.0, 0.0)):
    """Initial time and state (x, x', z, z') just after the +D/2 impact, optionally perturbed."""
    t0, x0, v0, w0 = orbit.post_impact_state
    dx, dv, dw = perturb
    return t0, [x0 + dx, v0 + dv, x0 + dx + orbit.clearance / 2.0, w0 + dw]


def cycle_deviation(orbit, impacts):
    """Scaled deviation from the orbit after every full cycle (every second impact)."""
    t0, x0, v0, w0 = orbit.post_impact_state
    h, A = orbit.half_period, orbit.amplitude
    V = orbit.Omega * A
    devs = []
    for k in range(2, len(impacts) + 1, 2):
        te, wall, _, post = impacts[k - 1]
        if wall != 1 or impacts[k - 2][1] != -1:
            devs.append(np.inf)   # not alternating any more
            break
        devs.append(max(abs(te - t0 - k * h) * orbit.Omega, abs(post[0] - x0) / A,
                        abs(post[1] - v0) / V, abs(post[3] - w0) / V))
    return np.array(devs)


# ----------------------------------------------------------------------------------- (a)
@pytest.mark.parametrize('point', STABLE_POINTS)
def test_orbit_matches_event_located_integration(point):
    p = params(*point)
    orbit = symmetric_two_impact_orbit(**p)
    assert orbit.stable
    assert np.abs(orbit_residuals(orbit)).max() < 1e-10
    assert orbit.relative_velocity_pre > 0.0
    assert 0.0 < orbit.clearance_margin <= orbit.clearance / 2.0

    t0, y0 = start_on(orbit)
    impacts, segments = simulate(p, t0, y0, 40)   # 20 cycles
    assert len(impacts) == 40
    h, A = orbit.half_period, orbit.amplitude
    V = orbit.Omega * A + abs(orbit.zdot_post)
    for k, (te, wall, pre, post) in enumerate(impacts, start=1):
        s = (-1) ** k
        assert wall == s   # odd impacts on the -D/2 wall
        assert te == pytest.approx(t0 + k * h, rel=1e-7, abs=1e-7 * h)
        # pre-impact velocities and post-impact state, relative to the orbit's scales
        assert abs(post[0] - s * orbit.x_impact) < 1e-7 * A
        assert abs(pre[1] - s * orbit.xdot_pre) < 1e-7 * V
        assert abs(pre[3] - s * orbit.zdot_pre) < 1e-7 * V
        assert abs(post[1] - s * orbit.xdot_post) < 1e-7 * V
        assert abs(post[3] - s * orbit.zdot_post) < 1e-7 * V

    # orbit_state between impacts agrees with the dense output, and the amplitude with max|x|
    xmax = 0.0
    for ta, tb, sol in segments[-4:]:
        tt = np.linspace(ta, tb, 401)[1:-1]
        ys = sol(tt)
        x, v, z, w = orbit_state(orbit, tt)
        xs = (x, v, z, w)
        for i, scale in enumerate((A, V, A, V)):
            assert np.abs(xs[i] - ys[i]).max() < 1e-7 * scale
        xmax = max(xmax, np.abs(ys[0]).max())
    assert xmax <= A * (1 + 1e-9)
    assert xmax == pytest.approx(A, rel=1e-4)   # grid of 400 points per flight


def test_orbit_with_interior_extremum_and_rejected_root():
    """The no-contact check: a root whose flight touches a wall must be rejected, and an
    accepted orbit whose z - x turns inside the flight must still be a true orbit."""
    # accepted, unstable, z - x has an interior extremum (margin < D/2)
    p = params(0.8, 0.02, 0.05, 0.5, 4.0)
    orbit = symmetric_two_impact_orbit(**p)
    assert orbit.clearance_margin < 0.4 * orbit.clearance
    assert np.abs(orbit_residuals(orbit)).max() < 1e-10
    t0, y0 = start_on(orbit)
    impacts, _ = simulate(p, t0, y0, 4)   # unstable (|lambda| ~ 5): two cycles only
    for k, (te, wall, _, _) in enumerate(impacts, start=1):
        assert wall == (-1) ** k
        assert te == pytest.approx(t0 + k * orbit.half_period, rel=1e-7)

    # rejected: flight of the '+' root reaches a wall before t0 + pi/Omega
    p = params(0.8, 0.02, 0.10, 0.5, 2.0)
    roots = {b: (s, why) for b, s, why in phase_equation_roots(**p)}
    state, why = roots[+1]
    assert 'reaches a wall' in why
    t0, x0, v0, w0 = state
    impacts, _ = simulate(p, t0, [x0, v0, x0 + p['clearance'] / 2.0, w0], 1)
    te, wall, _, _ = impacts[0]
    h = np.pi / p['Omega']
    assert te < t0 + h * (1 - 1e-3) or wall != -1
    # and the '-' root is rejected because the impactor would leave the wall
    assert 'recedes' in roots[-1][1]
    with pytest.raises(NoSymmetricOrbit):
        symmetric_two_impact_orbit(**p)


def test_residuals_over_parameter_grid():
    n = 0
    for r in (0.8, 0.9, 1.0, 1.1, 1.2):
        for mu in (0.02, 0.05, 0.1, 0.2):
            for e in (0.3, 0.5, 0.8):
                for d in (2.0, 6.0, 16.0):
                    for orbit in symmetric_two_impact_orbits(**params(r, 0.02, mu, e, d)):
                        assert np.abs(orbit_residuals(orbit)).max() < 1e-10
                        assert orbit.relative_velocity_pre > 0.0
                        n += 1
    assert n > 50


@pytest.mark.parametrize('point', [STABLE_POINTS[3], (1.2, 0.02, 0.10, 0.6, 4.0)])
def test_jacobian_matches_finite_differences(point):
    orbit = symmetric_two_impact_orbit(**params(*point))
    s = orbit.post_impact_state
    assert np.abs(symmetric_half_map(orbit, s) - s).max() < 1e-12 * np.abs(s).max()
    scale = np.array([orbit.half_period, orbit.amplitude, orbit.Omega * orbit.amplitude,
                      orbit.Omega * orbit.amplitude])
    J = symmetric_half_map_jacobian(orbit)
    Jfd = np.empty((4, 4))
    for j in range(4):
        d = np.zeros(4)
        d[j] = 1e-6 * scale[j]
        Jfd[:, j] = (symmetric_half_map(orbit, s + d)
                     - symmetric_half_map(orbit, s - d)) / (2 * d[j])
    scaled = lambda A: A * scale[None, :] / scale[:, None]   # noqa: E731
    assert np.abs(scaled(J) - scaled(Jfd)).max() < 1e-6
    lam = np.sort_complex(np.linalg.eigvals(J) ** 2)
    assert np.allclose(lam, np.sort_complex(np.array(orbit.multipliers)), atol=1e-12)


# ----------------------------------------------------------------------------------- (b)
@pytest.mark.parametrize('point', STABLE_POINTS)
def test_stable_orbit_attracts_small_perturbation(point):
    p = params(*point)
    orbit = symmetric_two_impact_orbit(**p)
    assert orbit.stable
    V = orbit.Omega * orbit.amplitude
    t0, y0 = start_on(orbit, perturb=(1e-3 * orbit.amplitude, 0.0, 1e-3 * V))
    impacts, _ = simulate(p, t0, y0, 60)
    dev = cycle_deviation(orbit, impacts)
    assert len(dev) == 30 and np.all(np.isfinite(dev))
    assert dev[-1] < 0.05 * dev[0]
    # decay rate per cycle agrees with the spectral radius of the computed multipliers
    # (fit above the integration noise floor)
    k = np.arange(10, 30)
    k = k[dev[k] > 1e-10]
    rate = np.exp(np.polyfit(k, np.log(dev[k]), 1)[0])
    assert rate == pytest.approx(orbit.spectral_radius, abs=0.02)


def test_unstable_orbit_departs_at_predicted_rate():
    p = params(1.2, 0.02, 0.10, 0.6, 4.0)
    orbit = symmetric_two_impact_orbit(**p)
    assert not orbit.stable
    lam = orbit.multipliers[0]
    assert abs(lam.imag) < 1e-12 and lam.real > 1.5   # real dominant multiplier
    V = orbit.Omega * orbit.amplitude
    t0, y0 = start_on(orbit, perturb=(0.0, 0.0, 1e-10 * V))
    impacts, _ = simulate(p, t0, y0, 60)
    dev = cycle_deviation(orbit, impacts)
    assert not np.all(dev[-3:] < 1e-3)   # left the orbit
    growth = dev[5:15] / dev[4:14]        # still linear here: deviation < 1e-6
    assert np.all(dev[:15] < 1e-5)
    assert np.allclose(growth, lam.real, rtol=0.02)

    # the other root at the same parameters is violently unstable and departs within cycles
    other = symmetric_two_impact_orbit(**params(1.2, 0.02, 0.10, 0.6, 8.0), branch=-1)
    assert other.spectral_radius > 10
    t0, y0 = start_on(other, perturb=(0.0, 0.0, 1e-10 * other.Omega * other.amplitude))
    impacts, _ = simulate(params(1.2, 0.02, 0.10, 0.6, 8.0), t0, y0, 30)
    assert cycle_deviation(other, impacts).max() > 1e-2


# ----------------------------------------------------------------------------------- (c)
def test_large_clearance_has_no_orbit():
    p = params(1.2, 0.02, 0.10, 0.6, 8.0)
    exists = []
    for d in np.geomspace(8.0, 1e4, 25):
        p['clearance'] = d * XS
        exists.append(bool(symmetric_two_impact_orbits(**p)))
    assert exists[0] and not exists[-1]
    assert not any(exists[exists.index(False):])   # once gone, gone for good
    with pytest.raises(NoSymmetricOrbit, match='exceeds'):
        symmetric_two_impact_orbit(**p)
    p['F0'] = 0.0
    p['clearance'] = 1e-6
    assert symmetric_two_impact_orbits(**p) == ()


def test_small_mass_ratio_recovers_linear_amplitude():
    point = (1.2, 0.02, None, 0.6, 2.0)
    p = params(*point[:2], 0.1, *point[3:])
    a_lin = linear_steady_amplitude(p['M'], p['K'], p['c'], p['F0'], p['Omega'])
    assert a_lin == pytest.approx(F0 / np.hypot(K - M * p['Omega'] ** 2, p['c'] * p['Omega']))
    err = []
    for mu in (1e-2, 1e-3, 1e-4, 1e-6):
        p['mass_ratio'] = mu
        orbit = symmetric_two_impact_orbit(**p)
        assert orbit.linear_amplitude == pytest.approx(a_lin, rel=1e-14)
        err.append(abs(orbit.amplitude / a_lin - 1.0))
    assert err[-1] < 1e-5
    assert all(b < 0.2 * a for a, b in zip(err[:-1], err[1:]))   # O(mu)


# ----------------------------------------------------------------------------------- misc
def test_orbit_state_is_antiperiodic_and_right_continuous():
    orbit = symmetric_two_impact_orbit(**params(*STABLE_POINTS[0]))
    h = orbit.half_period
    t = orbit.t_impact + np.linspace(-3 * h, 3 * h, 97) + 0.123 * h
    a = np.array(orbit_state(orbit, t))
    b = np.array(orbit_state(orbit, t + h))
    c = np.array(orbit_state(orbit, t + 2 * h))
    assert np.allclose(b, -a, rtol=1e-12, atol=1e-12 * orbit.amplitude * orbit.Omega)
    assert np.allclose(c, a, rtol=1e-12, atol=1e-12 * orbit.amplitude * orbit.Omega)
    x, v, z, w = orbit_state(orbit, orbit.t_impact)
    assert (x, v, w) == pytest.approx((orbit.x_impact, orbit.xdot_post, orbit.zdot_post))
    assert z - x == pytest.approx(orbit.clearance / 2.0)
    x, v, z, w = orbit_state(orbit, t)
    assert np.all(np.abs(z - x) <= orbit.clearance / 2.0 * (1 + 1e-12))


def test_invalid_parameters():
    p = params(*STABLE_POINTS[0])
    for key, bad in (('M', 0.0), ('clearance', -1.0), ('cor', 1.5), ('c', -1.0)):
        with pytest.raises(ValueError):
            symmetric_two_impact_orbit(**{**p, key: bad})


def test_print_stable_points_table():
    rows = []
    for point in STABLE_POINTS:
        orbit = symmetric_two_impact_orbit(**params(*point))
        assert orbit.stable
        rows.append((*point, orbit.amplitude / XS, orbit.amplitude / orbit.linear_amplitude,
                     orbit.alpha, orbit.relative_velocity_pre / (XS * WN),
                     orbit.zdot_post / (XS * WN), orbit.multipliers))
    print('\nStable symmetric two-impact orbits (D, A in F0/K; velocities in omega_n F0/K):')
    print(f"{'r':>4} {'zeta':>5} {'mu':>5} {'e':>4} {'D':>5} {'A':>8} {'A/Alin':>7} "
          f"{'alpha':>7} {'vrel-':>7} {'zdot+':>8}  |multipliers|")
    for r, z, mu, e, d, a, al, alpha, vr, zd, lam in rows:
        mods = ' '.join(f'{abs(v):.4f}' for v in lam)
        print(f'{r:4.2f} {z:5.2f} {mu:5.2f} {e:4.2f} {d:5.1f} {a:8.5f} {al:7.4f} '
              f'{alpha:7.4f} {vr:7.4f} {zd:8.4f}  {mods}')
