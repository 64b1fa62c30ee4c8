"""The node's batch topics in NumPy: a ``sensor_msgs/PointCloud2`` in, arrays out.

Every batch topic of ``vibration_node`` (``accel/<name>/batch``, ``accel/<name>/truth``,
``impacts``, ``rotor/tach``, ``rotor/keyphasor``) is a PointCloud2 with one row per sample
or event; its ``fields`` name the columns (layouts: :mod:`impact_damper_sim.recording.batches`).
These helpers read the layout from the message itself, so one call serves every batch topic,
and a layout with other fields or another field order decodes by name:

>>> import numpy as np
>>> from rclpy.serialization import deserialize_message
>>> from sensor_msgs.msg import PointCloud2
>>> from impact_damper_sim.recording.batches import (ACCEL_DTYPE, ACCEL_FIELDS,
...                                                  ACCEL_POINT_STEP, BatchEncoder)
>>> samples = np.zeros(3, ACCEL_DTYPE)
>>> samples['t'] = [0.0, 0.0005, 0.001]          # s after header.stamp (2 kHz)
>>> samples['ay'] = [1.0, -2.0, 0.5]             # m/s^2
>>> encoder = BatchEncoder('hpotp_casing_bottom', ACCEL_FIELDS, ACCEL_POINT_STEP)
>>> msg = deserialize_message(encoder.encode(2_500_000_000, samples), PointCloud2)
>>> rows = batch_rows(msg)
>>> rows.dtype.names
('t', 'ax', 'ay', 'az', 'wx', 'wy', 'wz')
>>> rows['ay']
array([ 1. , -2. ,  0.5])
>>> batch_times(msg)                             # sim time of each row (s)
array([2.5   , 2.5005, 2.501 ])
>>> batch_columns(msg)['ay'].flags['C_CONTIGUOUS']
True
"""
from __future__ import annotations

import numpy as np

from ..recording.batches import rows_of


def batch_rows(msg):
    """The rows of a batch as a NumPy structured array, one field per PointCloud2 field.

    Parameters
    ----------
    msg : sensor_msgs.msg.PointCloud2
        A batch of the node (any decoded PointCloud2: rclpy, mcap_ros2, rosbags), little-endian.

    Returns
    -------
    numpy.ndarray, shape (n,)
        A copy, fields named and typed as ``msg.fields`` says, in SI as the node publishes
        them: ``t`` (s after ``header.stamp``), accelerations (m/s^2), angular velocities
        (rad/s), impulses (N s), speeds (m/s or rad/s), angles (rad), energy (J).

    Raises
    ------
    ValueError
        Big-endian data, an unknown field datatype, or ``data`` shorter than its rows.
    """
    return rows_of(msg)


def batch_columns(msg):
    """The columns of a batch: field name -> contiguous 1-D array.

    Parameters
    ----------
    msg : sensor_msgs.msg.PointCloud2
        As for :func:`batch_rows`.

    Returns
    -------
    dict of str to numpy.ndarray
        Each field's values in row order (units as in :func:`batch_rows`), in the message's
        field order.
    """
    rows = batch_rows(msg)
    return {name: np.ascontiguousarray(rows[name]) for name in rows.dtype.names}


def batch_start(msg):
    """The batch's ``header.stamp`` in seconds of sim time.

    Parameters
    ----------
    msg : sensor_msgs.msg.PointCloud2
        A batch: for samples the first sample's time, for events (``impacts``,
        ``rotor/keyphasor``) the start of the interval the batch covers.

    Returns
    -------
    float
        Sim time (s).
    """
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def batch_times(msg, rows=None):
    """The sim time of each row: ``header.stamp`` + ``t``.

    Parameters
    ----------
    msg : sensor_msgs.msg.PointCloud2
        A batch with a ``t`` field (s after ``header.stamp``); every batch topic has one.
    rows : numpy.ndarray, optional
        ``batch_rows(msg)`` when already decoded.

    Returns
    -------
    numpy.ndarray of float64, shape (n,)
        Sim time (s).
    """
    rows = batch_rows(msg) if rows is None else rows
    return batch_start(msg) + rows['t']


__all__ = ['batch_columns', 'batch_rows', 'batch_start', 'batch_times']
