"""The paper's "direct" method (section 3.1): Newmark in physical coordinates.

:func:`physical_model` turns an :class:`~impact_damper_sim.fem.system.AssembledSystem` into a
:class:`~.model.LinearModel` with ``kind='physical'`` over the condensed (mass-carrying) DOFs;
integrate it with :class:`~.newmark.NewmarkIntegrator` (``solver='sparse'`` for large sparse
models, e.g. with lumped rotary inertia so that nothing is condensed and ``K`` stays banded).

Damping. Per-mode "tare" damping does not exist in physical coordinates. The model gets the
system's discrete dampers (condensed like ``K``), plus optionally

* ``rayleigh=(alpha, beta)``: ``alpha M + beta K_sym`` (1/s, s);
* ``damping``: an explicit matrix over the system's *active* DOFs (N s/m), condensed as
  ``[I; T]^T C [I; T]``;
* ``tare_zeta``: ``M Phi diag(2 zeta omega) Phi^T M`` over all modes of the condensed system,
  which reproduces a complete modal model's tare damping exactly (with truncated modal models
  it damps the discarded modes differently).
"""
from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
import scipy.linalg as sla
import scipy.sparse as sp

from ..dampers.impactors import Impactor
from .model import LinearModel

if TYPE_CHECKING:
    from ..fem import AssembledSystem


def modal_damping_matrix(M: npt.NDArray[np.float64], K: npt.NDArray[np.float64],
                         zeta: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Physical damping matrix equivalent to per-mode damping ratios over all modes.

    Parameters
    ----------
    M : ndarray, shape (n, n)
        Mass matrix (kg), symmetric positive definite.
    K : ndarray, shape (n, n)
        Stiffness (N/m); its symmetric part defines the modes.
    zeta : float or array_like, shape (n,)
        Damping ratio of every mode, ascending frequency order (dimensionless).

    Returns
    -------
    ndarray, shape (n, n)
        ``C = M Phi diag(2 zeta omega) Phi^T M`` with mass-normalized ``Phi`` (N s/m).
    """
    K_sym = 0.5 * (K + K.T)
    w2, phi = sla.eigh(K_sym, M)
    omega = np.sqrt(np.clip(w2, 0.0, None))
    ratios = np.broadcast_to(np.asarray(zeta, dtype=float), omega.shape)
    Mphi = M @ phi
    return (Mphi * (2.0 * ratios * omega)) @ Mphi.T


def physical_model(system: AssembledSystem, *, force_indices: Sequence[int],
                   sensor_indices: Sequence[int],
                   impactors: Iterable[tuple[Impactor, Sequence[int]]] = (),
                   rayleigh: tuple[float, float] | None = None,
                   damping: npt.ArrayLike | sp.spmatrix | None = None,
                   tare_zeta: npt.ArrayLike | None = None, sensor_names: Iterable[str] = (),
                   input_names: Iterable[str] = ()) -> LinearModel:

    """Build the condensed physical-coordinate model of ``system``.

    Parameters
    ----------
    system : AssembledSystem
        Assembled structure (kg, N s/m, N/m) over its active DOFs.
    force_indices : sequence of int
        Active DOF index of each force input (dimensionless); input ``k`` is a force (N) or
        moment (N m) on DOF ``force_indices[k]``.
    sensor_indices : sequence of int
        Active DOF index of each sensor (dimensionless); massless DOFs are recovered through
        the condensation.
    impactors : sequence of (Impactor, indices)
        Each impactor spec (its ``rows`` are ignored) with the active DOF index (SDOF) or the
        two indices (planar, in the impactor's plane order) of its housing. The rows become
        the recovery rows of those DOFs (unit selectors on DOFs with mass). A spec with
        ``housing_mass = 0`` gets the lumped mass ``M_ii`` of its (first) housing DOF (kg),
        0 on a massless DOF.
    rayleigh : (float, float), optional
        ``(alpha, beta)``: adds ``alpha M + beta K_sym`` (alpha in 1/s, beta in s).
    damping : array_like or sparse matrix, shape (n_active, n_active), optional
        Extra damping over the active DOFs (N s/m), condensed with the stiffness recovery.
    tare_zeta : float or array_like, optional
        Per-mode damping ratios turned into a physical matrix by
        :func:`modal_damping_matrix` (dimensionless).
    sensor_names, input_names : tuple of str, optional
        Names (defaults as in :class:`LinearModel`).

    Returns
    -------
    LinearModel
        ``kind='physical'``; coordinates are the master DOFs of ``system.condense()``.
    """
    cond = system.condense()
    M = cond.M
    K = cond.K
    C = np.array(cond.C, dtype=float)
    n_active = cond.n_active
    if damping is not None:
        # (sp.issparse narrows nothing for mypy: scipy has no type stubs here)
        D = (damping.toarray() if sp.issparse(damping)  # type: ignore[union-attr]
             else np.asarray(damping, dtype=float))

        if D.shape != (n_active, n_active):
            raise ValueError(f'damping must be ({n_active}, {n_active}) over the active DOFs '
                             f'(N s/m), got {D.shape}')
        P = cond.recovery(np.arange(n_active))
        C = C + P.T @ D @ P
    if rayleigh is not None:
        alpha, beta = (float(x) for x in rayleigh)
        C = C + alpha * M + beta * 0.5 * (K + K.T)
    if tare_zeta is not None:
        C = C + modal_damping_matrix(M, K, tare_zeta)
    B = cond.recovery(np.atleast_1d(force_indices)).T
    S = cond.recovery(np.atleast_1d(sensor_indices))
    lumped = system.M.diagonal()
    bound = []
    for spec, indices in impactors:
        if not isinstance(spec, Impactor):
            raise TypeError(f'impactors must be (Impactor, indices) pairs, got {spec!r}')
        idx = np.atleast_1d(np.asarray(indices, dtype=np.int64))
        if idx.size != spec.dim:
            raise ValueError(f'impactor {spec.name!r} ({spec.kind}) needs {spec.dim} housing '
                             f'DOF index(es), got {idx.size}')
        m_h = spec.housing_mass if spec.housing_mass > 0 else float(lumped[idx[0]])
        bound.append(spec.with_rows(cond.recovery(idx), housing_mass=m_h))
    return LinearModel(M=M, C=C, K=K, B=B, sensors=S, sensor_names=tuple(sensor_names),
                       impactors=tuple(bound), kind='physical', input_names=tuple(input_names))
