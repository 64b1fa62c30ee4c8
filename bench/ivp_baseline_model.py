"""Parameters, result and impact law of the ``solve_ivp`` baseline (``ivp_baseline.py``).

:class:`Params` (the SDOF impact damper in SI units, or built from the usual dimensionless
groups), :class:`Result` (impact history, stuck phases, energy ledger, counts and timings of a
run), the mechanical :func:`energy` and the restitution :func:`impact_law`. Apart from the
event loop so that the model and what a run returns read on their own; like the rest of the
baseline it imports nothing from ``impact_damper_sim`` and needs only numpy.
"""

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np


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
