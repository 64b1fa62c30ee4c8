"""Numba kernels against their plain-Python twins and independent references."""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from impact_damper_sim.integrate.kernels import flow as K
from impact_damper_sim.integrate.kernels import ledger as L
from impact_damper_sim.integrate.kernels import poly as PL


@pytest.fixture
def rng():
    return np.random.default_rng(20261121)


def test_phis_twin_and_closed_form(rng):
    # phi1 = (e^z - 1)/z, phi2 = (e^z - 1 - z)/z^2: series near 0, direct formula elsewhere.
    # Twin vs JIT to 1e-15; vs a reference at a scale where the formula is well conditioned
    # (|z| >= 0.2) and vs the series sum in extended precision near 0, 1e-13 relative.
    for z in list(rng.normal(size=20) * 0.1 + 1j * rng.normal(size=20) * 0.1) + \
            list(rng.normal(size=20) * 3 + 1j * rng.normal(size=20) * 30):
        a, b = K.phis(z)
        a_py, b_py = K.phis_py(z)
        assert abs(a - a_py) <= 1e-15 * abs(a) and abs(b - b_py) <= 1e-15 * abs(b)
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
    n_coarse = 0
    for _ in range(500):
        g0 = rng.uniform(1e-6, 1.0)
        g1, g2 = rng.normal(size=2) * [3.0, 30.0]
        g3 = rng.uniform(0.0, 300.0)
        T = rng.uniform(0.01, 1.0)
        s = PL.cubic_safe_step(g0, g1, g2, g3, T, 0.0)
        assert s == PL.cubic_safe_step_py(g0, g1, g2, g3, T, 0.0)
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
    assert n_coarse > 50


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


def test_ledger_step_equals_ledger_panel(rng):
    # The whole-step ledger (precomputed Gauss node factors, sparse rows, circulatory term
    # skipped without skew stiffness) is the same quadrature as ledger_panel: the three
    # entries agree to 1e-12 of their size, on a dense coupled model with two harmonics, a
    # held input slope and skew stiffness, and on an uncoupled one (modal damping: diagonal
    # C, its zeros skipped) without skew stiffness.
    n, nf, nh, h, t = 4, 3, 2, 7.3e-4, 0.137
    n2 = 2 * n
    lam = -rng.uniform(1.0, 30.0, n2) + 1j * rng.uniform(-3e3, 3e3, n2)
    cplx = lambda *shape: rng.normal(size=shape) + 1j * rng.normal(size=shape)  # noqa: E731
    yh, w0, ws, W = cplx(n2), cplx(n2), cplx(n2), cplx(n2, nf)
    pp, pm = cplx(nh, n2), cplx(nh, n2)
    omegas = rng.uniform(100.0, 2000.0, nh)
    amps = cplx(nh, nf)
    u0, us = rng.normal(size=nf), rng.normal(size=nf)
    B = rng.normal(size=(n, nf))
    C = rng.normal(size=(n, n))
    C = C @ C.T
    for Vq, Vv, Kskew, C in ((cplx(n, n2), cplx(n, n2), rng.normal(size=(n, n)), C),
                             (np.kron(np.eye(n), [[1.0, 1.0]]).astype(complex),
                              np.kron(np.eye(n), [[1.0, 1.0]]) * lam, np.zeros((n, n)),
                              np.diag(np.diag(C)))):
        Kskew = Kskew - Kskew.T
        ref = np.zeros(5)
        L.ledger_panel(yh, lam, W, w0, ws, pp, pm, omegas, amps, u0, us, t, h, Vq, Vv, C,
                       Kskew, B, np.empty(n2, complex), np.empty(n2, complex),
                       np.empty((6, nf)), np.empty((6, n2), complex), ref)
        m = L.ledger_node_count(lam, h)
        s, w = np.empty(m), np.empty(m)
        E, P1, P2 = (np.empty((m, n2), complex) for _ in range(3))
        EH = np.empty((m, nh), complex)
        L.ledger_nodes(lam, omegas, h, s, w, E, P1, P2, EH)
        cols = [np.empty((n, n2), np.int64), np.empty(n, np.int64)]
        vcols = [np.empty((n, n2), np.int64), np.empty(n, np.int64)]
        L.row_pattern(Vq, *cols)
        L.row_pattern(Vv, *vcols)
        ccols = [np.empty((n, n), np.int64), np.empty(n, np.int64)]
        L.row_pattern(C, *ccols)
        out = np.zeros(5)
        L.ledger_step(yh, w0, ws, pp, pm, omegas, amps, u0, us, t, s, w, E, P1, P2, EH, Vq, Vv,
                      *cols, *vcols, C, *ccols, Kskew, bool(np.any(Kskew)), B,
                      np.empty(n2, complex),
                      np.full(2 * n + nf, np.nan), np.full(nh, np.nan, complex), out)
        np.testing.assert_allclose(out[2:], ref[2:], rtol=1e-12, atol=1e-12 * np.abs(ref).max())
        assert np.any(Kskew) == (out[4] != 0.0)


def test_borrowed_view_is_the_callers_memory():
    # borrow (kernels/borrow.py) drops only the reference counting: the view has the same
    # data, shape and strides (here a non-contiguous view), writes through it land in the
    # caller's array and nowhere else, and its NumPy twin is the identity.
    from numba import njit
    from impact_damper_sim.integrate.kernels.borrow import borrow, borrow_py

    @njit
    def fill(a):
        b = borrow(a)
        for i in range(b.shape[0]):
            for j in range(b.shape[1]):
                b[i, j] = 10.0 * i + j
        return b.shape[0], b.shape[1], b.strides[0], b.strides[1]

    base = np.zeros((4, 6))
    view = base[:, ::2]
    assert fill(view) == (4, 3) + view.strides
    np.testing.assert_array_equal(view, 10.0 * np.arange(4)[:, None] + np.arange(3))
    assert not np.any(base[:, 1::2])
    assert borrow_py(view) is view
