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

Run ``python bench/ivp_baseline.py --help`` for the command-line benchmark.
"""

import argparse
import dataclasses
import math
import sys
import time
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq, minimize_scalar

METHODS = ('DOP853', 'RK45', 'RK23', 'Radau', 'BDF', 'LSODA')
_IMPLICIT = ('Radau', 'BDF', 'LSODA')
_EPS = np.finfo(float).eps


@dataclass(frozen=True)
class Params:
    """Physical parameters of the SDOF impact damper (SI units).

    Parameters
    ----------
    M : float
        Primary (housing) mass (kg).
    K : float
        Primary stiffness (N/m).
    c : float
        Primary viscous damping (N s/m).
    F0 : float
        Amplitude of the force ``F0 cos(Omega t)`` on the primary mass (N).
    Omega : float
        Forcing frequency (rad/s).
    mu : float
        Mass ratio ``m / M`` of impactor to primary (dimensionless).
    e : float
        Coefficient of restitution, ``0 <= e <= 1`` (dimensionless).
    D : float
        Total free travel of the impactor in the cavity (m); ``|z - x| <= D/2``.
    """

    M: float
    K: float
    c: float
    F0: float
    Omega: float
    mu: float
    e: float
    D: float

    def __post_init__(self):
        for name in ('M', 'K', 'mu', 'D'):
            if not getattr(self, name) > 0:
                raise ValueError(f'{name} must be > 0, got {getattr(self, name)!r}')
        if not self.c >= 0:
            raise ValueError(f'c must be >= 0, got {self.c!r}')
        if not 0 <= self.e <= 1:
            raise ValueError(f'e must be in [0, 1], got {self.e!r}')
        if not (math.isfinite(self.F0) and math.isfinite(self.Omega) and self.Omega >= 0):
            raise ValueError('F0 must be finite and Omega finite and >= 0')

    @classmethod
    def from_nondim(cls, *, f_n=10.0, zeta=0.01, r=1.0, mu=0.05, e=0.6, D, M=1.0, F0=1.0):
        """Build parameters from the usual dimensionless groups.

        Parameters
        ----------
        f_n : float
            Natural frequency of the primary alone, ``sqrt(K/M)/(2 pi)`` (Hz).
        zeta : float
            Damping ratio of the primary alone, ``c / (2 sqrt(K M))`` (dimensionless).
        r : float
            Frequency ratio ``Omega / omega_n`` (dimensionless).
        mu : float
            Mass ratio ``m / M`` (dimensionless).
        e : float
            Coefficient of restitution (dimensionless).
        D : float
            Total free travel in the cavity (m).
        M : float
            Primary mass (kg).
        F0 : float
            Force amplitude (N).

        Returns
        -------
        Params
            The physical parameters.
        """
        wn = 2.0 * math.pi * f_n
        K = M * wn * wn
        return cls(M=M, K=K, c=2.0 * zeta * math.sqrt(K * M), F0=F0, Omega=r * wn,
                   mu=mu, e=e, D=D)

    @property
    def m(self):
        """Impactor mass ``mu M`` (kg)."""
        return self.mu * self.M

    @property
    def m_red(self):
        """Reduced mass ``M m / (M + m)`` of the impact pair (kg)."""
        return self.M * self.m / (self.M + self.m)

    @property
    def omega_n(self):
        """Natural circular frequency of the primary alone, ``sqrt(K/M)`` (rad/s)."""
        return math.sqrt(self.K / self.M)

    @property
    def T_n(self):
        """Natural period of the primary alone (s)."""
        return 2.0 * math.pi / self.omega_n

    @property
    def x_st(self):
        """Static deflection ``F0 / K`` (m)."""
        return abs(self.F0) / self.K


def _as_params(params):
    """Return ``params`` as :class:`Params`; a mapping must name every field and no other."""
    if isinstance(params, Params):
        return params
    if not isinstance(params, Mapping):
        raise TypeError(f'params must be Params or a mapping, not {type(params).__name__}')
    names = [f.name for f in dataclasses.fields(Params)]
    unknown = sorted(set(params) - set(names))
    missing = [n for n in names if n not in params]
    if unknown:
        raise ValueError(f'unknown parameter(s) {unknown}; allowed: {names}')
    if missing:
        raise ValueError(f'missing parameter(s) {missing}')
    return Params(**{n: float(params[n]) for n in names})


@dataclass
class Result:
    """Outcome of :func:`simulate`.

    Attributes
    ----------
    params : Params
        The parameters simulated.
    t_end : float
        Final time (s).
    method, rtol, atol
        Solver settings actually used (``atol`` per state component).
    impact_times : ndarray
        Times of all impacts, including the plastic impacts that start a stuck phase (s).
    impact_walls : ndarray of int8
        Wall of each impact: ``+1`` at ``r = +D/2``, ``-1`` at ``r = -D/2``.
    impact_vrel : ndarray
        Pre-impact relative velocity ``z' - x'`` of each impact (m/s, signed).
    impact_plastic : ndarray of bool
        True where the impact was made plastic to enter the stuck state.
    stick_intervals : ndarray, shape (n, 2)
        ``[t_enter, t_release]`` of every stuck phase (s); ``t_release = t_end`` if still stuck.
    stick_walls : ndarray of int8
        Wall (``+1``/``-1``) of every stuck phase.
    y_end : ndarray, shape (4,)
        State ``[x, x', z, z']`` at ``t_end`` (m, m/s, m, m/s).
    stuck_end : int
        Wall the impactor is stuck to at ``t_end`` (``+1``/``-1``), 0 if in flight.
    t_rec, y_rec : ndarray or None
        Uniform sample times (s) and states ``[x, x', z, z']`` there, if ``record_dt`` was given.
    E0, E_end : float
        Mechanical energy ``0.5 M x'^2 + 0.5 K x^2 + 0.5 m z'^2`` at 0 and ``t_end`` (J).
    work_force : float
        Work done by the external force (J); NaN with ``ledger=False``.
    diss_damping : float
        Energy dissipated by ``c`` (J); NaN with ``ledger=False``.
    diss_impact : float
        Energy dissipated by impacts, ``sum 0.5 m_red (1 - e^2) v_rel^2`` (``e = 0`` for the
        plastic ones) (J).
    n_restarts : int
        Number of flight and stuck-phase ``solve_ivp`` calls (the first run and one restart
        per impact, stick or release); re-steps and graze checks are counted separately.
    n_rhs, n_jac, n_lu : int
        Right-hand-side evaluations, Jacobian evaluations and LU decompositions summed over
        all calls.
    n_grazes : int
        Wall contacts handled without impulse (zero relative velocity, no pressing force).
    n_missed_recovered : int
        Grazing impacts that fell inside one solver step and were recovered from the dense
        output.
    n_resteps : int
        Extra ``solve_ivp`` calls that re-took the step containing an event (``restep``).
    n_graze_checks : int
        Extra one-step ``solve_ivp`` calls made to check a suspicious step on dense output.
    wall_time : float
        Wall-clock time of the simulation loop (s).
    cpu_time : float
        Process CPU time of the simulation loop (s); less sensitive to a busy machine.
    settings : dict
        Resolved ``max_step`` (s), ``v_stick`` (m/s), ``dt_stick`` (s) and the other options.
    """

    params: Params
    t_end: float
    method: str
    rtol: float
    atol: np.ndarray
    impact_times: np.ndarray
    impact_walls: np.ndarray
    impact_vrel: np.ndarray
    impact_plastic: np.ndarray
    stick_intervals: np.ndarray
    stick_walls: np.ndarray
    y_end: np.ndarray
    stuck_end: int
    t_rec: np.ndarray | None
    y_rec: np.ndarray | None
    E0: float
    E_end: float
    work_force: float
    diss_damping: float
    diss_impact: float
    n_restarts: int
    n_rhs: int
    n_jac: int
    n_lu: int
    n_grazes: int
    n_missed_recovered: int
    n_resteps: int
    n_graze_checks: int
    wall_time: float
    cpu_time: float
    settings: dict = field(default_factory=dict)

    @property
    def n_impacts(self):
        """Number of impacts, plastic ones included."""
        return int(self.impact_times.size)

    @property
    def n_stick(self):
        """Number of times the stuck state was entered."""
        return int(self.stick_intervals.shape[0])

    @property
    def n_release(self):
        """Number of releases from a wall (stuck phases that ended before ``t_end``)."""
        return self.n_stick - (1 if self.stuck_end else 0)

    @property
    def stuck_time(self):
        """Total time spent stuck to a wall (s)."""
        return float(np.sum(self.stick_intervals[:, 1] - self.stick_intervals[:, 0]))

    @property
    def stuck_fraction(self):
        """Fraction of ``[0, t_end]`` spent stuck (dimensionless)."""
        return self.stuck_time / self.t_end

    @property
    def x_rec(self):
        """Recorded housing displacement ``x`` on ``t_rec`` (m), or None."""
        return None if self.y_rec is None else self.y_rec[:, 0]

    @property
    def wall_per_sim_second(self):
        """Wall-clock time per simulated second (s/s)."""
        return self.wall_time / self.t_end

    @property
    def energy_residual(self):
        """``E0 + W - Ec - E_impact - E_end`` (J); zero for an exact solution."""
        return self.E0 + self.work_force - self.diss_damping - self.diss_impact - self.E_end

    @property
    def energy_residual_rel(self):
        """:attr:`energy_residual` over ``max(E0 + |W|, E_end + Ec + E_impact)`` (-)."""
        scale = max(self.E0 + abs(self.work_force),
                    self.E_end + self.diss_damping + self.diss_impact)
        return self.energy_residual / scale if scale > 0 else 0.0


def energy(params, y):
    """Mechanical energy of the state (J).

    Parameters
    ----------
    params : Params
        System parameters.
    y : array_like, shape (4,) or (n, 4)
        State(s) ``[x, x', z, z']`` (m, m/s, m, m/s).

    Returns
    -------
    float or ndarray
        ``0.5 M x'^2 + 0.5 K x^2 + 0.5 m z'^2`` (J).
    """
    y = np.asarray(y, dtype=float)
    return (0.5 * params.M * y[..., 1] ** 2 + 0.5 * params.K * y[..., 0] ** 2
            + 0.5 * params.m * y[..., 3] ** 2)


def impact_law(xd, zd, mu, e):
    """Post-impact velocities of housing and impactor.

    Parameters
    ----------
    xd, zd : float
        Housing and impactor velocities just before the impact (m/s).
    mu : float
        Mass ratio ``m / M`` (dimensionless).
    e : float
        Coefficient of restitution along the line of impact (dimensionless).

    Returns
    -------
    tuple of float
        ``(x'+, z'+)`` (m/s). Momentum ``M x' + m z'`` is conserved and
        ``z'+ - x'+ = -e (z'- - x'-)``.
    """
    return (((1.0 - mu * e) * xd + mu * (1.0 + e) * zd) / (1.0 + mu),
            ((1.0 + e) * xd + (mu - e) * zd) / (1.0 + mu))


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


def _housing_derivatives(p, t, x, xd, order):
    """Time derivatives ``x, x', ..., x^(order)`` of the free housing (no impactor contact).

    Parameters
    ----------
    p : Params
        System parameters.
    t, x, xd : ndarray
        Times (s), positions (m) and velocities (m/s) of the housing.
    order : int
        Highest derivative wanted (>= 1).

    Returns
    -------
    list of ndarray
        ``d[k] = x^(k)`` (m/s^k), from the recursion ``M x^(k+2) = F^(k) - c x^(k+1) - K x^(k)``.
    """
    d = [np.asarray(x, dtype=float), np.asarray(xd, dtype=float)]
    for k in range(order - 1):
        # k-th derivative of F0 cos(Omega t).
        force = p.F0 * p.Omega ** k * np.cos(p.Omega * t + 0.5 * math.pi * k)
        d.append((force - p.c * d[k + 1] - p.K * d[k]) / p.M)
    return d


def _quintic_hermite_basis(tau):
    """Quintic Hermite basis on ``[0, 1]`` for ``f0, h f0', h^2 f0'', h^2 f1'', h f1', f1``."""
    t2, t3 = tau * tau, tau ** 3
    t4, t5 = t3 * tau, t3 * t2
    return np.stack([1 - 10 * t3 + 15 * t4 - 6 * t5,
                     tau - 6 * t3 + 8 * t4 - 3 * t5,
                     0.5 * t2 - 1.5 * t3 + 1.5 * t4 - 0.5 * t5,
                     0.5 * t3 - t4 + 0.5 * t5,
                     -4 * t3 + 7 * t4 - 3 * t5,
                     10 * t3 - 15 * t4 + 6 * t5], axis=-1)


_N_SCREEN = 64
_SCREEN_BASIS = _quintic_hermite_basis(np.arange(1, _N_SCREEN + 1) / (_N_SCREEN + 1))


def _graze_candidates(ts, ys, lim, p):
    """Steps of a free flight in which the impactor may have touched a wall unseen.

    ``solve_ivp`` sees an event only as a sign change between step ends, so an excursion
    through a wall and back within one step (a graze, or a short flight back to the wall just
    left followed by a second separation) is lost. The relative coordinate ``r = z - x`` is
    reconstructed in every step from the step-end data by quintic Hermite interpolation
    (``r, r', r''`` at both ends; in free flight ``r'' = -x''`` follows from the state). A step
    is a candidate if that reconstruction comes closer to a wall than its error bound
    ``h^6 max|x^(6)| / 46080`` (times 4; ``max|x^(6)|`` estimated from ``x^(6)`` and
    ``x^(7)`` at the ends) plus the sampling error.

    Parameters
    ----------
    ts : ndarray, shape (n,)
        Step end times of a free-flight segment (s).
    ys : ndarray, shape (>= 4, n)
        States at ``ts``.
    lim : float
        Wall position ``|r|`` used by the wall events (m).
    p : Params
        System parameters.

    Returns
    -------
    ndarray of int
        Indices ``i`` of the candidate steps ``[ts[i], ts[i+1]]``, ascending.
    """
    h = np.diff(ts)
    d = _housing_derivatives(p, ts, ys[0], ys[1], 7)
    r = ys[2] - ys[0]
    v = ys[3] - ys[1]
    a = -d[2]   # the impactor is force-free in flight
    data = np.stack([r[:-1], h * v[:-1], h * h * a[:-1], h * h * a[1:], h * v[1:], r[1:]])
    rq = _SCREEN_BASIS @ data   # (samples, steps)
    w_min = min(p.omega_n, p.Omega) if p.Omega > 0 else p.omega_n
    b6 = np.sqrt(d[6] ** 2 + (d[7] / w_min) ** 2)
    b6 = np.maximum(b6[:-1], b6[1:])
    amax = np.maximum(np.abs(a[:-1]), np.abs(a[1:]))
    margin = (4.0 * h ** 6 / 46080.0 * b6 + amax * (h / (_N_SCREEN + 1)) ** 2 / 8.0
              + 64 * _EPS * lim)
    near = (np.max(np.abs(rq), axis=0) > lim - margin) & (h > 0)
    return np.nonzero(near)[0]


def _locate_graze(ta, tb, dense, lim, p, depth=0.0, n=65):
    """Find the first wall contact hidden inside ``[ta, tb]`` on the dense output, or None.

    Parameters
    ----------
    ta, tb : float
        Step start and end (s); the impactor is inside the cavity at ``ta``.
    dense : callable
        Dense output of the step, ``dense(t) -> state`` (also for an array of times).
    lim : float
        Wall position ``|r|`` used by the wall events (m).
    p : Params
        System parameters.
    depth : float
        Penetrations up to this depth are not contacts (m); use the position tolerance of the
        solver, below which the dense output cannot tell.
    n : int
        Number of samples of the step.

    Returns
    -------
    tuple or None
        ``(wall, t_contact, y_contact)``: the earliest crossing of ``|r| = lim`` in the step,
        outward (s, state). None if ``r`` stays inside.
    """
    tt = np.linspace(ta, tb, n)
    Y = dense(tt)
    R = Y[2] - Y[0]
    acc = np.abs((p.F0 * np.cos(p.Omega * tt) - p.c * Y[1] - p.K * Y[0]) / p.M)
    slack = np.max(acc) * (tt[1] - tt[0]) ** 2 / 8.0   # peak above the samples, at most
    xtol = 4 * _EPS * max(1.0, abs(tb))
    # Penetrations below what r = z - x and the event times resolve are not contacts (this
    # also keeps the located crossing that ends a terminated segment from counting).
    tol_q = (depth + 64 * _EPS * max(lim, float(np.max(np.abs(Y[0]))))
             + 4 * xtol * float(np.max(np.abs(Y[3] - Y[1]))))
    best = None
    for s in (1, -1):
        def q(t_, s=s):
            y_ = dense(t_)
            return s * (y_[2] - y_[0]) - lim

        Q = s * R - lim
        out = np.nonzero(Q[1:] > tol_q)[0]
        k_out = out[0] + 1 if out.size else n
        bracket = (tt[k_out - 1], tt[k_out]) if k_out < n else None
        # A hidden excursion between two samples shows up as a local maximum close to 0.
        for k in range(1, min(k_out, n)):
            right = Q[k + 1] if k + 1 < n else -np.inf
            if Q[k] >= Q[k - 1] and Q[k] >= right and Q[k] > -slack:
                hi = tt[min(k + 1, n - 1)]
                peak = minimize_scalar(lambda t_: -q(t_), bounds=(tt[k - 1], hi),
                                       method='bounded', options=dict(xatol=xtol))
                if -peak.fun > tol_q:
                    bracket = (tt[k - 1], peak.x)
                    break
        if bracket is not None:
            lo, hi = bracket
            if q(lo) >= 0.0:   # already at the wall at the left sample: contact there
                tc = lo
            else:
                tc = brentq(q, lo, hi, xtol=xtol, rtol=4 * _EPS)
            if best is None or tc < best[1]:
                best = (s, tc)
    if best is None:
        return None
    return best[0], best[1], dense(best[1])


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

    M, K, c, F0, Om, mu, e = p.M, p.K, p.c, p.F0, p.Omega, p.mu, p.e
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

            def hit_pos(t_, y_):
                return (y_[2] - y_[0]) - lim

            def hit_neg(t_, y_):
                return (y_[2] - y_[0]) + lim

            hit_pos.terminal, hit_pos.direction = True, 1.0    # only closing: r' > 0
            hit_neg.terminal, hit_neg.direction = True, -1.0   # only closing: r' < 0
            opts = dict(solver_opts, jac=jac_free) if implicit else solver_opts
            sol = solve_ivp(rhs_free, (t, t_end), y, events=(hit_pos, hit_neg), **opts)
        else:
            s = mode

            def release(t_, y_):
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
