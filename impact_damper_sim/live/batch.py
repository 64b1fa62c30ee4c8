"""What one chunk of a live simulation produced: :class:`Batch` (ROS-free, SI).

Kept apart from :mod:`.realtime`, which steps the scene and makes these, so that the
stepping module stays about stepping and commands.
"""
from __future__ import annotations

import dataclasses

import numpy as np


@dataclasses.dataclass
class Batch:
    """What one :meth:`LiveSimulation.step` produced.

    Attributes
    ----------
    t : ndarray, shape (k,)
        Output sample times (s).
    linear_acceleration : ndarray, shape (k, n_acc, 3)
        Accelerometer readings (m/s^2).
    angular_velocity : ndarray, shape (k, n_acc, 3)
        Rotational DOF rates (rad/s).
    events : ndarray of EVENT_DTYPE
        Impacts, sticks and releases in the chunk (times in s).
    states_changed : bool
        Some impactor changed between stuck and free during the chunk.
    imu_t : ndarray, shape (j,)
        Times (s) of the live per-sample stream's samples completed in this chunk: the
        decimated signal, a filter delay behind ``t`` (see :class:`StreamingDecimator`).
    imu_linear_acceleration, imu_angular_velocity : ndarray, shape (j, n_acc, 3)
        The decimated readings (m/s^2, rad/s).
    truth : ndarray, shape (k, n_acc, 3)
        Ground truth at the output samples: the model's acceleration (model frame) through
        the anti-alias low-pass and no other stage of the channel (m/s^2).
    clipped, imu_clipped : ndarray of int, shape (n_acc,)
        Values clipped by the measuring range or the ADC in this chunk, per accelerometer:
        of ``linear_acceleration`` and of ``imu_linear_acceleration`` (values, 3 per sample).
    shaft_angle, shaft_speed : ndarray, shape (k,), or None
        The tachometer at ``t``: the rotor angle ``phi(t)`` the unbalance force uses,
        unwrapped (rad, 0 at t = 0, never decreasing), and the speed (rad/s); None without a
        rotor.
    keyphasor : ndarray of KEYPHASOR_DTYPE, or None
        The times in this chunk's interval (end of the previous chunk, ``t[-1]``] at which
        ``phi`` reached a whole number of turns; None without a rotor.
    valid : ndarray of bool, shape (k, n_acc)
        Whether each full-rate sample of each accelerometer is there: False where a sensor
        fault (a dropout, an intermittent connection with ``off: dropout``) lost it. A
        missing sample is not published; its value in ``linear_acceleration`` is what the
        channel made (the decimator downstream sees a continuous signal).
    imu_valid : ndarray of bool, shape (j, n_acc)
        The same for the decimated samples at ``imu_t`` (the full-rate sample each stands
        for).
    """

    t: np.ndarray
    linear_acceleration: np.ndarray
    angular_velocity: np.ndarray
    events: np.ndarray
    states_changed: bool
    imu_t: np.ndarray | None = None
    imu_linear_acceleration: np.ndarray | None = None
    imu_angular_velocity: np.ndarray | None = None
    truth: np.ndarray | None = None
    clipped: np.ndarray | None = None
    imu_clipped: np.ndarray | None = None
    shaft_angle: np.ndarray | None = None
    shaft_speed: np.ndarray | None = None
    keyphasor: np.ndarray | None = None
    valid: np.ndarray | None = None
    imu_valid: np.ndarray | None = None


__all__ = ['Batch']
