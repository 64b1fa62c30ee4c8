"""Two-node, 12-DOF 3D Timoshenko beam element (Przemieniecki) with a lumped mass.

Conventions
-----------
* DOFs per node, in this order: ``ux, uy, uz`` (m) and ``rx, ry, rz`` (rad); the element
  vector is ``[node i (6), node j (6)]``.
* Local frame: ``x`` runs from node i to node j. Local ``y`` is the part of an orientation
  (reference) vector normal to ``x``, normalised; local ``z = x cross y``. The default
  reference is global Z; for an element parallel to global Z (within 1e-6 rad) it is global Y.
  So a beam along global X gets local ``y = +Z`` and local ``z = -Y``.
* ``u_local = T u_global`` with ``T = blockdiag(R, R, R, R)`` and the rows of ``R`` the local
  unit vectors in global coordinates; element matrices are ``T^T k_local T``.
* Bending in the local x-y plane (``uy``, ``rz``) uses ``E Iz`` and
  ``Phi_y = 12 E Iz / (kappa_y G A L^2)``; bending in the x-z plane (``uz``, ``ry``) uses
  ``E Iy`` and ``Phi_z = 12 E Iy / (kappa_z G A L^2)``. ``Phi = 0`` is Euler-Bernoulli.

Reference: J. S. Przemieniecki, *Theory of Matrix Structural Analysis*, McGraw-Hill, 1968.
"""
from __future__ import annotations

import numpy as np
import numpy.typing as npt

from .materials import Material
from .sections import Section

_PARALLEL_SIN = 1e-6  # sin of the angle below which a reference vector counts as parallel


def _point(name: str, xyz: npt.ArrayLike, unit: str = 'm') -> np.ndarray:
    try:
        p = np.asarray(xyz, dtype=float)
    except (TypeError, ValueError):
        p = None
    if p is None or p.shape != (3,) or not np.all(np.isfinite(p)):
        raise ValueError(f'{name} must be 3 finite coordinates ({unit}); got {xyz!r}')
    return p


def _flag(name: str, value: object) -> bool:
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f'{name} must be True or False; got {value!r}')
    return bool(value)


def _length(length: float | np.floating) -> float:
    try:
        value = float(length)
    except (TypeError, ValueError):
        value = np.nan
    if not np.isfinite(value) or value <= 0.0:
        raise ValueError(f'length must be a finite number > 0 (m); got {length!r}')
    return value


def shear_parameters(material: Material, section: Section, length: float | np.floating, *,
                     shear: bool = True) -> tuple[float, float]:
    """Return the shear-deformation parameters ``(Phi_y, Phi_z)``.

    Parameters
    ----------
    material : Material
        ``E`` (Pa) and ``G`` (Pa) are used.
    section : section object
        ``A`` (m^2), ``Iy``, ``Iz`` (m^4) and ``shear_coefficients(nu)`` are used.
    length : float
        Element length (m), > 0.
    shear : bool
        False gives Euler-Bernoulli (``Phi = 0``).

    Returns
    -------
    tuple of float
        ``Phi_y = 12 E Iz/(kappa_y G A L^2)`` (x-y plane) and
        ``Phi_z = 12 E Iy/(kappa_z G A L^2)`` (x-z plane), dimensionless.
    """
    length = _length(length)
    if not _flag('shear', shear):
        return 0.0, 0.0
    kappa_y, kappa_z = section.shear_coefficients(material.nu)
    gal2 = material.G * section.A * length ** 2
    # kappa = inf (no shear deformation) gives exactly 0.
    return (12.0 * material.E * section.Iz / (kappa_y * gal2),
            12.0 * material.E * section.Iy / (kappa_z * gal2))


def _bending_block(ei: float, phi: float, length: float, sign: float) -> np.ndarray:
    """4x4 bending stiffness on (v_i, theta_i, v_j, theta_j) in N/m, N/rad, N m/rad.

    ``sign`` is +1 in the x-y plane (theta_z = +dv/dx) and -1 in the x-z plane
    (theta_y = -dw/dx), which flips the translation-rotation coupling.
    """
    L = length
    c = ei / (L ** 3 * (1.0 + phi))
    s = sign * 6.0 * L
    a = (4.0 + phi) * L * L
    b = (2.0 - phi) * L * L
    return c * np.array([[12.0, s, -12.0, s],
                         [s, a, -s, b],
                         [-12.0, -s, 12.0, -s],
                         [s, b, -s, a]])


def beam_local_stiffness(material: Material, section: Section, length: float | np.floating, *,
                         shear: bool = True) -> np.ndarray:
    """Return the 12x12 element stiffness in the local frame.

    Parameters
    ----------
    material : Material
        ``E`` (Pa), ``G`` (Pa).
    section : section object
        ``A`` (m^2), ``Iy``, ``Iz``, ``J`` (m^4), ``shear_coefficients(nu)``.
    length : float
        Element length (m), > 0.
    shear : bool
        Include shear deformation (Timoshenko); False gives Euler-Bernoulli.

    Returns
    -------
    ndarray, shape (12, 12)
        Stiffness (N/m, N/rad, N m/rad), symmetric.

    Examples
    --------
    A 0.5 m steel shaft of 50 mm diameter: the lateral term is ``12 E I / L^3`` without shear
    and about 2 % less with it; the corner is axial ``E A / L``, lateral and torsional
    ``G J / L`` (MN/m, MN m/rad):

    >>> import numpy as np
    >>> from impact_damper_sim.fem import STEEL, SolidCircular
    >>> section, length = SolidCircular(0.05), 0.5
    >>> k = beam_local_stiffness(STEEL, section, length, shear=False)
    >>> round(float(k[1, 1]) * length**3 / (STEEL.E * section.Iz), 9)
    12.0
    >>> np.round(k[:4, :4] / 1e6, 1).tolist()
    [[785.4, 0.0, 0.0, 0.0], [0.0, 5.9, 0.0, 0.0], [0.0, 0.0, 5.9, 0.0], [0.0, 0.0, 0.0, 0.1]]
    >>> round(float(beam_local_stiffness(STEEL, section, length)[1, 1] / k[1, 1]), 4)
    0.9785
    """
    length = _length(length)
    phi_y, phi_z = shear_parameters(material, section, length, shear=shear)
    E, G = material.E, material.G
    k = np.zeros((12, 12))
    for dofs, value in (((0, 6), E * section.A / length), ((3, 9), G * section.J / length)):
        k[np.ix_(dofs, dofs)] = value * np.array([[1.0, -1.0], [-1.0, 1.0]])
    k[np.ix_((1, 5, 7, 11), (1, 5, 7, 11))] = _bending_block(E * section.Iz, phi_y, length, 1.0)
    k[np.ix_((2, 4, 8, 10), (2, 4, 8, 10))] = _bending_block(E * section.Iy, phi_z, length, -1.0)
    return k


def beam_local_mass(material: Material, section: Section, length: float | np.floating, *,
                    rotary_inertia: bool = False) -> np.ndarray:
    """Return the 12x12 lumped element mass in the local frame (diagonal).

    Parameters
    ----------
    material : Material
        ``rho`` (kg/m^3).
    section : section object
        ``A`` (m^2); with rotary inertia also ``Ip``, ``Iy``, ``Iz`` (m^4).
    length : float
        Element length (m), > 0.
    rotary_inertia : bool
        Lump ``rho Ip L/2``, ``rho Iy L/2``, ``rho Iz L/2`` on ``rx, ry, rz`` at each end;
        otherwise the rotations are massless.

    Returns
    -------
    ndarray, shape (12, 12)
        Mass (kg on translations, kg m^2 on rotations).

    Examples
    --------
    Half of the 7.71 kg element on each end's translations, nothing on its rotations:

    >>> import numpy as np
    >>> from impact_damper_sim.fem import STEEL, SolidCircular
    >>> m = beam_local_mass(STEEL, SolidCircular(0.05), 0.5)
    >>> np.round(np.diag(m)[:6], 4).tolist()
    [3.8534, 3.8534, 3.8534, 0.0, 0.0, 0.0]
    """
    length = _length(length)
    half = 0.5 * material.rho * length
    m = half * section.A
    if _flag('rotary_inertia', rotary_inertia):
        assert section.Ip is not None   # GeneralSection.__post_init__ fills in Iy + Iz
        rot = [half * section.Ip, half * section.Iy, half * section.Iz]
    else:
        rot = [0.0, 0.0, 0.0]
    return np.diag(np.tile([m, m, m, *rot], 2))


def beam_rotation(xyz_i: npt.ArrayLike, xyz_j: npt.ArrayLike,
                  orientation: npt.ArrayLike | None = None) -> np.ndarray:
    """Return the rotation ``R`` (rows = local x, y, z in global coordinates).

    Parameters
    ----------
    xyz_i, xyz_j : array_like, shape (3,)
        End coordinates (m); must differ.
    orientation : array_like, shape (3,), optional
        Reference vector (any unit; only its direction is used) whose component normal to the
        axis sets local y. It must not be parallel to the axis (angle > 1e-6 rad). Default:
        global Z, or global Y if the element is parallel to Z.

    Returns
    -------
    ndarray, shape (3, 3)
        Proper orthogonal matrix (dimensionless).
    """
    pi, pj = _point('xyz_i', xyz_i), _point('xyz_j', xyz_j)
    axis = pj - pi
    length = np.linalg.norm(axis)
    if not length > 0.0:
        raise ValueError(f'beam end points coincide at {pi.tolist()} (m): length must be > 0')
    ex = axis / length
    if orientation is None:
        ref = np.array([0.0, 0.0, 1.0])
        if np.linalg.norm(np.cross(ex, ref)) < _PARALLEL_SIN:
            ref = np.array([0.0, 1.0, 0.0])
    else:
        ref = _point('orientation', orientation, 'any unit')
        norm = np.linalg.norm(ref)
        if not norm > 0.0 or np.linalg.norm(np.cross(ex, ref / norm)) < _PARALLEL_SIN:
            raise ValueError(f'orientation must be a nonzero vector not parallel to the beam '
                             f'axis {ex.tolist()} (angle > 1e-6 rad); got {orientation!r}')
        ref = ref / norm
    ey = ref - ref.dot(ex) * ex
    ey /= np.linalg.norm(ey)
    return np.vstack([ex, ey, np.cross(ex, ey)])


def beam_transformation(rotation: npt.ArrayLike) -> np.ndarray:
    """Return ``T = blockdiag(R, R, R, R)`` (12x12, dimensionless), ``u_local = T u_global``.

    Parameters
    ----------
    rotation : array_like, shape (3, 3)
        ``R`` from :func:`beam_rotation` (dimensionless).
    """
    return np.kron(np.eye(4), np.asarray(rotation, dtype=float))


def beam_stiffness(xyz_i: npt.ArrayLike, xyz_j: npt.ArrayLike, material: Material,
                   section: Section, *, shear: bool = True,
                   orientation: npt.ArrayLike | None = None) -> np.ndarray:
    """Return the 12x12 element stiffness in the global frame.

    Parameters
    ----------
    xyz_i, xyz_j : array_like, shape (3,)
        End coordinates (m).
    material : Material
        ``E`` (Pa), ``G`` (Pa).
    section : section object
        See :mod:`impact_damper_sim.fem.sections` (m^2, m^4).
    shear : bool
        Include shear deformation; False gives Euler-Bernoulli.
    orientation : array_like, shape (3,), optional
        Reference vector for local y (direction only); see :func:`beam_rotation`.

    Returns
    -------
    ndarray, shape (12, 12)
        Stiffness (N/m, N/rad, N m/rad), symmetric.
    """
    R = beam_rotation(xyz_i, xyz_j, orientation)
    length = np.linalg.norm(np.asarray(xyz_j, float) - np.asarray(xyz_i, float))
    T = beam_transformation(R)
    return T.T @ beam_local_stiffness(material, section, length, shear=shear) @ T


def beam_mass(xyz_i: npt.ArrayLike, xyz_j: npt.ArrayLike, material: Material,
              section: Section, *, rotary_inertia: bool = False,
              orientation: npt.ArrayLike | None = None) -> np.ndarray:
    """Return the 12x12 lumped element mass in the global frame.

    Parameters
    ----------
    xyz_i, xyz_j : array_like, shape (3,)
        End coordinates (m).
    material : Material
        ``rho`` (kg/m^3).
    section : section object
        ``A`` (m^2); ``Ip``, ``Iy``, ``Iz`` (m^4) with rotary inertia.
    rotary_inertia : bool
        Lump the rotary inertia of the section on the end rotations.
    orientation : array_like, shape (3,), optional
        Reference vector for local y (direction only); see :func:`beam_rotation`.

    Returns
    -------
    ndarray, shape (12, 12)
        Mass (kg, kg m^2), symmetric; the rotation blocks are full when ``Iy, Iz, Ip`` differ.
    """
    R = beam_rotation(xyz_i, xyz_j, orientation)
    length = np.linalg.norm(np.asarray(xyz_j, float) - np.asarray(xyz_i, float))
    T = beam_transformation(R)
    return T.T @ beam_local_mass(material, section, length, rotary_inertia=rotary_inertia) @ T


__all__ = ['beam_local_mass', 'beam_local_stiffness', 'beam_mass', 'beam_rotation',
           'beam_stiffness', 'beam_transformation', 'shear_parameters']
