"""Newmark average-acceleration integrator with impactors (the paper's method, section 3).

Same interface and impact physics as :class:`~.exact.ExactPropagator`; only the flow between
events differs. Two ways of handling impacts:

* ``impacts='step_end'`` (the paper's baseline): a step is taken with the impactors in free
  flight; if a gap is violated at the step end with a closing velocity, the impact law is
  applied there, positions as they are. Impact times are quantized to the step: order ~1.
* ``impacts='located'``: the crossing is located inside the step on the cubic Hermite
  interpolant of the gap (housing positions and velocities at both step ends), the step is
  redone from its start to the event with a Newmark step of that size, the impact is applied
  there and the rest of the step follows (possibly with further events). The impactor is put
  exactly on the wall at the event (this absorbs the O(h^3) mismatch between the Hermite root
  and the re-stepped state). Order 2 for states and impact times.

Impact law, sticking and release mirror :mod:`.kernels.exact`: the effective-mass (or lumped)
law with the impulse applied through the model (``qd += M^{-1} R^T P``), the paper's or the
accumulation sticking rule, the cap on impacts per output step, the plastic lock at stick
entry, the stuck state (impactor mass added to the housing rows, ``M + m R^T R``) and release
when the normal contact force reaches zero (``step_end``: sign test at step ends; ``located``:
linear interpolation of the force inside the step, refined by regula falsi on re-steps so that
the released state has a non-compressive force). Differences from the exact kernel:

* a stuck planar impactor's release force is that of a frictionless normal contact,
  ``-n . (I - m G_s)^{-1} a_h`` (see :func:`.kernels.newmark.release_force`), which has the
  sign of the lock criterion; the kernel's ``-n . a_h`` in the stuck configuration can
  disagree with it when the mobility ``G`` is anisotropic, giving stick/release pairs at one
  instant. For SDOF the factor is a positive scalar and the release instant is the kernel's;
* instead of the kernel's "grace" shift after a stick or release, a closed gap that is at rest
  on its wall or leaving it (``g' > 0``, or ``g' = 0`` with ``g'' >= 0``) is not an event;
* event counts are reset once per output step (the kernel also restarts them whenever it
  returns for a configuration change).

Event loops are bounded as in the kernel: every event (impact, contact, stick, release)
counts towards its impactor's total in the output step; above ``max_events_per_step`` a
contact is completed plastically (the lock, released again at once if the wall does not
press), above ``4 max_events_per_step + 16`` a ``RuntimeError`` is raised.

Energy ledger: impact and lock losses are exact from the law. Damping dissipation, forcing
work and circulatory work use the trapezoidal means of the step-end quantities
(``h v.C v`` with ``v = (v0 + v1)/2`` and so on): O(dt^2) approximations of the true
integrals that match the scheme's own discrete energy balance, so the ledger residual is
round-off, not O(dt^2).
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..dampers.law import law_mobility, IMPACT_LAWS
from .base import IntegratorBase
from .events import EVENT_DTYPE, EVENT_KINDS, Samples, STICK_RULES
from .kernels import newmark as kernels

IMPACT_MODES = ('located', 'step_end')
SOLVERS = ('auto', 'dense', 'sparse')
_EV_IMPACT = EVENT_KINDS.index('impact')
_EV_STICK = EVENT_KINDS.index('stick')
_EV_RELEASE = EVENT_KINDS.index('release')
#: internal steps per chunk of precomputed inputs (bounds memory on long runs)
_CHUNK = 1 << 16
#: above this many coordinates 'auto' may choose the sparse solver
_SPARSE_MIN_N = 400
_EPS = np.finfo(float).eps
#: Newmark steps per period of the highest retained mode at least, with impactors: event
#: location works on the cubic Hermite gap of the step ends, and the textbook bound T/10
#: keeps the highest mode's period elongation ((omega h)^2/12) under 3.3 %; longer steps
#: detune resonances and miss impacts (an SDOF at resonance with zeta = 0.02 loses every
#: impact at T/6.3; ``test/test_extremes.py``)
MIN_STEPS_PER_PERIOD = 10


def _omega_max(M, C, K, sparse):
    """Largest ``|lambda|`` of the first-order system (1/s): sets the paper's stick time.

    Up to 200 coordinates this is the exact propagator's definition (eigenvalues of the
    state matrix). Larger models use the highest undamped frequency of ``(K_sym, M)``, which
    is the same unless the highest modes are overdamped.
    """
    n = K.shape[0]
    if n <= 200:
        A = np.block([[np.zeros((n, n)), np.eye(n)],
                      [-np.linalg.solve(M, K), -np.linalg.solve(M, C)]])
        lam = np.linalg.eigvals(A)
        return float(np.max(np.abs(lam))) if lam.size else 1.0
    K_sym = 0.5 * (K + K.T)
    if sparse:
        w2 = spla.eigsh(sp.csc_matrix(K_sym), k=1, M=sp.csc_matrix(M), which='LA',
                        return_eigenvectors=False)[0]
    else:
        w2 = sla.eigh(K_sym, M, eigvals_only=True, subset_by_index=[n - 1, n - 1])[0]
    return float(np.sqrt(max(w2, 0.0)))


def _poly_eval(p, s):
    acc = 0.0
    for c in p[::-1]:
        acc = acc * s + c
    return acc


def _first_crossing(p, H, tol):
    """First ``s`` in ``(0, H]`` where the polynomial ``p`` (ascending) reaches 0 from above.

    The caller has decided already that ``s = 0`` is not an event (``p`` starts positive, or
    on or through the boundary moving out). ``[0, H]`` is cut at the critical points so every
    piece is monotone. Returns None when there is no crossing.
    """
    dp = np.arange(1, len(p)) * np.asarray(p[1:])
    if len(p) == 4:     # SDOF gap: the critical points of a cubic in closed form
        crit = _quadratic_roots(dp[2], dp[1], dp[0])
    else:
        crit = []
        if np.any(dp != 0.0):
            for r in np.roots(dp[::-1]):
                # near-real pairs are kept: an extra cut is harmless, a missing one is not
                if abs(r.imag) <= 1e-6 * H:
                    crit.append(r.real)
    knots = [0.0] + sorted(c for c in crit if 0.0 < c < H) + [H]
    pa = p[0]
    for a, b in zip(knots[:-1], knots[1:]):
        pb = _poly_eval(p, b)
        if pb <= 0.0:
            if pa > 0.0:
                return _refine(p, a, b, pa, pb, tol)
            if a > 0.0 and pb < pa:
                return a   # rising from a wall, then turning back before leaving it
        pa = pb
    return None


def _quadratic_roots(a, b, c):
    """Real roots of ``a s^2 + b s + c`` (a double root once), numerically stable."""
    if a == 0.0:
        return [-c / b] if b != 0.0 else []
    disc = b * b - 4.0 * a * c
    if disc < 0.0:
        return []
    qq = -0.5 * (b + np.copysign(np.sqrt(disc), b))
    if qq == 0.0:
        return [0.0]
    return [qq / a, c / qq]


def _refine(p, a, b, fa, fb, tol):
    """Illinois regula falsi on ``fa > 0 >= fb``; returns the ``b`` side."""
    side = 0
    for _ in range(200):
        if b - a <= tol:
            break
        c = (a * fb - b * fa) / (fb - fa)
        if not (a < c < b):
            c = 0.5 * (a + b)
        fc = _poly_eval(p, c)
        if fc > 0.0:
            a, fa = c, fc
            if side == 1:
                fb *= 0.5
            side = 1
        else:
            b, fb = c, fc
            if side == -1:
                fa *= 0.5
            side = -1
    return b


class _Config:
    """Matrices of one stuck configuration: ``M + sum m R^T R`` and its solves."""

    def __init__(self, model, rows, stuck_masses, law, sparse, C, K):
        self.sparse = sparse
        self.C = C
        self.K = K
        Md = model.stuck_mass_matrix(stuck_masses)
        self.M = sp.csc_matrix(Md) if sparse else Md
        if sparse:
            self._lu_M = spla.splu(self.M)
        else:
            self.Minv = np.linalg.inv(Md)
        ni = len(model.impactors)
        n = model.n
        self.kick = np.zeros((ni, n, 2))          # M^{-1} R^T per impactor (1/kg)
        self.mobility = np.zeros((ni, 2, 2))      # law mobility (1/kg)
        self.house_mobility = np.zeros((ni, 2, 2))   # the model's R M^{-1} R^T (1/kg)
        self.rel_T = np.zeros((ni, 2, 2))         # release transforms (I - m G_s)^{-1}
        for j, imp in enumerate(model.impactors):
            d = imp.dim
            MinvRt = self.solve_M(rows[j, :d].T)
            self.kick[j, :, :d] = MinvRt
            G = rows[j, :d] @ MinvRt
            self.house_mobility[j, :d, :d] = G
            self.mobility[j, :d, :d] = law_mobility(G, imp.housing_mass, law)
            self.rel_T[j, :d, :d] = np.linalg.inv(np.eye(d) - stuck_masses[j] * G)
        self._S = {}

    def solve_M(self, r):
        """``M^{-1} r`` for this configuration."""
        if self.sparse:
            return self._lu_M.solve(np.asarray(r, dtype=float))
        return self.Minv @ r

    def S(self, h):
        """``M + h/2 C + h^2/4 K`` (the effective stiffness times ``h^2/4``)."""
        return self.M + (0.5 * h) * self.C + (0.25 * h * h) * self.K

    def Sinv(self, h):
        """Cached inverse (dense) or LU (sparse) of ``S(h)`` for the main step size."""
        fac = self._S.get(h)
        if fac is None:
            fac = spla.splu(sp.csc_matrix(self.S(h))) if self.sparse \
                else np.linalg.inv(self.S(h))
            if len(self._S) > 4:      # only a few step sizes recur
                self._S.clear()
            self._S[h] = fac
        return fac

    def solve_S(self, h, r, cached):
        """``S(h)^{-1} r``; ``cached`` for the recurring step size, else a fresh solve."""
        if cached:
            fac = self.Sinv(h)
            return fac.solve(r) if self.sparse else fac @ r
        if self.sparse:
            return spla.splu(sp.csc_matrix(self.S(h))).solve(r)
        return np.linalg.solve(self.S(h), r)


class NewmarkIntegrator(IntegratorBase):
    """Average-acceleration Newmark integration of a :class:`~.model.LinearModel`.

    Parameters
    ----------
    model : LinearModel
        Model with its impactors (modal or physical coordinates).
    forcing : Forcing
        External forcing on the model's inputs (N); evaluated at every internal step end
        (and at located event times), not held linearly between output samples.
    dt : float
        Output step (s): sensor samples every ``dt``.
    impacts : {'located', 'step_end'}
        Event handling (see the module docstring).
    law : {'effective_mass', 'lumped_mass'}
        Impact law (see :mod:`impact_damper_sim.dampers.law`).
    stick_rule : {'paper', 'accumulation', 'none'}
        When a bounce-down becomes the stuck state (as in the exact kernel).
    stick_fraction : float
        Fraction of the period of the highest mode, ``2 pi/max|lambda|``, giving the sticking
        time (dimensionless); default 0.002.
    max_events_per_step : int
        Impacts of one impactor in one output step after which it is made to stick.
    ledger : bool
        Accumulate damping, forcing and circulatory work.
    q0, qd0 : ndarray, optional
        Initial coordinates and velocities (m and m/s, or modal units).
    t0 : float
        Initial time (s).
    substeps : int
        Internal Newmark steps per output step (dimensionless, >= 1); ``h = dt/substeps``.
    solver : {'auto', 'dense', 'sparse'}
        ``'dense'``: cached inverse of ``S`` and the Numba step loop; ``'sparse'``:
        ``scipy.sparse.linalg.splu`` and a Python step loop, for large sparse physical
        models. ``'auto'`` picks sparse above 400 coordinates when ``M, C, K`` are under 5 %
        filled.
    stick_time : float, optional
        Sticking time of the rules (s); default ``stick_fraction * 2 pi / max|lambda|`` of this
        model. A physical model's highest mode is far above a truncated modal model's: pass
        the modal integrator's ``stick_time`` to apply the same rule to both.
    """

    def __init__(self, model, forcing, dt, *, impacts='located', law='effective_mass',
                 stick_rule='paper', stick_fraction=0.002, max_events_per_step=64, ledger=True,
                 q0=None, qd0=None, t0=0.0, substeps=1, solver='auto', stick_time=None):
        if not (np.isfinite(dt) and dt > 0):
            raise ValueError(f'dt must be a positive time in s, got {dt}')
        if impacts not in IMPACT_MODES:
            raise ValueError(f'impacts must be one of {IMPACT_MODES}, got {impacts!r}')
        if law not in IMPACT_LAWS:
            raise ValueError(f'law must be one of {IMPACT_LAWS}, got {law!r}')
        if stick_rule not in STICK_RULES:
            raise ValueError(f'stick_rule must be one of {STICK_RULES}, got {stick_rule!r}')
        if not (0 < stick_fraction < 1):
            raise ValueError(f'stick_fraction must be in (0, 1), got {stick_fraction}')
        if int(substeps) != substeps or substeps < 1:
            raise ValueError(f'substeps must be an integer >= 1, got {substeps}')
        if int(max_events_per_step) < 1:
            raise ValueError(f'max_events_per_step must be >= 1, got {max_events_per_step}')
        if solver not in SOLVERS:
            raise ValueError(f'solver must be one of {SOLVERS}, got {solver!r}')
        if forcing.n_inputs != model.n_inputs:
            raise ValueError(f'forcing has {forcing.n_inputs} inputs, model has {model.n_inputs}')
        self.model = model
        self.forcing = forcing
        self.dt = float(dt)
        self.substeps = int(substeps)
        self.h = self.dt / self.substeps
        self.impacts = impacts
        self.law = law
        self.stick_rule = stick_rule
        self.max_events_per_step = int(max_events_per_step)
        self.ledger_on = bool(ledger)
        n = model.n
        if solver == 'auto':
            fill = np.count_nonzero((model.M != 0) | (model.C != 0) | (model.K != 0)) / n ** 2
            solver = 'sparse' if n >= _SPARSE_MIN_N and fill < 0.05 else 'dense'
        self.solver = solver
        self._sparse = solver == 'sparse'
        self._C = sp.csr_matrix(model.C) if self._sparse else model.C
        self._K = sp.csr_matrix(model.K) if self._sparse else model.K
        self._K_skew = model.K_skew
        self._K_sym = model.K_sym
        self._Kskew_op = sp.csr_matrix(self._K_skew) if self._sparse else self._K_skew
        self._B = model.B
        ni = len(model.impactors)
        self._rows = np.zeros((ni, 2, n))
        for j, imp in enumerate(model.impactors):
            self._rows[j, :imp.dim] = imp.rows
        self._imp_dim = np.array([imp.dim for imp in model.impactors], dtype=np.int64)
        self._imp_mass = np.array([imp.mass for imp in model.impactors], dtype=float)
        self._imp_cor = np.array([imp.cor for imp in model.impactors], dtype=float)
        self._imp_limit = np.array([imp.limit for imp in model.impactors], dtype=float)
        self._stuck = np.zeros(ni, dtype=np.int64)
        self._configs = {}
        if stick_time is None:
            stick_time = stick_fraction * 2 * np.pi / _omega_max(model.M, model.C, model.K,
                                                                self._sparse)
        elif not (np.isfinite(stick_time) and stick_time > 0):
            raise ValueError(f'stick_time must be a positive time in s, got {stick_time}')
        self.stick_time = float(stick_time)
        # the period of the highest mode the sticking rule uses: this model's, or the retained
        # modes' of a direct model given their stick_time
        period = self.stick_time / stick_fraction
        if ni and self.h > period / MIN_STEPS_PER_PERIOD:
            h_max = period / MIN_STEPS_PER_PERIOD
            raise ValueError(
                f'simulation.dt = {self.dt:.4g} s (Newmark step {self.h:.4g} s) is too large to '
                f'track impacts: it must be at most 1/{MIN_STEPS_PER_PERIOD} of the period of '
                f'the highest retained mode ({1.0 / period:.5g} Hz), {h_max:.4g} s; lower '
                'simulation.dt, retain fewer modes, or use method exact')
        self.t = float(t0)
        self._q = np.zeros(n) if q0 is None else np.array(q0, dtype=float).reshape(n)
        self._v = np.zeros(n) if qd0 is None else np.array(qd0, dtype=float).reshape(n)
        self._f = self._force_at(self.t)
        self._a = self._accel(self._config(), self._f)
        self._imp_z = np.zeros((ni, 2))
        self._imp_v = np.zeros((ni, 2))
        for j, imp in enumerate(model.impactors):
            self._imp_z[j, :imp.dim] = imp.rows @ self._q + imp.position
            self._imp_v[j, :imp.dim] = imp.velocity
        self._imp_normal = np.zeros((ni, 2))
        self._imp_last_t = np.full(ni, -np.inf)
        self._imp_rel = np.zeros((ni, 2))
        self._count = np.zeros(ni, dtype=np.int64)
        self._count_index = -1
        # just released: the wall it leaves is shifted out by 1e-9 of the clearance until
        # the next step of non-zero length, as the exact kernel's grace, so that a release
        # at a vanishing contact force cannot be undone by round-off at the same instant
        self._grace = np.zeros(ni, dtype=bool)
        self._out_done = 0            # output steps completed since t0
        self._ledger = np.zeros(5)
        self._events = []
        self.n_config_changes = 0
        self.max_impacts_per_step = 0
        self.grazing_undecided = 0    # interface parity with ExactPropagator (no scan here)
        self._info = np.zeros(2, dtype=np.int64)
        structure, impactors = self._energy_now()
        self._initial_energy = structure + impactors

    # -- configuration and dynamics ----------------------------------------------------------
    def _config(self):
        key = tuple(int(s) for s in self._stuck)
        cfg = self._configs.get(key)
        if cfg is None:
            masses = [float(m) if s else 0.0 for m, s in zip(self._imp_mass, self._stuck)]
            cfg = _Config(self.model, self._rows, masses, self.law, self._sparse, self._C,
                          self._K)
            self._configs[key] = cfg
        return cfg

    def _force_at(self, t):
        return self._B @ self.forcing.evaluate(t)[0]

    def _accel(self, cfg, f):
        return cfg.solve_M(f - self._C @ self._v - self._K @ self._q)

    def _trial(self, cfg, h, f1, cached):
        """One Newmark step of ``h`` (s) from the current state; returns ``(q1, v1, a1)``."""
        q0, v0, a0 = self._q, self._v, self._a
        if cached and not self._sparse:
            q1, v1, a1, work = (np.empty_like(q0) for _ in range(4))
            kernels.step(cfg.Sinv(h), self._C, self._K, f1, h, q0, v0, a0, q1, v1, a1, work)
            return q1, v1, a1
        qp = q0 + h * v0 + 0.25 * h * h * a0
        vp = v0 + 0.5 * h * a0
        a1 = cfg.solve_S(h, f1 - self._C @ vp - self._K @ qp, cached)
        return qp + 0.25 * h * h * a1, vp + 0.5 * h * a1, a1

    def _commit(self, h, f1, q1, v1, a1):
        """Accept a step of ``h`` (s): ledger, state, impactor flight."""
        if self.ledger_on and h > 0.0:
            vb = 0.5 * (self._v + v1)
            qb = 0.5 * (self._q + q1)
            self._ledger[2] += h * float(vb @ (self._C @ vb))
            self._ledger[3] += h * float(vb @ (0.5 * (self._f + f1)))
            self._ledger[4] -= h * float(vb @ (self._Kskew_op @ qb))
        self._q, self._v, self._a, self._f = q1, v1, a1, f1
        if h > 0.0:
            self._grace[:] = False
        free = self._stuck == 0
        self._imp_z[free] += self._imp_v[free] * h

    # -- public state ------------------------------------------------------------------------
    def state(self):
        """Return ``(q, qd)``: coordinates and their velocities now (copies)."""
        return self._q.copy(), self._v.copy()

    def _housing_rows(self):
        return [self._rows[j, :d] for j, d in enumerate(self._imp_dim)]

    def _structure_energy(self, q, qd):
        return 0.5 * float(qd @ (self.model.M @ qd)) + 0.5 * float(q @ (self._K_sym @ q))

    def take_events(self):
        """Return the events recorded since the last call (see ``EVENT_DTYPE``) and clear."""
        out = np.array(self._events, dtype=EVENT_DTYPE) if self._events \
            else np.zeros(0, dtype=EVENT_DTYPE)
        self._events = []
        return out

    # -- stepping ----------------------------------------------------------------------------
    def _time(self, t_base, k):
        """Time (s) of internal step end ``k``; output instants are exactly ``t_base + i dt``."""
        return t_base + (k // self.substeps) * self.dt + (k % self.substeps) * self.h

    def advance(self, n_steps):
        """Advance ``n_steps`` output steps of ``dt``.

        Parameters
        ----------
        n_steps : int
            Number of output steps (dimensionless).

        Returns
        -------
        Samples
            Sensor displacement (m), velocity (m/s) and smooth acceleration (m/s^2) at the
            end of each output step.
        """
        n_steps = int(n_steps)
        ns = self.model.sensors.shape[0]
        t_base = self.t
        times = t_base + self.dt * np.arange(1, n_steps + 1)
        disp = np.empty((n_steps, ns))
        vel = np.empty((n_steps, ns))
        acc = np.empty((n_steps, ns))
        outs = (disp, vel, acc)
        n_int = n_steps * self.substeps
        chunk = max(self.substeps, (_CHUNK // self.substeps) * self.substeps)
        out_done0 = self._out_done
        for k0 in range(0, n_int, chunk):
            k1 = min(n_int, k0 + chunk)
            t_grid = self._time(t_base, np.arange(k0, k1 + 1))
            u_grid = np.ascontiguousarray(self.forcing.evaluate(t_grid))
            k = 0
            while k < k1 - k0:
                status, k = self._run(k, k1 - k0, k0, u_grid, outs)
                if status == kernels.DONE:
                    break
                if status == kernels.NONFINITE:
                    self.t = float(t_grid[k])
                    raise FloatingPointError(f'non-finite state at t = {self.t:.6g} s')
                # a possible event in local step k: handle it in Python
                m = k0 + k + 1
                index = out_done0 + (m - 1) // self.substeps
                if index != self._count_index:
                    self._count[:] = 0
                    self._count_index = index
                if self.impacts == 'located':
                    self._located_step(t_grid[k], t_grid[k + 1], u_grid[k + 1])
                else:
                    self._step_end_step(t_grid[k + 1], u_grid[k + 1])
                if not (np.all(np.isfinite(self._q)) and np.all(np.isfinite(self._v))):
                    self.t = float(t_grid[k + 1])
                    raise FloatingPointError(f'non-finite state at t = {self.t:.6g} s')
                if m % self.substeps == 0:
                    o = m // self.substeps - 1
                    S = self.model.sensors
                    disp[o], vel[o], acc[o] = S @ self._q, S @ self._v, S @ self._a
                k += 1
        self._out_done = out_done0 + n_steps
        self.t = t_base + n_steps * self.dt if n_steps else t_base
        return Samples(times, disp, vel, acc)

    def _run(self, k, k_stop, k0, u_grid, outs):
        """Event-free steps from local step ``k``; returns ``(status, step reached)``."""
        cfg = self._config()
        h = self.h
        located = self.impacts == 'located'
        if not self._sparse:
            status = kernels.run_steps(
                k, k_stop, k0, self.substeps, h, u_grid, self._B, cfg.Sinv(h), self._C, self._K,
                self._K_skew, self._q, self._v, self._a, self._f, self._rows, self._imp_dim,
                self._imp_limit, self._imp_z, self._imp_v, self._stuck, self._imp_normal,
                cfg.rel_T, located, self.ledger_on, self._ledger, self.model.sensors, outs[0],
                outs[1], outs[2], self._info)
            return status, int(self._info[0])
        # sparse models: the same loop in Python around splu solves
        S = self.model.sensors
        while k < k_stop:
            f1 = self._B @ u_grid[k + 1]
            q1, v1, a1 = self._trial(cfg, h, f1, True)
            j = kernels.event_flag(located, h, self._q, self._v, q1, v1, a1, self._rows,
                                   self._imp_dim, self._imp_limit, self._imp_z, self._imp_v,
                                   self._stuck, self._imp_normal, cfg.rel_T,
                                   np.empty((2, 4)))
            if j >= 0:
                return kernels.FLAGGED, k
            self._commit(h, f1, q1, v1, a1)
            m = k0 + k + 1
            if m % self.substeps == 0:
                if not (np.all(np.isfinite(q1)) and np.all(np.isfinite(v1))):
                    return kernels.NONFINITE, k
                o = m // self.substeps - 1
                outs[0][o], outs[1][o], outs[2][o] = S @ q1, S @ v1, S @ a1
            k += 1
        return kernels.DONE, k

    def _step_end_step(self, t_b, u_b):
        """Paper's baseline: full free-flight step, then the impact law at the step end."""
        cfg = self._config()
        f_b = self._B @ u_b
        q1, v1, a1 = self._trial(cfg, self.h, f_b, True)
        self._commit(self.h, f_b, q1, v1, a1)
        for j in range(self._imp_dim.size):
            d = self._imp_dim[j]
            R = self._rows[j, :d]
            if self._stuck[j]:
                if self._release_force(j, self._a) <= 0.0:
                    self._release(j, t_b)
                continue
            r = self._imp_z[j, :d] - R @ self._q
            dist = float(np.sqrt(r @ r))
            if dist >= self._imp_limit[j]:
                nrm = np.zeros(2)
                nrm[:d] = r / dist
                if nrm[:d] @ (self._imp_v[j, :d] - R @ self._v) > 0.0:
                    self._contact(j, t_b, nrm, project=False)

    def _located_step(self, t_a, t_b, u_b):
        """One step with every event inside it located and stepped to."""
        f_b = self._B @ u_b
        t = t_a
        # per-impactor counts raise first (see _count_event); this only bounds the loop
        cap = (4 * self.max_events_per_step + 17) * max(1, self._imp_dim.size) + 1
        for _ in range(cap):
            # the whole step uses the nominal h (cached factorization); the rest of a step
            # after an event is a fresh solve
            whole = t == t_a
            H = self.h if whole else t_b - t
            if H <= 0.0:
                return
            cfg = self._config()
            q1, v1, a1 = self._trial(cfg, H, f_b, whole)
            tau, j, nrm = self._find_event(t, H, q1, v1, a1)
            if j < 0:
                self._commit(H, f_b, q1, v1, a1)
                return
            if tau >= H:
                self._commit(H, f_b, q1, v1, a1)
                t = t_b
            elif tau > 0.0:
                if self._stuck[j]:
                    tau, end = self._release_time(cfg, t, tau, H, f_b, q1, v1, a1, j)
                else:
                    t_e = t + tau
                    f_e = self._force_at(t_e)
                    end = (f_e,) + self._trial(cfg, tau, f_e, False)
                self._commit(tau, *end)
                t = t_b if tau >= H else t + tau
            if self._stuck[j]:
                self._release(j, t)
            else:
                self._contact(j, t, nrm, project=True)
        raise RuntimeError(f'chatter not resolved at t = {t:.6g} s: more than {cap} events in '
                           f'one step of {self.h:.3g} s')

    def _find_event(self, t, H, q1, v1, a1):
        """Earliest event in ``[0, H]`` from the current state and the trial step end.

        Returns ``(tau, impactor, normal)``; ``impactor = -1`` when there is none.
        """
        best, best_j, best_n = H, -1, None
        tol = 4.0 * _EPS * (abs(t) + H)
        for j in range(self._imp_dim.size):
            d = self._imp_dim[j]
            R = self._rows[j, :d]
            L = self._imp_limit[j]
            if self._stuck[j]:
                f0 = self._release_force(j, self._a)
                f1 = self._release_force(j, a1)
                if f0 > 0.0:
                    if f1 > 0.0:
                        continue
                    tau = H * f0 / (f0 - f1)
                elif f1 > 0.0:
                    continue        # the force builds up again inside the step: stay stuck
                else:
                    tau = 0.0
                if tau < best or best_j < 0:
                    best, best_j, best_n = tau, j, self._imp_normal[j].copy()
                continue
            c = np.empty((d, 4))
            x0, xd0, x1, xd1 = R @ self._q, R @ self._v, R @ q1, R @ v1
            for r in range(d):
                kernels.hermite_relative(self._imp_z[j, r], self._imp_v[j, r], x0[r], xd0[r],
                                         x1[r], xd1[r], H, c[r])
            ah = R @ self._a
            if d == 1:
                lo, hi = kernels.cubic_range(c[0], H)
                for s in (1.0, -1.0):
                    if (hi if s > 0 else -lo) < L and s * c[0, 0] < L:
                        continue        # this wall is not reached in the step
                    g = np.array([L - s * c[0, 0], -s * c[0, 1], -s * c[0, 2], -s * c[0, 3]])
                    if self._grace[j]:
                        g[0] += 1e-9 * L
                    g2 = s * ah[0]                         # g'' from the true acceleration
                    tau = self._gap_event(g, g2, H, tol)
                    if tau is not None and (tau < best or best_j < 0):
                        best, best_j, best_n = tau, j, np.array([s, 0.0])
            else:
                r2 = np.convolve(c[0], c[0]) + np.convolve(c[1], c[1])
                g = -r2
                g[0] += L * L * (1.0 + 1e-9 * self._grace[j])
                rd = c[:, 1]
                g2 = -2.0 * (rd @ rd - c[:, 0] @ ah)
                tau = self._gap_event(g, g2, H, tol)
                if tau is not None and (tau < best or best_j < 0):
                    nrm = np.zeros(2)
                    # the normal is taken at the event, see _contact; provisional here
                    best, best_j, best_n = tau, j, nrm
        return best, best_j, best_n

    def _release_time(self, cfg, t, tau, H, f_b, q1, v1, a1, j):
        """Refine a release time on the re-stepped contact force; returns ``(tau, end)``.

        The linear interpolation ``tau`` of the release force ``f`` (:meth:`_release_force`)
        starts an Illinois iteration on ``f`` evaluated from Newmark steps of size ``s`` from
        the current state, bracketed by ``f(0) > 0 >= f(H)``. The returned
        ``end = (force, q, v, a)`` is a state with ``f <= 0``, so the freed impactor is not
        pushed straight back into its wall.
        """
        a, fa = 0.0, self._release_force(j, self._a)
        b, fb = H, self._release_force(j, a1)
        end_b = (f_b, q1, v1, a1)
        s = tau
        side = 0
        tol = 4.0 * _EPS * (abs(t) + H)
        for _ in range(40):
            if not (a < s < b):
                s = 0.5 * (a + b)
            f_s = self._force_at(t + s)
            state = self._trial(cfg, s, f_s, False)
            fc = self._release_force(j, state[2])
            if fc > 0.0:
                a, fa = s, fc
                if side == 1:
                    fb *= 0.5
                side = 1
            else:
                b, fb, end_b = s, fc, (f_s,) + state
                if side == -1:
                    fa *= 0.5
                side = -1
            if b - a <= max(tol, 1e-10 * H) or fc == 0.0:
                break
            s = (a * fb - b * fa) / (fb - fa)
        return b, end_b

    @staticmethod
    def _gap_event(g, g2, H, tol):
        """Event time of one gap polynomial ``g`` (ascending) in ``[0, H]``, or None.

        ``s = 0`` is an event when the gap starts closed and moving in (``g' < 0``, or
        ``g' = 0`` with ``g'' < 0``); a tangential rest (``g' = g'' = 0``) is not.
        """
        if g[0] <= 0.0 and (g[1] < 0.0 or (g[1] == 0.0 and g2 < 0.0)):
            return 0.0
        return _first_crossing(g, H, tol)

    # -- events ------------------------------------------------------------------------------
    def _record(self, t, j, kind, nrm, v_n, J, loss, v_after, vh_jump):
        self._events.append((t, j, kind, (nrm[0], nrm[1]), v_n, J, loss, v_after, vh_jump))

    def _count_event(self, j, t):
        """Count an event of impactor ``j`` in this output step; bounded as in the kernel."""
        self._count[j] += 1
        if self._count[j] > 4 * self.max_events_per_step + 16:
            raise RuntimeError(f'chatter not resolved at t = {t:.6g} s for impactor '
                               f'{self.model.impactors[j].name!r}')

    def _contact(self, j, t, nrm, project):
        """Contact of impactor ``j`` with its wall at ``t``: impact, then maybe the lock.

        Mirrors :func:`.kernels.exact.advance_py`; ``nrm`` is the outward wall normal (the
        planar normal is recomputed from the positions here). ``project`` puts a bouncing
        impactor exactly on the wall (located events).
        """
        self._count_event(j, t)
        cfg = self._config()
        d = self._imp_dim[j]
        R = self._rows[j, :d]
        L = self._imp_limit[j]
        if d == 2:
            rel = self._imp_z[j, :2] - R @ self._q
            nrm = np.array([rel[0], rel[1]]) / np.sqrt(rel @ rel)
        n_ = nrm[:d]
        vh = R @ self._v
        ah = R @ self._a                  # pre-impact housing acceleration, as the kernel
        vrel = self._imp_v[j, :d] - vh
        v_n = float(n_ @ vrel)
        m_i = self._imp_mass[j]
        G = cfg.mobility[j, :d, :d]
        G_model = cfg.house_mobility[j, :d, :d]
        g_nn = float(n_ @ G @ n_)
        e_cor = self._imp_cor[j]
        same_wall = float(nrm @ self._imp_normal[j]) > 0.95
        dt_prev = t - self._imp_last_t[j]
        if v_n > 0.0:
            J = (1.0 + e_cor) * v_n / (1.0 / m_i + g_nn)
            # what the impulse takes out of impactor and model (see kernels.exact.impact_py)
            loss = 0.5 * J * (v_n * (1.0 - e_cor) + J * (g_nn - float(n_ @ G_model @ n_)))
            self._imp_v[j, :d] -= J * n_ / m_i
            self._v = self._v + cfg.kick[j, :, :d] @ (J * n_)
            self._ledger[0] += loss
            self.max_impacts_per_step = max(self.max_impacts_per_step, int(self._count[j]))
            vh_a = R @ self._v
            self._record(t, j, _EV_IMPACT, nrm, v_n, J, loss,
                         float(n_ @ (self._imp_v[j, :d] - vh_a)), float(n_ @ (vh_a - vh)))
            vh = vh_a                     # the lock below starts from the post-impact state
        stick = v_n <= 0.0
        if same_wall and v_n > 0.0:
            if self.stick_rule == 'paper' and dt_prev < self.stick_time:
                stick = True
            elif self.stick_rule == 'accumulation' and e_cor < 1.0 and \
                    dt_prev * e_cor / (1.0 - e_cor) < self.stick_time:
                stick = True
        chatter = self._count[j] > self.max_events_per_step
        self._imp_last_t[j] = t
        self._imp_normal[j] = 0.0
        self._imp_normal[j, :d] = n_
        # the wall must push to keep the contact: -n . a_h > 0, plus on a round wall the
        # centripetal part |v_t|^2/c of a tangentially sliding impactor (zero for SDOF)
        vr = self._imp_v[j, :d] - vh
        v_t = vr - (n_ @ vr) * n_
        pushes = float(v_t @ v_t) / L - float(n_ @ ah) > 0.0
        # chatter: complete it plastically; the release follows if the wall does not press
        if (stick and pushes) or chatter:
            # plastic completion of the bounce-down: cancel the relative velocity
            P = np.linalg.solve(np.eye(d) / m_i + G, vr)
            self._imp_v[j, :d] -= P / m_i
            self._v = self._v + cfg.kick[j, :, :d] @ P
            self._stuck[j] = 1
            self._imp_rel[j] = 0.0
            self._imp_rel[j, :d] = n_ * L
            vh_l = R @ self._v
            # what the lock takes out of impactor and model; the stuck impactor rides with
            # the housing's velocity (see kernels.exact.impact_py)
            w = self._imp_v[j, :d] - vh_l
            lock_loss = 0.5 * float(vr @ P + P @ (G - G_model) @ P
                                    + m_i * (w @ (self._imp_v[j, :d] + vh_l)))
            self._ledger[1] += lock_loss
            self._record(t, j, _EV_STICK, nrm, float(n_ @ vr), float(np.sqrt(P @ P)), lock_loss,
                         float(n_ @ (self._imp_v[j, :d] - vh_l)), float(n_ @ (vh_l - vh)))
            self.n_config_changes += 1
        elif project:
            self._imp_z[j, :d] = R @ self._q + n_ * L
        self._a = self._accel(self._config(), self._f)

    def _release_force(self, j, a):
        """Normal contact force per unit mass of stuck impactor ``j`` for accelerations ``a``."""
        return kernels.release_force(self._rows[j], self._imp_dim[j], self._config().rel_T[j],
                                     self._imp_normal[j], a)

    def _release_now(self, j):
        self._release(j, self.t)

    def _release(self, j, t):
        """The stuck impactor ``j`` leaves its wall at ``t`` with the housing velocity."""
        self._count_event(j, t)
        d = self._imp_dim[j]
        R = self._rows[j, :d]
        self._stuck[j] = 0
        self._imp_z[j, :d] = R @ self._q + self._imp_rel[j, :d]
        self._imp_v[j, :d] = R @ self._v
        self._imp_last_t[j] = t
        self._grace[j] = True
        self._record(t, j, _EV_RELEASE, self._imp_normal[j], 0.0, 0.0, 0.0, 0.0, 0.0)
        self.n_config_changes += 1
        self._a = self._accel(self._config(), self._f)
