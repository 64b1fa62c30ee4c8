"""The paper's stuck formulation: a second modal basis per stuck set (paper Eq. 2.3.7-2.3.14).

While an impactor rides on a cavity wall the paper integrates a *different* modal model: the
modes of the physical structure with the impactor mass added at its housing DOF(s). Switching
between configurations maps the modal state by equating the two modal expansions of the
physical displacement, with mass-normalized modes (``diag(1/m) = I``)::

    q_b = T_ab q_a,    T_ab = Phi_b^T M_b Phi_a     (over the master DOFs of b)

which is the paper's ``B Phi_f`` (free -> stuck, ``b`` stuck) and ``A Phi_s`` (stuck -> free,
``b`` free), generalised to any pair of stuck sets (several impactors). The same matrix maps
velocities: at a stick or release the impactor moves with its housing, so the physical
velocity field is one and the same in both configurations.

On complete bases ``T_ba T_ab = I`` and the two formulations of
:mod:`impact_damper_sim.integrate.exact` agree to rounding (with zero tare damping, see
below). On truncated bases each switch is an ``M_b``-orthogonal projection onto the retained
modes of ``b``: the kinetic energy of the structure and the impactors stuck in ``b`` can only
drop, the strain energy may move either way, and the energy ledger shows the sum as its
residual (:meth:`BasisSwitch.switch_loss` gives it switch by switch).
:class:`~.exact.MassUpdate` (the default) has no such loss.

Tare damping is per mode, so it is *not* the same physical damping in the two bases: mode
``k`` of a stuck basis gets the free basis' ratio ``zeta_k`` with its own ``omega_k``. Even on
complete bases the two formulations then differ by ``O(zeta mu)``. The damping force, hence
the housing acceleration, also jumps at every switch, so a release (zero contact force in the
stuck basis) can meet a housing that pushes into the impactor again in the free basis: a few
zero-length stick/release pairs follow.

Limitation: the exact kernel releases on the frictionless normal contact force through
``release_map = (I - m G_s)^-1``, which :func:`~.flow.build_flow` forms from the stuck masses.
Here they are zero (the mass is in the basis), so the map is ``I``. For an SDOF impactor this
changes nothing (a positive factor); for a planar impactor on a truncated basis the release
uses the stuck housing acceleration instead of the frictionless criterion.
"""
from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING, TypeVar

import numpy as np
import numpy.typing as npt

from ..modal.basis import ModalBasis, modal_reduction
from ..modal.stuck import add_point_mass
from .memory import MAX_CACHED_CONFIGURATIONS
from .model import LinearModel

if TYPE_CHECKING:
    from ..fem import AssembledSystem

FloatArray = npt.NDArray[np.float64]
#: stuck flags as a hashable tuple of 0/1
Key = tuple[int, ...]
#: stuck flags as given: a sequence of bool or int
Flags = Iterable[int] | np.ndarray

__all__ = ['BasisSwitch']

#: Relative tolerance when checking the model's impactor rows against the free basis.
_ROWS_RTOL = 1e-9


_CacheKey = TypeVar('_CacheKey')
_Cached = TypeVar('_Cached')


def _bound(cache: dict[_CacheKey, _Cached], keep: _CacheKey | None = None) -> None:

    """Drop the oldest entries of ``cache`` (never ``keep``) beyond
    :data:`~impact_damper_sim.integrate.memory.MAX_CACHED_CONFIGURATIONS`: a run visiting many
    stuck sets keeps a bounded number of bases (each a modal reduction and its dense
    condensation), built again if reached again."""
    while len(cache) > MAX_CACHED_CONFIGURATIONS:
        del cache[next(k for k in cache if k != keep)]


def _key(stuck: Flags) -> Key:
    """Stuck flags as a hashable tuple of 0/1 (the cache key of a configuration)."""
    return tuple(int(bool(s)) for s in stuck)


class BasisSwitch:
    """Configuration provider of :class:`~.exact.ExactPropagator`: one modal basis per stuck set.

    For each tuple of stuck flags it builds, on first use, the modal basis of the physical
    system with every stuck impactor's mass added at its housing DOF(s) (one DOF for an SDOF
    impactor, both in-plane translations for a planar one), keeping the free basis' number of
    modes (all of them if the free basis is complete) and its tare damping ratios by mode
    index; physical dashpots and cross-coupled stiffness are projected as usual, and so is a
    rotor's gyroscopic coupling (``gyroscopic``). The stuck masses are then inside the basis,
    so :meth:`model` returns zero stuck masses.

    Parameters
    ----------
    system : AssembledSystem
        Physical system without impactors (kg, N s/m, N/m).
    free_basis : ModalBasis
        Retained modes of ``system`` (mode shapes in 1/sqrt(kg)); ``model`` lives in it.
    model : LinearModel
        The free modal model (``M = I``, coordinates in m sqrt(kg)) with its impactors.
    housing_indices : sequence of sequence of int
        ``housing_indices[j]``: active DOF indices of impactor ``j``'s housing, one (sdof) or
        two (planar), in the order of its rows (dimensionless).
    sensor_indices, force_indices : sequence of int, optional
        Active DOF index of each sensor row and force input (dimensionless); a rotor's
        unbalance inputs count as force inputs. Default: found by matching the model's rows
        against every active DOF's mode-shape row (an error if that is ambiguous).
    method : {'auto', 'dense', 'sparse'}
        Eigen solver for the stuck bases, see :func:`~impact_damper_sim.modal.modal_reduction`.
    gyroscopic : sequence of (int, int, float), optional
        The physical gyroscopic matrix of a spinning rotor as ``(ry, rz, c)`` triples: active
        DOF indices of a disk's tilts (dimensionless) and ``c = Ip Omega`` (kg m^2/s), its
        polar inertia times the spin speed; the damping matrix gets ``+c`` at ``[ry, rz]``
        and ``-c`` at ``[rz, ry]``. Each stuck model gets this matrix projected on its basis;
        the model's own damping must hold it projected on ``free_basis``.

    Notes
    -----
    While an impactor is stuck, :meth:`ExactPropagator.state` returns coordinates of the stuck
    basis (its length can differ from the free one when the basis is complete and the
    impactor sits on a massless DOF).
    """

    def __init__(self, system: AssembledSystem, free_basis: ModalBasis, model: LinearModel,
                 housing_indices: Iterable[int | Sequence[int]], *,
                 sensor_indices: Iterable[int] | None = None,
                 force_indices: Iterable[int] | None = None, method: str = 'auto',
                 gyroscopic: Iterable[tuple[int, int, float]] = ()) -> None:
        n = free_basis.n_modes
        if model.n != n:
            raise ValueError(f'model has {model.n} coordinates, free basis {n} modes')
        if not np.allclose(model.M, np.eye(n), rtol=0, atol=1e-12):
            raise ValueError('BasisSwitch needs a mass-normalized modal model (M = I)')
        housing = tuple(tuple(int(k) for k in np.atleast_1d(idx)) for idx in housing_indices)
        if len(housing) != len(model.impactors):
            raise ValueError(f'{len(housing)} housing index sets for '
                             f'{len(model.impactors)} impactors')
        for imp, idx in zip(model.impactors, housing):
            if len(idx) != imp.dim:
                raise ValueError(f'impactor {imp.name!r} ({imp.kind}) needs {imp.dim} housing '
                                 f'DOF index(es), got {list(idx)}')
            # a wrong index would silently put the stuck mass elsewhere: check the rows agree
            rows = free_basis.rows(list(idx))
            scale = max(np.abs(rows).max(), np.abs(imp.rows).max())
            if not np.allclose(rows, imp.rows, rtol=0, atol=_ROWS_RTOL * scale):
                raise ValueError(f'impactor {imp.name!r}: housing DOFs {list(idx)} do not give '
                                 "the model's housing rows")
        self.system = system
        self.free_basis = free_basis
        self.base = model
        self.housing_indices = housing
        self.method = method
        self.sensor_indices = self._indices(model.sensors, sensor_indices, 'sensor')
        self.force_indices = self._indices(model.B.T, force_indices, 'force')
        self.gyroscopic = tuple((int(ry), int(rz), float(c)) for ry, rz, c in gyroscopic)
        self._check_gyroscopic()
        free = _key([0] * len(model.impactors))
        self._free_key = free
        self._bases: dict[Key, ModalBasis] = {free: free_basis}
        self._models: dict[Key, LinearModel] = {free: model}
        self._K_sym: dict[Key, FloatArray] = {}
        self._transforms: dict[tuple[Key, Key], FloatArray] = {}

    def _gyroscopic_coupling(self, basis: ModalBasis) -> FloatArray:
        """``Phi^T G Phi`` of :attr:`gyroscopic` on ``basis`` (1/s), skew-symmetric."""
        n = basis.n_modes
        coupling = np.zeros((n, n))
        for ry, rz, c in self.gyroscopic:
            rows = basis.rows([ry, rz])
            coupling += c * (np.outer(rows[0], rows[1]) - np.outer(rows[1], rows[0]))
        return coupling

    def _check_gyroscopic(self) -> None:
        """Refuse a model whose damping's skew part is not :attr:`gyroscopic` projected on
        the free basis: the stuck models would lose (or invent) the coupling."""
        C = self.base.C
        skew = 0.5 * (C - C.T)
        expected = self._gyroscopic_coupling(self.free_basis)
        scale = max(np.abs(C).max(), np.abs(expected).max(), 1e-300)
        if not np.allclose(skew, expected, rtol=0, atol=_ROWS_RTOL * scale):
            raise ValueError('the model\'s damping has a skew-symmetric (gyroscopic) part that '
                             'gyroscopic does not give (largest mismatch '
                             f'{np.abs(skew - expected).max():.3g} 1/s); pass the rotor\'s '
                             'gyroscopic terms so that the stuck bases keep the coupling')

    def _indices(self, rows: FloatArray, given: Iterable[int] | None, what: str
                 ) -> tuple[int, ...]:
        """Active DOF index of each row of ``rows`` (free-basis mode-shape rows)."""
        if given is not None:
            indices = tuple(int(k) for k in given)
            if len(indices) != rows.shape[0]:
                raise ValueError(f'{len(indices)} {what} indices for {rows.shape[0]} {what} '
                                 'rows')
            if indices:
                check = self.free_basis.rows(list(indices))
                scale = max(np.abs(check).max(), np.abs(rows).max(), 1e-300)
                if not np.allclose(check, rows, rtol=0, atol=_ROWS_RTOL * scale):
                    raise ValueError(f'{what} indices {list(indices)} do not give the model\'s '
                                     f'{what} rows')
            return indices
        if rows.shape[0] == 0:
            return ()
        every = self.free_basis.rows(np.arange(self.system.n_dof))
        scale = max(np.abs(every).max(), 1e-300)
        found: list[int] = []
        for r, row in enumerate(rows):
            match = np.flatnonzero(np.all(np.abs(every - row) <= _ROWS_RTOL * scale, axis=1))
            if match.size != 1:
                raise ValueError(f'{what} row {r} matches {match.size} active DOFs in the free '
                                 f'basis; pass {what}_indices')
            found.append(int(match[0]))
        return tuple(found)

    # -- bases and models ---------------------------------------------------------------------
    def basis(self, stuck: Flags) -> ModalBasis:
        """Return the :class:`~impact_damper_sim.modal.ModalBasis` of a stuck set.

        Parameters
        ----------
        stuck : sequence of bool or int
            One flag per impactor (dimensionless).

        Returns
        -------
        ModalBasis
            The free basis for no stuck impactor; otherwise the basis of the system with the
            stuck impactors' masses added (built once, then cached).
        """
        key = _key(stuck)
        if len(key) != len(self.base.impactors):
            raise ValueError(f'{len(key)} stuck flags for {len(self.base.impactors)} impactors')
        found = self._bases.get(key)
        if found is not None:
            return found
        system = self.system
        for imp, idx, s in zip(self.base.impactors, self.housing_indices, key):
            if s:
                system = add_point_mass(system, list(idx), float(imp.mass))
        free = self.free_basis
        complete = free.n_modes == free.condensation.master.size
        zeta = free.zeta
        # mode k keeps the free ratio zeta_k; modes beyond the free count (a complete basis
        # whose impactor turned a massless DOF into a master) take the highest free mode's
        overrides = {k: float(z) for k, z in enumerate(zeta)}
        basis = modal_reduction(system, n_modes=None if complete else free.n_modes,
                                zeta=float(zeta[-1]), zeta_overrides=overrides,
                                method=self.method)
        self._bases[key] = basis
        _bound(self._bases, self._free_key)
        return basis

    def model(self, stuck: Flags
              ) -> tuple[LinearModel, tuple[float, ...], tuple[float, ...]]:
        """Return ``(LinearModel, stuck_masses, carried_masses)`` of a stuck set.

        Parameters
        ----------
        stuck : sequence of bool or int
            One flag per impactor (dimensionless).

        Returns
        -------
        (LinearModel, tuple of float, tuple of float)
            The modal model in the coordinates of :meth:`basis` (``M = I``; sensor, force and
            housing rows of that basis, in 1/sqrt(kg)), zero stuck masses (kg): the masses
            are already in the basis, and those carried masses (kg) for the release rule.
        """
        key = _key(stuck)
        found = self._models.get(key)
        if found is None:
            basis = self.basis(key)
            base = self.base
            n = basis.n_modes
            B = (basis.rows(list(self.force_indices)).T if self.force_indices
                 else np.zeros((n, 0)))
            S = (basis.rows(list(self.sensor_indices)) if self.sensor_indices
                 else np.zeros((0, n)))
            impactors = tuple(imp.with_rows(basis.rows(list(idx)))
                              for imp, idx in zip(base.impactors, self.housing_indices))
            found = LinearModel(M=np.eye(n),
                                C=basis.damping_matrix() + self._gyroscopic_coupling(basis),
                                K=basis.stiffness_matrix(), B=B, sensors=S,
                                sensor_names=base.sensor_names, impactors=impactors,
                                kind='modal', input_names=base.input_names)
            self._models[key] = found
            _bound(self._models, self._free_key)
        carried = tuple(imp.mass if flag else 0.0 for imp, flag in zip(self.base.impactors, key))
        return found, (0.0,) * len(key), carried

    def transform(self, stuck_from: Flags, stuck_to: Flags) -> FloatArray | None:
        """Return ``T = Phi_b^T M_b Phi_a`` mapping coordinates of ``a`` to ``b`` (provider).

        Parameters
        ----------
        stuck_from, stuck_to : sequence of bool or int
            Stuck flags of the configurations ``a`` and ``b`` (dimensionless).

        Returns
        -------
        ndarray, shape (n_b, n_a), or None
            Dimensionless; the same matrix maps velocities. ``None`` when ``a == b``.
        """
        a, b = _key(stuck_from), _key(stuck_to)
        if a == b:
            return None
        T = self._transforms.get((a, b))
        if T is None:
            ba, bb = self.basis(a), self.basis(b)
            cb = bb.condensation
            # every mass sits on b's master DOFs: evaluate a's modes there (through a's own
            # condensation recovery, since the master sets can differ)
            T = bb.shapes.T @ cb.M @ ba.rows(cb.master)
            T.setflags(write=False)
            self._transforms[(a, b)] = T
            _bound(self._transforms)
        return T

    # -- energies -------------------------------------------------------------------------------
    def _k_sym(self, key: Key) -> FloatArray:
        K = self._K_sym.get(key)
        if K is None:
            K = self._K_sym[key] = self.model(key)[0].K_sym
            _bound(self._K_sym)
        return K

    def _kinetic(self, key: Key, which: Iterable[bool | int], qd: FloatArray) -> float:
        """``sum_j 0.5 m_j |R_j qd|^2`` over impactors flagged in ``which`` (J).

        ``R_j`` are the housing rows of configuration ``key``, the one ``qd`` belongs to.
        """
        model = self.model(key)[0]
        return sum(0.5 * imp.mass * float(np.sum((imp.rows @ qd) ** 2))
                   for imp, w in zip(model.impactors, which) if w)

    def structure_energy(self, stuck: Flags, q: npt.ArrayLike, qd: npt.ArrayLike) -> float:
        """Return the structure's kinetic plus strain energy, without stuck impactors (J).

        Parameters
        ----------
        stuck : sequence of bool or int
            Stuck flags of the configuration ``q`` belongs to (dimensionless).
        q : ndarray, shape (n,)
            Modal coordinates (m sqrt(kg)).
        qd : ndarray, shape (n,)
            Modal velocities (m sqrt(kg)/s).

        Returns
        -------
        float
            ``0.5 |qd|^2 + 0.5 q^T K_sym q - sum_stuck 0.5 m_j |R_j qd|^2`` (J): the basis
            carries the stuck impactors' mass, whose kinetic energy the propagator counts
            with the impactors.
        """
        key = _key(stuck)
        q = np.asarray(q, dtype=float)
        qd = np.asarray(qd, dtype=float)
        return self.carried_energy(key, (0,) * len(key), q, qd)

    def carried_energy(self, stuck: Flags, carried: Flags, q: npt.ArrayLike,
                       qd: npt.ArrayLike) -> float:
        """Return the energy of the structure plus the impactors it carries (J).

        Parameters
        ----------
        stuck : sequence of bool or int
            Stuck flags of the configuration ``q`` belongs to (dimensionless).
        carried : sequence of bool or int
            Impactors counted as moving with their housing (dimensionless).
        q : ndarray, shape (n,)
            Modal coordinates (m sqrt(kg)).
        qd : ndarray, shape (n,)
            Modal velocities (m sqrt(kg)/s).

        Returns
        -------
        float
            ``0.5 |qd|^2 + 0.5 q^T K_sym q`` plus ``0.5 m_j |R_j qd|^2`` of each carried
            impactor the basis does not hold, minus that of each impactor the basis holds but
            that is not carried (J); :meth:`structure_energy` carries none.
        """
        key, carried_key = _key(stuck), _key(carried)
        q = np.asarray(q, dtype=float)
        qd = np.asarray(qd, dtype=float)
        add = [c and not s for c, s in zip(carried_key, key)]
        drop = [s and not c for c, s in zip(carried_key, key)]
        return (0.5 * float(qd @ qd) + 0.5 * float(q @ self._k_sym(key) @ q)
                + self._kinetic(key, add, qd) - self._kinetic(key, drop, qd))

    def switch_loss(self, stuck_from: Flags, stuck_to: Flags, q: FloatArray,
                    qd: FloatArray) -> float:
        """Return the energy one switch loses (J), at a stick or a release.

        The propagator gives a sticking impactor its housing's velocity before the switch and
        the new basis' housing velocity after it, while a released impactor leaves with the
        velocity its housing had before the switch. So the energy a switch changes is that of
        the structure plus the impactors stuck *after* it (:meth:`carried_energy`), before
        and after ``T`` (:meth:`transform`); it is what the energy ledger shows as residual.

        Parameters
        ----------
        stuck_from, stuck_to : sequence of bool or int
            Stuck flags before and after (dimensionless).
        q : ndarray, shape (n_a,)
            Coordinates before the switch (m sqrt(kg)).
        qd : ndarray, shape (n_a,)
            Velocities before the switch (m sqrt(kg)/s).

        Returns
        -------
        float
            ``E_before - E_after`` (J); positive when the switch dissipates, 0 on complete
            bases (to rounding).
        """
        a, b = _key(stuck_from), _key(stuck_to)
        T = self.transform(a, b)
        q2, qd2 = (q, qd) if T is None else (T @ q, T @ qd)
        return self.carried_energy(a, b, q, qd) - self.carried_energy(b, b, q2, qd2)

    def round_trip_loss(self, q: npt.ArrayLike, qd: npt.ArrayLike, stuck: Flags) -> float:
        """Return the relative energy change of a free -> stuck -> free round trip.

        Parameters
        ----------
        q : array_like, shape (n_f,)
            Free modal coordinates (m sqrt(kg)).
        qd : array_like, shape (n_f,)
            Free modal velocities (m sqrt(kg)/s).
        stuck : sequence of bool or int
            Stuck flags of the intermediate configuration (dimensionless).

        Returns
        -------
        float
            ``1 - E_after/E_before`` (dimensionless) with ``E`` the free model's energy
            ``0.5 |qd|^2 + 0.5 q^T K_sym q``: positive when the round trip loses energy,
            0 for a zero state or a complete basis (to rounding).
        """
        q = np.asarray(q, dtype=float)
        qd = np.asarray(qd, dtype=float)
        free, key = self._free_key, _key(stuck)
        before = self.structure_energy(free, q, qd)
        if before == 0.0 or key == free:
            return 0.0
        there, back = self.transform(free, key), self.transform(key, free)
        assert there is not None and back is not None   # key != free: a real change

        q2, qd2 = back @ (there @ q), back @ (there @ qd)
        return 1.0 - self.structure_energy(free, q2, qd2) / before
