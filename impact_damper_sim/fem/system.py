"""Assembled structural system over the active DOFs, and static condensation.

Conventions
-----------
* Every node carries six DOFs in the global frame, in the order of :data:`DOF_NAMES`:
  translations ``ux, uy, uz`` (m) and rotations ``rx, ry, rz`` (rad).
* *Active* DOFs are those left after clamping. ``AssembledSystem.dofs[k] = (node, component)``
  names active DOF ``k``; matrices are indexed by active DOF.
* Units are SI: mass kg (kg m^2 on rotations), stiffness N/m (N m/rad), damping N s/m.
"""
from __future__ import annotations

import numbers
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
import scipy.sparse.linalg as spla

# a dense array_like or a scipy.sparse matrix (scipy has no type information: Any)
MatrixLike = Any

DOF_NAMES = ('ux', 'uy', 'uz', 'rx', 'ry', 'rz')
DOFS_PER_NODE = 6


def component_index(component: int | str) -> int:
    """Return the component number (0..5) of a DOF name or number.

    Parameters
    ----------
    component : int or str
        ``0..5`` or one of ``'ux', 'uy', 'uz', 'rx', 'ry', 'rz'`` (dimensionless).

    Returns
    -------
    int
        Component number (dimensionless).
    """
    if isinstance(component, str):
        try:
            return DOF_NAMES.index(component)
        except ValueError:
            raise ValueError(f'unknown DOF component {component!r}; allowed: {DOF_NAMES}') from None
    # int() would silently truncate 1.7 -> 1 and accept True: allow integers only.
    if isinstance(component, (bool, np.bool_)) or not isinstance(component, numbers.Integral):
        raise ValueError(
            f'DOF component must be 0..5 or one of {DOF_NAMES}; got {component!r}')
    component = int(component)
    if not 0 <= component < DOFS_PER_NODE:
        raise ValueError(f'DOF component {component} out of range 0..5')
    return component


@dataclass(frozen=True)
class Condensation:
    """Static condensation of the massless DOFs (exact for a lumped, diagonal-block mass).

    With ``u = [u_m; u_s]`` and ``M_ss = 0``, equilibrium of the slave rows gives
    ``u_s = T u_m`` with ``T = -K_ss^{-1} K_sm``. The condensed matrices are
    ``K_c = K_mm + K_ms T`` and ``C_c = [I; T]^T C [I; T]``; ``M_c = M_mm``.

    Attributes
    ----------
    master : ndarray of int
        Active indices of the DOFs that carry mass (kept).
    slave : ndarray of int
        Active indices of the massless DOFs (condensed out).
    M, C, K : ndarray
        Condensed mass (kg), damping (N s/m) and stiffness (N/m) over ``master``; dense.
    T : ndarray
        Slave recovery matrix, ``u_s = T u_m`` (shape ``(len(slave), len(master))``).
    n_active : int
        Number of active DOFs before condensation.
    """

    master: np.ndarray
    slave: np.ndarray
    M: np.ndarray
    C: np.ndarray
    K: np.ndarray
    T: np.ndarray
    n_active: int
    _position: np.ndarray = field(repr=False)

    @property
    def K_sym(self) -> np.ndarray:
        """ndarray: Symmetric part of the condensed stiffness (N/m)."""
        return 0.5 * (self.K + self.K.T)

    def recovery(self, active_rows: npt.ArrayLike) -> np.ndarray:
        """Return ``R`` such that ``u[active_rows] = R @ u_master``.

        Parameters
        ----------
        active_rows : array_like of int
            Active DOF indices (dimensionless).

        Returns
        -------
        ndarray
            Shape ``(len(active_rows), len(master))`` (dimensionless).
        """
        rows = np.atleast_1d(np.asarray(active_rows, dtype=np.int64))
        out = np.zeros((rows.size, self.master.size))
        for r, k in enumerate(rows):
            if not 0 <= k < self.n_active:
                raise IndexError(f'active DOF index {k} out of range 0..{self.n_active - 1}')
            pos = self._position[k]
            if pos >= 0:
                out[r, pos] = 1.0
            else:
                out[r] = self.T[-pos - 1]
        return out


@dataclass(frozen=True)
class AssembledSystem:
    """Global ``M``, ``C`` and ``K`` over the active (unclamped) DOFs.

    Attributes
    ----------
    M : scipy.sparse.csr_matrix
        Mass matrix (kg, kg m^2), symmetric.
    C : scipy.sparse.csr_matrix
        Physical (discrete) damping matrix (N s/m), symmetric.
    K : scipy.sparse.csr_matrix
        Stiffness matrix (N/m); non-symmetric when a cross-coupled stiffness is present.
    dofs : ndarray of int, shape (n, 2)
        ``(node, component)`` of each active DOF.
    """

    M: sp.csr_matrix
    C: sp.csr_matrix
    K: sp.csr_matrix
    dofs: np.ndarray
    # not an init field: dataclasses.replace() would otherwise share (and mutate) the dict
    _lookup: dict[tuple[int, int], int] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        n = self.dofs.shape[0]
        for name in ('M', 'C', 'K'):
            shape = getattr(self, name).shape
            if shape != (n, n):
                raise ValueError(f'{name} has shape {shape}, expected ({n}, {n})')
        object.__setattr__(self, '_lookup',
                           {(int(a), int(b)): k for k, (a, b) in enumerate(self.dofs)})

    @property
    def n_dof(self) -> int:
        """int: Number of active DOFs."""
        return self.dofs.shape[0]

    def index(self, node: int, component: int | str) -> int:
        """Return the active index of DOF ``component`` at ``node``.

        Parameters
        ----------
        node : int
            Node id (dimensionless).
        component : int or str
            ``0..5`` or ``'ux'`` ... ``'rz'``.

        Returns
        -------
        int
            Active DOF index. Raises ``KeyError`` naming the DOF if it is clamped or unknown.
        """
        key = (int(node), component_index(component))
        try:
            return self._lookup[key]
        except KeyError:
            raise KeyError(
                f'DOF {DOF_NAMES[key[1]]} at node {key[0]} is clamped or does not exist'
            ) from None

    def skew_part(self) -> sp.csr_matrix:
        """Return the skew-symmetric part ``(K - K^T)/2`` of the stiffness (N/m), sparse."""
        return ((self.K - self.K.T) * 0.5).tocsr()

    def massless(self, rtol: float = 1e-14) -> np.ndarray:
        """Return a boolean mask of DOFs whose mass row is zero (to ``rtol`` of the largest)."""
        row_max = abs(self.M).max(axis=1).toarray().ravel()
        scale = row_max.max() if row_max.size else 0.0
        return row_max <= rtol * scale

    def condense(self) -> Condensation:
        """Condense the massless DOFs statically.

        Returns
        -------
        Condensation
            Dense condensed matrices over the DOFs with mass, and the slave recovery.
        """
        n = self.n_dof
        mass_free = self.massless()
        master = np.flatnonzero(~mass_free)
        slave = np.flatnonzero(mass_free)
        if master.size == 0:
            raise ValueError('the structure has no mass: nothing to simulate')
        K = self.K.tocsc()
        C = self.C.tocsc()
        M = self.M.tocsc()
        if slave.size:
            K_ss = K[slave][:, slave].tocsc()
            K_sm = K[slave][:, master].toarray()
            try:
                lu = spla.splu(K_ss)
                T = -lu.solve(K_sm)
            except RuntimeError as exc:
                raise ValueError(
                    'the massless DOFs are not restrained (singular K_ss): clamp the structure '
                    'or give rotary inertia to the free rotations') from exc
            if not np.all(np.isfinite(T)):
                raise ValueError('static condensation produced non-finite values (singular K_ss)')
        else:
            T = np.zeros((0, master.size))
        P = np.zeros((n, master.size))
        P[master, np.arange(master.size)] = 1.0
        P[slave] = T
        Kc = P.T @ (K @ P)
        Cc = P.T @ (C @ P)
        Mc = M[master][:, master].toarray()
        position = np.empty(n, dtype=np.int64)
        position[master] = np.arange(master.size)
        position[slave] = -(np.arange(slave.size) + 1)
        return Condensation(master=master, slave=slave, M=Mc, C=np.asarray(Cc),
                            K=np.asarray(Kc), T=T, n_active=n, _position=position)


def dense_symmetric_part(matrix: MatrixLike) -> np.ndarray:
    """Return the symmetric part ``(A + A^T)/2`` of a dense or sparse matrix, dense."""
    a = matrix.toarray() if sp.issparse(matrix) else np.asarray(matrix, dtype=float)
    return 0.5 * (a + a.T)


def is_symmetric(matrix: MatrixLike, rtol: float = 1e-12) -> bool:
    """Return True if ``matrix`` equals its transpose to ``rtol`` of its largest entry."""
    a = matrix.toarray() if sp.issparse(matrix) else np.asarray(matrix)
    scale = np.abs(a).max() if a.size else 0.0
    return bool(np.abs(a - a.T).max(initial=0.0) <= rtol * max(scale, np.finfo(float).tiny))


__all__ = ['DOF_NAMES', 'DOFS_PER_NODE', 'AssembledSystem', 'Condensation', 'component_index',
           'dense_symmetric_part', 'is_symmetric']
