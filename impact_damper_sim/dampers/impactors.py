"""Impactors bound to a linear model: particles moving freely inside a clearance.

An impactor's *housing* is a set of one (SDOF) or two (planar) DOF rows of the simulated
model: ``x_h = rows @ q`` is the housing displacement (m). For a modal model the rows are
mode-shape values; for a physical model they are unit selectors.

* SDOF impactor: relative coordinate ``r = z - x_h`` with ``-D/2 <= r <= D/2``; ``D`` is the
  total free travel (m).
* Planar (cylindrical) impactor: relative position ``r = z - x_h`` (2-vector) with
  ``|r| <= c``; ``c`` is the radial clearance (m).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

SDOF = 'sdof'
PLANAR = 'planar'


@dataclass(frozen=True)
class Impactor:
    """One impactor bound to the rows of a model.

    Parameters
    ----------
    name : str
        Identifier used in events and outputs.
    kind : {'sdof', 'planar'}
        One direction at one DOF, or two in-plane directions at one node.
    mass : float
        Impactor mass (kg), > 0.
    cor : float
        Coefficient of restitution along the contact normal (dimensionless), 0..1.
    clearance : float
        SDOF: total free travel D (m). Planar: radial clearance c (m). > 0.
    rows : ndarray, shape (1, n) or (2, n)
        Housing DOF rows of the model (dimensionless map from coordinates to m).
    housing_mass : float
        Lumped housing mass at the impactor location (kg), used only by the paper's
        lumped-mass impact law. ``0`` means not given.
    position : ndarray
        Initial relative position ``z - x_h`` (m), inside the clearance.
    velocity : ndarray
        Initial absolute impactor velocity (m/s).
    """

    name: str
    kind: str
    mass: float
    cor: float
    clearance: float
    rows: np.ndarray
    housing_mass: float = 0.0
    position: np.ndarray | None = field(default=None)
    velocity: np.ndarray | None = field(default=None)

    def __post_init__(self) -> None:
        if self.kind not in (SDOF, PLANAR):
            raise ValueError(f'impactor {self.name!r}: kind must be "sdof" or "planar", '
                             f'got {self.kind!r}')
        dim = 1 if self.kind == SDOF else 2
        rows = np.atleast_2d(np.asarray(self.rows, dtype=float))
        if rows.shape[0] != dim:
            raise ValueError(f'impactor {self.name!r}: {self.kind} needs {dim} housing row(s), '
                             f'got {rows.shape[0]}')
        checks = (('mass', self.mass, 0.0, np.inf, False),
                  ('cor', self.cor, 0.0, 1.0, True),
                  ('clearance', self.clearance, 0.0, np.inf, False),
                  ('housing_mass', self.housing_mass, 0.0, np.inf, True))
        for name, value, lo, hi, lo_ok in checks:
            ok = np.isfinite(value) and (value >= lo if lo_ok else value > lo) and value <= hi
            if not ok:
                bracket = '[' if lo_ok else '('
                raise ValueError(f'impactor {self.name!r}: {name}={value} out of range '
                                 f'{bracket}{lo}, {hi}]')
        pos = np.zeros(dim) if self.position is None else np.asarray(self.position, float)
        vel = np.zeros(dim) if self.velocity is None else np.asarray(self.velocity, float)
        if pos.shape != (dim,) or vel.shape != (dim,):
            raise ValueError(f'impactor {self.name!r}: position/velocity must have {dim} entries')
        limit = self.clearance / 2 if self.kind == SDOF else self.clearance
        if np.linalg.norm(pos) > limit * (1 + 1e-12):
            raise ValueError(f'impactor {self.name!r}: initial position {pos} m lies outside '
                             f'the clearance (|r| <= {limit} m)')
        object.__setattr__(self, 'rows', rows)
        object.__setattr__(self, 'position', pos)
        object.__setattr__(self, 'velocity', vel)

    @property
    def dim(self) -> int:
        """int: 1 for SDOF, 2 for planar."""
        return self.rows.shape[0]

    @property
    def limit(self) -> float:
        """float: largest allowed ``|r|`` (m): ``D/2`` for SDOF, ``c`` for planar."""
        return self.clearance / 2 if self.kind == SDOF else self.clearance

    def with_rows(self, rows: np.ndarray, housing_mass: float | None = None) -> Impactor:
        """Return a copy bound to other rows (e.g. another coordinate system)."""
        return Impactor(self.name, self.kind, self.mass, self.cor, self.clearance, rows,
                        self.housing_mass if housing_mass is None else housing_mass,
                        self.position, self.velocity)
