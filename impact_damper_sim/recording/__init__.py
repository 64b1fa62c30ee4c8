"""Record to MCAP exactly as rosbag2 (jazzy, ``rosbag2_storage_mcap``) writes it; recover crashes.

* :class:`Rosbag2McapWriter` -- synchronous writer (schemas with dependencies, ``cdr``
  channels with ``offered_qos_profiles`` and ``topic_type_hash``, the ``rosbag2`` record at
  close), small chunks closed at least every 0.5 s.
* :class:`AsyncRecorder` -- the same behind a queue and a writer thread, for the stepping loop.
* :func:`recover` -- a finished copy of a file cut off by a crash (``study recover``).
* :class:`FileLockedError` -- what a second writer of a log being written gets (one writer per
  file, :mod:`.log_file`).

Messages arrive already serialized (``rclpy.serialization.serialize_message``): nothing here
imports rclpy. QoS is an ``rclpy.qos.QoSProfile`` (read by attribute) or a plain dict.

The names below are imported on first use, so that ``study`` (which imports
:mod:`.cli` for its ``recover`` subcommand) does not pay for mcap and PyYAML.

Three ``std_msgs/Float64`` messages (CDR: a 4-byte little-endian encapsulation header, then
the double) written 10 ms apart, read back with
:class:`~impact_damper_sim.studies.log_reader.RosLog`:

>>> import os, struct, tempfile
>>> from impact_damper_sim.recording import Rosbag2McapWriter
>>> from impact_damper_sim.studies.log_reader import RosLog
>>> folder = tempfile.TemporaryDirectory()
>>> path = os.path.join(folder.name, 'speed.mcap')
>>> t0 = 1_700_000_000_000_000_000                      # ns since the epoch
>>> with Rosbag2McapWriter(path) as writer:        # True: accepted (False: dropped)
...     [writer.write('/rotor/speed_command', 'std_msgs/msg/Float64', {'depth': 10},
...                   bytes([0, 1, 0, 0]) + struct.pack('<d', speed), t, t)
...      for speed, t in [(100.0, t0), (150.0, t0 + 10**7), (200.0, t0 + 2 * 10**7)]]
[True, True, True]
>>> writer.finished, writer.error
(True, None)
>>> log = RosLog(path)
>>> log.profile, log.message_count, round(log.duration_s, 6)
('ros2', 3, 0.02)
>>> [(ch.topic, log.type_of(ch)) for ch in log.channels.values()]
[('/rotor/speed_command', 'std_msgs/msg/Float64')]
>>> [struct.unpack('<d', msg.data[4:])[0] for _, msg in log.messages()]
[100.0, 150.0, 200.0]
>>> folder.cleanup()
"""
import importlib

_EXPORTS = {
    'AsyncRecorder': 'async_recorder',
    'DEFAULT_CHUNK_SIZE': 'rosbag2_mcap',
    'DEFAULT_FLUSH_PERIOD': 'rosbag2_mcap',
    'DEFAULT_FSYNC_PERIOD': 'rosbag2_mcap',
    'DefinitionNotFoundError': 'definitions',
    'FileLockedError': 'log_file',
    'RecoveryError': 'recovery',
    'RecoveryReport': 'recovery',
    'Rosbag2McapWriter': 'rosbag2_mcap',
    'message_definition': 'definitions',
    'qos_dict': 'bag_metadata',
    'recover': 'recovery',
    'type_hash': 'definitions',
}
__all__ = sorted(_EXPORTS)


def __getattr__(name):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
    value = getattr(importlib.import_module(f'.{module}', __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_EXPORTS))
