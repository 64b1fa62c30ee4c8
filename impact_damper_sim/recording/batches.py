"""Batched samples and events as ``sensor_msgs/PointCloud2``: the layout, CDR bytes, decoding.

High-rate streams (an accelerometer at 20 or 50 kHz, thousands of impacts a second) cannot go
one message per sample to the clients our users write: a Python subscriber takes about 2,000
messages a second. They go as ROS drivers of high-rate sensors send them, many samples per
message: LiDAR drivers put each point's time offset in a field ``t`` of a PointCloud2, a
common_interfaces type that rosbags, the mcap readers, rclpy, Foxglove and PlotJuggler read
without a custom package. Each row of ``data`` is one sample; the fields name its columns.

Layouts (every field little-endian, count 1; ``header.stamp`` the start of the batch):

``accel/<accelerometer>/batch`` (:data:`ACCEL_FIELDS`, 56 bytes a sample)
    ``t`` float64 (s): the sample's time minus ``header.stamp``; ``ax ay az`` float64
    (m/s^2): linear acceleration; ``wx wy wz`` float64 (rad/s): angular velocity.
    ``header.stamp`` is the chunk's first sample time, ``header.frame_id`` the accelerometer
    frame. A sample a sensor fault dropped has no row (the rows keep their own ``t``; a
    chunk with every sample dropped is an empty batch).

``accel/<accelerometer>/truth`` (:data:`ACCEL_FIELDS`, the same 56 bytes a sample)
    The ground truth of the same samples: ``ax ay az`` the model's acceleration (m/s^2, the
    model's axes at the node) through the anti-alias low-pass only (no other stage of the
    channel); ``t`` and ``wx wy wz`` as in the batch. Off unless asked for.

``rotor/tach`` (:data:`TACH_FIELDS`, 24 bytes a sample)
    ``t`` float64 (s): the sample's time minus ``header.stamp`` (the same times as the
    accelerometer batches); ``angle`` float64 (rad): the shaft angle ``phi(t)`` the unbalance
    force uses, unwrapped (0 at sim time 0, never decreasing; ``angle mod 2 pi`` is
    ``rotor/joint_states``' position); ``speed`` float64 (rad/s). ``header.stamp`` the first
    sample's time, ``header.frame_id`` empty (a shaft angle has no frame).

``rotor/keyphasor`` (:data:`KEYPHASOR_FIELDS`, 24 bytes an event)
    ``t`` float64 (s): the time ``phi`` reached ``2 pi revolution`` minus ``header.stamp``;
    ``revolution`` uint32: that whole number of turns (1 first); ``speed`` float64 (rad/s)
    then. ``header.stamp`` the start of the interval the batch covers (one per stepped chunk,
    empty when no turn was completed), as for ``impacts``.

``impacts`` (:data:`IMPACT_FIELDS`, 64 bytes an impact)
    ``t`` float64 (s): the impact time minus ``header.stamp``; ``impactor`` uint32: index of
    the impactor in the scene (the order of ``impactor_state``); ``jx jy jz`` float64 (N s):
    impulse on the impactor (direction the contact normal); ``v_approach`` and
    ``v_separation`` float64 (m/s): normal speeds before and after; ``energy`` float64 (J):
    energy dissipated. ``header.stamp`` is the start of the interval the batch covers (one
    batch per stepped chunk, empty when nothing hit), so a batch of width 0 still says that
    nothing happened in its interval.

The CDR bytes are written here, not by rclpy, so that equal batches are equal bytes: every
alignment pad is zero (rclpy leaves pads uninitialised) and there is no trailing padding.
Nothing here imports rclpy.
"""
from __future__ import annotations

import struct

import numpy as np

from .node_topics import BATCH_SUFFIX, POINTCLOUD2

#: PointField datatypes (sensor_msgs/PointField) and their NumPy formats.
_DATATYPES = {1: 'i1', 2: 'u1', 3: 'i2', 4: 'u2', 5: 'i4', 6: 'u4', 7: 'f4', 8: 'f8'}
FLOAT64, UINT32 = 8, 6
_CDR_HEADER = b'\x00\x01\x00\x00'   # encapsulation: little-endian CDR (XCDR1)

#: Fields of an accelerometer batch: (name, offset in bytes, datatype).
ACCEL_FIELDS = (('t', 0, FLOAT64), ('ax', 8, FLOAT64), ('ay', 16, FLOAT64),
                ('az', 24, FLOAT64), ('wx', 32, FLOAT64), ('wy', 40, FLOAT64),
                ('wz', 48, FLOAT64))
ACCEL_POINT_STEP = 56
#: Fields of an impact batch (4 bytes of padding after ``impactor`` keep the floats aligned).
IMPACT_FIELDS = (('t', 0, FLOAT64), ('impactor', 8, UINT32), ('jx', 16, FLOAT64),
                 ('jy', 24, FLOAT64), ('jz', 32, FLOAT64), ('v_approach', 40, FLOAT64),
                 ('v_separation', 48, FLOAT64), ('energy', 56, FLOAT64))
IMPACT_POINT_STEP = 64
#: Fields of the tachometer: one row per full-rate sample.
TACH_FIELDS = (('t', 0, FLOAT64), ('angle', 8, FLOAT64), ('speed', 16, FLOAT64))
TACH_POINT_STEP = 24
#: Fields of the keyphasor: one row per revolution (4 bytes of padding after ``revolution``).
KEYPHASOR_FIELDS = (('t', 0, FLOAT64), ('revolution', 8, UINT32), ('speed', 16, FLOAT64))
KEYPHASOR_POINT_STEP = 24


def dtype_of(fields, point_step):
    """The NumPy structured dtype of a row.

    Parameters
    ----------
    fields : sequence of (str, int, int)
        Name, offset (bytes) and PointField datatype of each field.
    point_step : int
        Row size (bytes).

    Returns
    -------
    numpy.dtype
    """
    return np.dtype({'names': [f[0] for f in fields],
                     'formats': ['<' + _DATATYPES[f[2]] for f in fields],
                     'offsets': [f[1] for f in fields], 'itemsize': int(point_step)})


ACCEL_DTYPE = dtype_of(ACCEL_FIELDS, ACCEL_POINT_STEP)
IMPACT_DTYPE = dtype_of(IMPACT_FIELDS, IMPACT_POINT_STEP)
TACH_DTYPE = dtype_of(TACH_FIELDS, TACH_POINT_STEP)
KEYPHASOR_DTYPE = dtype_of(KEYPHASOR_FIELDS, KEYPHASOR_POINT_STEP)


class CdrWriter:
    """A little-endian CDR (XCDR1) writer; alignment is counted after the 4-byte header.

    The one writer of the package's message bytes: batches here, every other message of the
    node in :mod:`.message_cdr`.
    """

    def __init__(self):
        self.parts = [_CDR_HEADER]
        self.size = 0

    def align(self, n):
        pad = -self.size % n
        if pad:
            self.raw(b'\x00' * pad)

    def raw(self, data):
        self.parts.append(data)
        self.size += len(data)

    def put(self, fmt, *values):
        """Primitives of one struct code (``'d'``, ``'I'``, ``'q'``, ...), aligned to it."""
        self.align(struct.calcsize(fmt.lstrip('0123456789')[0]))
        self.raw(struct.pack('<' + fmt, *values))

    def u32(self, value):
        self.put('I', value)

    def stamp(self, ns):
        sec, nsec = divmod(int(ns), 1_000_000_000)
        self.put('iI', sec, nsec)

    def string(self, text):
        data = text.encode() + b'\x00'
        self.put('I', len(data))
        self.raw(data)

    def doubles(self, values):
        """A ``float64[]`` sequence: its length, then the values (aligned only if any)."""
        values = [float(v) for v in values]
        self.put('I', len(values))
        if values:
            self.put(f'{len(values)}d', *values)

    def strings(self, texts):
        self.put('I', len(texts))
        for text in texts:
            self.string(text)

    def bytes(self):
        return b''.join(self.parts)


class BatchEncoder:
    """Writes one batch layout as ``sensor_msgs/PointCloud2`` CDR bytes.

    The bytes before ``data`` depend only on the stamp, the frame and the width, so they are
    put together from pieces made once.

    Parameters
    ----------
    frame_id : str
        ``header.frame_id``.
    fields : sequence of (str, int, int)
        The layout (:data:`ACCEL_FIELDS`, :data:`IMPACT_FIELDS`, :data:`TACH_FIELDS` or
        :data:`KEYPHASOR_FIELDS`).
    point_step : int
        Row size (bytes).
    """

    def __init__(self, frame_id, fields, point_step):
        self.dtype = dtype_of(fields, point_step)
        self.point_step = int(point_step)
        head = CdrWriter()
        head.raw(b'\x00' * 8)            # stamp: sec int32, nanosec uint32
        head.string(frame_id)
        head.align(4)
        frame = b''.join(head.parts[2:])  # frame_id's length, text and pad
        # height, width, fields, is_bigendian, point_step, row_step, data length: width
        # changes per message, so the part after it is made once with a fixed offset
        mid = CdrWriter()
        mid.size = head.size + 8         # after height and width
        mid.u32(len(fields))
        for name, offset, datatype in fields:
            mid.string(name)
            mid.u32(offset)
            mid.raw(bytes([datatype]))
            mid.u32(1)
        mid.raw(b'\x00')                 # is_bigendian
        mid.u32(self.point_step)
        self._frame, self._mid = frame, b''.join(mid.parts[1:])
        # everything before ``data`` in one pack: header, stamp, frame, height, width, the
        # fixed middle, row_step and data's length (each u32 lands aligned)
        self._prefix = struct.Struct(f'<4siI{len(frame)}sII{len(self._mid)}sII')

    def encode(self, stamp_ns, rows):
        """CDR bytes of one batch.

        Parameters
        ----------
        stamp_ns : int
            ``header.stamp`` (ns, >= 0).
        rows : ndarray of :attr:`dtype`, shape (n,)
            The samples; their ``t`` is relative to the stamp (s).

        Returns
        -------
        bytes
        """
        # field by field into zeros: a structured copy leaves the gaps between fields
        # uninitialised, and equal batches must be equal bytes
        out = np.zeros(len(rows), self.dtype)
        for name in self.dtype.names:
            out[name] = rows[name]
        return self.encode_data(stamp_ns, out.size, out.tobytes())

    def encode_data(self, stamp_ns, width, data):
        """CDR bytes of one batch whose rows are already laid out: what :meth:`encode`
        writes for rows whose bytes (every gap zero) are ``data``.

        Parameters
        ----------
        stamp_ns : int
            ``header.stamp`` (ns, >= 0).
        width : int
            Number of rows.
        data : bytes
            ``width`` rows of :attr:`point_step` bytes in the layout of :attr:`dtype`.

        Returns
        -------
        bytes
        """
        sec, nsec = divmod(int(stamp_ns), 1_000_000_000)
        return b''.join((self._prefix.pack(_CDR_HEADER, sec, nsec, self._frame, 1, width,
                                           self._mid, self.point_step * width, len(data)),
                         data, b'\x01'))   # is_dense: no invalid samples


def rows_of(msg):
    """The samples of a decoded PointCloud2 as a NumPy structured array (a copy).

    Works on any decoded message object with PointCloud2's fields (rclpy, mcap_ros2, rosbags):
    the dtype is built from the message's own ``fields``, so a reader needs no layout table.

    Parameters
    ----------
    msg : sensor_msgs/PointCloud2
        Decoded message.

    Returns
    -------
    ndarray, shape (height * width,)

    Raises
    ------
    ValueError
        Big-endian data, an unknown datatype, or ``data`` shorter than the rows it claims.
    """
    if msg.is_bigendian:
        raise ValueError('PointCloud2: big-endian data is not supported')
    fields = [(f.name, f.offset, f.datatype) for f in msg.fields]
    for name, _, datatype in fields:
        if datatype not in _DATATYPES:
            raise ValueError(f'PointCloud2: field {name!r} has unknown datatype {datatype}')
    n = int(msg.height) * int(msg.width)
    data = msg.data
    buf = data if isinstance(data, (bytes, bytearray, memoryview)) else (
        data.tobytes() if hasattr(data, 'tobytes') else bytes(data))
    if len(buf) < n * int(msg.point_step):
        raise ValueError(f'PointCloud2: data holds {len(buf)} bytes, '
                         f'{n} rows of {msg.point_step} need {n * int(msg.point_step)}')
    dtype = dtype_of(fields, msg.point_step)
    return np.frombuffer(buf, dtype, count=n).copy()


def sample_times_ns(msg, rows=None):
    """Absolute times (ns, int64) of a batch's rows: ``header.stamp`` + ``t``.

    Parameters
    ----------
    msg : sensor_msgs/PointCloud2
        Decoded message with a ``t`` field (s).
    rows : ndarray, optional
        ``rows_of(msg)`` when already decoded.
    """
    rows = rows_of(msg) if rows is None else rows
    stamp = msg.header.stamp
    base = int(stamp.sec) * 1_000_000_000 + int(getattr(stamp, 'nanosec', 0))
    return base + np.rint(rows['t'] * 1e9).astype(np.int64)


__all__ = ['ACCEL_DTYPE', 'ACCEL_FIELDS', 'ACCEL_POINT_STEP', 'BATCH_SUFFIX', 'BatchEncoder',
           'IMPACT_DTYPE', 'IMPACT_FIELDS', 'IMPACT_POINT_STEP', 'KEYPHASOR_DTYPE',
           'KEYPHASOR_FIELDS', 'KEYPHASOR_POINT_STEP', 'POINTCLOUD2', 'TACH_DTYPE',
           'TACH_FIELDS', 'TACH_POINT_STEP', 'dtype_of', 'rows_of', 'sample_times_ns']
