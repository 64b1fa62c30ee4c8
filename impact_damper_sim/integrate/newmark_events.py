"""Event handling of the Newmark integrator: where an event lies inside a step, and what it does.

:class:`NewmarkEventsMixin` finds the first event of a step (a gap's crossing on the cubic
Hermite interpolant of the step ends, a release on the re-stepped contact force) and applies
it (the impact law, sticking and the plastic lock, release, the event records). It is separate
from :mod:`.newmark` because it is the impact physics and its root finding, not the stepping:
a mixin of :class:`~impact_damper_sim.integrate.newmark.NewmarkIntegrator` only, it keeps no
state of its own and works on the integrator's (``_q``, ``_v``, ``_a``, ``_rows``,
``_imp_*``, ``_stuck``, ``_grace``, ``_count``, ``_ledger``, ``_events``) through its
``_config``, ``_trial``, ``_force_at`` and ``_accel``.

Impact law, sticking and release mirror the exact kernels (:mod:`.kernels.contact`,
:func:`.kernels.event_loop.advance`): the effective-mass (or lumped) law with the impulse applied
through the model (``qd += M^{-1} R^T P``), the paper's or the accumulation sticking rule, the
cap on impacts per output step, the plastic lock at stick entry, the stuck state (impactor
mass added to the housing rows, ``M + m R^T R``) and release when the normal contact force
reaches zero (``step_end``: sign test at step ends; ``located``: linear interpolation of the
force inside the step, refined by regula falsi on re-steps so that the released state has a
non-compressive force). Differences from the exact kernel:

* a stuck planar impactor's release force is that of a frictionless normal contact,
  ``-n . (I - m G_s)^{-1} a_h`` (see :func:`.kernels.newmark_step.release_force`), which has the
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
"""
from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from .events import EVENT_KINDS
from .kernels import newmark_step as kernels

if TYPE_CHECKING:
    from .base import IntegratorBase as _Integrator
    from .newmark_config import StuckConfiguration
else:
    _Integrator = object

FloatArray = npt.NDArray[np.float64]
#: a gap or force polynomial's coefficients, ascending
Coefficients = Sequence[float] | FloatArray

_EV_IMPACT = EVENT_KINDS.index('impact')
_EV_STICK = EVENT_KINDS.index('stick')
_EV_RELEASE = EVENT_KINDS.index('release')
_EPS = np.finfo(float).eps


def _poly_eval(p: Coefficients, s: float) -> float:
    acc = 0.0
    for c in p[::-1]:
        acc = acc * s + c
    return acc


def _first_crossing(p: Coefficients, H: float, tol: float) -> float | None:
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


def _quadratic_roots(a: float, b: float, c: float) -> list[float]:
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


def _refine(p: Coefficients, a: float, b: float, fa: float, fb: float, tol: float) -> float:
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


class NewmarkEventsMixin(_Integrator):
    """Event location and impact physics of
    :class:`~impact_damper_sim.integrate.newmark.NewmarkIntegrator` (a mixin of that
    integrator; no state of its own)."""

    if TYPE_CHECKING:   # the integrator's state and steps it works on (for mypy only)
        _q: FloatArray
        _v: FloatArray
        _a: FloatArray
        _f: FloatArray
        _rows: FloatArray
        _grace: npt.NDArray[np.bool_]
        _count: npt.NDArray[np.int64]

        def _config(self) -> StuckConfiguration: ...

        def _force_at(self, t: float) -> FloatArray: ...

        def _accel(self, cfg: StuckConfiguration, f: FloatArray) -> FloatArray: ...

        def _trial(self, cfg: StuckConfiguration, h: float, f1: FloatArray, cached: bool
                   ) -> tuple[FloatArray, FloatArray, FloatArray]: ...

    # -- event location ----------------------------------------------------------------------
    def _find_event(self, t: float, H: float, q1: FloatArray,
                    v1: FloatArray, a1: FloatArray) -> tuple[float, int, FloatArray | None]:
        """Earliest event in ``[0, H]`` from the current state and the trial step end.

        Returns ``(tau, impactor, normal)``; ``impactor = -1`` when there is none.
        """
        best, best_j = H, -1
        best_n: FloatArray | None = None
        tau: float | None
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

    def _release_time(self, cfg: StuckConfiguration, t: float, tau: float, H: float,
                      f_b: FloatArray, q1: FloatArray, v1: FloatArray, a1: FloatArray, j: int
                      ) -> tuple[float, tuple[FloatArray, FloatArray, FloatArray, FloatArray]]:
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
    def _gap_event(g: FloatArray, g2: float | FloatArray, H: float, tol: float
                   ) -> float | None:

        """Event time of one gap polynomial ``g`` (ascending) in ``[0, H]``, or None.

        ``s = 0`` is an event when the gap starts closed and moving in (``g' < 0``, or
        ``g' = 0`` with ``g'' < 0``); a tangential rest (``g' = g'' = 0``) is not.
        """
        if g[0] <= 0.0 and (g[1] < 0.0 or (g[1] == 0.0 and g2 < 0.0)):
            return 0.0
        return _first_crossing(g, H, tol)

    # -- events ------------------------------------------------------------------------------
    def _record(self, t: float, j: int, kind: int, nrm: FloatArray,
                v_n: float, J: float, loss: float, v_after: float, vh_jump: float) -> None:
        self._events.append((t, j, kind, (nrm[0], nrm[1]), v_n, J, loss, v_after, vh_jump))

    def _count_event(self, j: int, t: float) -> None:
        """Count an event of impactor ``j`` in this output step; bounded as in the kernel."""
        self._count[j] += 1
        if self._count[j] > 4 * self.max_events_per_step + 16:
            raise RuntimeError(f'chatter not resolved at t = {t:.6g} s for impactor '
                               f'{self.model.impactors[j].name!r}')

    def _contact(self, j: int, t: float, nrm: FloatArray,
                 project: bool) -> None:
        """Contact of impactor ``j`` with its wall at ``t``: impact, then maybe the lock.

        Mirrors :func:`.kernels.contact.impact_py`; ``nrm`` is the outward wall normal (the
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
            # what the impulse takes out of impactor and model (see kernels.contact.impact_py)
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
            # the housing's velocity (see kernels.contact.impact_py)
            w = self._imp_v[j, :d] - vh_l
            lock_loss = 0.5 * float(vr @ P + P @ (G - G_model) @ P
                                    + m_i * (w @ (self._imp_v[j, :d] + vh_l)))
            self._ledger[1] += lock_loss
            self._record(t, j, _EV_STICK, nrm, float(n_ @ vr), float(np.sqrt(P @ P)), lock_loss,
                         float(n_ @ (self._imp_v[j, :d] - vh_l)), float(n_ @ (vh_l - vh)))
            self._config_changes += 1
        elif project:
            self._imp_z[j, :d] = R @ self._q + n_ * L
        self._a = self._accel(self._config(), self._f)

    def _release_force(self, j: int, a: FloatArray) -> float:
        """Normal contact force per unit mass of stuck impactor ``j`` for accelerations ``a``."""
        return kernels.release_force(self._rows[j], self._imp_dim[j], self._config().rel_T[j],
                                     self._imp_normal[j], a)

    def _release_now(self, j: int) -> None:
        self._release(j, self.t)

    def _release(self, j: int, t: float) -> None:

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
        self._config_changes += 1
        self._a = self._accel(self._config(), self._f)
