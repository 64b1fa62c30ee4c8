"""Canonical CDR for any ROS 2 message: zero padding, no trailing bytes, equal messages equal.

``rclpy.serialization.serialize_message`` (Fast-CDR) leaves alignment pads uninitialised
and pads the end to 8 bytes: a ``sensor_msgs/JointState`` with an empty ``effort`` comes out
76 bytes long with 4 trailing bytes of garbage, which rosbags refuses ("CDR message size
mismatch": readers allow at most 3 trailing bytes), and two serializations of one message
differ. This writer follows the message's own type description (``SLOT_TYPES``) and writes
little-endian XCDR1 as rosbags and the DDS specification do: each primitive aligned to its
size counted after the 4-byte encapsulation header, pads zero, nothing after the last field.
rclpy, rosbags and mcap_ros2 read its bytes (``test/test_cdr.py``).

It runs in Python, for the node's low-rate topics (rotor, clock, state, diagnostics,
commands); the per-sample streams use the vectorised packers of :mod:`.wire` and
:mod:`impact_damper_sim.recording.batches`, which write the same layout.
"""
from __future__ import annotations

import struct

import numpy as np

#: rosidl basic type -> (struct format, size)
_BASIC = {
    'boolean': ('?', 1), 'octet': ('B', 1), 'char': ('B', 1), 'uint8': ('B', 1),
    'int8': ('b', 1), 'int16': ('h', 2), 'uint16': ('H', 2), 'int32': ('i', 4),
    'uint32': ('I', 4), 'int64': ('q', 8), 'uint64': ('Q', 8), 'float': ('f', 4),
    'double': ('d', 8),
}


class _Writer:
    def __init__(self):
        self.parts = [b'\x00\x01\x00\x00']   # little-endian CDR
        self.size = 0

    def align(self, n):
        pad = -self.size % n
        if pad:
            self.parts.append(b'\x00' * pad)
            self.size += pad

    def raw(self, data):
        self.parts.append(data)
        self.size += len(data)

    def basic(self, typename, value):
        fmt, size = _BASIC[typename]
        self.align(size)
        if typename == 'octet' and isinstance(value, (bytes, bytearray)):
            value = value[0]
        elif typename == 'char' and isinstance(value, str):
            value = ord(value)
        self.raw(struct.pack('<' + fmt, value))

    def basics(self, typename, values):
        """A run of primitives (the elements of an array or sequence)."""
        n = len(values)
        if not n:
            return
        fmt, size = _BASIC[typename]
        self.align(size)
        if isinstance(values, (bytes, bytearray)):   # byte[] / octet sequences
            self.raw(bytes(values))
        elif n <= 64:   # struct beats a NumPy round trip on short runs
            self.raw(struct.pack(f'<{n}{fmt}', *values))
        else:
            self.raw(np.asarray(values, '<' + fmt if fmt != '?' else '?').tobytes())

    def string(self, text):
        data = text.encode() + b'\x00'
        self.basic('uint32', len(data))
        self.raw(data)


def _write(w, slot_type, value):
    kind = type(slot_type).__name__
    if kind == 'BasicType':
        w.basic(slot_type.typename, value)
    elif kind in ('UnboundedString', 'BoundedString'):
        w.string(value)
    elif kind == 'NamespacedType':
        _write_message(w, value)
    elif kind in ('Array', 'UnboundedSequence', 'BoundedSequence'):
        if kind != 'Array':
            w.basic('uint32', len(value))
        item = slot_type.value_type
        if type(item).__name__ == 'BasicType':
            w.basics(item.typename, value)
        else:
            for element in value:
                _write(w, item, element)
    else:
        raise TypeError(f'CDR: field type {kind} is not supported')


_FIELDS = {}   # message class -> ((field name, slot type), ...)


def _write_message(w, msg):
    cls = type(msg)
    fields = _FIELDS.get(cls)
    if fields is None:
        fields = _FIELDS[cls] = tuple(zip(cls.get_fields_and_field_types(), cls.SLOT_TYPES))
    for name, slot_type in fields:
        _write(w, slot_type, getattr(msg, name))


def serialize(msg):
    """The canonical CDR bytes of a ROS 2 message.

    Parameters
    ----------
    msg : ROS 2 message (an instance of a rosidl-generated class)

    Returns
    -------
    bytes
        Encapsulation header and little-endian XCDR1, pads zero, no trailing padding.

    Raises
    ------
    TypeError
        A field type this writer does not know (wide strings).
    """
    w = _Writer()
    _write_message(w, msg)
    return b''.join(w.parts)


__all__ = ['serialize']
