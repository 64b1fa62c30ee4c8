"""Whirl modes over spin speed: branches tracked by shape, critical speeds, onset.

The Campbell data of a :class:`~.whirl.RotorModel`, from its whirl modes at each speed
(:func:`~.whirl.whirl_modes`). :func:`campbell` follows each mode over the speeds by its
shape, not by sorting: the modal assurance criterion (MAC, mass-weighted) between the modes
at consecutive speeds and an optimal one-to-one assignment (Hungarian,
``scipy.optimize.linear_sum_assignment``), so crossing branches keep their identity.
:func:`critical_speeds` finds where a branch's damped frequency meets a harmonic of the spin
speed, refined with Brent's method on the tracked branch; :func:`instability_onset` the first
speed where a log decrement turns negative, refined with Brent's method on the largest
``Re(lambda) / |lambda|``.

Kept apart from :mod:`.whirl` (one speed): this is the bookkeeping across speeds. ROS-free,
no scene or studies import.
"""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import scipy.linalg as sla

from .whirl import OSCILLATORY_RTOL, ROUNDOFF_RTOL, Eigenvalues, RotorModel, WhirlModes, whirl_modes


def mac(M: np.ndarray, a: np.ndarray, b: np.ndarray) -> npt.NDArray[np.float64]:
    """Mass-weighted modal assurance criterion between two sets of shapes.

    Parameters
    ----------
    M : ndarray, shape (n, n)
        Mass matrix (kg), the weight of the inner product.
    a : ndarray of complex, shape (n, p)
        Shapes (any consistent unit).
    b : ndarray of complex, shape (n, r)
        Shapes (the same unit as ``a``).

    Returns
    -------
    ndarray, shape (p, r)
        ``|a_i^H M b_j|^2 / ((a_i^H M a_i)(b_j^H M b_j))`` in [0, 1] (dimensionless).
    """
    Mb = M @ b
    cross = np.abs(a.conj().T @ Mb) ** 2
    na = np.real(np.einsum('ip,ij,jp->p', a.conj(), M, a))
    nb = np.real(np.einsum('ir,ir->r', b.conj(), Mb))
    with np.errstate(divide='ignore', invalid='ignore'):
        return np.nan_to_num(cross / np.outer(na, nb))


@dataclass(frozen=True, eq=False)
class Campbell(Eigenvalues):
    """Whirl modes tracked over spin speed (one column per branch).

    Attributes
    ----------
    rotor : RotorModel
    speeds : ndarray, shape (k,)
        Spin speeds (rad/s), ascending.
    eigenvalues : ndarray of complex, shape (k, b)
        Eigenvalue of each branch at each speed (1/s); nan where the branch has no mode
        (an overdamped stretch).
    whirl_index : ndarray, shape (k, b)
        ``kappa`` (dimensionless; nan where no mode).
    directions : ndarray of str, shape (k, b)
        ``forward``, ``backward``, ``none`` ('' where no mode).
    shapes : ndarray of complex, shape (k, n, b)
        Mode shapes (nan where no mode).
    growth : ndarray, shape (k,)
        :attr:`WhirlModes.growth` at each speed (dimensionless).
    """

    rotor: RotorModel
    speeds: np.ndarray
    eigenvalues: np.ndarray
    whirl_index: np.ndarray
    directions: np.ndarray
    shapes: np.ndarray
    growth: np.ndarray

    @property
    def n_branches(self) -> int:
        """int: Number of branches."""
        return self.eigenvalues.shape[1]


def campbell(rotor: RotorModel, speeds: npt.ArrayLike) -> Campbell:
    """Whirl modes over spin speed, each branch followed by its shape.

    Parameters
    ----------
    rotor : RotorModel
        The model.
    speeds : array_like of float
        Spin speeds (rad/s), strictly increasing.

    Returns
    -------
    Campbell
        Branches numbered by ascending frequency at the first speed; a mode that matches no
        branch (the number of oscillatory modes grew) starts a new one.
    """
    from scipy.optimize import linear_sum_assignment
    speeds = np.asarray(speeds, dtype=float)
    if speeds.ndim != 1 or speeds.size == 0:
        raise ValueError('speeds must be a non-empty 1-D sequence (rad/s)')
    if np.any(np.diff(speeds) <= 0):
        raise ValueError('speeds must be strictly increasing (rad/s)')
    per_speed = [whirl_modes(rotor, s) for s in speeds]
    n = rotor.n
    columns: list[list[tuple[int, int]]] = []   # per branch: list of (speed index, mode index)
    last = np.empty((n, 0), dtype=complex)   # each branch's latest shape
    for k, modes in enumerate(per_speed):
        m = modes.eigenvalues.size
        assigned = {}
        if columns and m:
            cost = 1.0 - mac(rotor.M, last, modes.shapes)
            rows, cols = linear_sum_assignment(cost)
            assigned = dict(zip(cols.tolist(), rows.tolist()))
        for j in range(m):
            b = assigned.get(j)
            if b is None:
                columns.append([])
                last = np.hstack([last, np.zeros((n, 1), dtype=complex)])
                b = len(columns) - 1
            columns[b].append((k, j))
            last[:, b] = modes.shapes[:, j]
    k_n, b_n = speeds.size, len(columns)
    lam = np.full((k_n, b_n), np.nan + 0j)
    kappa = np.full((k_n, b_n), np.nan)
    dirs = np.full((k_n, b_n), '', dtype=object)
    shapes = np.full((k_n, n, b_n), np.nan + 0j)
    for b, entries in enumerate(columns):
        for k, j in entries:
            modes = per_speed[k]
            lam[k, b] = modes.eigenvalues[j]
            kappa[k, b] = modes.whirl_index[j]
            dirs[k, b] = modes.directions[j]
            shapes[k, :, b] = modes.shapes[:, j]
    return Campbell(rotor, speeds, lam, kappa, dirs, shapes,
                    np.array([modes.growth for modes in per_speed]))


@dataclass(frozen=True)
class CriticalSpeed:
    """A branch meeting a harmonic of the spin speed.

    Attributes
    ----------
    harmonic : float
        Order ``h`` of the excitation line ``f = h Omega / (2 pi)`` (dimensionless).
    branch : int
        Branch index (0-based) of the :class:`Campbell` data.
    speed : float
        Spin speed of the crossing (rad/s).
    frequency_hz : float
        Damped natural frequency there (Hz), ``h speed / (2 pi)``.
    direction : str
        Whirl direction of the branch there.
    log_dec : float
        Logarithmic decrement of the branch there (dimensionless).
    """

    harmonic: float
    branch: int
    speed: float
    frequency_hz: float
    direction: str
    log_dec: float


def _tracked(rotor: RotorModel, speed: float,
             reference: np.ndarray) -> tuple[WhirlModes, int]:
    """The mode at ``speed`` whose shape matches ``reference`` best (MAC)."""
    modes = whirl_modes(rotor, speed)
    j = int(np.argmax(mac(rotor.M, reference[:, None], modes.shapes)[0]))
    return modes, j


def critical_speeds(data: Campbell,
                    harmonics: Iterable[float] = (1.0,)) -> list[CriticalSpeed]:
    """Return where each branch's damped frequency meets each harmonic line.

    Between two speeds where ``omega_d - h Omega`` changes sign, the crossing is refined by
    Brent's method on the branch, followed by its shape from the lower speed.

    Parameters
    ----------
    data : Campbell
        Tracked branches.
    harmonics : sequence of float
        Orders ``h`` > 0 of the excitation lines (dimensionless).

    Returns
    -------
    list of CriticalSpeed
        By speed.
    """
    from scipy.optimize import brentq
    rotor, speeds = data.rotor, data.speeds
    out = []
    for h in harmonics:
        h = float(h)
        if not h > 0:
            raise ValueError(f'harmonic orders must be > 0, got {h:g}')
        for b in range(data.n_branches):
            gap = data.eigenvalues[:, b].imag - h * speeds
            for k in range(speeds.size - 1):
                g0, g1 = gap[k], gap[k + 1]
                if not (np.isfinite(g0) and np.isfinite(g1)) or g0 * g1 > 0 or g0 == 0:
                    continue
                reference = data.shapes[k, :, b]
                if g1 == 0:
                    crossing = speeds[k + 1]
                else:
                    def g(s: float, reference: np.ndarray = reference, h: float = h) -> float:
                        modes, j = _tracked(rotor, s, reference)
                        return modes.eigenvalues[j].imag - h * s
                    crossing = brentq(g, speeds[k], speeds[k + 1],
                                      xtol=max(1e-12 * abs(speeds[k + 1]), 1e-300),
                                      rtol=1e-13)
                modes, j = _tracked(rotor, crossing, reference)
                out.append(CriticalSpeed(h, b, float(crossing), h * crossing / (2.0 * np.pi),
                                         modes.directions[j], float(modes.log_dec[j])))
    return sorted(out, key=lambda c: (c.speed, c.harmonic, c.branch))


@dataclass(frozen=True)
class Onset:
    """The first speed where a log decrement turns negative.

    Attributes
    ----------
    speed : float
        Spin speed (rad/s) where the largest real part of the eigenvalues crosses zero, or
        the first speed of the range when the model is unstable there already.
    from_start : bool
        Unstable at the first speed of the range.
    branch : int or None
        Branch (0-based) that goes unstable; None when the growing motion is not
        oscillatory (a real eigenvalue: divergence).
    frequency_hz : float or None
        Its damped natural frequency there (Hz).
    direction : str or None
        Its whirl direction there.
    """

    speed: float
    from_start: bool
    branch: int | None
    frequency_hz: float | None
    direction: str | None


def _growth(rotor: RotorModel, speed: float) -> float:
    """:attr:`WhirlModes.growth` at ``speed`` (dimensionless), eigenvalues only."""
    lam = sla.eigvals(rotor.state_matrix(speed))
    scale = np.where(np.abs(lam) > 0, np.abs(lam), 1.0)
    return float((lam.real / scale).max())


def instability_onset(data: Campbell, rtol: float = 1e-10) -> Onset | None:
    """Return the first speed of the range where the model is unstable, or None.

    Unstable: an eigenvalue with ``Re(lambda) > ROUNDOFF_RTOL |lambda|`` (a negative log
    decrement, or a real positive eigenvalue). Between the last stable and the first unstable
    speed of the range, the crossing of the largest ``Re(lambda) / |lambda|`` through zero
    is found by Brent's method.

    Parameters
    ----------
    data : Campbell
        Tracked branches.
    rtol : float
        Relative width of the bisection bracket (dimensionless).

    Returns
    -------
    Onset or None
        None when every eigenvalue has a negative real part at every speed of the range.
    """
    from scipy.optimize import brentq
    rotor, speeds = data.rotor, data.speeds
    growth = data.growth
    first = next((k for k, g in enumerate(growth) if g > ROUNDOFF_RTOL), None)
    if first is None:
        return None
    if first == 0:
        speed = float(speeds[0])
    else:
        # an undamped model may sit at +rounding below: cross the tolerance instead of 0
        level = 0.0 if growth[first - 1] <= 0 else ROUNDOFF_RTOL
        speed = float(brentq(lambda s: _growth(rotor, s) - level, speeds[first - 1],
                             speeds[first], xtol=max(rtol * abs(speeds[first]), 1e-300),
                             rtol=max(rtol, 4e-16)))
    # at the crossing itself the real part is zero: identify the mode just past it
    probe = speed if first == 0 else min(speed * (1 + 1e-9), speeds[first])
    lam = sla.eigvals(rotor.state_matrix(probe))
    top = lam[np.argmax(lam.real)]
    if abs(top.imag) <= OSCILLATORY_RTOL * abs(top):   # a real eigenvalue: divergence
        return Onset(speed, first == 0, None, None, None)
    modes = whirl_modes(rotor, probe)
    j = int(np.argmin(np.abs(modes.eigenvalues - complex(top.real, abs(top.imag)))))
    valid = np.isfinite(data.eigenvalues[first].real)
    scores = mac(rotor.M, modes.shapes[:, [j]],
                 np.nan_to_num(data.shapes[first]))[0] * valid
    return Onset(speed, first == 0, int(np.argmax(scores)), float(modes.frequency_hz[j]),
                 modes.directions[j])


__all__ = ['Campbell', 'CriticalSpeed', 'Onset', 'campbell', 'critical_speeds',
           'instability_onset', 'mac']
