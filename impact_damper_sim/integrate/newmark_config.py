"""The matrices of one stuck configuration of the Newmark integrator and their solves.

:class:`StuckConfiguration` holds ``M + sum m R^T R`` (the stuck impactors' masses added), the
impact mobilities and release transforms of each impactor, and the cached factors of the
Newmark step matrix; :class:`~.newmark.NewmarkIntegrator` keeps one per set of stuck
impactors and :mod:`.newmark_events` reads them.
"""
from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..dampers.law import law_mobility

if TYPE_CHECKING:
    from .model import LinearModel

FloatArray = npt.NDArray[np.float64]


class StuckConfiguration:
    """Matrices of one stuck configuration: ``M + sum m R^T R`` and its solves."""

    def __init__(self, model: LinearModel, rows: FloatArray, stuck_masses: Sequence[float],
                 law: str, sparse: bool, C: FloatArray | sp.spmatrix,
                 K: FloatArray | sp.spmatrix) -> None:
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
        # inverse (dense) or LU (sparse) of S(h) by step size h
        self._S: dict[float, Any] = {}

    def solve_M(self, r: FloatArray) -> FloatArray:
        """``M^{-1} r`` for this configuration."""
        if self.sparse:
            return self._lu_M.solve(np.asarray(r, dtype=float))
        return self.Minv @ r

    def S(self, h: float) -> Any:
        """``M + h/2 C + h^2/4 K`` (the effective stiffness times ``h^2/4``)."""
        return self.M + (0.5 * h) * self.C + (0.25 * h * h) * self.K

    def Sinv(self, h: float) -> Any:
        """Cached inverse (dense) or LU (sparse) of ``S(h)`` for the main step size."""
        fac = self._S.get(h)
        if fac is None:
            fac = spla.splu(sp.csc_matrix(self.S(h))) if self.sparse \
                else np.linalg.inv(self.S(h))
            if len(self._S) > 4:      # only a few step sizes recur
                self._S.clear()
            self._S[h] = fac
        return fac

    def solve_S(self, h: float, r: FloatArray, cached: bool) -> FloatArray:
        """``S(h)^{-1} r``; ``cached`` for the recurring step size, else a fresh solve."""
        if cached:
            fac = self.Sinv(h)
            return fac.solve(r) if self.sparse else fac @ r
        if self.sparse:
            return spla.splu(sp.csc_matrix(self.S(h))).solve(r)
        return np.linalg.solve(self.S(h), r)


__all__ = ['StuckConfiguration']
