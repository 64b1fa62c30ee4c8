"""The linear model every integrator works on.

``M q'' + C q' + K q = B u(t)``, with sensor rows ``S`` (``x_s = S q``) and impactors whose
housings are rows of the same coordinates. A *modal* model has ``M = I`` and mass-normalized
modal coordinates; a *physical* model has the condensed physical matrices and unit rows.
"""
from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from ..dampers.impactors import Impactor


@dataclass(frozen=True)
class LinearModel:
    """A second-order linear model with its force inputs, sensors and impactors.

    Parameters
    ----------
    M : ndarray, shape (n, n)
        Mass matrix (kg, or 1 for mass-normalized modal coordinates), symmetric positive.
    C : ndarray, shape (n, n)
        Damping matrix (N s/m in physical coordinates, 1/s in modal ones).
    K : ndarray, shape (n, n)
        Stiffness (N/m, or rad^2/s^2 modal); its skew part is a circulatory coupling.
    B : ndarray, shape (n, n_f)
        Force input matrix: generalized force ``B u`` for forces ``u`` (N).
    sensors : ndarray, shape (n_s, n)
        Sensor rows: sensor displacement ``S q`` (m).
    sensor_names : tuple of str
        One name per sensor row.
    impactors : tuple of Impactor
        Impactors bound to rows of these coordinates.
    kind : {'modal', 'physical'}
        Coordinates of the model.
    """

    M: np.ndarray
    C: np.ndarray
    K: np.ndarray
    B: np.ndarray
    sensors: np.ndarray
    sensor_names: tuple[str, ...] = ()
    impactors: tuple[Impactor, ...] = ()
    kind: str = 'modal'
    input_names: tuple[str, ...] = ()
    _cache: dict[object, object] = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self) -> None:
        n = np.shape(self.K)[0]
        for name in ('M', 'C', 'K'):
            value = np.asarray(getattr(self, name), dtype=float)
            if value.shape != (n, n) or not np.all(np.isfinite(value)):
                raise ValueError(f'LinearModel.{name} must be a finite ({n}, {n}) matrix')
            object.__setattr__(self, name, value)
        B = np.asarray(self.B, dtype=float).reshape(n, -1)
        S = np.asarray(self.sensors, dtype=float).reshape(-1, n)
        object.__setattr__(self, 'B', B)
        object.__setattr__(self, 'sensors', S)
        if not self.sensor_names:
            object.__setattr__(self, 'sensor_names',
                               tuple(f'sensor{k}' for k in range(S.shape[0])))
        if len(self.sensor_names) != S.shape[0]:
            raise ValueError('one sensor name per sensor row is required')
        if not self.input_names:
            object.__setattr__(self, 'input_names', tuple(f'input{k}' for k in range(B.shape[1])))
        object.__setattr__(self, 'impactors', tuple(self.impactors))
        for imp in self.impactors:
            if not isinstance(imp, Impactor) or imp.rows.shape[1] != n:
                raise ValueError(f'impactor {getattr(imp, "name", imp)!r} is not bound to '
                                 f'{n} coordinates')
        if not np.allclose(self.M, self.M.T, rtol=0, atol=1e-12 * np.abs(self.M).max()):
            raise ValueError('LinearModel.M must be symmetric')

    @property
    def n(self) -> int:
        """int: Number of coordinates."""
        return self.K.shape[0]

    @property
    def n_inputs(self) -> int:
        """int: Number of force inputs."""
        return self.B.shape[1]

    @property
    def K_sym(self) -> npt.NDArray[np.float64]:
        """ndarray: Symmetric (conservative) part of ``K``."""
        return 0.5 * (self.K + self.K.T)

    @property
    def K_skew(self) -> npt.NDArray[np.float64]:
        """ndarray: Skew (circulatory) part of ``K``."""
        return 0.5 * (self.K - self.K.T)

    def stuck_mass_matrix(self, stuck_masses: Sequence[float] | np.ndarray
                          ) -> npt.NDArray[np.float64]:
        """Return ``M + sum_j m_j R_j^T R_j`` for impactors moving with their housing.

        Parameters
        ----------
        stuck_masses : sequence of float
            Mass (kg) riding each impactor's housing, 0 for free impactors.

        Returns
        -------
        ndarray, shape (n, n)
            The mass matrix of the stuck configuration (exact rank updates, no basis change).
        """
        M = self.M.copy()
        for imp, m in zip(self.impactors, stuck_masses):
            if m:
                M += m * imp.rows.T @ imp.rows
        return M

    def with_impactors(self, impactors: Iterable[Impactor]) -> LinearModel:

        """Return a copy with other impactors (e.g. none, to run the linear path)."""
        return LinearModel(self.M, self.C, self.K, self.B, self.sensors, self.sensor_names,
                           tuple(impactors), self.kind, self.input_names)
