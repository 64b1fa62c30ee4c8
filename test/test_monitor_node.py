"""The ``monitor`` node, launch-free: synthetic topics in, /diagnostics values out.

Each test has its own rclpy context (the ``ros_context`` fixture). A publisher node in the
same context plays the simulator; the monitor is spun with ``spin_once`` until a condition
holds. Diagnostic values are text with 6 significant digits, hence ``rel=1e-5``.
"""
import math
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

rclpy = pytest.importorskip('rclpy')

from builtin_interfaces.msg import Time  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus  # noqa: E402
from geometry_msgs.msg import WrenchStamped  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from sensor_msgs.msg import Imu, JointState  # noqa: E402

from impact_damper_sim.ros import interface  # noqa: E402
from impact_damper_sim.ros.monitor import VibrationMonitor  # noqa: E402

from conftest import next_domain_id  # noqa: E402

pytestmark = pytest.mark.ros

G0 = interface.G0
FS = 1000.0        # synthetic sample rate (Hz)
T0 = 50            # sim time of the first sample (s)
TEXT_REL = 1e-5    # diagnostics carry 6 significant digits


def stamp(t):
    """builtin_interfaces/Time of ``t`` s (t >= 0)."""
    sec = int(math.floor(t))
    return Time(sec=sec, nanosec=int(round((t - sec) * 1e9)))


class Simulator:
    """A publisher node with the simulator's topics, and a /diagnostics listener."""

    def __init__(self, ctx, namespace='/', sensors=('tip',)):
        self.node = rclpy.create_node('fake_sim', context=ctx, namespace=namespace)
        self.accel = {name: self.node.create_publisher(Imu, interface.accel_topic(name),
                                                       interface.SENSOR_QOS)
                      for name in sensors}
        self.impacts = self.node.create_publisher(WrenchStamped, interface.IMPACTS,
                                                  interface.EVENT_QOS)
        self.state = self.node.create_publisher(JointState, interface.IMPACTOR_STATE,
                                                interface.LATCHED_QOS)
        self.arrays = []
        self.node.create_subscription(DiagnosticArray, interface.DIAGNOSTICS,
                                      self.arrays.append, interface.DIAGNOSTICS_QOS)

    def imu(self, sensor, t, acc):
        msg = Imu()
        msg.header.stamp = stamp(t)
        msg.header.frame_id = f'{sensor}_frame'
        msg.linear_acceleration.x, msg.linear_acceleration.y, msg.linear_acceleration.z = (
            float(v) for v in acc)
        msg.orientation_covariance[0] = -1.0
        self.accel[sensor].publish(msg)

    def impact(self, t):
        msg = WrenchStamped()
        msg.header.stamp = stamp(t)
        msg.header.frame_id = 'housing/i0'
        msg.wrench.force.x = 1e-3
        self.impacts.publish(msg)

    def stuck(self, t, names, efforts):
        msg = JointState()
        msg.header.stamp = stamp(t)
        msg.name = list(names)
        msg.position = [0.0] * len(names)
        msg.velocity = [0.0] * len(names)
        msg.effort = [float(e) for e in efforts]
        self.state.publish(msg)


def spin_until(executor, condition, timeout=5.0):
    """Spin until ``condition()`` holds; fail after ``timeout`` s (wall)."""
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, 'condition not met in time'
        executor.spin_once(timeout_sec=0.01)


def received(monitor, stream, count):
    return lambda: monitor.message_counts[stream] >= count


def status(array, name):
    (found,) = [s for s in array.status if s.name == name]
    return found, {kv.key: kv.value for kv in found.values}


def latest_status(sim, name):
    return status(sim.arrays[-1], name) if sim.arrays else (None, {})


@pytest.fixture
def setup(ros_context):
    """Build ``(monitor, simulator, executor)`` for a test; destroy them afterwards."""
    made = []

    def make(monitor_kwargs, **sim_kwargs):
        sim = Simulator(ros_context, **sim_kwargs)
        monitor = VibrationMonitor(context=ros_context, **monitor_kwargs)
        executor = SingleThreadedExecutor(context=ros_context)
        executor.add_node(monitor)
        executor.add_node(sim.node)
        made.append((monitor, sim, executor))
        return monitor, sim, executor

    yield make
    for monitor, sim, executor in made:
        executor.shutdown()
        monitor.destroy_node()
        sim.node.destroy_node()


def test_diagnostics_match_the_synthetic_input(setup):
    """1.5 s of a 2 g circular 40 Hz vibration, 25 impacts/s and a known stuck schedule."""
    a_g, hz, window = 2.0, 40.0, 1.0
    monitor, sim, executor = setup(
        dict(namespace='/hpotp', parameter_overrides=[
            Parameter('sensors', value=['tip']), Parameter('window', value=window),
            Parameter('report_period', value=0.1), Parameter('log_reports', value=False)]),
        namespace='/hpotp')
    names = ['i0/y', 'i0/z', 'i1/x']
    # stuck/free efforts from ms after T0 on: i0 sticks at 0.8 s, i1 at 1.2 s, i0 frees at 1.4 s
    schedule = [(800, [1, 1, 0]), (1200, [1, 1, 1]), (1400, [0, 0, 1])]
    sim.stuck(T0, names, [0, 0, 0])
    states = 1
    spin_until(executor, received(monitor, 'impactor_state', states))
    impacts = T0 + 0.013 + np.arange(38) / 25.0      # 25 a second, the last at T0 + 1.493
    next_impact = 0
    n_samples, chunk = 1500, 50                       # 1.5 s at FS, in 50 ms chunks
    for start in range(0, n_samples, chunk):
        end = start + chunk                           # ms after T0
        for k in range(start, end):
            t = T0 + (k + 0.5) / FS
            t = stamp(t).sec + 1e-9 * stamp(t).nanosec        # as the monitor reads it
            phase = 2 * np.pi * hz * t
            sim.imu('tip', t, [a_g * G0 * np.sin(phase), a_g * G0 * np.cos(phase), 0.0])
        while next_impact < impacts.size and impacts[next_impact] < T0 + end / FS:
            sim.impact(impacts[next_impact])
            next_impact += 1
        while schedule and schedule[0][0] < end:
            ms, efforts = schedule.pop(0)
            sim.stuck(T0 + ms / 1000, names, efforts)
            states += 1    # latched depth 1: let each state in before the next
            spin_until(executor, received(monitor, 'impactor_state', states))
        # best-effort samples: let the monitor take each chunk before its queue would overflow
        spin_until(executor, received(monitor, 'accel', end))
    spin_until(executor, received(monitor, 'impacts', impacts.size))
    spin_until(executor, lambda: latest_status(sim, 'monitor: /hpotp/impacts')[1].get(
        'window_end_s') == f'{T0 + 1.4995:.6g}')

    array = sim.arrays[-1]
    assert array.header.stamp.sec > 0 or array.header.stamp.nanosec > 0
    tip, values = status(array, 'monitor: /hpotp/tip')
    assert tip.level == DiagnosticStatus.OK, tip.message
    assert tip.hardware_id == 'tip_frame'
    value = {key: float(text) for key, text in values.items()}
    assert value['samples_in_window'] == 1000
    assert value['samples_per_s'] == pytest.approx(FS, rel=TEXT_REL)
    # |a| = A at every sample; each axis has RMS A/sqrt(2) over 40 whole periods
    assert value['rms_g'] == pytest.approx(a_g, rel=TEXT_REL)
    assert value['peak_g'] == pytest.approx(a_g, rel=TEXT_REL)
    assert value['rms_g_x'] == pytest.approx(a_g / np.sqrt(2), rel=TEXT_REL)
    assert value['rms_g_y'] == pytest.approx(a_g / np.sqrt(2), rel=TEXT_REL)
    assert value['rms_g_z'] == 0.0
    # the largest sample of a sine lies within A (1 - cos(pi f / fs)) below A
    assert a_g * np.cos(np.pi * hz / FS) * (1 - TEXT_REL) <= value['peak_g_x'] <= a_g
    # 40 Hz falls on a bin of the 1 s window: the parabola must not move it (0.02 bin)
    assert value['resolution_hz'] == pytest.approx(1.0 / window, rel=TEXT_REL)
    assert value['dominant_hz'] == pytest.approx(hz, abs=0.02 * value['resolution_hz'])
    assert value['dominant_hz_x'] == pytest.approx(hz, abs=0.02 * value['resolution_hz'])
    assert math.isnan(value['dominant_hz_z'])
    assert value['rejected_samples'] == 0

    imp, values = status(array, 'monitor: /hpotp/impacts')
    assert imp.level == DiagnosticStatus.OK, imp.message
    assert imp.hardware_id == 'housing'
    value = {key: float(text) for key, text in values.items()}
    assert value['impacts_in_window'] == 25
    assert value['impacts_per_s'] == pytest.approx(25.0, rel=TEXT_REL)
    # window (T0 + 0.4995, T0 + 1.4995]: stuck fraction 0 for 0.3005 s, 1/2 for 0.4 s,
    # 1 for 0.2 s, 1/2 for 0.0995 s
    assert value['stuck_fraction'] == pytest.approx(0.2 + 0.2 + 0.0995 / 2, rel=TEXT_REL)
    assert (value['impactors'], value['stuck_impactors']) == (2, 1)


def test_discovers_sensors_and_flags_stale_ones(setup):
    """Empty ``sensors``: accel/* topics are found at start and later; silence gives WARN."""
    monitor, sim, executor = setup(
        dict(parameter_overrides=[Parameter('window', value=0.1),
                                  Parameter('report_period', value=0.05)]),
        sensors=('a',))
    assert monitor.sensors == ('a',)
    late = sim.node.create_publisher(Imu, interface.accel_topic('b'), interface.SENSOR_QOS)
    spin_until(executor, lambda: monitor.sensors == ('a', 'b'))
    assert late.get_subscription_count() == 1
    for k in range(20):
        sim.imu('a', 1.0 + k / FS, [G0, 0.0, 0.0])
    spin_until(executor, lambda: latest_status(sim, 'monitor: /a')[1].get(
        'samples_in_window') == '20')
    a, _ = latest_status(sim, 'monitor: /a')
    assert a.level == DiagnosticStatus.OK, a.message
    b, _ = latest_status(sim, 'monitor: /b')
    assert b.level == DiagnosticStatus.WARN and b.message == 'no valid sample received'
    # no sample for more than two windows (0.2 s on the node clock): stale
    spin_until(executor, lambda: latest_status(sim, 'monitor: /a')[0].message.startswith(
        'stale'))
    assert latest_status(sim, 'monitor: /a')[0].level == DiagnosticStatus.WARN


def test_bad_messages_are_counted_not_fatal(setup):
    monitor, sim, executor = setup(
        dict(parameter_overrides=[Parameter('sensors', value=['tip']),
                                  Parameter('report_period', value=0.05)]))
    bad = [[math.nan, 0.0, 0.0], [0.0, math.inf, 0.0], [0.0, 0.0, -math.inf], [1e300, 0, 0]]
    good = 0
    for k in range(40):
        acc = bad[k // 10] if k % 10 == 9 else [0.5 * G0, 0.0, 0.0]
        good += k % 10 != 9
        sim.imu('tip', 2.0 + k / FS, acc)
    sim.stuck(2.0, ['i0/x', 'i1/x'], [math.nan, 0.0])   # non-finite flag
    spin_until(executor, received(monitor, 'impactor_state', 1))
    sim.stuck(2.01, ['i0/x', 'i1/x'], [1.0])            # fewer efforts than names
    spin_until(executor, received(monitor, 'impactor_state', 2))
    spin_until(executor, received(monitor, 'accel', 40))
    spin_until(executor, lambda: latest_status(sim, 'monitor: /tip')[1].get(
        'rejected_samples') == '4')
    tip, values = latest_status(sim, 'monitor: /tip')
    assert tip.level == DiagnosticStatus.WARN and 'rejected' in tip.message
    assert int(values['samples_in_window']) == good
    assert float(values['peak_g']) == pytest.approx(0.5, rel=TEXT_REL)
    imp, values = latest_status(sim, 'monitor: /impacts')
    assert values['rejected_states'] == '2'
    assert values['stuck_fraction'] == 'nan'
    # still alive and reporting: a later report has no new rejections, so tip is OK
    count = len(sim.arrays)
    spin_until(executor, lambda: len(sim.arrays) > count)
    assert latest_status(sim, 'monitor: /tip')[0].level == DiagnosticStatus.OK


def test_parameters_are_ranged_and_window_is_live(setup):
    monitor, _, _ = setup(dict(parameter_overrides=[Parameter('sensors', value=['tip'])]))
    monitor.report()
    assert monitor.last_report.window == 2.0
    assert not monitor.set_parameters([Parameter('window', value=100.0)])[0].successful
    assert monitor.set_parameters([Parameter('window', value=0.5)])[0].successful
    array = monitor.report()
    assert monitor.last_report.window == 0.5
    assert status(array, 'monitor: /tip')[1]['window_s'] == '0.5'
    assert not monitor.set_parameters([Parameter('sensors', value=['x'])])[0].successful
    assert not monitor.set_parameters([Parameter('report_period', value=2.0)])[0].successful
    descriptor = monitor.describe_parameter('window')
    assert '(s' in descriptor.description
    assert descriptor.floating_point_range[0].from_value == 0.1


def test_main_runs_and_stops_on_sigint(tmp_path):
    """``monitor`` as ``ros2 run`` starts it: report lines, then a clean Ctrl-C."""
    env = dict(os.environ, ROS_DOMAIN_ID=str(next_domain_id()),
               ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST', PYTHONUNBUFFERED='1')
    process = subprocess.Popen(
        [sys.executable, '-c', 'from impact_damper_sim.ros.monitor import main; main()',
         '--ros-args', '-r', '__ns:=/rbs', '-p', 'sensors:=[tip]', '-p', 'report_period:=0.2'],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        output = ''
        deadline = time.monotonic() + 10.0
        while 'impacts:' not in output and time.monotonic() < deadline:
            output += process.stdout.readline()
        process.send_signal(signal.SIGINT)
        rest, _ = process.communicate(timeout=5.0)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    output += rest
    assert 'watching /rbs/accel/tip' in output
    assert 'impacts:' in output
    assert process.returncode == 0, output
    assert 'Traceback' not in output


def test_malformed_parameter_request_is_refused_and_the_monitor_stays_up(ros_context):
    """A SetParameters with ParameterValue type 200 (any process on the domain can send
    one) gets a refusal; the executor keeps spinning."""
    from rcl_interfaces.msg import Parameter as ParameterMsg
    from rcl_interfaces.msg import ParameterValue
    from rcl_interfaces.srv import SetParameters
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node

    from impact_damper_sim.ros.monitor import VibrationMonitor
    monitor = VibrationMonitor(context=ros_context)
    client_node = Node('fuzzer', context=ros_context)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(monitor)
    ex.add_node(client_node)
    try:
        client = client_node.create_client(SetParameters, '/monitor/set_parameters')
        assert client.wait_for_service(timeout_sec=10.0)
        for kind in (200, 255, 0):
            future = client.call_async(SetParameters.Request(parameters=[ParameterMsg(
                name='window', value=ParameterValue(type=kind, double_value=1.0))]))
            end = time.monotonic() + 5.0
            while not future.done() and time.monotonic() < end:
                ex.spin_once(timeout_sec=0.01)   # would raise if the callback raised
            assert future.done() and not future.result().results[0].successful
        assert monitor.get_parameter('window').value == 2.0
    finally:
        client_node.destroy_node()
        monitor.destroy_node()
