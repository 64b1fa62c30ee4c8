"""What goes on the wire: publishers that serialize once and a vectorised ``Imu`` packer.

* :class:`Outlet` publishes serialized bytes (rclpy sends ``bytes`` as they are) and gives
  the same bytes to the recorder, so a message is serialized once for both, by
  :func:`.cdr.serialize` (canonical CDR: zero pads, no trailing bytes, readable by rosbags).
  The bytes go to the middleware through :func:`write_raw`, the part of rclpy's
  ``Publisher.publish`` that bytes need (some 1,700 a second leave one node).
* :class:`StampedPacker` (and :class:`ImuPacker`) writes a whole chunk of stamped messages
  (``sensor_msgs/Imu`` samples) as CDR in one NumPy pass from a canonical template; the field
  offsets are found in that template, and the packer checks a packed message against rclpy
  (a round trip) before it is used.
"""
from __future__ import annotations

import functools
import struct

import numpy as np
from builtin_interfaces.msg import Time
from rclpy.serialization import deserialize_message

from .cdr import serialize


def type_name(msg_type):
    """``pkg/msg/Type`` of a generated message class (str)."""
    return f"{msg_type.__module__.split('.')[0]}/msg/{msg_type.__name__}"


def stamp(t):
    """A ``builtin_interfaces/Time`` for sim time ``t`` (s)."""
    ns = int(round(t * 1e9))
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def set_stamp(header, t):
    """Set ``header.stamp`` to ``t`` (s) in place (cheaper than a new Time per message)."""
    ns = int(round(t * 1e9))
    header.stamp.sec, header.stamp.nanosec = divmod(ns, 1_000_000_000)


class Outlet:
    """A publisher that serializes a message once and gives the same bytes to the recorder.

    Parameters
    ----------
    node : rclpy.node.Node
        Owner (creates the publisher).
    msg_type : type
        Message class.
    topic : str
        Topic name (relative names resolve in the node's namespace).
    qos : QoSProfile
        Offered QoS (also written to the record file).
    record : callable
        ``record(topic, type_name, qos, data, ns)`` receives every message's bytes.

    Attributes
    ----------
    wire : bool
        Some subscription was matched at the last :meth:`look_up` (False before the first).
    write : callable
        ``write(data)`` puts serialized bytes on the wire: :func:`write_raw` on the
        publisher's handle, or the publisher's ``publish`` where a test or a bench replaced
        it on the instance (:meth:`look_up` notices that). Replacing :meth:`publish_raw`
        on the instance captures everything the outlet would send, counts and records.
    """

    def __init__(self, node, msg_type, topic, qos, record):
        self.pub = node.create_publisher(msg_type, topic, qos)
        self.topic = self.pub.topic_name   # fully qualified; cached (a C call each time)
        self.type_name = type_name(msg_type)
        self.msg_type = msg_type
        self.qos = qos
        self.count = 0   # messages published
        self._record = record
        self.wire = False
        self._write_raw = functools.partial(write_raw, self.pub.handle)
        self.write = self._write_raw

    def publish(self, msg, ns=None, wire=True):
        """Serialize ``msg`` once, publish (if ``wire``) and record the bytes (``ns``: log
        time, ns)."""
        self.publish_raw(serialize(msg), ns, wire)

    def publish_raw(self, data, ns=None, wire=True):
        """Publish (if ``wire``) and record serialized bytes ``data`` (``ns``: log time)."""
        if wire:
            self.write(data)
        self.count += 1
        self._record(self.topic, self.type_name, self.qos, data, ns)

    def has_subscribers(self):
        """bool: Some subscription is matched (DDS drops what nobody reads anyway)."""
        return self.pub.get_subscription_count() > 0

    def look_up(self):
        """Ask whether anybody reads the topic now (:meth:`has_subscribers`) into
        :attr:`wire`, and bind :attr:`write` anew; :attr:`wire` (bool)."""
        # a publish replaced on the rclpy publisher itself (how tests and benches watch the
        # wire) is honoured from here on
        self.write = vars(self.pub).get('publish', self._write_raw)
        self.wire = wire = bool(self.has_subscribers())
        return wire


def write_raw(handle, data):
    """Put serialized ``data`` (bytes) on the wire through an rclpy publisher's ``handle``.

    What rclpy's ``Publisher.publish`` does with bytes, without its per-call type checks. The
    handle is held while it sends, as rclpy holds it: a publisher destroyed meanwhile (a
    stepping thread that outlived ``destroy_node``) raises ``InvalidHandle``, never crashes.
    """
    with handle:
        handle.publish_raw(data)


class StampedPacker:
    """Serializes chunks of one stamped message type that differ only in stamp and vectors.

    The message has a ``header`` and some ``geometry_msgs/Vector3`` fields (``paths``, e.g.
    ``('angular_velocity', 'linear_acceleration')`` of an ``Imu``); everything else is the
    template's. Offsets are found by serializing the template with sentinel values, and the
    packer checks a packed message against rclpy (a round trip) before it is used.

    Parameters
    ----------
    template : message
        Frame id and every other field of each message (copied now).
    paths : sequence of str
        Dotted paths of the Vector3 fields the chunks fill, in :meth:`pack`'s order.

    Raises
    ------
    RuntimeError
        The packed bytes do not deserialize to the message they should be (the CDR layout is
        not the one assumed); the caller then serializes message by message.
    """

    def __init__(self, template, paths):
        msg_type = type(template)
        self.paths = tuple(paths)
        probe = deserialize_message(serialize(template), msg_type)
        sentinels = [tuple(float(v) * (i + 1) * 1.0e-300 for v in (3.0, 7.0, 11.0))
                     for i in range(len(self.paths))]
        for path, values in zip(self.paths, sentinels):
            _set_vector(probe, path, values)
        probe.header.stamp.sec, probe.header.stamp.nanosec = 0x5EC0CAFE, 0x0DDBA11
        raw = serialize(probe)
        offsets = [raw.find(struct.pack('<3d', *values)) for values in sentinels]
        stamp_at = raw.find(struct.pack('<iI', 0x5EC0CAFE, 0x0DDBA11))
        if min(offsets + [stamp_at]) < 0 or raw[:2] != b'\x00\x01':   # little-endian CDR
            raise RuntimeError(f'{type_name(msg_type)}: unexpected CDR layout')
        self.size = len(raw)
        names = [f'v{i}' for i in range(len(self.paths))]
        self.dtype = np.dtype({'names': ['sec', 'nsec', *names],
                               'formats': ['<i4', '<u4'] + [('<f8', 3)] * len(names),
                               'offsets': [stamp_at, stamp_at + 4, *offsets],
                               'itemsize': self.size})
        self._names = names
        self._template = np.frombuffer(serialize(template), np.uint8).copy()
        # the round trip: a packed message must read back as the one rclpy would send
        check = deserialize_message(serialize(template), msg_type)
        check.header.stamp.sec, check.header.stamp.nanosec = 12, 345678901
        values = [(0.25 * (i + 1), -1.5e5, 2.0 ** -40) for i in range(len(self.paths))]
        for path, v in zip(self.paths, values):
            _set_vector(check, path, v)
        packed = self.pack(np.array([12_345_678_901]), *[np.array([v]) for v in values])[0]
        if len(packed) != self.size or deserialize_message(packed, msg_type) != check:
            raise RuntimeError(f'{type_name(msg_type)}: packed bytes do not read back')

    def pack(self, t_ns, *vectors):
        """Serialized messages (list of bytes), one per row.

        Parameters
        ----------
        t_ns : ndarray of int, shape (k,)
            Stamps (ns, >= 0).
        *vectors : ndarray, shape (k, 3)
            One array per path, in the units of that field.
        """
        k = len(t_ns)
        buf = np.empty(k, self.dtype)
        buf.view(np.uint8).reshape(k, self.size)[:] = self._template
        sec, nsec = np.divmod(np.asarray(t_ns, np.int64), 1_000_000_000)
        buf['sec'], buf['nsec'] = sec, nsec
        for name, values in zip(self._names, vectors):
            buf[name] = values
        raw = buf.tobytes()
        n = self.size
        return [raw[i:i + n] for i in range(0, k * n, n)]


def _set_vector(msg, path, values):
    target = msg
    for part in path.split('.'):
        target = getattr(target, part)
    target.x, target.y, target.z = values


class ImuPacker(StampedPacker):
    """A :class:`StampedPacker` of ``sensor_msgs/Imu``: ``pack(t_ns, linear_acceleration,
    angular_velocity)``."""

    def __init__(self, template):
        super().__init__(template, ('linear_acceleration', 'angular_velocity'))


__all__ = ['ImuPacker', 'Outlet', 'StampedPacker', 'set_stamp', 'stamp', 'type_name',
           'write_raw']
