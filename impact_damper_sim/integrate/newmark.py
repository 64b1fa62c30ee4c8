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

Event location inside a step, the impact law, sticking and release are in
:mod:`.newmark_events` (:class:`~.newmark_events.NewmarkEventsMixin`, with how they differ
from the exact kernel); this module steps the model between events.

Energy ledger: impact and lock losses are exact from the law. Damping dissipation, forcing
work and circulatory work use the trapezoidal means of the step-end quantities
(``h v.C v`` with ``v = (v0 + v1)/2`` and so on): O(dt^2) approximations of the true
integrals that match the scheme's own discrete energy balance, so the ledger residual is
round-off, not O(dt^2).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..dampers.law import IMPACT_LAWS
from ..modal.basis import lanczos_start
from .base import IntegratorBase
from .events import EVENT_DTYPE, Samples
from .kernels import newmark_step as kernels
from .newmark_config import StuckConfiguration
from .newmark_events import NewmarkEventsMixin

if TYPE_CHECKING:
    from .forcing import Forcing
    from .model import LinearModel

FloatArray = npt.NDArray[np.float64]

IMPACT_MODES = ('located', 'step_end')
SOLVERS = ('auto', 'dense', 'sparse')
#: internal steps per chunk of precomputed inputs (bounds memory on long runs)
_CHUNK = 1 << 16
#: above this many coordinates 'auto' may choose the sparse solver
_SPARSE_MIN_N = 400
#: Newmark steps per period of the highest retained mode at least, with impactors: event
#: location works on the cubic Hermite gap of the step ends, and the textbook bound T/10
#: keeps the highest mode's period elongation ((omega h)^2/12) under 3.3 %; longer steps
#: detune resonances and miss impacts (an SDOF at resonance with zeta = 0.02 loses every
#: impact at T/6.3; ``test/test_extremes.py``)
MIN_STEPS_PER_PERIOD = 10


class StepTooLarge(ValueError):
    """A Newmark step too long to track impacts (at most 1/``MIN_STEPS_PER_PERIOD`` of the
    period of the highest retained mode).

    Parameters
    ----------
    dt : float
        The requested time step (s).
    h : float
        The Newmark step it gives (s).
    h_max : float
        The longest step that tracks impacts (s).
    f_max : float
        The highest retained mode (Hz).
    """

    def __init__(self, dt: float, h: float, h_max: float, f_max: float) -> None:
        self.dt, self.h, self.h_max, self.f_max = dt, h, h_max, f_max
        super().__init__(self.text('dt'))

    def text(self, step_name: str) -> str:
        """The message, naming the time step as the caller's user sets it (``step_name``,
        e.g. a scene key)."""
        return (f'{step_name} = {self.dt:.4g} s (Newmark step {self.h:.4g} s) is too large '
                f'to track impacts: it must be at most 1/{MIN_STEPS_PER_PERIOD} of the period '
                f'of the highest retained mode ({self.f_max:.5g} Hz), {self.h_max:.4g} s; '
                f'lower {step_name}, retain fewer modes, or use method exact')


def _omega_max(M: FloatArray, C: FloatArray, K: FloatArray, sparse: bool) -> float:
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
                        v0=lanczos_start(n), return_eigenvectors=False)[0]   # same bits
    else:
        w2 = sla.eigh(K_sym, M, eigvals_only=True, subset_by_index=[n - 1, n - 1])[0]
    return float(np.sqrt(max(w2, 0.0)))


class NewmarkIntegrator(NewmarkEventsMixin, IntegratorBase):
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

    def __init__(self, model: LinearModel, forcing: Forcing, dt: float, *,
                 impacts: str = 'located', law: str = 'effective_mass', stick_rule: str = 'paper',
                 stick_fraction: float = 0.002, max_events_per_step: int = 64,
                 ledger: bool = True, q0: npt.ArrayLike | None = None,
                 qd0: npt.ArrayLike | None = None, t0: float = 0.0, substeps: int = 1,
                 solver: str = 'auto', stick_time: float | None = None) -> None:
        super().__init__(model, forcing, dt, law=law, stick_rule=stick_rule,
                         stick_fraction=stick_fraction, max_events_per_step=max_events_per_step,
                         ledger=ledger, t0=t0)
        if impacts not in IMPACT_MODES:
            raise ValueError(f'impacts must be one of {IMPACT_MODES}, got {impacts!r}')
        if law not in IMPACT_LAWS:
            raise ValueError(f'law must be one of {IMPACT_LAWS}, got {law!r}')
        if int(substeps) != substeps or substeps < 1:
            raise ValueError(f'substeps must be an integer >= 1, got {substeps}')
        if int(max_events_per_step) < 1:
            raise ValueError(f'max_events_per_step must be >= 1, got {max_events_per_step}')
        if solver not in SOLVERS:
            raise ValueError(f'solver must be one of {SOLVERS}, got {solver!r}')
        self.substeps = int(substeps)
        self.h = self.dt / self.substeps
        self.impacts = impacts
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
        self._configs: dict[tuple[int, ...], StuckConfiguration] = {}
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
            raise StepTooLarge(self.dt, self.h, period / MIN_STEPS_PER_PERIOD, 1.0 / period)
        self._q = np.zeros(n) if q0 is None else np.array(q0, dtype=float).reshape(n)
        self._v = np.zeros(n) if qd0 is None else np.array(qd0, dtype=float).reshape(n)
        self._f = self._force_at(self.t)
        self._a = self._accel(self._config(), self._f)
        self._place_impactors(self._q)
        self._count = np.zeros(ni, dtype=np.int64)
        self._count_index = -1
        # just released: the wall it leaves is shifted out by 1e-9 of the clearance until
        # the next step of non-zero length, as the exact kernel's grace, so that a release
        # at a vanishing contact force cannot be undone by round-off at the same instant
        self._grace = np.zeros(ni, dtype=bool)
        self._out_done = 0            # output steps completed since t0
        self._info = np.zeros(2, dtype=np.int64)   # grazing_undecided stays 0: no scan here
        self._start_ledger()

    # -- configuration and dynamics ----------------------------------------------------------
    def _config(self) -> StuckConfiguration:
        key = tuple(int(s) for s in self._stuck)
        cfg = self._configs.get(key)
        if cfg is None:
            masses = [float(m) if s else 0.0 for m, s in zip(self._imp_mass, self._stuck)]
            cfg = StuckConfiguration(self.model, self._rows, masses, self.law, self._sparse,
                                     self._C, self._K)
            self._configs[key] = cfg
        return cfg

    def _force_at(self, t: float) -> FloatArray:
        return self._B @ self.forcing.evaluate(t)[0]

    def _accel(self, cfg: StuckConfiguration, f: FloatArray) -> FloatArray:
        return cfg.solve_M(f - self._C @ self._v - self._K @ self._q)

    def _trial(self, cfg: StuckConfiguration, h: float, f1: FloatArray, cached: bool
               ) -> tuple[FloatArray, FloatArray, FloatArray]:
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

    def _commit(self, h: float, f1: FloatArray, q1: FloatArray, v1: FloatArray,
                a1: FloatArray) -> None:
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
    def state(self) -> tuple[FloatArray, FloatArray]:
        """Return ``(q, qd)``: coordinates and their velocities now (copies)."""
        return self._q.copy(), self._v.copy()

    def _housing_rows(self) -> list[FloatArray]:
        return [self._rows[j, :d] for j, d in enumerate(self._imp_dim)]

    def _structure_energy(self, q: FloatArray, qd: FloatArray) -> float:
        return 0.5 * float(qd @ (self.model.M @ qd)) + 0.5 * float(q @ (self._K_sym @ q))

    def take_events(self) -> np.ndarray:
        """Return the events recorded since the last call (see ``EVENT_DTYPE``) and clear."""
        out = np.array(self._events, dtype=EVENT_DTYPE) if self._events \
            else np.zeros(0, dtype=EVENT_DTYPE)
        self._events = []
        return out

    # -- stepping ----------------------------------------------------------------------------
    def _time(self, t_base: float, k: np.ndarray) -> FloatArray:
        """Time (s) of internal step end ``k``; output instants are exactly ``t_base + i dt``."""
        return t_base + (k // self.substeps) * self.dt + (k % self.substeps) * self.h

    def advance(self, n_steps: int) -> Samples:
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

    def _run(self, k: int, k_stop: int, k0: int, u_grid: FloatArray,
             outs: tuple[FloatArray, ...]) -> tuple[int, int]:
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

    def _step_end_step(self, t_b: float, u_b: FloatArray) -> None:
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

    def _located_step(self, t_a: float, t_b: float, u_b: FloatArray) -> None:

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
                assert nrm is not None   # an event (j >= 0) has its normal
                self._contact(j, t, nrm, project=True)

        raise RuntimeError(f'chatter not resolved at t = {t:.6g} s: more than {cap} events in '
                           f'one step of {self.h:.3g} s')
