"""The contract every integrator of a run fulfils, and the bookkeeping they share.

:class:`IntegratorBase` states what :class:`~impact_damper_sim.integrate.simulation.Simulation`
and the studies rely on (its docstring), sets every shared attribute in its ``__init__`` and
declares the methods a subclass must implement (``abc.abstractmethod``: a subclass missing
one cannot be instantiated). It implements what follows from them: impactor states, the
energy ledger and switching the impact dampers off and on during a run.
"""
from __future__ import annotations

import abc
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from .events import STICK_RULES, EnergyLedger, Samples

if TYPE_CHECKING:
    from .forcing import Forcing
    from .model import LinearModel

FloatArray = npt.NDArray[np.float64]

#: Half-travel given to disabled impactors (m): larger than any structural motion, so they
#: fly free and never reach a wall (1e6 m also keeps the planar gap ``L^2 - r^2`` well scaled).
DISABLED_LIMIT = 1.0e6


class IntegratorBase(abc.ABC):
    """An integrator of a :class:`~.model.LinearModel` with impactors, advanced by ``dt``.

    Parameters
    ----------
    model : LinearModel
        Model with its impactors (modal or physical coordinates).
    forcing : Forcing
        External forcing on the model's inputs (N); ``forcing.n_inputs == model.n_inputs``.
    dt : float
        Output step (s), positive and finite.
    law : str
        Impact law (see :mod:`impact_damper_sim.dampers.law`).
    stick_rule : {'paper', 'accumulation', 'none'}
        When a bounce-down becomes the stuck state.
    stick_fraction : float
        Fraction of the period of the highest mode giving the sticking time
        (dimensionless, in (0, 1)).
    max_events_per_step : int
        Impacts of one impactor in one output step after which it is made to stick.
    ledger : bool
        Integrate damping dissipation, forcing and circulatory work.
    t0 : float
        Initial time (s).

    Notes
    -----
    Set here, read by the shared methods and by callers (subclasses update them):

    * ``model``, ``forcing``, ``dt`` (s), ``law``, ``stick_rule``, ``max_events_per_step``,
      ``ledger_on``; ``t``, the current time (s); ``stick_time`` (s), the sticking time of
      the rules: ``None`` here, a subclass sets it from its model's highest mode;
    * per impactor ``j`` (arrays over ``model.impactors``): ``_imp_dim`` (1 or 2),
      ``_imp_mass`` (kg), ``_imp_cor``, ``_imp_limit`` (half-travel, m), ``_stuck[j]`` (1
      while it rides its housing), ``_imp_z``/``_imp_v`` (absolute position and velocity in
      free flight, m and m/s; :meth:`_place_impactors` puts them at their housing),
      ``_imp_rel`` (position relative to the housing while stuck, m), ``_imp_normal`` (the
      wall normal of its last contact), ``_imp_last_t`` (time of its last event, s);
    * ``_ledger``: dissipated by impacts, by sticking, by damping; work of forcing and of
      the circulatory stiffness (J); ``_initial_energy`` (J), set by :meth:`_start_ledger`
      once the subclass's state is ready;
    * ``_events``: the events recorded since the last :meth:`take_events`;
    * ``max_impacts_per_step`` and ``grazing_undecided`` (counts); ``n_config_changes``,
      the changes of configuration so far (a property over ``_config_changes``);
    * ``impacts_enabled``: see :meth:`set_impacts_enabled`.

    A subclass calls ``super().__init__(...)`` first, then builds its own state, calls
    :meth:`_place_impactors` and :meth:`_start_ledger`, and implements :meth:`state`,
    :meth:`advance`, :meth:`take_events`, :meth:`_housing_rows`, :meth:`_structure_energy`
    and :meth:`_release_now`.
    """

    def __init__(self, model: LinearModel, forcing: Forcing, dt: float, *, law: str,
                 stick_rule: str, stick_fraction: float, max_events_per_step: int,
                 ledger: bool, t0: float) -> None:
        if not (np.isfinite(dt) and dt > 0):
            raise ValueError(f'dt must be a positive time in s, got {dt}')
        if stick_rule not in STICK_RULES:
            raise ValueError(f'stick_rule must be one of {STICK_RULES}, got {stick_rule!r}')
        if not (0 < stick_fraction < 1):
            raise ValueError(f'stick_fraction must be in (0, 1), got {stick_fraction}')
        if forcing.n_inputs != model.n_inputs:
            raise ValueError(f'forcing has {forcing.n_inputs} inputs, model has {model.n_inputs}')
        self.model = model
        self.forcing = forcing
        self.dt = float(dt)
        self.law = law
        self.stick_rule = stick_rule
        self.max_events_per_step = int(max_events_per_step)
        self.ledger_on = bool(ledger)
        self.t = float(t0)
        self.stick_time: float | None = None
        impactors = model.impactors
        ni = len(impactors)
        self._imp_dim = np.array([imp.dim for imp in impactors], dtype=np.int64)
        self._imp_mass = np.array([imp.mass for imp in impactors], dtype=float)
        self._imp_cor = np.array([imp.cor for imp in impactors], dtype=float)
        self._imp_limit = np.array([imp.limit for imp in impactors], dtype=float)
        self._limits_enabled = self._imp_limit.copy()
        self._stuck = np.zeros(ni, dtype=np.int64)
        self._imp_z = np.zeros((ni, 2))
        self._imp_v = np.zeros((ni, 2))
        self._imp_rel = np.zeros((ni, 2))
        self._imp_normal = np.zeros((ni, 2))
        self._imp_last_t = np.full(ni, -np.inf)
        self._ledger = np.zeros(5)
        self._initial_energy = 0.0
        # exact: arrays of EVENT_DTYPE; Newmark: one record tuple per event
        self._events: list[Any] = []
        self._config_changes = 0
        self.max_impacts_per_step = 0
        self.grazing_undecided = 0
        self.impacts_enabled = True

    def _place_impactors(self, q: FloatArray) -> None:
        """Put every impactor at its housing plus its initial offset, with its initial
        velocity, for coordinates ``q`` of the model."""
        for j, imp in enumerate(self.model.impactors):
            assert imp.position is not None   # an array after Impactor.__post_init__
            self._imp_z[j, :imp.dim] = imp.rows @ q + imp.position

            self._imp_v[j, :imp.dim] = imp.velocity

    def _start_ledger(self) -> None:
        """Take the energy now as the ledger's initial energy (J)."""
        self._initial_energy = sum(self._energy_now())

    @property
    def n_config_changes(self) -> int:
        """int: Changes of configuration so far (stick and release; dimensionless)."""
        return self._config_changes

    # -- what a subclass implements --------------------------------------------------------
    @abc.abstractmethod
    def state(self) -> tuple[FloatArray, FloatArray]:
        """Return ``(q, qd)``: coordinates and their velocities now (copies)."""

    @abc.abstractmethod
    def advance(self, n_steps: int) -> Samples:
        """Advance ``n_steps`` output steps of ``dt`` and return their
        :class:`~.events.Samples` (sensor outputs at the end of each step)."""

    @abc.abstractmethod
    def take_events(self) -> np.ndarray:
        """Return the events recorded since the last call (``EVENT_DTYPE``) and clear."""

    @abc.abstractmethod
    def _housing_rows(self) -> list[FloatArray]:
        """Housing rows of each impactor in the current coordinates (list of arrays)."""

    @abc.abstractmethod
    def _structure_energy(self, q: FloatArray, qd: FloatArray) -> float:
        """Kinetic plus potential energy of the structure alone (J)."""

    @abc.abstractmethod
    def _release_now(self, j: int) -> None:
        """Release stuck impactor ``j`` at the current time with its housing's velocity."""

    # -- what follows from them ------------------------------------------------------------
    def set_impacts_enabled(self, enabled: bool) -> None:
        """Switch the impact dampers on or off during a run.

        Off: stuck impactors are released with their housing's velocity and every impactor
        flies free without walls (it no longer acts on the structure; its mass stays off the
        structure, as in a free flight). On: each impactor is put back at its housing centre,
        moving with the housing, and impacts resume. Both switches change no structural
        state, so the response is continuous. The impactors' kinetic-energy change when they
        are put back is added to the ledger's ``initial`` energy (it is not physics).

        Parameters
        ----------
        enabled : bool
            True to enable impacts (dimensionless).
        """
        enabled = bool(enabled)
        if enabled == self.impacts_enabled:
            return
        if not enabled:
            for index in np.flatnonzero(self._stuck):
                self._release_now(int(index))
            self._limits_enabled = self._imp_limit.copy()
            self._imp_limit[:] = DISABLED_LIMIT
        else:
            before = self._energy_now()[1]
            q, qd = self.state()
            for j, R in enumerate(self._housing_rows()):
                d = R.shape[0]
                self._imp_z[j, :d] = R @ q
                self._imp_v[j, :d] = R @ qd
            self._imp_last_t[:] = -np.inf
            self._imp_limit[:] = self._limits_enabled
            # putting the impactors back is not physics: book its kinetic-energy change as
            # a new reference so that the ledger keeps balancing
            self._initial_energy += self._energy_now()[1] - before
        self.impacts_enabled = enabled

    def impactor_states(self) -> tuple[FloatArray, FloatArray, npt.NDArray[np.bool_]]:
        """Return relative positions (m), absolute velocities (m/s) and stuck flags.

        Returns
        -------
        rel : ndarray, shape (n_i, 2)
            ``z - x_h`` (m); SDOF impactors use column 0.
        vel : ndarray, shape (n_i, 2)
            Absolute impactor velocity (m/s).
        stuck : ndarray of bool, shape (n_i,)
            True while the impactor rides its housing.
        """
        q, qd = self.state()
        rows = self._housing_rows()
        rel = np.zeros((len(rows), 2))
        vel = np.zeros((len(rows), 2))
        for j, R in enumerate(rows):
            d = R.shape[0]
            if self._stuck[j]:
                rel[j, :d] = self._imp_rel[j, :d]
                vel[j, :d] = R @ qd
            else:
                rel[j, :d] = self._imp_z[j, :d] - R @ q
                vel[j, :d] = self._imp_v[j, :d]
        return rel, vel, self._stuck.astype(bool)

    def _energy_now(self) -> tuple[float, float]:
        q, qd = self.state()
        _, vel, _ = self.impactor_states()
        impactors = 0.5 * float(np.sum(self._imp_mass * np.sum(vel * vel, axis=1)))
        return self._structure_energy(q, qd), impactors

    def energy(self) -> EnergyLedger:

        """Return the :class:`~.events.EnergyLedger` now (J)."""
        structure, impactors = self._energy_now()
        led = self._ledger
        return EnergyLedger(structure, impactors, led[0], led[1], led[2], led[3], led[4],
                            self._initial_energy)
