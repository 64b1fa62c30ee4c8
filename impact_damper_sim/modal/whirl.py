"""Whirl modes of a rotating linear model: damped modes at one speed and their whirl direction.

The rotating model is ``M q'' + (C + Omega G) q' + K q = 0``: ``G`` is the gyroscopic matrix
per unit spin speed (skew-symmetric, kg m^2 on rotations), ``K`` may be non-symmetric
(cross-coupled stiffness), ``Omega`` is the spin speed (rad/s) about global +X. Its
first-order state matrix (:func:`~impact_damper_sim.modal.stability.state_matrix`) is solved
per speed. Each eigenvalue ``lambda = sigma + i omega_d`` with ``omega_d > 0`` is one whirl
mode (one member of a forward/backward pair; its conjugate is the same real motion):

* damped natural frequency ``f = omega_d / (2 pi)`` (Hz);
* logarithmic decrement ``log_dec = -2 pi sigma / omega_d`` (the log of the ratio of
  successive peaks; negative: the mode grows, the model is unstable);
* damping ratio ``zeta = -sigma / |lambda|``.

A real part within :data:`ROUNDOFF_RTOL` ``|lambda|`` of zero is taken as zero (an undamped
mode). Real eigenvalues (overdamped motion) are not whirl modes and are left out.

**Whirl direction.** At an orbit station, a node's ``(uy, uz)`` pair (or its tilt
``(rz, -ry)``, which turns the same way as the shaft's centre line beside the node), the
complex amplitudes ``Y, Z`` of a mode trace an ellipse,
``y + i z = a_f exp(i omega_d t) + a_b exp(-i omega_d t)``, with the forward radius
``a_f = |Y + i Z| / 2`` and the backward radius ``a_b = |Y - i Z| / 2``: major semi-axis
``a_f + a_b``, minor ``|a_f - a_b|``, turning from +y towards +z (with a spin about +X) when
``a_f > a_b``. The mode's whirl index
``kappa = sum_s w_s (a_f^2 - a_b^2) / sum_s w_s (a_f^2 + a_b^2)``, in [-1, 1], weights each
station by its mass (or diametral inertia), so it is the mode's angular momentum about the
spin axis over the most a motion of that size could have. A mode is ``forward`` when kappa
has the sign of the spin speed, ``backward`` when it has the other, and ``none`` when
``|kappa| <= PLANAR_TOL`` (planar orbits, or no lateral motion at all, e.g. torsion) or the
model has no spin axis. In a degenerate pair (equal eigenvalues, e.g. an isotropic rotor
without gyroscopic terms) any combination is a mode; the forward and the backward circular
combinations are chosen, the limits of the pair that the spin splits.

The modes over a range of speeds (Campbell data: branches tracked by shape, critical speeds,
onset of instability) are :mod:`.tracking`'s.

This module is ROS-free and imports neither the scene nor the studies layer: it takes
matrices (modal or physical) and orbit stations; :func:`modal_rotor` and
:func:`condensed_rotor` make them from a modal basis or an assembled system.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
import scipy.linalg as sla

from .stability import state_matrix

if TYPE_CHECKING:
    import scipy.sparse as sp

    from impact_damper_sim.fem.system import AssembledSystem

    from .basis import ModalBasis

#: ``|kappa|`` at or below this is a planar (non-whirling) mode.
PLANAR_TOL = 1e-6
#: Eigenvalues closer than this (relative) form a degenerate cluster.
DEGENERATE_RTOL = 1e-8
#: An eigenvalue with ``|Im| <= OSCILLATORY_RTOL |lambda|`` is real (overdamped motion).
OSCILLATORY_RTOL = 1e-9
#: A real part with ``|Re| <= ROUNDOFF_RTOL |lambda|`` is the rounding of an undamped mode
#: (about 1e-15 |lambda| from the eigen-solver): its log decrement is reported as 0 and it
#: does not make the model unstable.
ROUNDOFF_RTOL = 1e-10
DIRECTIONS = ('forward', 'backward', 'none')


@dataclass(frozen=True, eq=False)   # arrays inside: compare by identity
class OrbitStations:
    """Where whirl orbits are read: pairs of rows giving the (y, z) motion of coordinates.

    Attributes
    ----------
    nodes : ndarray of int, shape (s,)
        Node id of each station (dimensionless).
    kinds : tuple of str
        ``'translation'`` (``(uy, uz)``, m per coordinate unit) or ``'tilt'``
        (``(rz, -ry)``, rad per coordinate unit) per station.
    y_rows, z_rows : ndarray, shape (s, n)
        ``Y = y_rows @ q``, ``Z = z_rows @ q`` (m or rad per unit of the coordinates).
    weights : ndarray, shape (s,)
        Mass (kg) of a translation station, diametral inertia (kg m^2) of a tilt station;
        the weight of the station in the whirl index.
    """

    nodes: np.ndarray
    kinds: tuple
    y_rows: np.ndarray
    z_rows: np.ndarray
    weights: np.ndarray

    def select(self, kind: str) -> OrbitStations:
        """Return the stations of one kind (``'translation'`` or ``'tilt'``).

        Parameters
        ----------
        kind : str
            ``'translation'`` or ``'tilt'``.

        Returns
        -------
        OrbitStations
        """
        keep = np.array([k == kind for k in self.kinds], dtype=bool)
        return OrbitStations(self.nodes[keep], tuple(k for k in self.kinds if k == kind),
                             self.y_rows[keep], self.z_rows[keep], self.weights[keep])


@dataclass(frozen=True, eq=False)
class RotorModel:
    """A rotating linear model ``M q'' + (C + Omega G) q' + K q = 0``.

    Attributes
    ----------
    M : ndarray, shape (n, n)
        Mass (kg; identity for mass-normalized modal coordinates).
    C : ndarray, shape (n, n)
        Damping at rest (N s/m; 1/s in modal coordinates).
    K : ndarray, shape (n, n)
        Stiffness, cross-coupled terms included (N/m; 1/s^2 in modal coordinates).
    G : ndarray, shape (n, n)
        Gyroscopic matrix per unit spin speed (kg, kg m^2 on rotations; dimensionless in
        modal coordinates), skew-symmetric; zero without gyroscopic terms.
    stations : OrbitStations
        Where orbits are read.
    spin_axis : bool
        The model spins (a rotor); without one every mode's direction is ``none``.
    """

    M: np.ndarray
    C: np.ndarray
    K: np.ndarray
    G: np.ndarray
    stations: OrbitStations
    spin_axis: bool = True

    @property
    def n(self) -> int:
        """int: Number of coordinates."""
        return self.K.shape[0]

    def state_matrix(self, speed: float) -> npt.NDArray[np.float64]:
        """Return the first-order state matrix at spin speed ``speed`` (rad/s)."""
        return state_matrix(self.K, self.C + float(speed) * self.G, self.M)


class Eigenvalues:
    """Mixin: what an attribute ``eigenvalues`` (1/s) gives: frequencies, log decrements,
    damping ratios (shared with :class:`~.tracking.Campbell`)."""

    eigenvalues: np.ndarray   # provided by the class it is mixed into

    @property
    def frequency_hz(self) -> npt.NDArray[np.float64]:
        """ndarray: Damped natural frequencies ``Im(lambda) / (2 pi)`` (Hz)."""
        return self.eigenvalues.imag / (2.0 * np.pi)

    @property
    def log_dec(self) -> npt.NDArray[np.float64]:
        """ndarray: Logarithmic decrements ``-2 pi sigma / omega_d`` (dimensionless)."""
        return log_decrement(self.eigenvalues)

    @property
    def damping_ratio(self) -> npt.NDArray[np.float64]:
        """ndarray: Damping ratios ``-sigma / |lambda|`` (dimensionless)."""
        return damping_ratio(self.eigenvalues)


@dataclass(frozen=True, eq=False)
class WhirlModes(Eigenvalues):
    """The damped whirl modes of a :class:`RotorModel` at one speed, by frequency.

    Attributes
    ----------
    speed : float
        Spin speed (rad/s).
    eigenvalues : ndarray of complex, shape (m,)
        ``sigma + i omega_d`` with ``omega_d > 0`` (1/s), ascending ``omega_d``.
    shapes : ndarray of complex, shape (n, m)
        Displacement part of each eigenvector, ``shape^H M shape = 1``.
    whirl_index : ndarray, shape (m,)
        ``kappa`` of each mode (dimensionless, -1 backward circular .. +1 forward circular,
        relative to +X).
    directions : tuple of str
        ``forward``, ``backward`` or ``none`` per mode.
    n_overdamped : int
        Real eigenvalues left out (overdamped motion).
    growth : float
        Largest ``Re(lambda) / |lambda|`` over every eigenvalue, real ones included
        (dimensionless): minus the smallest damping ratio; above :data:`ROUNDOFF_RTOL` the
        model is unstable.
    """

    speed: float
    eigenvalues: np.ndarray
    shapes: np.ndarray
    whirl_index: np.ndarray
    directions: tuple
    n_overdamped: int
    growth: float


def _real_part(lam: np.ndarray) -> npt.NDArray[np.float64]:
    """``Re(lambda)`` with the rounding of undamped modes set to 0 (1/s)."""
    return np.where(np.abs(lam.real) <= ROUNDOFF_RTOL * np.abs(lam), 0.0, lam.real)


def log_decrement(eigenvalues: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Return ``-2 pi Re(lambda) / |Im(lambda)|`` (dimensionless; nan for real eigenvalues).

    Parameters
    ----------
    eigenvalues : array_like of complex
        Eigenvalues (1/s); a real part within ``ROUNDOFF_RTOL |lambda|`` counts as 0.

    Returns
    -------
    ndarray
    """
    lam = np.asarray(eigenvalues, dtype=complex)
    with np.errstate(divide='ignore', invalid='ignore'):
        return np.where(lam.imag != 0, -2.0 * np.pi * _real_part(lam) / np.abs(lam.imag),
                        np.nan) + 0.0   # + 0.0: no -0.0 for an undamped mode


def damping_ratio(eigenvalues: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Return ``-Re(lambda) / |lambda|`` (dimensionless).

    Parameters
    ----------
    eigenvalues : array_like of complex
        Eigenvalues (1/s); a real part within ``ROUNDOFF_RTOL |lambda|`` counts as 0.

    Returns
    -------
    ndarray
    """
    lam = np.asarray(eigenvalues, dtype=complex)
    with np.errstate(divide='ignore', invalid='ignore'):
        return -_real_part(lam) / np.abs(lam) + 0.0


def orbit_radii(stations: OrbitStations, shapes: npt.ArrayLike
                ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Return the forward and backward orbit radii of modes at the stations.

    Parameters
    ----------
    stations : OrbitStations
        Stations (s of them).
    shapes : array_like of complex, shape (n, m) or (n,)
        Mode shapes in the stations' coordinates.

    Returns
    -------
    a_f, a_b : ndarray, shape (s, m) (or (s,))
        ``|Y + i Z| / 2`` and ``|Y - i Z| / 2`` (m or rad per unit of the shapes): the major
        semi-axis is ``a_f + a_b``, the minor ``|a_f - a_b|``, and the orbit turns with +X
        where ``a_f > a_b``.
    """
    v = np.asarray(shapes, dtype=complex)
    Y, Z = stations.y_rows @ v, stations.z_rows @ v
    return np.abs(Y + 1j * Z) / 2.0, np.abs(Y - 1j * Z) / 2.0


def whirl_index(stations: OrbitStations, shapes: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Return the whirl index ``kappa`` of modes (see the module docstring).

    Parameters
    ----------
    stations : OrbitStations
        Where the orbits are read, with their weights (kg, kg m^2).
    shapes : array_like of complex, shape (n, m)
        Mode shapes in the stations' coordinates.

    Returns
    -------
    ndarray, shape (m,)
        In [-1, 1] (dimensionless); 0 where no station moves.
    """
    a_f, a_b = orbit_radii(stations, np.atleast_2d(np.asarray(shapes).T).T)
    w = stations.weights[:, None]
    num = (w * (a_f ** 2 - a_b ** 2)).sum(axis=0)
    den = (w * (a_f ** 2 + a_b ** 2)).sum(axis=0)
    with np.errstate(divide='ignore', invalid='ignore'):
        return np.where(den > 0, num / np.where(den > 0, den, 1.0), 0.0)


def direction(kappa: float, speed: float, spin_axis: bool = True,
              tol: float = PLANAR_TOL) -> str:
    """Whirl direction of a mode from its whirl index.

    Parameters
    ----------
    kappa : float
        Whirl index (dimensionless, relative to +X).
    speed : float
        Spin speed (rad/s); a negative speed spins about -X. Zero counts as +X (the limit of
        a slow positive spin).
    spin_axis : bool
        False: no rotor, every direction is ``none``.
    tol : float
        ``|kappa|`` at or below it is planar (dimensionless).

    Returns
    -------
    str
        ``forward``, ``backward`` or ``none``.
    """
    if not spin_axis or abs(kappa) <= tol:
        return 'none'
    spin = -1.0 if speed < 0 else 1.0
    return 'forward' if kappa * spin > 0 else 'backward'


def whirl_modes(rotor: RotorModel, speed: float) -> WhirlModes:
    """Return the damped whirl modes of ``rotor`` at spin speed ``speed``.

    Parameters
    ----------
    rotor : RotorModel
        The model.
    speed : float
        Spin speed (rad/s).

    Returns
    -------
    WhirlModes
        By ascending damped frequency.
    """
    speed = float(speed)
    lam, vec = sla.eig(rotor.state_matrix(speed))
    scale = np.abs(lam)
    growth = float((lam.real / np.where(scale > 0, scale, 1.0)).max())
    keep = lam.imag > OSCILLATORY_RTOL * np.where(scale > 0, scale, 1.0)
    n_real = int(np.sum(np.abs(lam.imag) <= OSCILLATORY_RTOL * np.where(scale > 0, scale, 1.0)))
    lam, shapes = lam[keep], vec[:rotor.n, keep]
    order = np.argsort(lam.imag, kind='stable')
    lam, shapes = lam[order], _mass_normalized(rotor.M, shapes[:, order])
    shapes = _resolve_degenerate(rotor, lam, shapes)
    kappa = whirl_index(rotor.stations, shapes)
    dirs = tuple(direction(k, speed, rotor.spin_axis) for k in kappa)
    return WhirlModes(speed, lam, shapes, kappa, dirs, n_real, growth)


def _mass_normalized(M: np.ndarray, shapes: np.ndarray) -> np.ndarray:
    """Scale each column to ``v^H M v = 1``."""
    norms = np.sqrt(np.abs(np.einsum('im,ij,jm->m', shapes.conj(), M, shapes)))
    return shapes / np.where(norms > 0, norms, 1.0)


def _resolve_degenerate(rotor: RotorModel, lam: np.ndarray,
                        shapes: np.ndarray) -> np.ndarray:
    """In each cluster of equal eigenvalues, the combinations of extreme whirl index."""
    st = rotor.stations
    out = shapes.copy()
    start = 0
    while start < lam.size:
        stop = start + 1
        while (stop < lam.size
               and abs(lam[stop] - lam[start]) <= DEGENERATE_RTOL * abs(lam[start])):
            stop += 1
        if stop - start > 1:
            V = shapes[:, start:stop]
            Y, Z = st.y_rows @ V, st.z_rows @ V
            W = st.weights[:, None]
            # kappa(V c) = c^H S c / c^H P c: extremes by a Hermitian eigenproblem
            S = 0.5j * (Y.conj().T @ (W * Z) - Z.conj().T @ (W * Y))
            P = 0.5 * (Y.conj().T @ (W * Y) + Z.conj().T @ (W * Z))
            try:
                _, c = sla.eigh(0.5 * (S + S.conj().T), 0.5 * (P + P.conj().T))
            except np.linalg.LinAlgError:   # the cluster does not move the stations
                c = None
            if c is not None:
                # ascending kappa: backward first, as the spin splits them
                out[:, start:stop] = _mass_normalized(rotor.M, V @ c)
        start = stop
    return out


# --- models from a modal basis or an assembled system ----------------------------------------

def gyroscopic_matrix(system: AssembledSystem,
                      polar_inertia: Mapping[int, float]) -> sp.csr_matrix:
    """Return the gyroscopic matrix per unit spin speed of spinning nodes, sparse.

    A disk of polar inertia ``Ip`` spinning at ``Omega`` about +X adds ``Ip Omega theta_z'``
    to its ``ry`` equation and ``-Ip Omega theta_y'`` to its ``rz`` one (the small-tilt
    change of its angular momentum): ``G[ry, rz] = +Ip``, ``G[rz, ry] = -Ip``.

    Parameters
    ----------
    system : AssembledSystem
        Active DOFs (kg, N s/m, N/m).
    polar_inertia : mapping of int to float
        Polar inertia (kg m^2) of each spinning node.

    Returns
    -------
    scipy.sparse.csr_matrix, shape (n_dof, n_dof)
        ``G`` (kg m^2): the damping matrix of the spin is ``Omega G``.

    Raises
    ------
    KeyError
        A spinning node's ``ry`` or ``rz`` is clamped.
    """
    import scipy.sparse as sp
    rows, cols, vals = [], [], []
    for node, ip in polar_inertia.items():
        ry, rz = system.index(node, 'ry'), system.index(node, 'rz')
        rows += [ry, rz]
        cols += [rz, ry]
        vals += [float(ip), -float(ip)]
    n = system.n_dof
    return sp.csr_matrix((vals, (rows, cols)), shape=(n, n))


def orbit_stations(system: AssembledSystem,
                   recovery: Callable[[list[int]], np.ndarray]) -> OrbitStations:
    """Return the orbit stations of every node that moves laterally.

    A node with both ``uy`` and ``uz`` active is a translation station weighted by its mass;
    one with both ``ry`` and ``rz`` active is a tilt station ``(rz, -ry)`` weighted by its
    diametral inertia (the masses are the diagonal of ``system.M``).

    Parameters
    ----------
    system : AssembledSystem
        Active DOFs and masses (kg, kg m^2).
    recovery : callable
        ``active indices -> rows`` from the coordinates to those DOFs (e.g.
        :meth:`ModalBasis.rows`, ``Condensation.recovery``).

    Returns
    -------
    OrbitStations
        Translation stations first, then tilt stations, by node id.
    """
    mass = np.asarray(system.M.diagonal(), dtype=float)
    active = {(int(n), int(c)) for n, c in system.dofs}
    nodes = sorted({int(n) for n, _ in system.dofs})
    found: dict[str, list[tuple]] = {'translation': [], 'tilt': []}
    for node in nodes:
        if (node, 1) in active and (node, 2) in active:
            found['translation'].append((node, system.index(node, 'uy'),
                                         system.index(node, 'uz'), 1.0))
        if (node, 4) in active and (node, 5) in active:
            # (rz, -ry) turns as the centre line beside the node: a tilt about z moves +x to +y
            found['tilt'].append((node, system.index(node, 'rz'),
                                  system.index(node, 'ry'), -1.0))
    entries = [(kind, e) for kind in ('translation', 'tilt') for e in found[kind]]
    if not entries:
        n = recovery([0]).shape[1] if system.n_dof else 0
        return OrbitStations(np.zeros(0, dtype=int), (), np.zeros((0, n)), np.zeros((0, n)),
                             np.zeros(0))
    y_idx = [e[1] for _, e in entries]
    z_idx = [e[2] for _, e in entries]
    y_rows = recovery(y_idx)
    z_rows = recovery(z_idx) * np.array([e[3] for _, e in entries])[:, None]
    weights = 0.5 * (mass[y_idx] + mass[z_idx])
    return OrbitStations(np.array([e[0] for _, e in entries]), tuple(k for k, _ in entries),
                         np.asarray(y_rows, dtype=float), np.asarray(z_rows, dtype=float),
                         weights)


def modal_rotor(basis: ModalBasis, gyroscopic: sp.spmatrix | None = None, *,
                spin_axis: bool = True) -> RotorModel:
    """Return the rotating model in the coordinates of a modal basis.

    Parameters
    ----------
    basis : ModalBasis
        Mass-normalized modes; ``K`` and ``C`` are its modal stiffness (cross-coupled terms
        included, 1/s^2) and damping (tare and physical, 1/s).
    gyroscopic : scipy.sparse matrix, optional
        Physical gyroscopic matrix per unit speed over the active DOFs (kg m^2), e.g. from
        :func:`gyroscopic_matrix`; projected as ``Phi^T G Phi`` (dimensionless).
    spin_axis : bool
        The model is a rotor (see :class:`RotorModel`).

    Returns
    -------
    RotorModel
    """
    n = basis.n_modes
    G = np.zeros((n, n))
    if gyroscopic is not None:
        coo = gyroscopic.tocoo()
        dofs = np.unique(np.concatenate([coo.row, coo.col]))
        if dofs.size:
            rows = basis.rows(dofs)
            sub = gyroscopic.tocsr()[dofs][:, dofs].toarray()
            G = rows.T @ sub @ rows
    return RotorModel(M=np.eye(n), C=basis.damping_matrix(), K=basis.stiffness_matrix(), G=G,
                      stations=orbit_stations(basis.system, basis.rows), spin_axis=spin_axis)


def condensed_rotor(system: AssembledSystem, gyroscopic: sp.spmatrix | None = None, *,
                    spin_axis: bool = True) -> RotorModel:
    """Return the rotating model over every DOF with mass (no modal truncation).

    The massless DOFs are condensed statically (:meth:`AssembledSystem.condense`); the
    gyroscopic matrix is condensed like the damping, ``[I; T]^T G [I; T]``.

    Parameters
    ----------
    system : AssembledSystem
        Physical matrices (kg, N s/m, N/m).
    gyroscopic : scipy.sparse matrix, optional
        Gyroscopic matrix per unit speed over the active DOFs (kg m^2).
    spin_axis : bool
        The model is a rotor.

    Returns
    -------
    RotorModel
        In physical coordinates of the master DOFs (no tare damping: it belongs to modes).
    """
    cond = system.condense()
    n = cond.master.size
    G = np.zeros((n, n))
    if gyroscopic is not None:
        R = cond.recovery(np.arange(system.n_dof))
        G = R.T @ (gyroscopic @ R)
    return RotorModel(M=np.asarray(cond.M, dtype=float), C=np.asarray(cond.C, dtype=float),
                      K=np.asarray(cond.K, dtype=float), G=np.asarray(G),
                      stations=orbit_stations(system, cond.recovery), spin_axis=spin_axis)


__all__ = ['DIRECTIONS', 'Eigenvalues', 'OrbitStations', 'RotorModel', 'WhirlModes',
           'condensed_rotor', 'damping_ratio', 'direction', 'gyroscopic_matrix', 'log_decrement',
           'modal_rotor', 'orbit_radii', 'orbit_stations', 'whirl_index', 'whirl_modes']
