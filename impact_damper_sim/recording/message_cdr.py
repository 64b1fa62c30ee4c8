"""The CDR bytes of the single messages ``vibration_node`` writes, without ROS.

``rosgraph_msgs/Clock``, ``std_msgs/Float64`` and ``String``, ``geometry_msgs/Vector3Stamped``,
``sensor_msgs/JointState``, ``rcl_interfaces/ParameterEvent``, and per-sample
``sensor_msgs/Imu`` in chunks (:class:`ImuEncoder`, one NumPy pass per chunk);
:class:`~impact_damper_sim.recording.node_messages.NodeMessages` puts them on the node's
streams. The messages of every chunk have encoders that make their fixed bytes once
(:class:`ImuEncoder`, :class:`Vector3StampedEncoder`, :class:`JointStateEncoder`); the
functions write the same bytes field by field (``test/test_packing_templates.py``).

The CDR written here is canonical little-endian XCDR1 as rosbags writes it (alignment counted
after the 4-byte encapsulation header, pads zero, nothing after the last field), so equal
messages are equal bytes; ``test/test_node_messages.py`` checks every encoder against rclpy's
message classes and :func:`impact_damper_sim.ros.cdr.serialize`.
"""
from __future__ import annotations

import functools
import struct

import numpy as np

from .batches import CdrWriter
from .log_metadata import plain

_HEADER = b'\x00\x01\x00\x00'   # CDR encapsulation: little-endian
#: rcl_interfaces/ParameterType values
PARAMETER_BOOL, PARAMETER_INTEGER, PARAMETER_DOUBLE, PARAMETER_STRING = 1, 2, 3, 4


_STAMP = struct.Struct('<iI')


def _stamp(ns):
    """The 8 bytes of a ``builtin_interfaces/Time`` (``CdrWriter.stamp``'s)."""
    return _STAMP.pack(*divmod(int(ns), 1_000_000_000))


def clock_cdr(ns):
    """``rosgraph_msgs/Clock`` bytes for sim time ``ns`` (ns, >= 0)."""
    return _HEADER + _stamp(ns)


def float64_cdr(value):
    """``std_msgs/Float64`` bytes of ``value`` (in the unit of the topic)."""
    return _HEADER + struct.pack('<d', float(value))


def string_cdr(text):
    """``std_msgs/String`` bytes of ``text`` (UTF-8)."""
    w = CdrWriter()
    w.string(str(text))
    return w.bytes()


def fault_command_text(key, value):
    """The ``accel/fault_command`` text a schedule's fault key stands for (YAML flow, SI).

    Parameters
    ----------
    key : str
        ``'fault'`` or ``'clear_fault'``.
    value : dict or str
        A fault's plain SI mapping (``FaultSpec.as_dict``; keys without a value are left
        out), or the name of the fault to clear (``'all'``: every one).

    Returns
    -------
    str
        ``{kind: gain, accelerometer: hpotp_casing_bottom, duration: 0.5, axes: xyz, gain:
        20.0}`` or ``{clear: all}``: what a live command would send, read back to the same
        fault by ``parse_command``.
    """
    import yaml
    data = ({'clear': str(value)} if key == 'clear_fault' else
            {k: plain(v) for k, v in value.items() if v is not None})
    return yaml.safe_dump(data, default_flow_style=True, sort_keys=False, width=1 << 16).strip()


class Vector3StampedEncoder:
    """Writes ``geometry_msgs/Vector3Stamped`` messages of one frame: one ``struct.pack``
    of the stamp, the frame's bytes (made once) and the vector.

    Parameters
    ----------
    frame_id : str
        ``header.frame_id``.
    """

    def __init__(self, frame_id):
        w = CdrWriter()
        w.stamp(0)
        w.string(frame_id)
        w.align(8)                                  # the vector's doubles
        self._frame = w.bytes()[len(_HEADER) + 8:]  # frame_id's length, text and pad
        self._struct = struct.Struct(f'<4siI{len(self._frame)}s3d')

    def pack(self, ns, x, y, z):
        """The message's bytes: ``header.stamp`` ``ns`` (ns, >= 0), the vector (x, y, z)
        (float, in the unit the topic states)."""
        sec, nsec = divmod(int(ns), 1_000_000_000)
        return self._struct.pack(_HEADER, sec, nsec, self._frame, x, y, z)


@functools.lru_cache(maxsize=64)
def _vector3_encoder(frame_id):
    return Vector3StampedEncoder(frame_id)


def vector3_stamped_cdr(ns, frame_id, vector):
    """``geometry_msgs/Vector3Stamped`` bytes.

    Parameters
    ----------
    ns : int
        ``header.stamp`` (ns, >= 0).
    frame_id : str
        ``header.frame_id``.
    vector : sequence of 3 float
        x, y, z (in the unit the topic states).
    """
    x, y, z = (float(v) for v in vector)
    return _vector3_encoder(frame_id).pack(ns, x, y, z)


def joint_state_cdr(ns, names, position=(), velocity=(), effort=(), frame_id=''):
    """``sensor_msgs/JointState`` bytes.

    Parameters
    ----------
    ns : int
        ``header.stamp`` (ns, >= 0).
    names : sequence of str
        Joint names.
    position, velocity, effort : sequence of float
        Per joint (m or rad, m/s or rad/s, N or N m); empty when not given.
    frame_id : str
        ``header.frame_id``.
    """
    w = CdrWriter()
    w.stamp(ns)
    w.string(frame_id)
    w.strings(list(names))
    w.doubles(position)
    w.doubles(velocity)
    w.doubles(effort)
    return w.bytes()


def parameter_value_type(value):
    """The ``rcl_interfaces/ParameterType`` of a bool, int, float or str value."""
    if isinstance(value, bool):
        return PARAMETER_BOOL
    if isinstance(value, (int, np.integer)):
        return PARAMETER_INTEGER
    if isinstance(value, (float, np.floating)):
        return PARAMETER_DOUBLE
    if isinstance(value, str):
        return PARAMETER_STRING
    raise TypeError(f'parameter value {value!r}: only bool, int, float and str are recorded')


def parameter_event_cdr(ns, node, changed):
    """``rcl_interfaces/ParameterEvent`` bytes: parameters of ``node`` changed at ``ns``.

    Parameters
    ----------
    ns : int
        ``stamp`` (ns, >= 0).
    node : str
        Fully qualified node name (``/vibration_node``).
    changed : sequence of (str, bool or int or float or str)
        ``changed_parameters``: name and new value, in order.
    """
    w = CdrWriter()
    w.stamp(ns)
    w.string(node)
    w.put('I', 0)                       # new_parameters
    w.put('I', len(changed))            # changed_parameters
    for name, value in changed:
        kind = parameter_value_type(value)
        w.string(name)
        w.put('B', kind)
        w.put('?', kind == PARAMETER_BOOL and bool(value))
        w.put('q', int(value) if kind == PARAMETER_INTEGER else 0)
        w.put('d', float(value) if kind == PARAMETER_DOUBLE else 0.0)
        w.string(value if kind == PARAMETER_STRING else '')
        for _ in range(5):              # the five array values: empty
            w.put('I', 0)
    w.put('I', 0)                       # deleted_parameters
    return w.bytes()


class JointStateEncoder:
    """Writes ``sensor_msgs/JointState`` messages whose frame and joint names are fixed.

    Only the stamp and the three arrays change (one value per joint each), so the bytes are
    a template with those slots filled in, one ``struct.pack``: what :func:`joint_state_cdr`
    writes, without its per-field Python (``impactor_state`` every chunk: 24 joints on
    hpotp; ``rotor/joint_states``: one joint, no effort).

    Parameters
    ----------
    names : sequence of str
        Joint names.
    frame_id : str
        ``header.frame_id``.
    effort : bool
        Whether ``effort`` carries a value per joint; False: it is empty (``rotor/joint_states``
        sends position and velocity only).
    """

    def __init__(self, names, frame_id='', *, effort=True):
        n = len(names)
        w = CdrWriter()
        w.stamp(0)
        w.string(frame_id)
        w.strings(list(names))
        slots = []
        for _ in range(3 if effort else 2):         # position, velocity[, effort]
            w.put('I', n)
            if n:
                w.align(8)
                slots.append(len(_HEADER) + w.size)
                w.raw(bytes(8 * n))
        if not effort:
            w.put('I', 0)                           # effort: empty
        template = w.bytes()
        # the fixed bytes between the stamp and the arrays, and after the last one: the
        # message is one struct.pack of these pieces, the stamp and the values
        edges = [len(_HEADER) + 8] + [e for at in slots for e in (at, at + 8 * n)]
        edges.append(len(template))
        self._pieces = [template[a:b] for a, b in zip(edges[::2], edges[1::2])]
        self._struct = struct.Struct('<4siI' + f'{n}d'.join(f'{len(p)}s' for p in self._pieces))
        self.n = n

    def pack(self, ns, position, velocity, effort=()):
        """The message's bytes.

        Parameters
        ----------
        ns : int
            ``header.stamp`` (ns, >= 0).
        position, velocity, effort : array_like, shape (n,)
            Per joint (m, m/s, N or the joint's own units); ``effort`` is not read when the
            encoder was made with ``effort=False``.
        """
        args = [_HEADER, *divmod(int(ns), 1_000_000_000), self._pieces[0]]
        for piece, values in zip(self._pieces[1:], (position, velocity, effort)):
            # as Python floats: what struct packs fastest (the same doubles)
            args += values.tolist() if isinstance(values, np.ndarray) else values
            args.append(piece)
        return self._struct.pack(*args)


class ImuEncoder:
    """Writes chunks of ``sensor_msgs/Imu`` that differ only in stamp and readings.

    Every other field is fixed: the frame, orientation unknown (``orientation_covariance[0]
    = -1``, REP-145; the quaternion rclpy's default, w = 1), ``angular_velocity_covariance``
    zero (unknown) and ``linear_acceleration_covariance`` diagonal with the noise variance.

    Parameters
    ----------
    frame_id : str
        ``header.frame_id``.
    noise_variance : float
        Diagonal of ``linear_acceleration_covariance`` ((m/s^2)^2; 0 = unknown).
    """

    def __init__(self, frame_id, noise_variance=0.0):
        var = float(noise_variance)
        w = CdrWriter()
        w.stamp(0)
        w.string(frame_id)
        w.put('4d', 0.0, 0.0, 0.0, 1.0)                 # orientation (not measured)
        w.put('9d', -1.0, *[0.0] * 8)                   # orientation_covariance
        angular_at = w.size
        w.put('3d', 0.0, 0.0, 0.0)                      # angular_velocity
        w.put('9d', *[0.0] * 9)                         # angular_velocity_covariance
        linear_at = w.size
        w.put('3d', 0.0, 0.0, 0.0)                      # linear_acceleration
        w.put('9d', var, 0.0, 0.0, 0.0, var, 0.0, 0.0, 0.0, var)
        raw = w.bytes()
        head = len(_HEADER)
        self.size = len(raw)
        self.dtype = np.dtype({'names': ['sec', 'nsec', 'lin', 'ang'],
                               'formats': ['<i4', '<u4', ('<f8', 3), ('<f8', 3)],
                               'offsets': [head, head + 4, head + linear_at, head + angular_at],
                               'itemsize': self.size})
        self._template = bytearray(raw)

    def pack(self, t_ns, linear_acceleration, angular_velocity):
        """Serialized messages (list of bytes), one per row.

        Parameters
        ----------
        t_ns : ndarray of int, shape (k,)
            Stamps (ns, >= 0).
        linear_acceleration : ndarray, shape (k, 3)
            Readings (m/s^2).
        angular_velocity : ndarray, shape (k, 3)
            Readings (rad/s).
        """
        k = len(t_ns)
        # k copies of the template (fixed fields, zero pads), viewed as rows to fill in
        block = self._template * k
        buf = np.frombuffer(block, self.dtype)
        buf['sec'], buf['nsec'] = np.divmod(np.asarray(t_ns, np.int64), 1_000_000_000)
        buf['lin'] = linear_acceleration
        buf['ang'] = angular_velocity
        raw = bytes(block)
        n = self.size
        return [raw[i:i + n] for i in range(0, k * n, n)]


__all__ = ['ImuEncoder', 'JointStateEncoder', 'PARAMETER_BOOL', 'PARAMETER_DOUBLE',
           'PARAMETER_INTEGER', 'PARAMETER_STRING', 'Vector3StampedEncoder', 'clock_cdr',
           'fault_command_text', 'float64_cdr', 'joint_state_cdr', 'parameter_event_cdr',
           'parameter_value_type', 'string_cdr', 'vector3_stamped_cdr']
