"""Isotropic linear-elastic materials (SI units: Pa, kg/m^3)."""
from __future__ import annotations

import math
from dataclasses import dataclass

NU_RANGE = (-1.0, 0.5)


def _positive(name: str, value: float, unit: str) -> float:
    """Return ``value`` as a float, or raise ValueError unless it is finite and > 0.

    Parameters
    ----------
    name : str
        Field name used in the error message.
    value : float
        Value to check (in ``unit``).
    unit : str
        Unit shown in the error message.

    Returns
    -------
    float
        The value (in ``unit``).
    """
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f'{name} must be a finite number > 0 ({unit}); got {value!r}') from None
    if isinstance(value, bool) or not math.isfinite(x) or x <= 0.0:
        raise ValueError(f'{name} must be a finite number > 0 ({unit}); got {value!r}')
    return x


def _poisson(nu: float) -> float:
    """Return ``nu`` as a float, or raise ValueError unless -1 < nu < 0.5 (dimensionless)."""
    try:
        ok = NU_RANGE[0] < float(nu) < NU_RANGE[1]
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ValueError(f'nu must lie in the open interval {NU_RANGE} (dimensionless); '
                         f'got {nu!r}')
    return float(nu)


@dataclass(frozen=True)
class Material:
    """Isotropic linear-elastic material.

    Parameters
    ----------
    E : float
        Young's modulus (Pa), finite and > 0.
    G : float
        Shear modulus (Pa), finite and > E/3 so that ``nu = E/(2G) - 1`` lies in (-1, 0.5).
    rho : float
        Density (kg/m^3), finite and > 0.

    Examples
    --------
    >>> steel = Material.from_poisson(200e9, 0.3, 7850.0)
    >>> round(steel.nu, 12), round(steel.G / 1e9, 6)
    (0.3, 76.923077)
    """

    E: float
    G: float
    rho: float

    def __post_init__(self) -> None:
        # Store plain floats so equality and hashing do not depend on the caller's types.
        object.__setattr__(self, 'E', _positive('E', self.E, 'Pa'))
        object.__setattr__(self, 'G', _positive('G', self.G, 'Pa'))
        object.__setattr__(self, 'rho', _positive('rho', self.rho, 'kg/m^3'))
        if not self.G > self.E / 3.0:
            raise ValueError(
                f'G must lie in (E/3, inf) = ({self.E / 3.0:.6g}, inf) Pa so that '
                f'nu = E/(2G) - 1 lies in {NU_RANGE}; got G={self.G!r} (nu={self.nu:.6g})')

    @classmethod
    def from_poisson(cls, E: float, nu: float, rho: float) -> Material:
        """Build a material from Young's modulus and Poisson's ratio.

        Parameters
        ----------
        E : float
            Young's modulus (Pa), finite and > 0.
        nu : float
            Poisson's ratio (dimensionless), in the open interval (-1, 0.5).
        rho : float
            Density (kg/m^3), finite and > 0.

        Returns
        -------
        Material
            With ``G = E / (2 (1 + nu))`` (Pa).
        """
        E = _positive('E', E, 'Pa')
        nu = _poisson(nu)
        return cls(E=E, G=E / (2.0 * (1.0 + nu)), rho=rho)

    @property
    def nu(self) -> float:
        """float: Poisson's ratio ``E/(2G) - 1`` (dimensionless)."""
        return self.E / (2.0 * self.G) - 1.0


STEEL = Material.from_poisson(200e9, 0.3, 7850.0)
"""Structural steel: E = 200 GPa, nu = 0.3, rho = 7850 kg/m^3."""

__all__ = ['Material', 'STEEL']
