"""The ROS-free packer of the node's messages writes what rclpy's message classes mean:
every encoder's bytes equal the canonical CDR of the same rclpy message (ros/cdr.py, read
by rosbags and rclpy) and read back in rclpy as that message; the topic table's QoS equals
the node's rclpy profiles."""
import math

import numpy as np
import pytest

rclpy = pytest.importorskip('rclpy')

from geometry_msgs.msg import Vector3Stamped  # noqa: E402
from rcl_interfaces.msg import Parameter, ParameterEvent, ParameterValue  # noqa: E402
from rclpy.serialization import deserialize_message  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from sensor_msgs.msg import Imu, JointState  # noqa: E402
from std_msgs.msg import Float64  # noqa: E402

from impact_damper_sim.recording import message_cdr as mc  # noqa: E402
from impact_damper_sim.recording import node_messages as nm  # noqa: E402
from impact_damper_sim.recording import node_topics as nt  # noqa: E402
from impact_damper_sim.recording.bag_metadata import qos_dict  # noqa: E402
from impact_damper_sim.ros import interface as itf  # noqa: E402
from impact_damper_sim.ros.cdr import serialize  # noqa: E402


def _same(data, msg):
    """``data`` is the canonical CDR of ``msg`` and reads back in rclpy as ``msg``."""
    assert data == serialize(msg)
    assert deserialize_message(data, type(msg)) == msg


@pytest.mark.parametrize('variance', [0.0, 0.25, 1e-300])
def test_imu_chunks_are_rclpys_messages(variance):
    rng = np.random.default_rng(1)
    t_ns = np.array([0, 12_345_678_901, 2**31 * 1_000_000_000 - 1])
    lin, ang = rng.normal(size=(3, 3)) * 1e3, rng.normal(size=(3, 3))
    packed = mc.ImuEncoder('sensor_é', variance).pack(t_ns, lin, ang)
    for ns, la, av, data in zip(t_ns.tolist(), lin, ang, packed):
        msg = Imu()
        msg.header.frame_id = 'sensor_é'
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(ns, 1_000_000_000)
        msg.orientation_covariance[0] = -1.0
        msg.linear_acceleration_covariance = [variance, 0.0, 0.0, 0.0, variance, 0.0, 0.0,
                                              0.0, variance]
        msg.linear_acceleration.x, msg.linear_acceleration.y, msg.linear_acceleration.z = la
        msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z = av
        _same(data, msg)


@pytest.mark.parametrize('names, position, velocity, effort', [
    ([], [], [], []), (['rotor'], [1.25], [2400.0], []),
    (['a/uy', 'a/uz', 'long_name/x'], [1e-6, -2e-6, 0.0], [0.5, 0.25, -1.0], [1.0, 1.0, -1.0])])
def test_joint_states_are_rclpys_messages(names, position, velocity, effort):
    msg = JointState(name=names, position=position, velocity=velocity, effort=effort)
    msg.header.stamp.sec, msg.header.stamp.nanosec = 7, 5
    _same(mc.joint_state_cdr(7_000_000_005, names, position, velocity, effort), msg)


def test_clock_float64_and_vector3_stamped_are_rclpys_messages():
    clock = Clock()
    clock.clock.sec, clock.clock.nanosec = 3, 999_999_999
    _same(mc.clock_cdr(3_999_999_999), clock)
    _same(mc.float64_cdr(-math.pi), Float64(data=-math.pi))
    v = Vector3Stamped()
    v.header.stamp.nanosec = 10_000_000
    v.header.frame_id = 'f'
    v.vector.x, v.vector.y, v.vector.z = 2400.0, -37.5, 2.5
    _same(mc.vector3_stamped_cdr(10_000_000, 'f', (2400.0, -37.5, 2.5)), v)


def test_parameter_events_are_rclpys_messages():
    changed = [('dampers_enabled', False), ('noise_std', 0.49), ('noise_seed', 2**31 - 1),
               ('scene', 'hpotp')]
    values = [ParameterValue(type=1, bool_value=False), ParameterValue(type=3, double_value=0.49),
              ParameterValue(type=2, integer_value=2**31 - 1),
              ParameterValue(type=4, string_value='hpotp')]
    msg = ParameterEvent(node='/rig/vibration_node', changed_parameters=[
        Parameter(name=n, value=v) for (n, _), v in zip(changed, values)])
    msg.stamp.sec = 1
    _same(mc.parameter_event_cdr(1_000_000_000, '/rig/vibration_node', changed), msg)
    with pytest.raises(TypeError, match='only bool, int, float and str'):
        mc.parameter_event_cdr(0, '/n', [('x', [1.0])])


def test_the_topic_table_is_the_nodes_interface():
    for name in ('SENSOR_QOS', 'BATCH_QOS', 'EVENT_QOS', 'LATCHED_QOS', 'COMMAND_QOS',
                 'CLOCK_QOS', 'DIAGNOSTICS_QOS', 'PARAMETER_EVENTS_QOS'):
        assert qos_dict(getattr(itf, name)) == qos_dict(getattr(nt, name)), name
    from rclpy.qos import qos_profile_parameter_events
    assert qos_dict(qos_profile_parameter_events) == qos_dict(nt.PARAMETER_EVENTS_QOS)
    assert itf.TYPES is nt.TYPES and itf.accel_batch_topic('s') == 'accel/s/batch'
    assert nt.qualified('impacts', '/rig') == '/rig/impacts'
    assert nt.qualified('impacts') == '/impacts' and nt.qualified('/clock', '/rig') == '/clock'


def test_every_stamped_message_names_its_frame():
    """Issue 38: ``rotor/speed`` had an empty frame_id. Every stamped message the packer writes
    (one chunk of a rotor scene with impactors: batches, Imu, impacts, tach, keyphasor,
    rotor/speed, rotor/joint_states, impactor_state) carries a frame: the accelerometer's,
    the housing's, or the rotor's (``<scene>_rotor``, the same on every rotor topic)."""
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import PointCloud2

    from impact_damper_sim.live.realtime import LiveSimulation
    from impact_damper_sim.live.streams import live_scene
    model, target = live_scene('rbs')
    live = LiveSimulation(model, initial_target=target)
    messages = nm.NodeMessages(live, model)
    items = messages.batch_items(live.step(20)) + messages.time_items()
    items.append((0, messages.state, messages.state_message()))
    classes = {'sensor_msgs/msg/Imu': Imu, 'sensor_msgs/msg/PointCloud2': PointCloud2,
               'sensor_msgs/msg/JointState': JointState,
               'geometry_msgs/msg/Vector3Stamped': Vector3Stamped}
    frames = {}
    for _, stream, data in items:
        s = messages.streams[stream]
        if s.type_name in classes:
            msg = deserialize_message(data, classes[s.type_name])
            frames.setdefault(s.topic.lstrip('/'), set()).add(msg.header.frame_id)
    housing = {acc.frame_id for acc in live.accelerometers}
    expected = {'rotor/speed', 'rotor/joint_states', 'rotor/tach', 'rotor/keyphasor',
                'impactor_state', 'impacts'}
    assert expected <= set(frames) and any(t.startswith('accel/') for t in frames)
    assert all(f != {''} and len(f) == 1 for f in frames.values()), frames
    for topic in ('rotor/speed', 'rotor/joint_states', 'rotor/tach', 'rotor/keyphasor'):
        assert frames[topic] == {'rbs_rotor'}, topic
    assert frames['impactor_state'] == frames['impacts'] and frames['impacts'] <= housing
    assert nm.rotor_frame_id('hpotp') == 'hpotp_rotor'


@pytest.mark.parametrize('names, frame', [([], ''), (['imp01/uy'], 'f'),
                                          (['a/uy', 'a/uz', 'long_name/x'], 'housing_é')])
def test_joint_state_encoder_writes_joint_state_cdrs_bytes(names, frame):
    rng = np.random.default_rng(2)
    n = len(names)
    pos, vel, eff = rng.normal(size=(3, n))
    for ns in (0, 7_000_000_005, 2**31 * 1_000_000_000 - 1):
        assert mc.JointStateEncoder(names, frame).pack(ns, pos, vel, eff) == \
            mc.joint_state_cdr(ns, names, pos, vel, eff, frame_id=frame)


def _state_from_dicts(messages, live):
    """``impactor_state`` as it was written before the encoder: per impactor dicts."""
    pos, vel, eff = [], [], []
    for s in live.impactor_states():
        d = len(s['position'])
        pos += [float(x) for x in s['position']]
        vel += [float(x) for x in s['velocity']]
        eff += [(1.0 if s['stuck'] else 0.0) if live.dampers_enabled else -1.0] * d
    return mc.joint_state_cdr(int(round(live.t * 1e9)), messages.joint_names, pos, vel, eff,
                              frame_id=messages.impactor_frame)


@pytest.mark.parametrize('scene', ['hpotp', 'sdof'])
def test_impactor_state_is_the_per_impactor_states_bytes(scene):
    """The flat arrays and the template give the very bytes of the per-impactor dicts, over
    chunks with impacts and stuck impactors (both flags seen on hpotp), and with the dampers
    off (effort -1, zeros)."""
    from impact_damper_sim.live.realtime import LiveSimulation
    from impact_damper_sim.live.streams import live_scene
    model, target = live_scene(scene)
    live = LiveSimulation(model, initial_target=target)
    messages = nm.NodeMessages(live, model)
    flags = set()
    for _ in range(120):
        live.step(20)
        assert messages.state_message() == _state_from_dicts(messages, live)
        flags.update(s['stuck'] for s in live.impactor_states())
    if scene == 'hpotp':
        assert flags == {True, False}
    live.set_dampers_enabled(False)
    live.step(20)
    assert messages.state_message() == _state_from_dicts(messages, live)
