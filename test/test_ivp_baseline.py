"""Tests for the solve_ivp event-restart baseline, ``bench/ivp_baseline.py``.

The module lives outside the package, so it is loaded from its file path with importlib.
"""
import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest

_BENCH = Path(__file__).resolve().parents[1] / 'bench'


def _load_baseline(name='ivp_baseline'):
    spec = importlib.util.spec_from_file_location(name, _BENCH / f'{name}.py')
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


ivb = _load_baseline()
grazes = _load_baseline('ivp_baseline_grazes')   # its step screen

F_N = 10.0                       # natural frequency of every case here (Hz)
K_REF = (2 * math.pi * F_N) ** 2  # stiffness for M = 1 kg (N/m); F0/K_REF is x_st for F0 = 1 N


def _steady_params():
    """Steady two-impacts-per-cycle case: r = 1, zeta = 0.01, mu = 0.05, e = 0.6, D = 30 x_st."""
    return ivb.Params.from_nondim(f_n=F_N, zeta=0.01, r=1.0, mu=0.05, e=0.6, D=30.0 / K_REF)


def _combined_accel(p, t, y):
    """Acceleration of housing and impactor moving together (m/s^2)."""
    return (p.F0 * np.cos(p.Omega * t) - p.c * y[:, 1] - p.K * y[:, 0]) / (p.M + p.m)


@pytest.fixture(scope='module')
def free_decay():
    """Free decay from a large displacement; the impactor chatters down every half cycle."""
    p = ivb.Params.from_nondim(f_n=F_N, zeta=0.01, r=1.0, mu=0.01, e=0.6, D=1e-3, F0=0.0)
    res = ivb.simulate(p, 5.0, rtol=1e-10, x0=(0.02, 0.0, 0.02, 0.0), record_dt=5e-4,
                       max_events=20_000)
    return p, res


@pytest.fixture(scope='module')
def forced_chatter():
    """Resonant forcing of a small gap: dozens of impacts and a stuck phase every cycle."""
    p = ivb.Params.from_nondim(f_n=F_N, zeta=0.01, r=1.0, mu=0.01, e=0.8, D=1.0 / K_REF)
    res = ivb.simulate(p, 5.0, rtol=1e-10, record_dt=5e-4, max_events=20_000)
    return p, res


@pytest.mark.parametrize('e', [0.0, 0.6, 1.0])
def test_impact_law_conserves_momentum_and_restitutes(e):
    M, mu = 1.3, 0.07
    m = mu * M
    xd, zd = 0.4, -1.1
    xp, zp = ivb.impact_law(xd, zd, mu, e)
    assert M * xp + m * zp == pytest.approx(M * xd + m * zd, rel=1e-15, abs=1e-15)
    assert zp - xp == pytest.approx(-e * (zd - xd), rel=1e-14)
    lost = 0.5 * M * (xd**2 - xp**2) + 0.5 * m * (zd**2 - zp**2)
    m_red = M * m / (M + m)
    assert lost == pytest.approx(0.5 * m_red * (1 - e * e) * (zd - xd) ** 2, rel=1e-12,
                                 abs=1e-16)


def test_elastic_impacts_conserve_energy():
    p = ivb.Params.from_nondim(f_n=F_N, zeta=0.0, r=1.0, mu=0.05, e=1.0, D=1e-3, F0=0.0)
    res = ivb.simulate(p, 1.0, rtol=1e-10, x0=(0.005, 0.0, 0.005, 0.3), record_dt=1e-3)
    assert res.n_impacts >= 100
    assert res.n_stick == 0 and res.diss_impact == 0.0
    assert abs(res.E_end / res.E0 - 1) < 1e-7
    # Samples come from the dense-output interpolant: still well within 1e-7.
    E = ivb.energy(p, res.y_rec)
    assert np.max(np.abs(E / res.E0 - 1)) < 1e-7
    assert np.all(np.abs(res.y_rec[:, 2] - res.y_rec[:, 0]) <= 0.5 * p.D * (1 + 1e-9))


def _check_stuck_phases(p, res):
    """Stuck phases ride the wall, the wall pushes into the cavity, and most end in release."""
    assert res.n_stick >= 10
    assert res.n_release >= res.n_stick - 1
    assert int(res.impact_plastic.sum()) == res.n_stick   # each entry is one plastic impact
    assert 0.0 < res.stuck_fraction < 1.0
    r = res.y_rec[:, 2] - res.y_rec[:, 0]
    assert np.all(np.abs(r) <= 0.5 * p.D * (1 + 1e-6))   # never leaves the cavity
    acc = _combined_accel(p, res.t_rec, res.y_rec)
    scale = p.K * p.D   # force scale for the contact-force sign check (N per kg)
    for (t0, t1), s in zip(res.stick_intervals, res.stick_walls):
        inside = (res.t_rec > t0) & (res.t_rec < t1)
        assert np.allclose(r[inside], s * 0.5 * p.D, rtol=0, atol=1e-9 * p.D)
        # Wall s can only push the impactor towards -s: N = m x'' requires -s x'' >= 0.
        assert np.all(-s * acc[inside] >= -1e-9 * scale)


def test_free_decay_chatter_sticks_releases_and_stays_bounded(free_decay):
    p, res = free_decay
    assert res.n_impacts < 5000   # bounded: about 10 impacts per half cycle
    _check_stuck_phases(p, res)


def test_forced_chatter_dozens_of_impacts_per_cycle(forced_chatter):
    p, res = forced_chatter
    cycles_late = 2.0 * p.Omega / (2 * math.pi)
    per_cycle = np.sum(res.impact_times > 3.0) / cycles_late
    assert per_cycle >= 24
    assert res.n_impacts < 10_000
    _check_stuck_phases(p, res)


@pytest.mark.parametrize('case', ['free_decay', 'forced_chatter', 'steady'])
def test_energy_balance_closes(case, request):
    if case == 'steady':
        p = _steady_params()
        res = ivb.simulate(p, 3.0, rtol=1e-10)
        assert res.n_impacts > 50
    else:
        p, res = request.getfixturevalue(case)
    assert res.diss_impact > 0
    assert abs(res.energy_residual_rel) < 1e-6


def test_without_sticking_chatter_hits_the_event_cap():
    p = ivb.Params.from_nondim(f_n=F_N, zeta=0.01, r=1.0, mu=0.01, e=0.6, D=1e-3, F0=0.0)
    with pytest.raises(RuntimeError, match='max_events=200'):
        ivb.simulate(p, 5.0, x0=(0.02, 0.0, 0.02, 0.0), v_stick=0.0, dt_stick=0.0,
                     max_events=200)


@pytest.mark.parametrize('method', ['RK45', 'Radau', 'LSODA', 'DOP853'])
def test_methods_agree_on_impact_times(method):
    p = _steady_params()
    ref = ivb.simulate(p, 1.0, rtol=1e-11)
    res = ivb.simulate(p, 1.0, rtol=1e-8, method=method)
    assert res.method == method
    assert res.n_impacts == ref.n_impacts > 10
    assert np.array_equal(res.impact_walls, ref.impact_walls)
    assert np.max(np.abs(res.impact_times - ref.impact_times)) < 1e-5
    assert res.n_rhs > 0 and res.wall_time > 0


def test_tolerance_convergence_and_ledger_switch():
    p = _steady_params()
    ref = ivb.simulate(p, 2.0, rtol=1e-12)
    err = []
    for rtol in (1e-6, 1e-9):
        res = ivb.simulate(p, 2.0, rtol=rtol)
        assert res.n_impacts == ref.n_impacts
        err.append(np.max(np.abs(res.impact_times - ref.impact_times)))
    assert err[1] < err[0] / 10 and err[1] < 1e-8
    bare = ivb.simulate(p, 2.0, rtol=1e-9, ledger=False, restep=False)
    assert math.isnan(bare.work_force) and math.isnan(bare.energy_residual)
    assert np.max(np.abs(bare.impact_times - ref.impact_times)) < 1e-7


def test_quintic_hermite_screen_is_exact_for_quintics():
    rng = np.random.default_rng(1)
    c = rng.normal(size=6)
    f = np.polynomial.Polynomial(c)
    h, t0 = 0.37, 1.2
    g = f.deriv(1)
    g2 = f.deriv(2)
    data = [f(t0), h * g(t0), h * h * g2(t0), h * h * g2(t0 + h), h * g(t0 + h), f(t0 + h)]
    tau = np.linspace(0.0, 1.0, 11)
    assert grazes._quintic_hermite_basis(tau) @ data == pytest.approx(f(t0 + h * tau), rel=1e-12)


def test_excursion_inside_one_step_is_found():
    # Free housing x = A cos t (M = K = 1, no force) and a free impactor z = z0 + w t that
    # has just left the wall r = z - x = lim with r' = w < 0. The housing pulls the wall back
    # onto it: r passes the wall around t = 1 and is inside again before t = 4, so no event
    # function changes sign between the ends of the step [0, 4].
    from scipy.optimize import brentq

    p = ivb.Params(M=1.0, K=1.0, c=0.0, F0=0.0, Omega=1.0, mu=0.1, e=0.5, D=2.0)
    lim, A = 1.0, 1.0

    def make_dense(w):
        def dense(t):
            t = np.asarray(t, dtype=float)
            return np.array([A * np.cos(t), -A * np.sin(t), lim + A + w * t, w + 0.0 * t])
        return dense

    ts = np.array([0.0, 4.0])
    dense = make_dense(-0.45)
    ys = dense(ts)
    assert abs(ys[2, 1] - ys[0, 1]) < lim
    assert list(grazes._graze_candidates(ts, ys, lim, p)) == [0]
    wall, t_c, y_c = grazes._locate_graze(0.0, 4.0, dense, lim, p)
    t_true = brentq(lambda t: -0.45 * t + A * (1 - np.cos(t)), 0.5, 1.5, xtol=1e-15)
    assert wall == 1 and t_c == pytest.approx(t_true, abs=1e-12)
    assert y_c[3] - y_c[1] > 0   # closing
    # Faster away from the wall, the impactor stays inside: no contact.
    assert grazes._locate_graze(0.0, 4.0, make_dense(-0.8), lim, p) is None


def test_record_grid_and_final_state():
    p = _steady_params()
    res = ivb.simulate(p, 1.0, rtol=1e-9, record_dt=0.01, x0=(1e-3, 0.0, 0.0, 0.0))
    assert res.t_rec.shape == (101,) and res.t_rec[-1] == pytest.approx(1.0)
    assert res.x_rec[0] == 1e-3
    assert res.y_rec[-1] == pytest.approx(res.y_end, rel=1e-6, abs=1e-9)
    assert res.wall_per_sim_second == pytest.approx(res.wall_time)


def test_params_mapping_is_strict():
    p = _steady_params()
    d = {f: getattr(p, f) for f in ('M', 'K', 'c', 'F0', 'Omega', 'mu', 'e', 'D')}
    assert ivb.simulate(d, 0.2).y_end == pytest.approx(ivb.simulate(p, 0.2).y_end)
    with pytest.raises(ValueError, match='unknown parameter'):
        ivb.simulate(dict(d, zeta=0.01), 0.2)
    with pytest.raises(ValueError, match='missing parameter'):
        ivb.simulate({k: v for k, v in d.items() if k != 'D'}, 0.2)
    with pytest.raises(ValueError, match='unknown method'):
        ivb.simulate(p, 0.2, method='Euler')
    with pytest.raises(ValueError, match='outside the cavity'):
        ivb.simulate(p, 0.2, x0=(0.0, 0.0, p.D, 0.0))
    with pytest.raises(ValueError, match='e must be'):
        ivb.Params(**dict(d, e=1.5))


def test_cli_prints_one_row_per_tolerance(capsys):
    assert ivb.main(['--t-end', '0.5', '--rtol', '1e-6', '1e-8']) == 0
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 4 and out[2].split()[0] == '1e-06' and out[3].split()[0] == '1e-08'
