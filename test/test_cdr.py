"""Every recorded topic of every live scene reads, message by message, with rosbags, mcap_ros2
and rclpy, to equal values; the recorded bytes are canonical CDR (deterministic).

Canonical means what rosbags writes: pads zero, nothing after the last field. rclpy's own
serialization leaves pads uninitialised and pads a ``JointState`` with an empty ``effort`` by
4 trailing bytes, which rosbags refuses; the node writes through
:mod:`impact_damper_sim.ros.cdr` and the vectorised packers instead.
"""
import math
import pathlib

import pytest

rclpy = pytest.importorskip('rclpy')
rosbags = pytest.importorskip('rosbags')

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue  # noqa: E402
from geometry_msgs.msg import Vector3Stamped  # noqa: E402
from mcap.reader import make_reader  # noqa: E402
from mcap_ros2.decoder import DecoderFactory  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.serialization import deserialize_message, serialize_message  # noqa: E402
from rosbags.highlevel import AnyReader  # noqa: E402
from rosbags.typesys import Stores, get_typestore  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from sensor_msgs.msg import Imu, JointState  # noqa: E402
from std_msgs.msg import Float64  # noqa: E402

from impact_damper_sim.ros.cdr import serialize  # noqa: E402
from impact_damper_sim.ros.vibration_node import VibrationNode  # noqa: E402
from impact_damper_sim.scene.build import load  # noqa: E402

pytestmark = pytest.mark.ros

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
SCENES = sorted(p.stem for p in (pathlib.Path(__file__).resolve().parents[1] / 'config'
                                 / 'scenes').glob('*.yaml'))


def get_message(name):
    """The rclpy class of ``pkg/msg/Type`` (or ``pkg/Type``)."""
    import importlib
    parts = name.split('/')
    return getattr(importlib.import_module(f'{parts[0]}.msg'), parts[-1])


def _plain(obj, cls):
    """A decoded message (rclpy, rosbags or mcap_ros2 object) as plain values, walking the
    fields of the rclpy class ``cls``."""
    out = {}
    for (name, _), slot in zip(cls.get_fields_and_field_types().items(), cls.SLOT_TYPES):
        value = getattr(obj, name)
        kind = type(slot).__name__
        inner = getattr(slot, 'value_type', None)
        if kind == 'NamespacedType':
            value = _plain(value, get_message('/'.join(slot.namespaces + [slot.name])))
        elif inner is not None and type(inner).__name__ == 'NamespacedType':
            sub = get_message('/'.join(inner.namespaces + [inner.name]))
            value = [_plain(v, sub) for v in value]
        elif kind == 'BasicType' and isinstance(value, (bytes, bytearray)):
            value = value[0]   # an octet: rclpy gives bytes, the others an int
        elif isinstance(value, (bytes, bytearray)):
            value = list(value)
        elif not isinstance(value, str) and hasattr(value, '__len__'):
            value = [v if isinstance(v, str) else float(v) for v in value]
        elif isinstance(value, float) and math.isnan(value):
            value = 'nan'
        out[name] = value
    return out


MESSAGES = [
    JointState(name=['rotor'], position=[1.25], velocity=[2.5]),   # empty effort
    JointState(name=['a/uy', 'a/uz'], position=[1.0, -2.0], velocity=[3.0, 4.0],
               effort=[1.0, 0.0]),
    Vector3Stamped(), Clock(), Float64(data=-2.5), Imu(),
    DiagnosticArray(status=[DiagnosticStatus(level=b'\x01', name='n: simulation',
                                             message='behind', hardware_id='hpotp',
                                             values=[KeyValue(key='k', value='1.5')])]),
]
MESSAGES[2].header.frame_id = 'ab'   # 3 pad bytes before the vector
MESSAGES[2].vector.x = 3.5
MESSAGES[5].header.frame_id = 'abc'


@pytest.mark.parametrize('msg', MESSAGES, ids=lambda m: type(m).__name__)
def test_canonical_bytes_equal_rosbags_and_read_back_in_rclpy(msg):
    data = serialize(msg)
    name = f'{type(msg).__module__.split(".")[0]}/msg/{type(msg).__name__}'
    assert TYPESTORE.serialize_cdr(TYPESTORE.deserialize_cdr(data, name), name) == data
    assert deserialize_message(data, type(msg)) == msg
    assert serialize(msg) == data   # deterministic


def test_rclpy_bytes_of_an_empty_effort_are_what_rosbags_refuses():
    """Why the node does not publish rclpy's bytes: this is the trap the issue found."""
    msg = MESSAGES[0]
    theirs, ours = serialize_message(msg), serialize(msg)
    assert len(theirs) == len(ours) + 4   # 4 trailing bytes past the last field
    with pytest.raises(Exception, match='size mismatch'):
        TYPESTORE.deserialize_cdr(theirs, 'sensor_msgs/msg/JointState')


def _record(ctx, scene, path, seconds=0.3):
    """Record ``seconds`` of a scene, driven by a fake wall clock, with a command received."""
    clock = type('Clock', (), {'now': 1000.0, '__call__': lambda self: self.now})()
    node = VibrationNode(context=ctx, start_stepping=False, clock=clock, parameter_overrides=[
        Parameter('scene', value=scene), Parameter('record', value=str(path))])
    try:
        for _ in range(round(seconds / 0.01)):
            clock.now += 0.01
            node.tick()
        node.on_unbalance_command(Float64(data=2.0))
        node.publish_diagnostics()
        node.publish_state()
        node.stop()   # publishes (and records) what is still queued
        return {o.topic: o.count for o in node.outlets}
    finally:
        node.destroy_node()


@pytest.mark.parametrize('scene', [s for s in SCENES if not load(s).scene['offline_only']])
def test_every_recorded_topic_reads_alike_in_three_readers(ros_context, tmp_path, scene):
    path = tmp_path / f'{scene}.mcap'
    published = _record(ros_context, scene, path)
    with AnyReader([path], default_typestore=TYPESTORE) as reader:
        bags = [(c.topic, c.msgtype, raw, reader.deserialize(raw, c.msgtype))
                for c, _, raw in reader.messages()]
    with open(path, 'rb') as f:
        decoded = [(ch.topic, dec) for _, ch, _, dec in make_reader(
            f, decoder_factories=[DecoderFactory()]).iter_decoded_messages(
                log_time_order=False)]
    assert len(bags) == len(decoded) > 0
    by_topic = {}
    # compare message by message, in each reader's order per topic (the same file order)
    mcap_by_topic, bag_by_topic = {}, {}
    for topic, dec in decoded:
        mcap_by_topic.setdefault(topic, []).append(dec)
    for topic, msgtype, raw, bag in bags:
        bag_by_topic.setdefault(topic, []).append((msgtype, raw, bag))
    assert set(mcap_by_topic) == set(bag_by_topic)
    for topic, entries in bag_by_topic.items():
        assert len(entries) == len(mcap_by_topic[topic]), topic
        for (msgtype, raw, bag), dec in zip(entries, mcap_by_topic[topic]):
            cls = get_message(msgtype)
            ours = deserialize_message(raw, cls)
            want = _plain(ours, cls)
            assert _plain(bag, cls) == want, topic
            assert _plain(dec, cls) == want, topic
            # canonical: rosbags writes back the very bytes (zero pads, no trailing bytes)
            assert TYPESTORE.serialize_cdr(bag, msgtype) == raw, topic
        by_topic[topic] = len(entries)
    for topic, n in published.items():
        assert by_topic.get(topic, 0) == n, topic
    assert any(t.endswith('/batch') for t in by_topic) or not load(scene).scene['sensors']


def test_a_recovered_log_reads_in_rosbags_byte_for_byte(ros_context, tmp_path):
    """study recover copies the node's bytes: the finished copy of a cut-off log reads in
    rosbags, and each message is the very bytes the node wrote."""
    from impact_damper_sim.recording import recover
    path = tmp_path / 'whole.mcap'
    _record(ros_context, 'rbs', path, 1.5)   # 1.7 MB: three 768 KiB chunks
    data = path.read_bytes()
    cut = tmp_path / 'cut.mcap'
    cut.write_bytes(data[:len(data) * 2 // 3])   # a crash: no summary, the open chunk lost
    recover(cut, tmp_path / 'recovered.mcap')
    with AnyReader([path], default_typestore=TYPESTORE) as reader:
        whole = [(c.topic, raw) for c, _, raw in reader.messages()]
    with AnyReader([tmp_path / 'recovered.mcap'], default_typestore=TYPESTORE) as reader:
        got = [(c.topic, raw, reader.deserialize(raw, c.msgtype)) for c, _, raw in
               reader.messages()]
    assert 0 < len(got) < len(whole)
    assert {(t, raw) for t, raw, _ in got} <= set(whole)
    assert any(t.endswith('/batch') for t, _, _ in got)
