"""The exact, piecewise-exact modal propagator with event-located impacts.

Between events the model flows exactly (see :mod:`.flow`); impacts are located by bracketed
root finding on the gap functions with a grazing guard (see :mod:`.kernels`). A stuck
impactor adds its mass to the housing rows of the *same* coordinates (a rank-one or rank-two
mass update), so switching between free and stuck loses nothing: the coordinates and their
velocities are continuous across the switch. The paper's alternative, a second modal basis,
is :class:`~.basis_switch.BasisSwitch`.
"""
from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Protocol, cast

import numpy as np
import numpy.typing as npt

from .base import IntegratorBase
from .events import EVENT_DTYPE, Samples
from .flow import FlowConfig, build_flow
from .kernels import event_loop as kernels
from .kernels import flow_eval as flow_kernels
from .kernels import ledger as ledger_kernels
from .kernels.prefetch import prefetch
from .kernels.quadrature import phi1_real
from .memory import (
    MAX_CACHED_CONFIGURATIONS,
    MAX_TABLE_BYTES,
    MAX_TABLE_SLOTS,
    cache_limit,
    configuration_bytes,
)

if TYPE_CHECKING:
    from .forcing import Forcing
    from .model import LinearModel

FloatArray = npt.NDArray[np.float64]
#: stuck flags (one 0/1 per impactor), or a table's stuck counts per group
Key = tuple[int, ...]


class Configurations(Protocol):
    """What an ``ExactPropagator``'s ``configurations`` provides (:class:`MassUpdate`,
    :class:`~.basis_switch.BasisSwitch`); see :class:`MassUpdate`."""

    def model(self, stuck: Key) -> (tuple[LinearModel, Sequence[float]]
                                    | tuple[LinearModel, Sequence[float], Sequence[float]]):
        ...

    def transform(self, stuck_from: Key, stuck_to: Key) -> FloatArray | None:
        ...

    def structure_energy(self, stuck: Key, q: FloatArray, qd: FloatArray) -> float:
        ...


class MassUpdate:
    """Stuck impactors add their mass to the housing rows of the free coordinates.

    The configuration-provider interface of :class:`ExactPropagator`:

    * ``model(stuck)`` returns ``(LinearModel, stuck_masses)`` for a tuple of stuck flags:
      the model whose coordinates the flow uses and the masses to add to its housing rows; a
      third item, the masses its coordinates already carry (kg), may follow;
    * ``transform(stuck_from, stuck_to)`` returns the matrix mapping coordinates (and
      velocities) of one configuration to the other, or ``None`` for the identity;
    * ``structure_energy(stuck, q, qd)`` returns the kinetic plus potential energy of the
      structure alone (J), without the stuck impactors' kinetic energy.

    Here the coordinates never change, so switching is exact (no loss).
    """

    def __init__(self, model: LinearModel) -> None:
        self.base = model
        self._K_sym = model.K_sym

    def model(self, stuck: Key) -> tuple[LinearModel, tuple[float, ...]]:
        masses = tuple(imp.mass if s else 0.0 for imp, s in zip(self.base.impactors, stuck))
        return self.base, masses

    def transform(self, stuck_from: Key, stuck_to: Key) -> None:
        return None

    def structure_energy(self, stuck: Key, q: FloatArray, qd: FloatArray) -> float:
        return 0.5 * qd @ self.base.M @ qd + 0.5 * q @ self._K_sym @ q


_RULE_CODES = {'paper': kernels.STICK_PAPER, 'accumulation': kernels.STICK_ACCUMULATION,
               'none': kernels.STICK_NONE}

# MAX_TABLE_SLOTS and MAX_TABLE_BYTES (the largest table of configurations inside the
# kernel; a scene with more, e.g. many impactors on distinct housings, switches through
# Python) and the configurations kept when switching through Python (cache_limit,
# MAX_CACHED_CONFIGURATIONS) are memory budgets, stated with the others in
# impact_damper_sim.integrate.memory.
#: Largest table whose configurations are all built when the engine is made (0.5 to 1 ms
#: each at 10 modes): the event loop then never returns to Python to build one, and a live
#: node never stalls for a build in the middle of a run. Larger tables build on first use.
PREBUILD_SLOTS = 64
#: Degree of the Taylor models of the event search (see :mod:`.kernels.search`).
TAYLOR_ORDER = 6
#: Whether the fields ExactPropagator.advance writes cover every byte of an event record
_EVENT_FIELDS: bool = (EVENT_DTYPE.names == ('t', 'impactor', 'kind', 'normal', 'v_n',
                                             'impulse', 'loss', 'v_n_after', 'v_h_jump')
                       and EVENT_DTYPE.itemsize == sum(   # no padding between them
                           EVENT_DTYPE[name].itemsize for name in EVENT_DTYPE.names or ()))
#: Stuck-flag patterns whose configuration key is remembered (:meth:`ExactPropagator._key`).
_MAX_KEYS = 4096


def _interchangeable_groups(model: LinearModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Housing sites and interchangeable groups of the model's impactors.

    Returns ``rep`` (per impactor, the first impactor with the same housing rows: they share
    the housing kinematics), ``group`` (per impactor, its group of equal rows and mass: their
    stuck masses are interchangeable in the mass matrix) and the group sizes.
    """
    imps = model.impactors
    rep = np.arange(len(imps), dtype=np.int64)
    group = np.zeros(len(imps), dtype=np.int64)
    keys: dict[tuple[int, float], int] = {}
    # equal rows -> first impactor: linear in the impactors, not quadratic
    sites: dict[tuple[int, tuple[int, ...], bytes], int] = {}
    for j, imp in enumerate(imps):
        rows = np.asarray(imp.rows, dtype=float) + 0.0   # -0.0 as 0.0, like array_equal
        rep[j] = sites.setdefault((imp.dim, rows.shape, rows.tobytes()), j)
        group[j] = keys.setdefault((int(rep[j]), float(imp.mass)), len(keys))
    sizes = np.bincount(group, minlength=len(keys)) if len(imps) else np.zeros(0, np.int64)
    return rep, group, sizes


class _Table:
    """Flow arrays of several configurations, stacked for the kernel (slot = first index)."""

    FIELDS = ('lam', 'V', 'Vinv', 'W', 'part_plus', 'part_minus', 'sensor_q', 'sensor_v',
              'house_q', 'kick', 'house_mobility', 'mobility', 'release_map')

    def __init__(self, n_slots: int, flow: FlowConfig, dt: float, ledger_on: bool, n_q: int,
                 k_skew: FloatArray) -> None:
        self.dt = dt
        self.ledger_on = ledger_on
        self.built = np.zeros(n_slots, dtype=np.int64)
        self.arrays = {name: np.zeros((n_slots,) + getattr(flow, name).shape,
                                      dtype=getattr(flow, name).dtype) for name in self.FIELDS}
        self.house_abs = np.zeros((n_slots,) + flow.house_q.shape)
        n2 = flow.lam.size
        self.lam_max = np.zeros(n_slots)
        self.e_h, self.p1_h, self.p2_h = (np.zeros((n_slots, n2), complex) for _ in range(3))
        self.m_h = np.zeros((n_slots, n2 if ledger_on else 0))   # int |e^(lam s)|^2 over dt
        # skew stiffness, for the ledger's circulatory work
        self.k_skew = k_skew if ledger_on and np.any(k_skew) else None
        # the ledger's dense rows, transposed (ledger_kernels.rows_transposed)
        self.vt = np.zeros((n_slots, 4, n2, n_q) if ledger_on else (n_slots, 4, 0, 0))
        self.q_cols = np.zeros((n_slots, n_q, n2), dtype=np.int64)
        self.q_counts = np.zeros((n_slots, n_q), dtype=np.int64)
        self.v_cols = np.zeros((n_slots, n_q, n2), dtype=np.int64)
        self.v_counts = np.zeros((n_slots, n_q), dtype=np.int64)
        self.v_modal = np.zeros(n_slots, dtype=np.bool_)   # one coordinate per velocity row
        self._args: dict[int, tuple[np.ndarray, ...]] = {}

    def fill(self, slot: int, flow: FlowConfig) -> None:
        """Store configuration ``flow`` (a :class:`~.flow.FlowConfig`) in ``slot``."""
        for name in self.FIELDS:
            self.arrays[name][slot] = getattr(flow, name)
        self.house_abs[slot] = np.abs(flow.house_q)
        lam = flow.lam
        self.lam_max[slot] = float(np.max(np.abs(lam))) if lam.size else 0.0
        flow_kernels.step_factors(lam, self.dt, self.e_h[slot], self.p1_h[slot],
                                    self.p2_h[slot])
        if self.ledger_on:
            n = flow.V.shape[0] // 2
            ledger_kernels.row_pattern(flow.V[:n], self.q_cols[slot], self.q_counts[slot])
            ledger_kernels.row_pattern(flow.V[n:], self.v_cols[slot], self.v_counts[slot])
            self.v_modal[slot] = bool(np.all(self.v_counts[slot] == 1))
            for k in range(lam.size):   # int |e^(lam s)|^2 over a step, as piece_factors
                self.m_h[slot, k] = self.dt * phi1_real(2.0 * lam[k].real * self.dt)
            kvq = self.k_skew @ flow.V[:n] if self.k_skew is not None else None
            self.vt[slot] = ledger_kernels.rows_transposed(flow.V[n:], kvq)
        self.built[slot] = 1

    def kernel_args(self, ni: int) -> tuple[np.ndarray, ...]:
        """The ``tb_*`` arguments of :func:`.kernels.event_loop.advance` (impactors ``[:ni]``):
        views of arrays that :meth:`fill` writes in place, so made once per ``ni``."""
        args = self._args.get(ni)
        if args is None:
            args = self._args[ni] = self._kernel_args(ni)
        return args

    def _kernel_args(self, ni: int) -> tuple[np.ndarray, ...]:
        a = self.arrays
        return (self.built, a['lam'], self.lam_max, a['V'], a['Vinv'], a['W'], a['part_plus'],
                a['part_minus'], a['sensor_q'], a['sensor_v'], a['house_q'][:, :ni],
                self.house_abs[:, :ni], a['kick'][:, :ni], a['house_mobility'][:, :ni],
                a['mobility'][:, :ni],
                a['release_map'][:, :ni], self.e_h, self.p1_h, self.p2_h, self.m_h, self.vt,
                self.q_cols, self.q_counts, self.v_cols, self.v_counts, self.v_modal)


class ExactPropagator(IntegratorBase):
    """Exact flow of a :class:`~.model.LinearModel` with impactors.

    Parameters
    ----------
    model : LinearModel
        Model with its impactors (modal coordinates, normally).
    forcing : Forcing
        External forcing on the model's inputs.
    dt : float
        Output step (s): sensor samples are taken every ``dt`` and sampled forcing is held
        linearly between steps. Accuracy does not depend on ``dt`` otherwise.
    law : {'effective_mass', 'lumped_mass'}
        Impact law (see :mod:`impact_damper_sim.dampers.law`).
    stick_rule : {'paper', 'accumulation', 'none'}
        When a bounce-down becomes the stuck state.
    stick_fraction : float
        Paper's rule: a second impact on the same wall within this fraction of the period of
        the highest retained mode (dimensionless); default 0.002. The accumulation rule uses
        the same time threshold for the predicted time to the accumulation point.
    max_events_per_step : int
        Impacts of one impactor in one step after which it is made to stick.
    ledger : bool
        Integrate damping dissipation, forcing and circulatory work (costs time).
    q0, qd0 : ndarray, optional
        Initial coordinates and velocities.
    t0 : float
        Initial time (s).
    event_capacity : int
        Size of the event buffer flushed between kernel calls.
    configurations : object, optional
        How stuck impactors change the model: :class:`MassUpdate` (default, exact) or the
        paper's second modal basis, :class:`~.basis_switch.BasisSwitch`. ``q0``/``qd0`` are
        coordinates of the all-free configuration.
    taylor_order : int
        Degree of the Taylor models of the event search (dimensionless, 2 to 12); a speed
        setting only, the events found do not depend on it.
    """

    def __init__(self, model: LinearModel, forcing: Forcing, dt: float, *,
                 law: str = 'effective_mass', stick_rule: str = 'paper',
                 stick_fraction: float = 0.002, max_events_per_step: int = 64,
                 ledger: bool = True, q0: npt.ArrayLike | None = None,
                 qd0: npt.ArrayLike | None = None, t0: float = 0.0, event_capacity: int = 4096,
                 configurations: Configurations | None = None,
                 taylor_order: int = TAYLOR_ORDER) -> None:
        super().__init__(model, forcing, dt, law=law, stick_rule=stick_rule,
                         stick_fraction=stick_fraction, max_events_per_step=max_events_per_step,
                         ledger=ledger, t0=t0)
        if int(taylor_order) != taylor_order or not 2 <= taylor_order <= 12:
            raise ValueError(f'taylor_order must be an integer in [2, 12], got {taylor_order}')
        if len(model.impactors):   # a cold cache compiles the event search while the rest is set up
            prefetch()
        self.configurations: Configurations = (MassUpdate(model) if configurations is None
                                               else configurations)
        self.taylor_order = int(taylor_order)
        self._omegas, self._amps = forcing.harmonic_table()
        n = model.n
        ni = len(model.impactors)
        q = np.zeros(n) if q0 is None else np.asarray(q0, dtype=float).copy()
        qd = np.zeros(n) if qd0 is None else np.asarray(qd0, dtype=float).copy()
        self._imp_rep, self._imp_group, sizes = _interchangeable_groups(model)
        self._radix = np.cumprod(np.concatenate([[1], sizes[:-1] + 1])).astype(np.int64) \
            if sizes.size else np.zeros(0, np.int64)
        n_keys = int(np.prod(sizes + 1.0)) if sizes.size else 1
        # one table for every stuck count per group when the coordinates never change
        per_config = configuration_bytes(n, ni, model.sensors.shape[0], model.n_inputs,
                                         self._omegas.size)
        self._table_mode = isinstance(self.configurations, MassUpdate) and \
            n_keys <= MAX_TABLE_SLOTS and n_keys * per_config <= MAX_TABLE_BYTES
        # configurations kept when switching through Python (least recently used dropped)
        self._cache_limit = cache_limit(per_config) if isinstance(
            self.configurations, MassUpdate) else MAX_CACHED_CONFIGURATIONS
        self._n_slots = n_keys if self._table_mode else 1
        # configuration key -> (FlowConfig, LinearModel)
        self._flows: dict[Key, tuple[FlowConfig, LinearModel]] = {}
        self._tables: dict[Key | str, _Table] = {}     # table key ('all' in table mode)
        self._slot_state = np.zeros(1, dtype=np.int64)
        # stuck flags' bytes -> key (see _key)
        self._keys: dict[bytes, Key] = {}
        # table mode, (key, ni) -> (model, slot, the kernel's table and impactor arguments):
        # what the kernel call needs of a configuration, once it is built (see _prepare)
        self._prepared: dict[tuple[Key, int], tuple[LinearModel, int,
                                                    tuple[np.ndarray, ...]]] = {}
        # output-step offsets dt * arange(n + 1) of the last n (s), and the kernel's t_state
        self._offsets: tuple[int, float, FloatArray] | None = None
        self._t_state = np.zeros(1)
        self._zero_particular: dict[int, npt.NDArray[np.complex128]] = {}
        cfg = self._config()
        # highest retained mode sets the paper's sticking time
        omega_max = float(np.max(np.abs(cfg.lam))) if cfg.lam.size else 1.0
        self.stick_time = stick_fraction * 2 * np.pi / omega_max
        self._yh = cfg.to_state(q, qd) - self._particular(cfg, self.t)
        self._place_impactors(q)
        self._imp_grace = np.zeros(ni, dtype=np.int64)
        self._count_step = np.zeros(ni, dtype=np.int64)
        # (C, None for a diagonal C, else the columns and counts of its non-zeros per row)
        self._c_pattern: tuple[FloatArray, tuple[np.ndarray, np.ndarray] | None] | None = None
        self._info = np.zeros(4, dtype=np.int64)
        self.counters = np.zeros(kernels.N_COUNTERS, dtype=np.int64)
        # the kernel's work arrays, (sizes, tuple); see _work_arrays
        self._work: tuple[tuple[int, ...], tuple[np.ndarray, ...]] | None = None
        self._cap = int(event_capacity)
        self._ev_buffers: tuple[np.ndarray, ...] | None = None
        self._imp_args: dict[int, tuple[np.ndarray, ...]] = {}
        self._python_switches = 0
        self._start_ledger()
        if self._table_mode and self._n_slots <= PREBUILD_SLOTS:
            for slot in range(self._n_slots):
                try:
                    self._table(self._key_of_slot(None, slot))
                except ValueError:
                    # a configuration with no flow (a defective state matrix, a harmonic on
                    # an undamped mode): left unbuilt, it raises if a run ever reaches it
                    pass

    # -- configuration ----------------------------------------------------------------------
    def _key(self) -> Key:
        """Configuration key: the stuck count of each group (table mode) or the stuck flags."""
        # read several times a chunk: looked up by the flags' bytes, computed once per pattern
        raw = self._stuck.tobytes()
        key = self._keys.get(raw)
        if key is None:
            if self._table_mode:
                key = tuple(int(c) for c in np.bincount(self._imp_group, weights=self._stuck,
                                                        minlength=self._radix.size))
            else:
                key = tuple(int(s) for s in self._stuck)
            if len(self._keys) >= _MAX_KEYS:   # 2^impactors patterns: bound the memory
                self._keys.clear()
            self._keys[raw] = key
        return key

    def _slot(self, key: Key) -> int:
        return int(np.dot(key, self._radix)) if self._table_mode else 0

    def _stuck_for(self, key: Key) -> Key:
        """Stuck flags standing for ``key`` (the first impactors of each group)."""
        if not self._table_mode:
            return key
        stuck = np.zeros(len(self._stuck), dtype=int)
        for g, count in enumerate(key):
            stuck[np.flatnonzero(self._imp_group == g)[:count]] = 1
        return tuple(int(s) for s in stuck)

    def _config(self, key: Key | None = None) -> FlowConfig:
        key = self._key() if key is None else key
        entry = self._flows.get(key)
        if entry is not None and not self._table_mode:   # most recently used last
            self._flows[key] = self._flows.pop(key)
        if entry is None:
            if not self._table_mode:
                while len(self._flows) >= self._cache_limit:   # drop the least recent use
                    old = next(iter(self._flows))
                    del self._flows[old]
                    self._tables.pop(old, None)
            model, masses, *carried = self.configurations.model(self._stuck_for(key))
            release = ([imp.mass for imp in model.impactors] if self._table_mode else None)
            flow = build_flow(model, masses, self._omegas, self._amps, self.law,
                              carried[0] if carried else None, release_masses=release)
            entry = (flow, model)
            self._flows[key] = entry
        return entry[0]

    def _config_model(self) -> LinearModel:
        key = self._key()
        self._config(key)
        return self._flows[key][1]

    def _table(self, key: Key | None = None) -> _Table:
        """The kernel's table holding configuration ``key``, built on first use."""
        key = self._key() if key is None else key
        table_key = 'all' if self._table_mode else key
        table = self._tables.get(table_key)
        flow = self._config(key)
        if table is None:
            table = _Table(self._n_slots, flow, self.dt, self.ledger_on, self.model.n
                           if self._table_mode else self._flows[key][1].n, self.model.K_skew)
            self._tables[table_key] = table
        slot = self._slot(key)
        if not table.built[slot]:
            table.fill(slot, flow)
        return table

    @property
    def n_config_changes(self) -> int:
        """int: Changes of configuration so far (stick and release; dimensionless)."""
        return int(self.counters[kernels.CNT_SWITCHES]) + self._python_switches

    def work_counters(self) -> dict[str, int]:
        """Work done so far, by kind: a dict of counts (see ``kernels.codes.CNT_*``)."""
        names = ('steps', 'searches', 'candidates', 'taylor_expansions', 'flow_evaluations',
                 'ledger_panels', 'fallback_scans', 'kernel_switches', 'segments',
                 'quiet_steps', 'ledger_closed', 'roots_certified')
        counts = dict(zip(names, (int(c) for c in self.counters)))
        counts['python_switches'] = self._python_switches
        return counts

    def _particular(self, cfg: FlowConfig, t: float) -> npt.NDArray[np.complex128]:
        if not self._omegas.size:   # no harmonics: zero, made once per size (read-only)
            zero = self._zero_particular.get(cfg.lam.size)
            if zero is None:
                zero = self._zero_particular[cfg.lam.size] = np.zeros(cfg.lam.size, complex)
                zero.flags.writeable = False
            return zero
        yp = np.zeros(cfg.lam.size, dtype=complex)
        for h, om in enumerate(self._omegas):
            e = np.exp(1j * om * t)
            yp += cfg.part_plus[h] * e + cfg.part_minus[h] * np.conj(e)
        return yp

    # -- state --------------------------------------------------------------------------------
    def state(self) -> tuple[FloatArray, FloatArray]:
        """Return ``(q, qd)``: coordinates and their velocities now."""
        cfg = self._config()
        return cfg.from_state(self._yh + self._particular(cfg, self.t))

    def _housing_rows(self) -> list[FloatArray]:
        return [imp.rows for imp in self._config_model().impactors]

    def _structure_energy(self, q: FloatArray, qd: FloatArray) -> float:
        return self.configurations.structure_energy(self._stuck_for(self._key()), q, qd)

    def _release_now(self, j: int) -> None:
        old_key, old_cfg = self._key(), self._config()
        q, qd = self.state()
        R = self._housing_rows()[j]
        d = R.shape[0]
        self._imp_z[j, :d] = R @ q + self._imp_rel[j, :d]
        self._imp_v[j, :d] = R @ qd
        self._stuck[j] = 0
        self._imp_grace[j] = 0
        self._count_step[j] = 0
        self._switch(self.t, old_cfg, old_key)

    def take_events(self) -> np.ndarray:
        """Return the events recorded since the last call (see ``EVENT_DTYPE``) and clear."""
        events = self._events
        if not events:
            return np.zeros(0, dtype=EVENT_DTYPE)
        # one chunk (the usual case) is a new array that nothing else holds: no copy
        out = events[0] if len(events) == 1 else np.concatenate(events)
        self._events = []
        return out

    # -- stepping -----------------------------------------------------------------------------
    def advance(self, n_steps: int) -> Samples:
        """Advance ``n_steps`` output steps of ``dt``.

        Parameters
        ----------
        n_steps : int
            Number of steps (dimensionless).

        Returns
        -------
        Samples
            Sensor outputs at the end of each step.
        """
        n_steps = int(n_steps)
        ns = self.model.sensors.shape[0]
        t_base = self.t
        dt = self.dt
        offsets = self._step_offsets(n_steps, dt)
        times = t_base + offsets[1:]
        u_grid = self.forcing.sample(t_base + offsets)
        disp = np.empty((n_steps, ns))
        vel = np.empty((n_steps, ns))
        acc = np.empty((n_steps, ns))
        t_state = self._t_state   # the kernel's clock, read back after each call
        t_state[0] = t_base
        k = 0
        # the event buffers are read into a new array after each kernel call: made once
        ev = self._event_buffers()
        (ev_t, ev_imp, ev_kind, ev_n, ev_vn, ev_J, ev_loss, ev_after, ev_count) = ev
        rule = _RULE_CODES[self.stick_rule]
        slot_state, info = self._slot_state, self._info
        while True:
            key = self._key()
            # disabled dampers (all free, no walls) are left out of the scan altogether: their
            # free flight is not needed, they are put back at their housings when re-enabled
            ni = len(self._imp_dim) if self.impacts_enabled else 0
            # built (or marked most recently used) before the kernel runs
            model, slot, config_args = self._prepare(key, ni)
            slot_state[0] = slot
            ev_count[0] = 0
            status = kernels.advance(
                t_state, t_base, dt, k, n_steps, u_grid, self._omegas, self._amps,
                self._yh, slot_state, self._table_mode, *config_args, rule, self.stick_time,
                self.max_events_per_step, self.taylor_order, *self._ledger_model(model),
                self._ledger, disp, vel, acc, *ev, info, self.counters,
                self._work_arrays(ni, model.C.shape[0]))
            m = int(ev_count[0])
            if m:
                # every byte is written below (_EVENT_FIELDS): no zeroing needed
                chunk = np.empty(m, dtype=EVENT_DTYPE) if _EVENT_FIELDS else \
                    np.zeros(m, dtype=EVENT_DTYPE)
                chunk['t'] = ev_t[:m]
                chunk['impactor'] = ev_imp[:m]
                chunk['kind'] = ev_kind[:m]
                chunk['normal'] = ev_n[:m]
                chunk['v_n'] = ev_vn[:m]
                chunk['impulse'] = ev_J[:m]
                chunk['loss'] = ev_loss[:m]
                chunk['v_n_after'] = ev_after[:m, 0]
                chunk['v_h_jump'] = ev_after[:m, 1]
                self._events.append(chunk)
            k, changed, undecided, most = info.tolist()
            self.grazing_undecided = undecided
            if most > self.max_impacts_per_step:
                self.max_impacts_per_step = most
            if status == kernels.DONE:
                break
            if status == kernels.CONFIG_CHANGE:
                # the kernel left yh in the configuration of slot_state, before the change
                old_key = self._key_of_slot(key, int(slot_state[0]))
                self._switch(float(t_state[0]), self._config(old_key), old_key)
                continue
            if status == kernels.BUFFER_FULL:
                continue
            self.t = float(t_state[0])
            if status == kernels.NONFINITE:
                raise FloatingPointError(f'non-finite state at t = {self.t:.6g} s')
            raise RuntimeError(f'chatter not resolved at t = {self.t:.6g} s for impactor '
                               f'{model.impactors[changed].name!r}')
        self.t = float(t_state[0])
        return Samples(times, disp, vel, acc)

    def _step_offsets(self, n_steps: int, dt: float) -> FloatArray:
        """``dt * arange(n_steps + 1)`` (s), read-only, made again only when ``n_steps`` or
        ``dt`` changes (a live run advances the same chunk every time)."""
        cached = self._offsets
        if cached is not None and cached[0] == n_steps and cached[1] == dt:
            return cached[2]
        offsets = cast(FloatArray, dt * np.arange(n_steps + 1))
        offsets.flags.writeable = False
        self._offsets = (n_steps, dt, offsets)
        return offsets

    def _prepare(self, key: Key, ni: int) -> tuple[LinearModel, int, tuple[np.ndarray, ...]]:
        """Build (or mark most recently used) configuration ``key`` and return its model, its
        slot and the kernel's table and impactor arguments (impactors ``[:ni]``).

        In table mode nothing of a built configuration changes (one table, never evicted,
        filled in place; the impactor arguments are views): the answer is kept per
        ``(key, ni)``. Otherwise the configurations are a least-recently-used cache and it is
        made each call.
        """
        if self._table_mode:
            prepared = self._prepared.get((key, ni))
            if prepared is not None:
                return prepared
        self._config(key)
        model = self._flows[key][1]
        table = self._table(key)
        prepared = (model, self._slot(key), table.kernel_args(ni) + self._impactor_args(ni))
        if self._table_mode:
            self._prepared[key, ni] = prepared
        return prepared

    def _ledger_model(self, model: LinearModel
                      ) -> tuple[tuple[FloatArray, FloatArray, FloatArray] | None,
                                 tuple[np.ndarray, np.ndarray] | None]:
        """The ``ledger_model`` and ``c_pattern`` arguments of :func:`.kernels.event_loop.advance`.

        ``(None, None)`` without the ledger. Otherwise ``(C, K_skew, B)`` of ``model``, and
        ``None`` for a diagonal ``C`` (modal damping) or the columns of the non-zero entries
        of each row of ``C`` and their counts, with which the ledger's damping power skips
        the zeros. The kernel compiles only the forms these select.
        """
        if not self.ledger_on:
            return None, None
        C = model.C
        if self._c_pattern is None or self._c_pattern[0] is not C:
            cols = np.zeros(C.shape, dtype=np.int64)
            counts = np.zeros(C.shape[0], dtype=np.int64)
            ledger_kernels.row_pattern(C, cols, counts)
            own = np.flatnonzero(counts == 1)
            diagonal = np.all(counts <= 1) and np.array_equal(cols[own, 0], own)
            self._c_pattern = (C, None if diagonal else (cols, counts))
        return (C, model.K_skew, model.B), self._c_pattern[1]

    def _work_arrays(self, ni: int, n: int) -> tuple[np.ndarray, ...]:
        """The kernel's work arrays, made again only when a size changes. Kept here, so
        alive while the kernel runs (kernels hold no references to arrays)."""
        sizes = (self._yh.size, self.forcing.n_inputs, ni, self._omegas.size, n,
                 self.taylor_order, self.ledger_on)
        if self._work is None or self._work[0] != sizes:
            self._work = (sizes, kernels.advance_work(*sizes))
        return self._work[1]

    def _event_buffers(self) -> tuple[np.ndarray, ...]:
        """The kernel's event buffers (``event_capacity`` events), made on first use."""
        buffers = self._ev_buffers
        if buffers is None:
            cap = self._cap
            buffers = self._ev_buffers = (
                np.empty(cap), np.empty(cap, dtype=np.int64), np.empty(cap, dtype=np.int64),
                np.empty((cap, 2)), np.empty(cap), np.empty(cap), np.empty(cap),
                np.empty((cap, 2)), np.zeros(1, dtype=np.int64))
        return buffers

    def _impactor_args(self, ni: int) -> tuple[np.ndarray, ...]:
        """The impactor arguments of :func:`.kernels.event_loop.advance` (``[:ni]`` views of
        the state arrays, which are updated in place and never replaced), made once per
        ``ni``."""
        cache = self._imp_args
        args = cache.get(ni)
        if args is None:
            args = cache[ni] = (
                self._imp_rep[:ni], self._imp_group[:ni], self._radix, self._imp_dim[:ni],
                self._imp_mass[:ni], self._imp_cor[:ni], self._imp_limit[:ni],
                self._imp_z[:ni], self._imp_v[:ni], self._stuck[:ni], self._imp_normal[:ni],
                self._imp_last_t[:ni], self._imp_rel[:ni], self._imp_grace[:ni],
                self._count_step[:ni])
        return args

    def _key_of_slot(self, key: Key | None, slot: int) -> Key:
        """The key of ``slot`` (table mode); the given key otherwise."""
        if not self._table_mode:
            # the stuck flags now include the change: undo it for the old key
            j = int(self._info[1])
            old = list(self._key())
            old[j] = 1 - old[j]
            return tuple(old)
        counts: list[int] = []
        for g in range(self._radix.size):
            size = int(np.count_nonzero(self._imp_group == g))
            counts.append((slot // int(self._radix[g])) % (size + 1))
        return tuple(counts)

    def _switch(self, t_event: float, old_cfg: FlowConfig, old_key: Key) -> None:

        """Carry the state across a change of the stuck set (same coordinates by default)."""
        y = self._yh + self._particular(old_cfg, t_event)
        q, qd = old_cfg.from_state(y)
        T = self.configurations.transform(self._stuck_for(old_key),
                                          self._stuck_for(self._key()))
        if T is not None:
            q, qd = T @ q, T @ qd
        new_cfg = self._config()
        self._yh = new_cfg.to_state(q, qd) - self._particular(new_cfg, t_event)
        self._slot_state[0] = self._slot(self._key())
        self._python_switches += 1
