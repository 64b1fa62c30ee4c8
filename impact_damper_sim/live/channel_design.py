"""Designs of the accelerometer channel's stages (:mod:`.channel`): mounting and high-pass.

Pure functions of the stage's values and the integrator's step rate; they carry no state and no
random numbers. Everything is SI.

* :func:`mounting_matrix`: the 3 x 3 matrix ``S (I + T) R^T`` from the model frame to the
  sensor's output axes (orientation, transverse sensitivity, sensitivity error).
* :func:`highpass_sos`: the IEPE coupling high-pass, first order.

The mounted resonance, a fit of causal biquads, is :mod:`.resonance_design`.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
import numpy.typing as npt


def rotation_matrix(orientation: Sequence[float]) -> npt.NDArray[np.float64]:
    """Rotation ``R = Rz(yaw) Ry(pitch) Rx(roll)``: the sensor's axes in the model frame.

    Column ``i`` of ``R`` is the sensor's axis ``i`` in model coordinates, so a sensor at this
    orientation reads ``R.T @ a`` for a model-frame acceleration ``a``.

    Parameters
    ----------
    orientation : sequence of 3 float
        ``[roll, pitch, yaw]`` (rad), the intrinsic z-y'-x'' (aerospace) angles.

    Returns
    -------
    ndarray, shape (3, 3)
        Orthonormal, determinant +1.
    """
    roll, pitch, yaw = (float(v) for v in orientation)
    cr, sr = _cos_sin(roll)
    cp, sp = _cos_sin(pitch)
    cy, sy = _cos_sin(yaw)
    rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    return rz @ ry @ rx


def _cos_sin(angle: float) -> tuple[float, float]:
    # exact at whole quarter turns, so a 90 deg yaw swaps the axes with no 6e-17 leak
    quarter = angle / (0.5 * math.pi)
    if abs(quarter - round(quarter)) < 1e-12:
        return ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))[round(quarter) % 4]
    return math.cos(angle), math.sin(angle)


def transverse_matrix(fraction: float, angle: float) -> npt.NDArray[np.float64]:
    """Transverse sensitivity ``T`` of a triaxial sensor (dimensionless, zero diagonal).

    Axis ``i`` senses along ``e_i + fraction * u_i``, where ``u_i`` is the unit vector of the
    plane normal to ``e_i`` at ``angle`` from the next axis, turning towards the one after
    (cyclic: x -> y -> z -> x)::

        u_x = cos(angle) e_y + sin(angle) e_z
        u_y = cos(angle) e_z + sin(angle) e_x
        u_z = cos(angle) e_x + sin(angle) e_y

    So ``fraction`` is the datasheet's (maximum) transverse sensitivity: an excitation along
    ``u_i`` reads ``fraction`` of itself on axis ``i``; a pure-axis excitation along y reads
    ``fraction cos(angle)`` on x and ``fraction sin(angle)`` on z (``angle = 0``: each axis
    picks up the next one only).

    Parameters
    ----------
    fraction : float
        Transverse sensitivity (dimensionless, 0.05 = 5 %), >= 0.
    angle : float
        Direction of the maximum in each axis' normal plane (rad).

    Returns
    -------
    ndarray, shape (3, 3)
        ``T[i, j]``: the share of the acceleration along sensor axis ``j`` read on axis ``i``
        (before the sensitivity error).
    """
    c, s = _cos_sin(float(angle))
    f = float(fraction)
    t = np.zeros((3, 3))
    for i in range(3):
        t[i, (i + 1) % 3] = f * c
        t[i, (i + 2) % 3] = f * s
    return t


def mounting_matrix(orientation: Sequence[float] | None = None,
                    transverse: Mapping[str, float] | None = None,
                    sensitivity_error: Sequence[float] | None = None
                    ) -> npt.NDArray[np.float64] | None:
    """The mounting stage ``M = S (I + T) R^T``: model-frame acceleration to sensor output.

    Parameters
    ----------
    orientation : sequence of 3 float or None
        ``[roll, pitch, yaw]`` (rad), see :func:`rotation_matrix`; None: aligned.
    transverse : dict or None
        ``{'fraction': f (dimensionless), 'angle': rad}``, see :func:`transverse_matrix`.
    sensitivity_error : sequence of 3 float or None
        Per-axis relative error (dimensionless): ``S = diag(1 + e)``.

    Returns
    -------
    ndarray, shape (3, 3) or None
        None when every part is off (the identity is skipped, not applied).
    """
    if orientation is None and transverse is None and sensitivity_error is None:
        return None
    m = np.eye(3)
    if orientation is not None:
        m = rotation_matrix(orientation).T
    if transverse is not None:
        m = (np.eye(3) + transverse_matrix(transverse['fraction'], transverse['angle'])) @ m
    if sensitivity_error is not None:
        m = np.diag(1.0 + np.asarray(sensitivity_error, dtype=float)) @ m
    return m


def highpass_sos(corner_hz: float, step_rate_hz: float) -> npt.NDArray[np.float64]:
    """First-order high-pass (IEPE coupling), bilinear, prewarped: -3 dB exactly at the corner.

    The analog ``s / (s + wc)`` mapped with ``s -> (wc / k) (1 - z^-1)/(1 + z^-1)``,
    ``k = tan(pi fc / fs)``: the digital response equals the analog one at the corner; its
    phase matches below (the warping is ``(f / fs)^2``-small at an IEPE corner).

    Parameters
    ----------
    corner_hz : float
        -3 dB corner fc (Hz), in ``(0, step_rate_hz / 2)``.
    step_rate_hz : float
        Step rate fs (Hz).

    Returns
    -------
    ndarray, shape (1, 6)
        One section ``[b0, b1, 0, 1, a1, 0]``.
    """
    fc, fs = float(corner_hz), float(step_rate_hz)
    if not (math.isfinite(fc) and 0.0 < fc < 0.5 * fs):
        raise ValueError(f"spec key 'highpass.corner': must lie in (0, {0.5 * fs:g}) Hz, the "
                         f'Nyquist frequency of the step rate, got {corner_hz!r}')
    k = math.tan(math.pi * fc / fs)
    g = 1.0 / (1.0 + k)
    return np.array([[g, -g, 0.0, 1.0, -(1.0 - k) * g, 0.0]])


__all__ = ['highpass_sos', 'mounting_matrix', 'rotation_matrix', 'transverse_matrix']
