"""Numba kernels against their plain-Python twins and independent references."""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from impact_damper_sim.integrate.kernels import flow_eval as K
from impact_damper_sim.integrate.kernels import ledger as L
from impact_damper_sim.integrate.kernels import poly as PL
from impact_damper_sim.integrate.kernels import quadrature as Q


@pytest.fixture
def rng():
    return np.random.default_rng(20261121)


def test_flow_factors_twin_and_closed_form(rng):
    # e^z, phi1 = (e^z - 1)/z, phi2 = (e^z - 1 - z)/z^2: one series near 0 (e^z = 1 + z phi1
    # there), the exponential elsewhere. Twin vs JIT to 1e-15; e^z vs np.exp to 2 ulp; phi1,
    # phi2 vs Simpson quadrature of their integrals, 1e-10.
    for z in list(rng.normal(size=20) * 0.1 + 1j * rng.normal(size=20) * 0.1) + \
            list(rng.normal(size=20) * 3 + 1j * rng.normal(size=20) * 30):
        e, a, b = K.flow_factors(z)
        e_py, a_py, b_py = K.flow_factors_py(z)
        assert abs(a - a_py) <= 1e-15 * abs(a) and abs(b - b_py) <= 1e-15 * abs(b)
        assert abs(e - e_py) <= 1e-15 * abs(e)
        assert abs(e - np.exp(z)) <= 4.5e-16 * abs(e)
        zl = complex(z)
        # reference by numerical quadrature of phi1 = int_0^1 e^{z s} ds, phi2 = int (1-s) e^{zs}
        s = np.linspace(0.0, 1.0, 20001)
        w = np.full(s.size, 2.0)
        w[1::2] = 4.0
        w[0] = w[-1] = 1.0
        w /= 3.0 * (s.size - 1)
        ref_a = np.sum(w * np.exp(zl * s))
        ref_b = np.sum(w * (1 - s) * np.exp(zl * s))
        assert abs(a - ref_a) <= 1e-10 * abs(ref_a)
        assert abs(b - ref_b) <= 1e-10 * abs(ref_b)


def test_propagate_twin_and_quadrature(rng):
    # yh(tau) for y' = lam y + w0 + ws t, against the twin (1e-15) and the variation-of-
    # constants integral evaluated by Simpson's rule (1e-10).
    n2 = 6
    lam = -rng.uniform(0.0, 5.0, n2) + 1j * rng.uniform(-300, 300, n2)
    yh = rng.normal(size=n2) + 1j * rng.normal(size=n2)
    w0 = rng.normal(size=n2) + 1j * rng.normal(size=n2)
    ws = rng.normal(size=n2) + 1j * rng.normal(size=n2)
    tau = 3.7e-3
    out = np.empty(n2, complex)
    out_py = np.empty(n2, complex)
    K.propagate(yh, lam, tau, w0, ws, out)
    K.propagate_py(yh, lam, tau, w0, ws, out_py)
    np.testing.assert_allclose(out, out_py, rtol=1e-15, atol=0)
    s = np.linspace(0.0, tau, 40001)
    w = np.full(s.size, 2.0)
    w[1::2] = 4.0
    w[0] = w[-1] = 1.0
    w *= (s[1] - s[0]) / 3.0
    for k in range(n2):
        ref = np.exp(lam[k] * tau) * yh[k] + np.sum(
            w * np.exp(lam[k] * (tau - s)) * (w0[k] + ws[k] * s))
        assert abs(out[k] - ref) <= 1e-10 * abs(ref)


def test_derivative_bounds_bound_the_true_derivatives(rng):
    # The bounds must dominate |d^m y/dt^m| everywhere on the interval (sampled densely), and
    # the twin must agree with the JIT exactly.
    n2, nf = 4, 2
    lam = -rng.uniform(0, 2, n2) + 1j * rng.uniform(-200, 200, n2)
    W = rng.normal(size=(n2, nf)) + 1j * rng.normal(size=(n2, nf))
    yh = rng.normal(size=n2) + 1j * rng.normal(size=n2)
    u0 = rng.normal(size=nf)
    us = rng.normal(size=nf) * 10
    omegas = np.array([150.0])
    amps = rng.normal(size=(1, nf)) + 1j * rng.normal(size=(1, nf))
    pp = (W @ amps[0]) / (2 * (1j * omegas[0] - lam))
    pm = (W @ amps[0].conj()) / (2 * (-1j * omegas[0] - lam))
    w0 = W @ u0
    ws = W @ us
    Th = 0.02
    u_abs = np.maximum(np.abs(u0), np.abs(u0 + us * Th))
    order = 3
    out = np.empty((order + 1, n2))
    out_py = np.empty((order + 1, n2))
    args = (yh, lam, W, pp[None, :], pm[None, :], w0, ws, 0.0, Th, u_abs, np.abs(us), omegas,
            amps, order)
    K.derivative_bounds(*args, np.empty((order + 1, nf)), np.empty(order + 1), out)
    K.derivative_bounds_py(*args, np.empty((order + 1, nf)), np.empty(order + 1), out_py)
    np.testing.assert_allclose(out, out_py, rtol=1e-14)
    yh_t = np.empty(n2, complex)
    y_t = np.empty(n2, complex)
    uder = np.empty((order + 1, nf))
    yd = np.empty((order + 1, n2), complex)
    for tau in np.linspace(0.0, Th, 401):
        K.point_eval(yh, lam, W, w0, ws, pp[None, :], pm[None, :], omegas, amps, u0, us, 0.0,
                     tau, order, yh_t, y_t, uder, yd)
        assert np.all(np.abs(yd) <= out * (1 + 1e-12))


def test_cubic_safe_step_is_safe_and_twin(rng):
    # The returned step s keeps p(t) = g0 + g1 t + g2 t^2/2 - G3 t^3/6 positive on [0, s), and
    # is within 0.1 % of the first root when there is one. With s_exact = T (a root below it
    # is not bisected) the step is still safe, no longer than the exact one, and the same
    # when there is no root.
    n_coarse = n_clear = 0
    for _ in range(500):
        g0 = rng.uniform(1e-6, 1.0)
        g1, g2 = rng.normal(size=2) * [3.0, 30.0]
        g3 = rng.uniform(0.0, 300.0)
        T = rng.uniform(0.01, 1.0)
        s = PL.cubic_safe_step(g0, g1, g2, g3, T, 0.0)
        assert s == PL.cubic_safe_step_py(g0, g1, g2, g3, T, 0.0)
        # the shortcut (each term at its least over [0, T] still positive) answers T
        drop = -T * min(g1, 0) - T ** 2 / 2 * min(g2, 0) + g3 * T ** 3 / 6
        if g0 - drop > 1e-12 * (g0 + drop):
            assert s == T
            n_clear += 1
        coarse = PL.cubic_safe_step(g0, g1, g2, g3, T, T)
        assert coarse == PL.cubic_safe_step_py(g0, g1, g2, g3, T, T)
        assert coarse <= s
        n_coarse += coarse < s
        for step in (s, coarse):
            t = np.linspace(0.0, step, 2001)[:-1]
            p = g0 + g1 * t + 0.5 * g2 * t ** 2 - g3 * t ** 3 / 6
            assert np.all(p > 0)
        if s < T:
            roots = np.roots([-g3 / 6, 0.5 * g2, g1, g0])
            real = roots[(abs(roots.imag) < 1e-12) & (roots.real > 0)].real
            assert abs(s - real.min()) <= 1e-3 * real.min()
        else:
            assert coarse == T
    assert n_coarse > 50 and n_clear > 50


RUN = r'''
import json, sys
import numpy as np
sys.path.insert(0, sys.argv[1])
from exact_cases import sdof_model, harmonic
from impact_damper_sim.integrate.exact import ExactPropagator
M, Kst, F0 = 2.0, 5e4, 10.0
wn = np.sqrt(Kst / M)
model = sdof_model(M, Kst, 0.02, dict(name='i', kind='sdof', mass=0.02, cor=0.6,
                                      clearance=2e-3))
prop = ExactPropagator(model, harmonic(1, 40.0, 1.3 * wn), dt=5e-4, q0=[np.sqrt(M) * 0.02])
s = prop.advance(400)
ev = prop.take_events()
json.dump({'x': s.displacement[:, 0].tolist(), 'a': s.acceleration[:, 0].tolist(),
           't': ev['t'].tolist(), 'kind': ev['kind'].tolist(), 'v_n': ev['v_n'].tolist(),
           'ledger': [prop.energy().damping, prop.energy().forcing]}, sys.stdout)
'''


def _run(disable_jit):
    env = dict(os.environ, NUMBA_DISABLE_JIT='1' if disable_jit else '0')
    out = subprocess.run([sys.executable, '-c', RUN, os.path.dirname(__file__)], env=env,
                         capture_output=True, text=True, timeout=600, check=True)
    return json.loads(out.stdout)


def test_whole_run_equals_its_pure_python_twin():
    # The same 0.2 s run (impacts, bounce-down, sticking and release, harmonic forcing) with
    # the JIT and with NUMBA_DISABLE_JIT=1: identical event kinds and times to 1e-12 s,
    # samples to 1e-12 relative. This executes every kernel line as plain Python under test.
    jit = _run(False)
    twin = _run(True)
    assert jit['kind'] == twin['kind']
    assert {0, 1, 2} <= set(jit['kind'])
    np.testing.assert_allclose(jit['t'], twin['t'], rtol=0, atol=1e-12)
    scale = np.max(np.abs(jit['x']))
    np.testing.assert_allclose(jit['x'], twin['x'], rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(jit['ledger'], twin['ledger'], rtol=1e-10)


def _fine_ledger(args, panels):
    """Reference: ledger_panel (4-point Gauss) over ``panels`` sub-intervals of the piece."""
    (yh, lam, W, w0, ws, pp, pm, omegas, amps, u0, us, t, tau, Vq, Vv, C, Kskew, B) = args
    n2, nf = lam.size, u0.size
    y_start = np.empty(n2, complex)
    ref = np.zeros(5)
    width = tau / panels
    for p in range(panels):
        # the held-input flow restarted at s0: state, then input (w0 + ws s0) and slope
        K.propagate(yh, lam, p * width, w0, ws, y_start)
        L.ledger_panel(y_start, lam, W, w0 + ws * (p * width), ws, pp, pm, omegas, amps,
                       u0 + us * (p * width), us, t + p * width, width, Vq, Vv, C, Kskew, B,
                       np.empty(n2, complex), np.empty(n2, complex), np.empty((6, nf)),
                       np.empty((6, n2), complex), ref)
    return ref[2:]


def _ledger_case(rng, n, nf, nh, kind, lam_top, tau):
    """A random flow over one piece: ``kind`` 'coupled' (dense rows, dense damping, skew
    stiffness), 'kcc' (dense rows, diagonal damping, skew stiffness: a rotor with
    cross-coupled stiffness), 'stuck' (dense rows, diagonal damping, as in a stuck
    configuration) or 'modal' (one complex coordinate per row, diagonal damping, no skew
    stiffness)."""
    coupled = kind != 'modal'
    n2 = 2 * n if coupled else n
    lam = -rng.uniform(1.0, 30.0, n2) + 1j * rng.uniform(-lam_top, lam_top, n2)
    lam[0] = -40.0 + 1j * lam_top
    cplx = lambda *shape: rng.normal(size=shape) + 1j * rng.normal(size=shape)  # noqa: E731
    yh, W = cplx(n2), cplx(n2, nf)
    u0, us = rng.normal(size=nf), 1e3 * rng.normal(size=nf)
    C = rng.normal(size=(n, n))
    if coupled:
        Vq, Vv, Kskew, C = cplx(n, n2), cplx(n, n2), rng.normal(size=(n, n)), C @ C.T
        if kind != 'coupled':
            C = np.diag(rng.uniform(0.1, 2.0, n))
        if kind == 'stuck':
            Kskew = np.zeros((n, n))
    else:
        Vq = np.zeros((n, n2), complex)
        Vq[np.arange(n), rng.permutation(n2)] = cplx(n)
        Vv, Kskew, C = Vq * lam, np.zeros((n, n)), np.diag(rng.uniform(0.1, 2.0, n))
    return (yh, lam, W, W @ u0, W @ us, cplx(nh, n2), cplx(nh, n2),
            rng.uniform(100.0, 2000.0, nh), cplx(nh, nf), u0, us, 0.137, tau, Vq, Vv, C,
            Kskew - Kskew.T, rng.normal(size=(n, nf)))


def _pattern(M):
    cols, counts = np.empty(M.shape, np.int64), np.empty(M.shape[0], np.int64)
    L.row_pattern(M, cols, counts)
    return cols, counts


@pytest.mark.parametrize('kind, nh, lam_top, tau', [
    ('coupled', 2, 3e3, 7.3e-4),  # |lam| tau 2.2: three Taylor panels, harmonics, skew
    ('coupled', 0, 8e3, 3e-6),    # a short piece: low degree
    ('kcc', 1, 3e3, 5e-5),        # RBS-like: dense rows, diagonal damping, skew, a harmonic
    ('stuck', 2, 3e3, 7.3e-4),    # dense rows, diagonal damping: three panels, harmonics
    ('stuck', 0, 8.1e3, 1e-4),    # the same, one panel of degree 13
    ('modal', 0, 8.1e3, 1e-4),    # HPOTP-like: |lam| tau 0.81, one panel of degree 13
    ('modal', 1, 8.1e3, 2e-3),    # modal, 17 panels, a harmonic
    ('modal', 0, 5e2, 1e-7),      # tiny piece: the polynomial (held-input) part dominates
])
def test_ledger_series_equal_fine_gauss_quadrature(rng, kind, nh, lam_top, tau):
    # The ledger's Taylor series, integrated exactly, against 4-point Gauss on 64 panels of
    # the piece (quadrature error < 1e-15 here): damping, forcing and circulatory work
    # agree to 1e-12 of the largest, and the form for diagonal damping (per row, or dense
    # rows of a stuck configuration or a cross-coupled rotor) to the general one to 1e-13
    # (each keeps the terms its own degree rule asks for).
    n, nf = 4, 3
    coupled = kind != 'modal'
    args = _ledger_case(rng, n, nf, nh, kind, lam_top, tau)
    (yh, lam, W, w0, ws, pp, pm, omegas, amps, u0, us, t, tau, Vq, Vv, C, Kskew, B) = args
    n2 = lam.size
    ref = _fine_ledger(args, 64)
    scale = np.abs(ref).max()
    for kernel in (L.ledger_taylor, L.ledger_taylor_py):
        out = np.zeros(5)
        panels = kernel(yh, lam, w0, ws, pp, pm, omegas, amps, u0, us, t, tau,
                        np.abs(lam).max(), Vq, Vv, *_pattern(Vq), *_pattern(Vv), C,
                        *_pattern(C), Kskew, bool(np.any(Kskew)), B,
                        np.full((n2, Q.N_TERMS), np.nan, complex),
                        np.full((5, max(n, n2), Q.N_TERMS), np.nan),
                        np.full((nf, Q.N_TERMS), np.nan),
                        np.zeros(n2 + n, np.int64), np.empty(n2, complex), out)
        assert panels == max(1, int(np.ceil(max(np.abs(lam).max(), *omegas, 0.0) * tau)))
        np.testing.assert_allclose(out[2:], ref, rtol=0, atol=1e-12 * scale)
        assert (out[4] != 0.0) == (kind in ('coupled', 'kcc'))
    if kind == 'coupled':
        return
    for kernel in (L.ledger_modal, L.ledger_modal_py):
        modal = np.zeros(5)
        kernel(yh, lam, w0, ws, pp, pm, omegas, amps, u0, us, t, tau, np.abs(lam).max(), Vv,
               _pattern(Vv)[0], coupled, L.rows_transposed(Vv, Kskew @ Vq),
               bool(np.any(Kskew)), C, B, np.full((4, Q.N_TERMS + 9, max(n, n2)), np.nan),
               np.full((nf, Q.N_TERMS), np.nan), np.empty(n2, complex), modal)
        np.testing.assert_allclose(modal[2:], ref, rtol=0, atol=1e-12 * scale)
        np.testing.assert_allclose(modal[2:], out[2:], rtol=0, atol=1e-13 * scale)


@pytest.mark.parametrize('lam_top, tau, y_scale, nh', [
    (8.1e3, 1e-4, 1.0, 0),    # HPOTP's whole step: |lam| tau up to 0.81
    (8.1e3, 2e-3, 1.0, 1),    # a long piece: |lam| tau 16, no panels needed; a harmonic
    (3e3, 3e-6, 1.0, 2),      # a short piece, two harmonics
    (160.0, 1e-4, 1.0, 1),    # SDOF-like: a slow mode and a harmonic near it
    (5e2, 1e-7, 1e-6, 0),     # nearly at rest, forced: the particular solution dwarfs the flow
])
def test_ledger_closed_form_equals_fine_gauss_quadrature(rng, lam_top, tau, y_scale, nh):
    # The closed form of the modal ledger (held inputs and harmonics): damping and forcing
    # work against 4-point Gauss on 64 panels to 1e-12 of the largest (measured: 5e-14 at
    # worst over 150 random pieces), whether a row is in closed form or, where its particular
    # solution is more than 10 times its flow (CLOSED_COND), in series; the kernel equals its
    # twin to 1e-14, and its flow factors equal the propagator's.
    n, nf = 4, 3
    n_series = n_closed = 0
    for _trial in range(8):
        args = _ledger_case(rng, n, nf, nh, 'modal', lam_top, tau)
        args = (args[0] * y_scale,) + args[1:]
        (yh, lam, W, w0, ws, pp, pm, omegas, amps, u0, us, t, tau, Vq, Vv, C, Kskew, B) = args
        n2 = lam.size
        ref = _fine_ledger(args, 64)
        scale = np.abs(ref).max()
        e, p1, p2 = (np.empty(n2, complex) for _ in range(3))
        m = np.empty(n2)
        Q.piece_factors(lam, tau, e, p1, p2, m)
        e_ref, p1_ref, p2_ref = (np.empty(n2, complex) for _ in range(3))
        K.step_factors(lam, tau, e_ref, p1_ref, p2_ref)
        np.testing.assert_allclose(e, e_ref, rtol=1e-14)
        np.testing.assert_allclose(p1, p1_ref, rtol=1e-14)
        np.testing.assert_allclose(p2, p2_ref, rtol=1e-13)
        x = 2.0 * lam.real * tau
        np.testing.assert_allclose(m, tau * np.expm1(x) / x, rtol=1e-14)
        harm = np.full((4 + 2 * nh, nh), np.nan, complex)
        Q.harmonic_factors(omegas, t, tau, harm)
        # which rows take the series: the particular solution against the flow, as the
        # kernel judges it (with harmonics such a row sends the piece to ledger_modal: -1)
        b_p = -ws / lam
        a_p = (b_p - w0) / lam
        size_p = (np.abs(yh - a_p) ** 2 * np.maximum(1.0, np.abs(e) ** 2) + np.abs(a_p) ** 2
                  + np.abs(b_p * tau) ** 2)
        series = size_p > L.CLOSED_COND * (np.abs(yh) ** 2 + np.abs(w0 * tau) ** 2
                                           + np.abs(ws * tau ** 2) ** 2)
        n_series += np.count_nonzero(series)
        expected = -1 if nh and series.any() else 1
        outs = []
        for kernel in (L.ledger_closed, L.ledger_closed_py):
            out = np.zeros(5)
            assert kernel(yh, lam, w0, ws, u0, us, tau, e, p1, p2, m, pp, pm, omegas, amps,
                          harm, Vv, _pattern(Vv)[0], C, B, np.full(Q.N_TERMS, np.nan),
                          np.full((2, nh), np.nan, complex), out) == expected
            if expected == -1:
                assert not out.any()
                continue
            np.testing.assert_allclose(out[2:4], ref[:2], rtol=0, atol=1e-12 * scale)
            assert out[4] == 0.0
            outs.append(out)
        if outs:
            n_closed += 1
            np.testing.assert_allclose(outs[0], outs[1], rtol=0, atol=1e-14 * scale)
    assert n_closed > 0 and (n_series > 0 or y_scale == 1.0)
    if y_scale < 1.0:
        assert n_series > 0


def test_ledger_closed_form_declines_a_long_piece_it_cannot_take():
    # A row whose closed form is too large against its flow (a growing mode: |e^(lam tau)|^2
    # = e^6 > CLOSED_COND) and whose |lam| tau (4.2) is above PANEL_RADIUS cannot take the
    # short series either: the closed form answers -1 and leaves the ledger alone (the engine
    # then takes the panelled series form).
    lam = np.array([3e3 + 3e3j])
    Vv = lam[None, :] * np.ones((1, 1))
    tau = 1e-3
    e, p1, p2 = (np.empty(1, complex) for _ in range(3))
    m = np.empty(1)
    Q.piece_factors(lam, tau, e, p1, p2, m)
    for kernel in (L.ledger_closed, L.ledger_closed_py):
        out = np.zeros(5)
        assert kernel(np.ones(1, complex), lam, np.zeros(1, complex), np.zeros(1, complex),
                      np.ones(1), np.ones(1), tau, e, p1, p2, m, np.zeros((0, 1), complex),
                      np.zeros((0, 1), complex), np.zeros(0), np.zeros((0, 1), complex),
                      np.zeros((4, 0), complex), Vv,
                      np.zeros((1, 1), np.int64), np.eye(1), np.ones((1, 1)),
                      np.empty(Q.N_TERMS), np.empty((2, 0), complex), out) == -1
        assert not out.any()


def test_ledger_series_degree_meets_its_tolerance():
    # taylor_degree(|z|^2) is the smallest degree d >= 2 whose first dropped term
    # 2 |z|^(d-1)/(d+1)! (relative to the largest of a coordinate's first three coefficients)
    # is below TAYLOR_TOL, up to the series length (14 for HPOTP's fastest mode per step);
    # and the remainder of an actual forced series near rest meets it.
    import math
    for r in (0.0, 1e-9, 5e-5, 0.05, 0.3, 0.81, 1.0):
        d = Q.taylor_degree(r * r)
        assert d >= 2 and 2 * r ** (d - 1) / math.factorial(d + 1) <= Q.TAYLOR_TOL * (1 + 1e-12)
        assert d == 2 or 2 * r ** (d - 2) / math.factorial(d) > Q.TAYLOR_TOL
        assert Q.taylor_degree_py(r * r) == d
    assert Q.taylor_degree(0.81 ** 2) == 14 and Q.taylor_degree(1.0) == Q.N_TERMS - 1
    # y' = lam y + w0 + ws s from y0 = 1e-6 over tau: coefficients c0, c1, c2, then
    # c_m = c_{m-1} z/m; the dropped tail against the largest of c0, c1, c2
    lam, tau, y0, w0, ws = -3.0 + 500j, 1e-7, 1e-6, 3.0, 3e3
    z = lam * tau
    c = [y0, tau * (lam * y0 + w0)]
    c.append(0.5 * (z * c[1] + tau * tau * ws))
    for m in range(3, 40):
        c.append(c[-1] * z / m)
    d = Q.taylor_degree(abs(z) ** 2)
    tail = sum(abs(x) for x in c[d + 1:])
    assert tail <= Q.TAYLOR_TOL * max(abs(x) for x in c[:3])


def test_kernels_compile_without_reference_counting():
    # KERNEL_OPTIONS turn Numba's reference counting (NRT) off with a private option,
    # ``_nrt``: should a Numba release ignore it, the kernels would count references again
    # (a sixth of hpotp's run) and nothing would say so. Without NRT a kernel that allocates
    # cannot compile; the same function with ``_nrt=True`` runs.
    from numba import config
    from numba.core.errors import TypingError

    from impact_damper_sim.integrate.kernels import KERNEL_OPTIONS, event_loop, kernel
    if config.DISABLE_JIT:
        pytest.skip('the kernels run as Python')

    def total(n):
        return np.ones(n).sum()

    with pytest.raises(TypingError):
        kernel(cache=False)(total)(3)
    assert kernel(cache=False, _nrt=True)(total)(3) == 3.0
    assert KERNEL_OPTIONS['_nrt'] is False and event_loop.advance.targetoptions['_nrt'] is False
