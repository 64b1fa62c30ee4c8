"""The "stuck" impactor: a second modal basis with the impactor mass added (paper 2.3).

While the impactor rides on a cavity wall it moves with the housing, so the structure carries
its mass ``m``: at one DOF for an SDOF impactor, or at both in-plane translations of the
housing node for a planar impactor. Free and stuck coordinates are related by equating the
two modal expansions of the physical displacement (paper Eq. 2.3.11-2.3.14), with
mass-normalized modes so that ``diag(1/m) = I``::

    q_s = (B Phi_f) q_f,  B Phi_f = Phi_s^T M_s Phi_f    (free -> stuck)
    q_f = (A Phi_s) q_s,  A Phi_s = Phi_f^T M_f Phi_s    (stuck -> free)

Both apply to ``q`` and ``qdot`` alike: at the switch the impactor and housing velocities are
equal, so the physical velocity field is the same in both systems. On complete bases the round
trip is exact; on truncated bases each switch projects the state onto the retained modes and
loses a little (see :meth:`StuckTransforms.switch_loss`).
"""
from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

from impact_damper_sim.fem.system import AssembledSystem
from impact_damper_sim.modal.basis import ModalBasis, modal_reduction


def add_point_mass(system: AssembledSystem, active_indices: npt.ArrayLike,
                   mass: float) -> AssembledSystem:
    """Return a copy of ``system`` with ``mass`` added on the diagonal at each given DOF.

    Parameters
    ----------
    system : AssembledSystem
        Physical system (kg, N s/m, N/m).
    active_indices : int or sequence of int
        Distinct active DOF indices carrying the mass, one (SDOF) or two (planar), all
        translations (dimensionless).
    mass : float
        Point mass added at each DOF (kg, > 0).

    Returns
    -------
    AssembledSystem
        Same ``C``, ``K`` and ``dofs``; ``M`` with the mass added.
    """
    if isinstance(mass, bool) or not isinstance(mass, numbers.Real) or not (
            math.isfinite(float(mass)) and float(mass) > 0):
        raise ValueError(f'mass={mass!r} kg must be finite and > 0')
    idx = np.atleast_1d(np.asarray(active_indices))
    if idx.ndim != 1 or idx.size == 0 or not np.issubdtype(idx.dtype, np.integer):
        raise ValueError(f'active_indices must be one or more integer DOF indices, '
                         f'got {active_indices!r}')
    if np.unique(idx).size != idx.size:
        raise ValueError(f'active_indices {idx.tolist()} repeat a DOF')
    n = system.n_dof
    bad = idx[(idx < 0) | (idx >= n)]
    if bad.size:
        raise ValueError(f'active_indices: {bad.tolist()} out of range 0..{n - 1}')
    rotations = [int(k) for k in idx if system.dofs[k, 1] >= 3]
    if rotations:
        raise ValueError(f'active_indices {rotations} are rotations; an impactor mass sits on '
                         f'translations')
    added = sp.csr_matrix((np.full(idx.size, float(mass)), (idx, idx)), shape=(n, n))
    return AssembledSystem(M=(system.M + added).tocsr(), C=system.C, K=system.K,
                           dofs=system.dofs)


def stuck_basis(system: AssembledSystem, active_indices: npt.ArrayLike, mass: float, *,
                n_modes: int | None = None, f_max: float | None = None, zeta: float = 0.0,
                zeta_overrides: Mapping[int, float] | None = None,
                method: str = 'auto') -> tuple[ModalBasis, ModalBasis]:
    """Return the free basis and the stuck basis (impactor mass added).

    The free basis is selected by ``n_modes``/``f_max`` as in :func:`modal_reduction`; the
    stuck basis keeps the same number of modes, so mode ``j`` (and its tare damping) has the
    same meaning in both. A complete free basis gets a complete stuck basis, which has one
    more mode per impactor DOF that was massless in the free system.

    Parameters
    ----------
    system : AssembledSystem
        Physical system without the impactor (kg, N s/m, N/m).
    active_indices : int or sequence of int
        Active DOF index of the impactor direction (SDOF), or of the two in-plane
        translations of the housing node (planar) (dimensionless).
    mass : float
        Impactor mass (kg, > 0).
    n_modes : int, optional
        Number of modes of the free basis (dimensionless, >= 1).
    f_max : float, optional
        Frequency cut-off of the free basis (Hz, > 0).
    zeta : float
        Tare damping ratio of every mode (dimensionless, ``0 <= zeta < 1``).
    zeta_overrides : dict of {int: float}, optional
        Per-mode tare damping by 0-based mode index (dimensionless).
    method : {'auto', 'dense', 'sparse'}
        Eigen-solver choice, see :func:`modal_reduction`.

    Returns
    -------
    (ModalBasis, ModalBasis)
        Free and stuck bases.
    """
    free = modal_reduction(system, n_modes=n_modes, f_max=f_max, zeta=zeta,
                           zeta_overrides=zeta_overrides, method=method)
    stuck_sys = add_point_mass(system, active_indices, mass)
    complete = free.n_modes == free.condensation.master.size
    # a complete free basis gets a complete stuck one: the impactor may turn a massless DOF
    # into a master, adding a mode, and dropping it would break the exact round trip
    stuck = modal_reduction(stuck_sys, n_modes=None if complete else free.n_modes, zeta=zeta,
                            zeta_overrides=zeta_overrides, method=method)
    rule = 'all modes, as the free basis' if complete else 'same count as the free basis'
    reason = (f'{stuck.n_modes} modes ({rule}) with the {mass:g} kg impactor added; highest '
              f'{stuck.frequencies_hz[-1]:.6g} Hz')
    return free, replace(stuck, selection_reason=reason)


def switch_matrices(free: ModalBasis, stuck: ModalBasis) -> tuple[np.ndarray, np.ndarray]:
    """Return ``(B Phi_f, A Phi_s)`` for two bases of the same structure (paper Eq. 2.3.13-14).

    Works when the two systems have different master sets (a massless DOF that receives the
    impactor becomes a master in the stuck system): each mode is evaluated at the other
    system's masses through its own condensation recovery.

    Parameters
    ----------
    free, stuck : ModalBasis
        Mass-normalized bases over the same active DOFs.

    Returns
    -------
    (ndarray, ndarray)
        ``free_to_stuck`` of shape (n_s, n_f) and ``stuck_to_free`` of shape (n_f, n_s)
        (dimensionless).
    """
    if not np.array_equal(free.system.dofs, stuck.system.dofs):
        raise ValueError('free and stuck bases are over different active DOFs')
    cf, cs = free.condensation, stuck.condensation
    # all mass sits on the master DOFs, so the mass-weighted products need only those rows
    free_to_stuck = stuck.shapes.T @ cs.M @ free.rows(cs.master)
    stuck_to_free = free.shapes.T @ cf.M @ stuck.rows(cf.master)
    return free_to_stuck, stuck_to_free


def round_trip_error(free: ModalBasis, stuck: ModalBasis) -> float:
    """Measure how far a free -> stuck -> free switch is from the identity.

    Returns ``||(A Phi_s)(B Phi_f) - I||_2`` (spectral norm, dimensionless). It is at
    rounding level (about 1e-15) when the stuck basis is complete, whatever the free
    truncation, and grows as stuck modes that the free modes excite are dropped.

    Parameters
    ----------
    free, stuck : ModalBasis
        Mass-normalized bases over the same active DOFs.

    Returns
    -------
    float
        Spectral norm of the round-trip error (dimensionless).
    """
    to_stuck, to_free = switch_matrices(free, stuck)
    product = to_free @ to_stuck
    return float(np.linalg.norm(product - np.eye(product.shape[0]), 2))


@dataclass(frozen=True, eq=False)   # arrays inside: compare by identity
class StuckTransforms:
    """Free/stuck coordinate transforms for one impactor.

    Attributes
    ----------
    free, stuck : ModalBasis
        The two bases.
    free_to_stuck : ndarray, shape (n_s, n_f)
        ``B Phi_f = Phi_s^T M_s Phi_f`` (dimensionless).
    stuck_to_free : ndarray, shape (n_f, n_s)
        ``A Phi_s = Phi_f^T M_f Phi_s`` (dimensionless).
    """

    free: ModalBasis
    stuck: ModalBasis
    free_to_stuck: np.ndarray
    stuck_to_free: np.ndarray

    @classmethod
    def from_bases(cls, free: ModalBasis, stuck: ModalBasis) -> StuckTransforms:
        """Build the transforms from a free and a stuck basis (see :func:`switch_matrices`)."""
        to_stuck, to_free = switch_matrices(free, stuck)
        to_stuck.setflags(write=False)
        to_free.setflags(write=False)
        return cls(free=free, stuck=stuck, free_to_stuck=to_stuck, stuck_to_free=to_free)

    def to_stuck(self, q: np.ndarray, qdot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Map free modal displacement (m sqrt(kg)) and velocity (m sqrt(kg)/s) to stuck."""
        return self.free_to_stuck @ q, self.free_to_stuck @ qdot

    def to_free(self, q: np.ndarray, qdot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Map stuck modal displacement (m sqrt(kg)) and velocity (m sqrt(kg)/s) to free."""
        return self.stuck_to_free @ q, self.stuck_to_free @ qdot

    def round_trip_error(self) -> float:
        """Return ``||(A Phi_s)(B Phi_f) - I||_2`` (dimensionless), as :func:`round_trip_error`."""
        product = self.stuck_to_free @ self.free_to_stuck
        return float(np.linalg.norm(product - np.eye(product.shape[0]), 2))

    def switch_loss(self, q: npt.ArrayLike, qdot: npt.ArrayLike) -> float:
        """Return the relative energy lost by a free -> stuck -> free round trip.

        The energy is that of the free modal model,
        ``E = (|qdot|^2 + q^T diag(omega^2) q)/2``, i.e. the mass-weighted velocity norm plus
        the strain energy of the symmetric stiffness.

        Parameters
        ----------
        q : array_like, shape (n_f,)
            Free modal displacement (m sqrt(kg)).
        qdot : array_like, shape (n_f,)
            Free modal velocity (m sqrt(kg)/s).

        Returns
        -------
        float
            ``1 - E_after/E_before`` (dimensionless); positive when energy is lost, 0 for a
            zero state.
        """
        q = np.asarray(q, dtype=float)
        qdot = np.asarray(qdot, dtype=float)
        q2, qdot2 = self.to_free(*self.to_stuck(q, qdot))
        w2 = self.free.omega ** 2
        before = qdot @ qdot + q @ (w2 * q)
        if before == 0.0:
            return 0.0
        after = qdot2 @ qdot2 + q2 @ (w2 * q2)
        return float(1.0 - after / before)


__all__ = ['StuckTransforms', 'add_point_mass', 'round_trip_error', 'stuck_basis',
           'switch_matrices']
