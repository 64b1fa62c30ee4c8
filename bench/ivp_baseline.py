"""SciPy ``solve_ivp`` event-restart baseline for an SDOF impact damper.

This is the reference that the project's own integrators (exact modal propagator, Newmark) are
benchmarked against "at equal accuracy". It is deliberately self-contained: it imports nothing
from ``impact_damper_sim`` and needs only numpy and scipy.

Model
-----
A primary mass ``M`` (kg) on a spring ``K`` (N/m) and damper ``c`` (N s/m) is driven by
``F0 cos(Omega t)`` (N). An impactor of mass ``m = mu M`` (kg) moves freely inside a cavity of
total free travel ``D`` (m) cut into the primary mass. With housing position ``x`` and impactor
position ``z`` (both m, inertial frame) the relative coordinate ``r = z - x`` is confined to
``[-D/2, +D/2]``. Wall ``s = +1`` is at ``r = +D/2``, wall ``s = -1`` at ``r = -D/2``.

State (free flight)::

    y = [x, x', z, z', W, Ec]

``W`` (J) is the work done by the external force, ``int F x' dt``, and ``Ec`` (J) the energy
dissipated by the viscous damper, ``int c x'^2 dt``. Both are integrated as extra states so the
energy ledger costs no quadrature outside the solver (``ledger=False`` drops them).

Impacts
-------
A closing contact (``s r' > 0`` at ``r = s D/2``) applies the restitution law (COR ``e`` along
the line, momentum conserved)::

    x'+ = ((1 - mu e) x'- + mu (1 + e) z'-) / (1 + mu)
    z'+ = ((1 + e) x'- + (mu - e) z'-) / (1 + mu)

so that ``r'+ = -e r'-`` and the kinetic energy lost is ``0.5 m_red (1 - e^2) r'-^2`` with
``m_red = M m / (M + m)``.

Sticking (chatter)
------------------
A restart-after-every-impact loop never gets past the accumulation point of a bounce-down
sequence (the flight times shrink like ``e^k``). The impactor is therefore *stuck* to wall
``s`` (plastic impact, ``e = 0``) at impact ``k`` when ``e < 1`` and any of

(a) the post-impact relative speed ``e |r'-|`` is below ``v_stick``;
(b) the previous impact was on the same wall less than ``dt_stick`` earlier (paper rule,
    ``dt_stick = 0.2 %`` of the natural period by default);
(c) the accumulation point ``t_inf = t_k + dt_k e / (1 - e)`` is less than ``dt_stick`` away,

*and* the wall actually presses on the impactor there. While stuck, the combined mass
``M + m`` is integrated with the impactor riding the wall. The force of the wall on the
impactor is ``N = m x''`` (the wall is the only force on it). Wall ``+1`` can only push the
impactor towards ``-x`` (into the cavity), wall ``-1`` only towards ``+x``, so contact needs
``-s x'' >= 0`` and the impactor is released when ``-s x''`` crosses zero from above (a
terminal ``solve_ivp`` event with ``direction = -1``).

The stick rules are checked at impact ``k`` and the plastic impact is applied there, not at
``t_inf``: momentum is exact, the time is off by less than ``dt_stick``. For ``e = 1`` they
are off (an elastic impactor cannot accumulate impacts).

Missed events
-------------
``solve_ivp`` only sees sign changes of an event function between step ends.

* Restarting exactly on a wall gives ``g(t0) = 0`` and a spurious root at ``t0``; a return to
  the same wall inside the first step would then be lost. Each wall event is offset outwards by
  a few ulps (``beta``) and the position is projected onto the wall after each impact, so
  ``g(t0) < 0`` strictly and a short same-wall flight inside one step is still bracketed.
* An excursion through a wall and back within one step (a graze, or a flight back to the wall
  just left followed by a second separation) shows no sign change at all. After every free
  segment each step is screened with a quintic Hermite reconstruction of ``r`` from the
  step-end data (vectorised, no extra right-hand-side calls); only steps that come within its
  error bound of a wall are checked on the dense output (that one step is re-taken with dense
  output if the run had none). A contact found there becomes an impact at the located
  crossing and the segment is cut there. ``max_step`` (default ``T_min / 8``, ``T_min`` the
  shorter of the natural and forcing periods) keeps that reconstruction tight.

Restarts
--------
The dense-output interpolant is several times less accurate than a step end (about ``7 rtol``
in energy for DOP853), and every restart inherits its error; with hundreds of impacts per
second that dominates. By default (``restep=True``) the step containing an event is re-taken
from its start so that it ends exactly on the event. A cap on the number of events
(``max_events``) turns any remaining pathology into an error instead of a hang.

This file holds the event loop (:func:`simulate`) and the command line; the parameters, the
result and the impact law are in ``ivp_baseline_model.py``, the screen for contacts hidden
inside a step in ``ivp_baseline_grazes.py`` (both beside it, numpy and scipy only). Run
``python bench/ivp_baseline.py --help`` for the command-line benchmark.
"""

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

# Run as a script or loaded from its path (tests, sdof_methods.py), never as a package: its
# two parts beside it are found either way.
if str(Path(__file__).resolve().parent) not in sys.path:
    sys.path.insert(0, str(Path(__file__).resolve().parent))
from ivp_baseline_grazes import _EPS, _graze_candidates, _locate_graze  # noqa: E402
from ivp_baseline_model import Params, Result, _as_params, energy, impact_law  # noqa: E402

METHODS = ('DOP853', 'RK45', 'RK23', 'Radau', 'BDF', 'LSODA')
_IMPLICIT = ('Radau', 'BDF', 'LSODA')


def _make_functions(p, ledger):
    """Right-hand sides and Jacobians for the free and the stuck phase (closures, fast)."""
    M, K, c, F0, Om, m = p.M, p.K, p.c, p.F0, p.Omega, p.m
    inv_m1, inv_m2 = 1.0 / M, 1.0 / (M + m)
    cos = math.cos
    array = np.array

    if ledger:
        def free(t, y):
            x, v, _, w = y[:4].tolist()
            f = F0 * cos(Om * t)
            return array((v, (f - c * v - K * x) * inv_m1, w, 0.0, f * v, c * v * v))

        def stuck(t, y):
            # Impactor rides the wall: both masses share one acceleration.
            x, v = y[:2].tolist()
            f = F0 * cos(Om * t)
            a = (f - c * v - K * x) * inv_m2
            return array((v, a, v, a, f * v, c * v * v))
    else:
        def free(t, y):
            x, v, _, w = y.tolist()
            return array((v, (F0 * cos(Om * t) - c * v - K * x) * inv_m1, w, 0.0))

        def stuck(t, y):
            x, v = y[:2].tolist()
            a = (F0 * cos(Om * t) - c * v - K * x) * inv_m2
            return array((v, a, v, a))

    n = 6 if ledger else 4

    def jac_factory(inv_mass, impactor_follows):
        base = np.zeros((n, n))
        base[0, 1] = 1.0
        base[1, 0], base[1, 1] = -K * inv_mass, -c * inv_mass
        if impactor_follows:
            base[2, 1] = 1.0
            base[3, 0], base[3, 1] = base[1, 0], base[1, 1]
        else:
            base[2, 3] = 1.0
        if not ledger:
            return base

        def jac(t, y):
            J = base.copy()
            J[4, 1] = F0 * cos(Om * t)
            J[5, 1] = 2.0 * c * y[1]
            return J
        return jac

    return free, stuck, jac_factory(inv_m1, False), jac_factory(inv_m2, True)


def _default_atol(p, y0, rtol, n):
    """Absolute tolerance ``rtol * scale`` with a length, velocity and energy scale."""
    w = max(p.omega_n, p.Omega)
    X = max(0.5 * p.D, p.x_st, abs(y0[0]), abs(y0[2]), abs(y0[1]) / w, abs(y0[3]) / w)
    V = w * X
    E = max(0.5 * p.K * X * X, 0.5 * (p.M + p.m) * V * V)
    return rtol * np.array([X, V, X, V, E, E][:n])


def simulate(params, t_end, *, rtol=1e-8, atol=None, method='DOP853', x0=(0.0, 0.0, 0.0, 0.0),
             record_dt=None, max_step=None, v_stick=None, dt_stick=None, max_events=200_000,
             ledger=True, restep=True):
    """Simulate the SDOF impact damper with event-restarted ``solve_ivp``.

    Parameters
    ----------
    params : Params or mapping
        System parameters; a mapping must give exactly the fields of :class:`Params`.
    t_end : float
        Simulated time (s), from ``t = 0``.
    rtol : float
        Relative tolerance passed to ``solve_ivp`` (dimensionless).
    atol : float or array_like or None
        Absolute tolerance (units of each state). None gives ``rtol`` times a length scale
        ``X = max(D/2, F0/K, |x0|...)`` on positions, ``omega X`` on velocities and
        ``0.5 K X^2`` on the two energy states.
    method : str
        ``solve_ivp`` method: 'DOP853' (default), 'RK45', 'RK23', 'Radau', 'BDF' or 'LSODA'.
        The implicit ones get the analytic Jacobian.
    x0 : array_like, shape (4,)
        Initial state ``[x, x', z, z']`` (m, m/s, m, m/s) with ``|z - x| <= D/2``.
    record_dt : float or None
        If given, the state is sampled on ``t = 0, record_dt, 2 record_dt, ... <= t_end`` (s).
    max_step : float or None
        Largest solver step (s). None gives ``T_min / 8``, ``T_min`` the shorter of the natural
        and the forcing period, which keeps the screen for contacts hidden inside a step tight.
    v_stick : float or None
        Stick when the post-impact relative speed is below this (m/s). None gives
        ``1e-4 omega_n D``.
    dt_stick : float or None
        Stick when two successive impacts on one wall, or the predicted accumulation point,
        are closer than this (s). None gives ``0.002 T_n`` (the paper's 0.2 % rule).
    max_events : int
        Cap on impacts, releases and grazes; exceeding it raises ``RuntimeError``.
    ledger : bool
        Integrate the work and damping-loss states (``True``) or not (slightly cheaper).
    restep : bool
        Re-take the step that contains each event so that it ends on the event, instead of
        restarting from the dense-output interpolant (one extra step per event, but the
        restart state then carries step-end rather than interpolant accuracy).

    Returns
    -------
    Result
        Impact history, final state, optional samples, energy ledger, counts and timings.

    Raises
    ------
    ValueError
        On bad parameters or options.
    RuntimeError
        If the solver fails or more than ``max_events`` events occur.
    """
    p = _as_params(params)
    if method not in METHODS:
        raise ValueError(f'unknown method {method!r}; allowed: {METHODS}')
    t_end = float(t_end)
    if not (t_end > 0 and math.isfinite(t_end)):
        raise ValueError(f't_end must be finite and > 0, got {t_end!r}')
    if not 0 < rtol < 1:
        raise ValueError(f'rtol must be in (0, 1), got {rtol!r}')
    y0 = np.asarray(x0, dtype=float)
    if y0.shape != (4,) or not np.all(np.isfinite(y0)):
        raise ValueError('x0 must be 4 finite numbers [x, dx/dt, z, dz/dt]')
    half = 0.5 * p.D
    if abs(y0[2] - y0[0]) > half:
        raise ValueError(f'initial impactor outside the cavity: |z - x| = '
                         f'{abs(y0[2] - y0[0]):.6g} m > D/2 = {half:.6g} m')
    n = 6 if ledger else 4
    if atol is None:
        atol = _default_atol(p, y0, rtol, n)
    else:
        atol = np.broadcast_to(np.asarray(atol, dtype=float), (n,)).copy()
        if np.any(atol <= 0):
            raise ValueError('atol must be > 0')
    T_min = 2.0 * math.pi / max(p.omega_n, p.Omega)
    max_step = T_min / 8.0 if max_step is None else float(max_step)
    v_stick = 1e-4 * p.omega_n * p.D if v_stick is None else float(v_stick)
    dt_stick = 0.002 * p.T_n if dt_stick is None else float(dt_stick)
    if record_dt is not None and not record_dt > 0:
        raise ValueError(f'record_dt must be > 0, got {record_dt!r}')
    max_events = int(max_events)
    restep_events = bool(restep)

    K, c, F0, Om, mu, e = p.K, p.c, p.F0, p.Omega, p.mu, p.e
    m_red = p.m_red
    sticking = e < 1.0   # an elastic impactor cannot accumulate impacts
    chatter_factor = e / (1.0 - e) if sticking else math.inf
    rhs_free, rhs_stuck, jac_free, jac_stuck = _make_functions(p, ledger)
    # Dense output only when sampling: DOP853 pays 3 extra stages per step for it. The graze
    # check below re-takes a single suspicious step with dense output when it needs one.
    solver_opts = dict(method=method, rtol=rtol, atol=atol, max_step=max_step,
                       dense_output=record_dt is not None)
    implicit = method in _IMPLICIT

    def restep(fun, jac, t_a, y_a, t_b, y_interp):
        # The interpolant at an event is several times less accurate than a step end (about
        # 7 rtol in energy for DOP853), and every restart would inherit that error. Re-take
        # the last step from its start so that it ends exactly on the event.
        nonlocal n_rhs, n_jac, n_lu, n_resteps
        if not restep_events or not t_b > t_a:
            return np.array(y_interp, dtype=float)
        o = dict(solver_opts, dense_output=False, first_step=t_b - t_a)
        if implicit:
            o['jac'] = jac
        r = solve_ivp(fun, (t_a, t_b), y_a, **o)
        n_rhs += r.nfev
        n_jac += r.njev
        n_lu += r.nlu
        n_resteps += 1
        if r.status < 0:
            raise RuntimeError(f'solve_ivp failed at t = {r.t[-1]:.9g} s: {r.message}')
        return r.y[:, -1].copy()

    def pressing(t, x, v, s):
        # Sign of the wall force on a stuck impactor, positive when the wall pushes it into
        # the cavity: N = m x'' and wall s can only push towards -s.
        return -s * (F0 * math.cos(Om * t) - c * v - K * x)

    # Recording grid.
    if record_dt is not None:
        t_rec = np.arange(int(math.floor(t_end / record_dt + 1e-9)) + 1) * record_dt
        y_rec = np.empty((t_rec.size, 4))
        y_rec[0] = y0
        k_rec = 1
    else:
        t_rec = y_rec = None

    def record(sol, t_b):
        nonlocal k_rec
        if t_rec is None:
            return
        k_new = int(np.searchsorted(t_rec, t_b, side='right'))
        if k_new > k_rec:
            y_rec[k_rec:k_new] = sol(t_rec[k_rec:k_new])[:4].T
            k_rec = k_new

    imp_t, imp_s, imp_v, imp_pl = [], [], [], []
    sticks, stick_walls = [], []
    diss_impact = 0.0
    n_restarts = n_rhs = n_jac = n_lu = 0
    n_grazes = n_missed = n_events = n_resteps = n_graze_checks = 0
    last_wall, last_t = 0, -math.inf   # previous impact, for the chatter rules

    y = np.zeros(n)
    y[:4] = y0
    t = 0.0
    mode = 0   # 0: free flight, +1/-1: stuck to that wall
    t_stick = 0.0
    wall_clock = time.perf_counter()
    cpu_clock = time.process_time()

    while t < t_end:
        if n_events >= max_events:
            raise RuntimeError(
                f'more than max_events={max_events} events before t = {t:.9g} s '
                f'(t_end = {t_end:g} s): {len(imp_t)} impacts, {len(sticks)} stuck entries. '
                'Unresolved chatter? Increase dt_stick/v_stick or max_events.')
        n_restarts += 1
        if mode == 0:
            # Wall events, offset outwards by a few ulps so that g(t0) < 0 after a restart on
            # the wall (a short same-wall flight within the first step is then bracketed).
            beta = 32.0 * _EPS * max(abs(y[0]), abs(y[2]), half)
            lim = half + beta

            def hit_pos(t_, y_, lim=lim):   # events bound to this step's offset
                return (y_[2] - y_[0]) - lim

            def hit_neg(t_, y_, lim=lim):
                return (y_[2] - y_[0]) + lim

            hit_pos.terminal, hit_pos.direction = True, 1.0    # only closing: r' > 0
            hit_neg.terminal, hit_neg.direction = True, -1.0   # only closing: r' < 0
            opts = dict(solver_opts, jac=jac_free) if implicit else solver_opts
            sol = solve_ivp(rhs_free, (t, t_end), y, events=(hit_pos, hit_neg), **opts)
        else:
            s = mode

            def release(t_, y_, s=s):
                return pressing(t_, y_[0], y_[1], s)

            release.terminal, release.direction = True, -1.0   # pressing -> pulling
            opts = dict(solver_opts, jac=jac_stuck) if implicit else solver_opts
            sol = solve_ivp(rhs_stuck, (t, t_end), y, events=(release,), **opts)
        n_rhs += sol.nfev
        n_jac += sol.njev
        n_lu += sol.nlu
        if sol.status < 0:
            raise RuntimeError(f'solve_ivp failed at t = {sol.t[-1]:.9g} s: {sol.message}')

        if mode != 0:
            record(sol.sol, sol.t[-1])
            y = sol.y[:, -1].copy()
            t = float(sol.t[-1])
            if sol.status == 1:   # release: leave the wall with zero relative velocity
                n_events += 1
                y = restep(rhs_stuck, jac_stuck, sol.t[-2], sol.y[:, -2], t, y)
                y[2], y[3] = y[0] + mode * half, y[1]
                sticks.append((t_stick, t))
                stick_walls.append(mode)
                mode = 0
                last_wall, last_t = 0, -math.inf
            continue

        # Free flight: which wall was hit, if any (the earliest terminal root wins).
        hit = None
        if sol.status == 1:
            for s, te in ((1, sol.t_events[0]), (-1, sol.t_events[1])):
                if te.size:
                    hit = (s, float(te[-1]), sol.y_events[0 if s > 0 else 1][-1],
                           sol.t[-2], sol.y[:, -2])
        # A graze, or a flight back to the wall just left, that starts and ends inside one
        # solver step shows no sign change: screen every step and check the suspicious ones
        # on the dense output (re-taking just that step if the run had none).
        for i in _graze_candidates(sol.t, sol.y, lim, p):
            ta, tb, ya = sol.t[i], sol.t[i + 1], sol.y[:, i]
            dense = sol.sol
            if dense is None:
                one = solve_ivp(rhs_free, (ta, tb), ya,
                                **dict(opts, first_step=tb - ta, dense_output=True))
                n_rhs += one.nfev
                n_jac += one.njev
                n_lu += one.nlu
                n_graze_checks += 1
                dense = one.sol
            found = _locate_graze(ta, tb, dense, lim, p, depth=min(atol[0], atol[2]))
            if found is not None and (hit is None or found[1] < hit[1]):
                hit = found + (ta, ya)
                n_missed += 1
                break

        if hit is None:
            record(sol.sol, sol.t[-1])
            y = sol.y[:, -1].copy()
            t = float(sol.t[-1])
            if abs(y[2] - y[0]) > lim + 1e-9 * half:
                raise RuntimeError(f'impactor left the cavity at t = {t:.9g} s')
            continue

        s, t, y, t_a, y_a = hit
        record(sol.sol, t)
        y = restep(rhs_free, jac_free, t_a, y_a, t, y)
        n_events += 1
        x, xd, zd = y[0], y[1], y[3]
        y[2] = x + s * half   # project onto the wall (removes the beta offset)
        vrel = zd - xd
        closing = s * vrel > 0
        dt_same = t - last_t if last_wall == s else math.inf
        stick = sticking and (
            e * abs(vrel) < v_stick                      # (a) slow rebound
            or dt_same < dt_stick                        # (b) paper rule
            or dt_same * chatter_factor < dt_stick)      # (c) accumulation point close
        if stick:
            vc = impact_law(xd, zd, mu, 0.0)[0]   # plastic impact: common velocity
            stick = pressing(t, x, vc, s) > 0.0
        if stick:
            y[1] = y[3] = vc
            diss_impact += 0.5 * m_red * vrel * vrel
            imp_t.append(t), imp_s.append(s), imp_v.append(vrel), imp_pl.append(True)
            mode, t_stick = s, t
        elif closing:
            y[1], y[3] = impact_law(xd, zd, mu, e)
            diss_impact += 0.5 * m_red * (1.0 - e * e) * vrel * vrel
            imp_t.append(t), imp_s.append(s), imp_v.append(vrel), imp_pl.append(False)
            last_wall, last_t = s, t
        else:
            # Tangential touch with the wall pulling away: no impulse, just continue.
            n_grazes += 1

    wall_clock = time.perf_counter() - wall_clock
    cpu_clock = time.process_time() - cpu_clock
    if mode != 0:
        sticks.append((t_stick, t_end))
        stick_walls.append(mode)
    y_end = y[:4].copy()
    if mode != 0:   # the impactor rides the wall exactly
        y_end[2], y_end[3] = y_end[0] + mode * half, y_end[1]
    return Result(
        params=p, t_end=t_end, method=method, rtol=rtol, atol=atol,
        impact_times=np.array(imp_t, dtype=float),
        impact_walls=np.array(imp_s, dtype=np.int8),
        impact_vrel=np.array(imp_v, dtype=float),
        impact_plastic=np.array(imp_pl, dtype=bool),
        stick_intervals=np.array(sticks, dtype=float).reshape(-1, 2),
        stick_walls=np.array(stick_walls, dtype=np.int8),
        y_end=y_end, stuck_end=int(mode), t_rec=t_rec, y_rec=y_rec,
        E0=float(energy(p, y0)), E_end=float(energy(p, y_end)),
        work_force=float(y[4]) if ledger else math.nan,
        diss_damping=float(y[5]) if ledger else math.nan,
        diss_impact=diss_impact,
        n_restarts=n_restarts, n_rhs=n_rhs, n_jac=n_jac, n_lu=n_lu,
        n_grazes=n_grazes, n_missed_recovered=n_missed, n_resteps=n_resteps,
        n_graze_checks=n_graze_checks,
        wall_time=wall_clock, cpu_time=cpu_clock,
        settings=dict(max_step=max_step, v_stick=v_stick, dt_stick=dt_stick,
                      max_events=max_events, ledger=ledger, restep=restep_events),
    )


def _parse_args(argv):
    ap = argparse.ArgumentParser(
        description='solve_ivp event-restart baseline for an SDOF impact damper: prints wall '
                    'time per simulated second, impact count, stuck fraction and final state.')
    ap.add_argument('--rtol', type=float, nargs='+', default=[1e-6, 1e-8, 1e-10],
                    help='one or more relative tolerances (default: 1e-6 1e-8 1e-10)')
    ap.add_argument('--atol', type=float, default=None,
                    help='absolute tolerance on every state (default: scaled rtol)')
    ap.add_argument('--method', choices=METHODS, default='DOP853')
    ap.add_argument('--t-end', type=float, default=10.0, help='simulated time (s)')
    ap.add_argument('--fn', type=float, default=10.0, help='natural frequency f_n (Hz)')
    ap.add_argument('--zeta', type=float, default=0.01, help='damping ratio (-)')
    ap.add_argument('--r', type=float, default=1.0, help='frequency ratio Omega/omega_n (-)')
    ap.add_argument('--mu', type=float, default=0.05, help='mass ratio m/M (-)')
    ap.add_argument('--e', type=float, default=0.6, help='coefficient of restitution (-)')
    ap.add_argument('--M', type=float, default=1.0, help='primary mass (kg)')
    ap.add_argument('--F0', type=float, default=1.0, help='force amplitude (N)')
    ap.add_argument('--D', type=float, default=None,
                    help='total free travel (m); default 30 F0/K (steady two impacts per cycle '
                         'for the other defaults)')
    ap.add_argument('--no-restep', action='store_true',
                    help='restart from the event interpolant instead of re-taking the step')
    ap.add_argument('--repeat', type=int, default=1,
                    help='runs per tolerance; the fastest wall time is reported')
    return ap.parse_args(argv)


def main(argv=None):
    """Command-line benchmark; see ``--help``."""
    a = _parse_args(argv)
    K = a.M * (2.0 * math.pi * a.fn) ** 2
    D = 30.0 * abs(a.F0) / K if a.D is None else a.D
    p = Params.from_nondim(f_n=a.fn, zeta=a.zeta, r=a.r, mu=a.mu, e=a.e, D=D, M=a.M, F0=a.F0)
    print(f'# {a.method}: f_n={a.fn:g} Hz zeta={a.zeta:g} r={a.r:g} mu={a.mu:g} e={a.e:g} '
          f'D={D:.6g} m (={D / p.x_st:.4g} F0/K) F0={a.F0:g} N t_end={a.t_end:g} s')
    print(f'{"rtol":>7} {"wall/sim_s":>10} {"cpu/sim_s":>10} {"impacts":>7} {"imp/cyc":>7} '
          f'{"sticks":>6} {"stuck_frac":>10} {"restarts":>8} {"rhs":>8} {"E_resid_rel":>11}  '
          f'final [x, xd, z, zd] (m, m/s)')
    cycles = a.t_end * p.Omega / (2.0 * math.pi) if p.Omega > 0 else math.nan
    for rtol in a.rtol:
        runs = [simulate(p, a.t_end, rtol=rtol, atol=a.atol, method=a.method,
                         restep=not a.no_restep) for _ in range(max(1, a.repeat))]
        res = min(runs, key=lambda q: q.wall_time)
        cpu = min(q.cpu_time for q in runs) / a.t_end
        final = ' '.join(f'{v:+.10e}' for v in res.y_end)
        print(f'{rtol:7.0e} {res.wall_per_sim_second:10.3e} {cpu:10.3e} {res.n_impacts:7d} '
              f'{res.n_impacts / cycles:7.3f} {res.n_stick:6d} {res.stuck_fraction:10.4f} '
              f'{res.n_restarts:8d} {res.n_rhs:8d} {res.energy_residual_rel:11.2e}  [{final}]')
    return 0


if __name__ == '__main__':
    sys.exit(main())
