"""Beam cross-sections.

Every section exposes, in the element's local frame (x along the axis):

* ``A`` : area (m^2);
* ``Iy``, ``Iz`` : second moments of area about local y and z (m^4). ``Iz`` resists bending in
  the local x-y plane, ``Iy`` bending in the x-z plane;
* ``J`` : torsion constant (m^4), giving the torsional stiffness ``G J / L``;
* ``Ip`` : polar second moment of area (m^4), giving the torsional rotary inertia ``rho Ip``;
* ``shear_coefficients(nu) -> (kappa_y, kappa_z)`` : Timoshenko shear coefficients for shear
  along local y and z (dimensionless); ``inf`` means no shear deformation.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from .materials import _poisson, _positive


def cowper_hollow_circle(nu: float, m: float) -> float:
    """Cowper's shear coefficient of a circular tube.

    Parameters
    ----------
    nu : float
        Poisson's ratio (dimensionless).
    m : float
        Diameter ratio ``d_i / d_o`` (dimensionless), 0 <= m < 1; m = 0 is the solid circle.

    Returns
    -------
    float
        ``6(1+nu)(1+m^2)^2 / ((7+6nu)(1+m^2)^2 + (20+12nu)m^2)`` (dimensionless); it tends to
        the thin-tube value ``2(1+nu)/(4+3nu)`` as m -> 1 (Cowper, J. Appl. Mech. 33, 1966).
    """
    nu = _poisson(nu)
    q = (1.0 + m * m) ** 2
    return 6.0 * (1.0 + nu) * q / ((7.0 + 6.0 * nu) * q + (20.0 + 12.0 * nu) * m * m)


@dataclass(frozen=True)
class SolidCircular:
    """Solid circular section.

    Parameters
    ----------
    diameter : float
        Diameter (m), finite and > 0.

    Examples
    --------
    >>> s = SolidCircular(0.05)
    >>> s.J == s.Ip == 2 * s.Iy
    True
    """

    diameter: float

    def __post_init__(self) -> None:
        object.__setattr__(self, 'diameter', _positive('diameter', self.diameter, 'm'))

    @property
    def A(self) -> float:
        """float: Area (m^2)."""
        return math.pi * self.diameter ** 2 / 4.0

    @property
    def Iy(self) -> float:
        """float: Second moment of area about local y (m^4)."""
        return math.pi * self.diameter ** 4 / 64.0

    @property
    def Iz(self) -> float:
        """float: Second moment of area about local z (m^4)."""
        return self.Iy

    @property
    def J(self) -> float:
        """float: Torsion constant (m^4); equals ``Ip`` for a circle."""
        return self.Ip

    @property
    def Ip(self) -> float:
        """float: Polar second moment of area (m^4)."""
        return math.pi * self.diameter ** 4 / 32.0

    def shear_coefficients(self, nu: float) -> tuple[float, float]:
        """Return Cowper's ``(kappa_y, kappa_z) = 6(1+nu)/(7+6nu)`` twice (dimensionless).

        Parameters
        ----------
        nu : float
            Poisson's ratio (dimensionless), in (-1, 0.5).
        """
        k = cowper_hollow_circle(nu, 0.0)
        return k, k


@dataclass(frozen=True)
class HollowCircular:
    """Circular tube.

    Parameters
    ----------
    outer_diameter : float
        Outer diameter (m), finite and > 0.
    inner_diameter : float
        Inner diameter (m), 0 <= inner_diameter < outer_diameter (0 gives the solid circle).
    """

    outer_diameter: float
    inner_diameter: float

    def __post_init__(self) -> None:
        do = _positive('outer_diameter', self.outer_diameter, 'm')
        try:
            di = float(self.inner_diameter)
        except (TypeError, ValueError):
            di = math.nan
        if not (0.0 <= di < do):
            raise ValueError(f'inner_diameter must lie in [0, outer_diameter) = [0, {do!r}) m; '
                             f'got {self.inner_diameter!r}')
        object.__setattr__(self, 'outer_diameter', do)
        object.__setattr__(self, 'inner_diameter', di)

    @property
    def A(self) -> float:
        """float: Area (m^2)."""
        return math.pi * (self.outer_diameter ** 2 - self.inner_diameter ** 2) / 4.0

    @property
    def Iy(self) -> float:
        """float: Second moment of area about local y (m^4)."""
        return math.pi * (self.outer_diameter ** 4 - self.inner_diameter ** 4) / 64.0

    @property
    def Iz(self) -> float:
        """float: Second moment of area about local z (m^4)."""
        return self.Iy

    @property
    def J(self) -> float:
        """float: Torsion constant (m^4); equals ``Ip`` for a circular tube."""
        return self.Ip

    @property
    def Ip(self) -> float:
        """float: Polar second moment of area (m^4)."""
        return math.pi * (self.outer_diameter ** 4 - self.inner_diameter ** 4) / 32.0

    def shear_coefficients(self, nu: float) -> tuple[float, float]:
        """Return Cowper's thick-tube ``(kappa_y, kappa_z)`` (dimensionless).

        Parameters
        ----------
        nu : float
            Poisson's ratio (dimensionless), in (-1, 0.5).
        """
        k = cowper_hollow_circle(nu, self.inner_diameter / self.outer_diameter)
        return k, k


@dataclass(frozen=True)
class GeneralSection:
    """Section given by its properties.

    Parameters
    ----------
    A : float
        Area (m^2), > 0.
    Iy : float
        Second moment of area about local y (m^4), > 0; resists bending in the x-z plane.
    Iz : float
        Second moment of area about local z (m^4), > 0; resists bending in the x-y plane.
    J : float
        Torsion constant (m^4), > 0.
    Ip : float, optional
        Polar second moment of area (m^4), > 0, for the torsional rotary inertia. Default
        ``Iy + Iz``.
    kappa_y, kappa_z : float, optional
        Shear coefficients for shear along local y and z (dimensionless), > 0. ``None`` (the
        default) means no shear deformation in that plane (``kappa = inf``).
    """

    A: float
    Iy: float
    Iz: float
    J: float
    Ip: float | None = None
    kappa_y: float | None = None
    kappa_z: float | None = None

    def __post_init__(self) -> None:
        for name in ('A', 'Iy', 'Iz', 'J'):
            unit = 'm^2' if name == 'A' else 'm^4'
            object.__setattr__(self, name, _positive(name, getattr(self, name), unit))
        ip = self.Iy + self.Iz if self.Ip is None else _positive('Ip', self.Ip, 'm^4')
        object.__setattr__(self, 'Ip', ip)
        for name in ('kappa_y', 'kappa_z'):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, _positive(name, value, 'dimensionless'))

    def shear_coefficients(self, nu: float) -> tuple[float, float]:
        """Return ``(kappa_y, kappa_z)`` (dimensionless), ``inf`` where not given.

        Parameters
        ----------
        nu : float
            Poisson's ratio (dimensionless), in (-1, 0.5); only validated.
        """
        _poisson(nu)
        return (math.inf if self.kappa_y is None else self.kappa_y,
                math.inf if self.kappa_z is None else self.kappa_z)


# any of the section classes: what the beam element and FEModel.add_beam take
Section = SolidCircular | HollowCircular | GeneralSection

__all__ = ['Section', 'SolidCircular', 'HollowCircular', 'GeneralSection', 'cowper_hollow_circle']
