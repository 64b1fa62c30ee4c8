"""The ``monitor`` node, launch-free: synthetic topics in, /diagnostics values out.

Each test has its own rclpy context (the ``ros_context`` fixture). A publisher node in the
same context plays the simulator, in the node's format (full-rate ``accel/<name>/batch`` and
``impacts`` PointCloud2 batches, their CDR from ``BatchEncoder``) or the old one (one Imu per
sample, one WrenchStamped per impact); the monitor is spun with ``spin_once`` until a
condition holds. Diagnostic values are text with 6 significant digits, hence ``rel=1e-5``.
"""
import math
import os
import signal
import subprocess
import sys
import time
from dataclasses import astuple

import numpy as np
import pytest

rclpy = pytest.importorskip('rclpy')

from builtin_interfaces.msg import Time  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus  # noqa: E402
from geometry_msgs.msg import WrenchStamped  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from sensor_msgs.msg import Imu, JointState, PointCloud2  # noqa: E402

from conftest import next_domain_id  # noqa: E402
from impact_damper_sim.recording.batches import (  # noqa: E402
    ACCEL_DTYPE,
    ACCEL_FIELDS,
    ACCEL_POINT_STEP,
    BATCH_SUFFIX,
    FLOAT64,
    IMPACT_DTYPE,
    IMPACT_FIELDS,
    IMPACT_POINT_STEP,
    BatchEncoder,
)
from impact_damper_sim.ros import interface  # noqa: E402
from impact_damper_sim.ros.monitor import VibrationMonitor  # noqa: E402
from node_helpers import call_service  # noqa: E402

pytestmark = pytest.mark.ros

G0 = interface.G0
FS = 1000.0        # synthetic sample rate (Hz)
T0 = 50            # sim time of the first sample (s)
CHUNK = 10         # samples per batch: the node's 10 ms chunk at FS
TEXT_REL = 1e-5    # diagnostics carry 6 significant digits


def stamp(t):
    """builtin_interfaces/Time of ``t`` s (t >= 0)."""
    sec = int(math.floor(t))
    return Time(sec=sec, nanosec=int(round((t - sec) * 1e9)))


def ns_of(t):
    """Stamps (ns, int64) of times ``t`` (s), rounded as :func:`stamp` rounds them."""
    return np.array([stamp(x).sec * 1_000_000_000 + stamp(x).nanosec
                     for x in np.atleast_1d(t)], dtype=np.int64)


class Simulator:
    """A publisher node with the simulator's topics, and a /diagnostics listener.

    ``batch`` sensors publish ``accel/<name>/batch``, ``imu`` sensors ``accel/<name>`` (a
    name may be in both); ``impacts`` is ``'batch'`` (PointCloud2) or ``'wrench'``.
    """

    def __init__(self, ctx, namespace='/', batch=('tip',), imu=(), impacts='batch'):
        self.node = rclpy.create_node('fake_sim', context=ctx, namespace=namespace)
        self.batches, self.encoders, self.imus = {}, {}, {}
        for name in batch:
            self.add_batch(name)
        for name in imu:
            self.imus[name] = self.node.create_publisher(Imu, interface.accel_topic(name),
                                                         interface.SENSOR_QOS)
        self.impact_format = impacts
        self.impacts = self.node.create_publisher(
            PointCloud2 if impacts == 'batch' else WrenchStamped, interface.IMPACTS,
            interface.EVENT_QOS)
        self.impact_encoder = BatchEncoder('housing', IMPACT_FIELDS, IMPACT_POINT_STEP)
        self.state = self.node.create_publisher(JointState, interface.IMPACTOR_STATE,
                                                interface.LATCHED_QOS)
        self.arrays = []
        self.node.create_subscription(DiagnosticArray, interface.DIAGNOSTICS,
                                      self.arrays.append, interface.DIAGNOSTICS_QOS)

    def add_batch(self, name):
        """Start publishing ``accel/<name>/batch``."""
        self.batches[name] = self.node.create_publisher(
            PointCloud2, interface.accel_topic(name) + BATCH_SUFFIX, interface.BATCH_QOS)
        self.encoders[name] = BatchEncoder(f'{name}_frame', ACCEL_FIELDS, ACCEL_POINT_STEP)

    def imu(self, sensor, t, acc):
        msg = Imu()
        msg.header.stamp = stamp(t)
        msg.header.frame_id = f'{sensor}_frame'
        msg.linear_acceleration.x, msg.linear_acceleration.y, msg.linear_acceleration.z = (
            float(v) for v in acc)
        msg.orientation_covariance[0] = -1.0
        self.imus[sensor].publish(msg)

    def batch(self, sensor, ns, acc):
        """One batch of samples stamped ``ns`` (ns) with accelerations ``acc`` (m/s^2)."""
        rows = np.zeros(len(ns), ACCEL_DTYPE)
        rows['t'] = (ns - ns[0]) * 1e-9
        rows['ax'], rows['ay'], rows['az'] = np.asarray(acc, dtype=float).T
        self.batches[sensor].publish(self.encoders[sensor].encode(int(ns[0]), rows))

    def impact(self, t):
        msg = WrenchStamped()
        msg.header.stamp = stamp(t)
        msg.header.frame_id = 'housing/i0'
        msg.wrench.force.x = 1e-3
        self.impacts.publish(msg)

    def impact_batch(self, start_ns, ns):
        """The impacts at ``ns`` (ns) of the interval from ``start_ns`` (ns), maybe none."""
        rows = np.zeros(len(ns), IMPACT_DTYPE)
        rows['t'] = (np.asarray(ns, dtype=np.int64) - start_ns) * 1e-9
        rows['jx'] = 1e-3
        self.impacts.publish(self.impact_encoder.encode(start_ns, rows))

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


def reading(monitor, sim, *sensors):
    """Condition: the monitor reads the sensors' published topics and the impacts, matched
    at both ends (a reliable message sent before the reader matched the writer is lost)."""
    def condition():
        machine = monitor.machines[sim.node.get_namespace()]
        publishers = [sim.batches.get(s) or sim.imus[s] for s in sensors] + [sim.impacts]
        streams = [machine.accel_streams[s] for s in sensors] + [machine.impact_stream]
        return (all(p.get_subscription_count() == 1 for p in publishers)
                and all(s.subscription.get_publisher_count() == 1 for s in streams))
    return condition


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


@pytest.mark.parametrize('fmt', ['batch', 'message'])
def test_diagnostics_match_the_synthetic_input(setup, fmt):
    """1.5 s of a 2 g circular 40 Hz vibration, 25 impacts/s and a known stuck schedule,
    in the node's batches and in the old per-sample messages: the same closed-form values."""
    a_g, hz, window = 2.0, 40.0, 1.0
    batches = fmt == 'batch'
    monitor, sim, executor = setup(
        dict(namespace='/hpotp', parameter_overrides=[
            Parameter('sensors', value=['tip']), Parameter('window', value=window),
            Parameter('report_period', value=0.1), Parameter('log_reports', value=False)]),
        namespace='/hpotp', batch=('tip',) if batches else (), imu=() if batches else ('tip',),
        impacts='batch' if batches else 'wrench')
    # best effort: nothing sent before the monitor reads the right topic would arrive
    spin_until(executor, reading(monitor, sim, 'tip'))
    names = ['i0/y', 'i0/z', 'i1/x']
    # stuck/free efforts from ms after T0 on: i0 sticks at 0.8 s, i1 at 1.2 s, i0 frees at 1.4 s
    schedule = [(800, [1, 1, 0]), (1200, [1, 1, 1]), (1400, [0, 0, 1])]
    sim.stuck(T0, names, [0, 0, 0])
    states = 1
    spin_until(executor, received(monitor, 'impactor_state', states))
    impacts = T0 + 0.013 + np.arange(38) / 25.0      # 25 a second, the last at T0 + 1.493
    impact_ns = ns_of(impacts)
    next_impact = 0
    n_samples, chunk = 1500, 50                       # 1.5 s at FS, in 50 ms chunks
    sent = {'accel': 0, 'impacts': 0}
    for start in range(0, n_samples, chunk):
        end = start + chunk                           # ms after T0
        ns = ns_of(T0 + (np.arange(start, end) + 0.5) / FS)
        t = ns // 1_000_000_000 + 1e-9 * (ns % 1_000_000_000)     # as the monitor reads it
        phase = 2 * np.pi * hz * t
        acc = np.column_stack([a_g * G0 * np.sin(phase), a_g * G0 * np.cos(phase),
                               np.zeros(t.size)])
        if batches:
            for k in range(0, chunk, CHUNK):
                sim.batch('tip', ns[k:k + CHUNK], acc[k:k + CHUNK])
                # the impacts of the node's chunk [k, k + CHUNK) ms, often none
                lo, hi = ns_of(T0 + (start + np.array([k, k + CHUNK])) / FS)
                sim.impact_batch(lo, impact_ns[(impact_ns >= lo) & (impact_ns < hi)])
            sent['accel'] += chunk // CHUNK
            sent['impacts'] += chunk // CHUNK
        else:
            for x, a in zip(t, acc):
                sim.imu('tip', x, a)
            sent['accel'] += chunk
            while next_impact < impacts.size and impacts[next_impact] < T0 + end / FS:
                sim.impact(impacts[next_impact])
                next_impact += 1
                sent['impacts'] += 1
        while schedule and schedule[0][0] < end:
            ms, efforts = schedule.pop(0)
            sim.stuck(T0 + ms / 1000, names, efforts)
            states += 1    # latched depth 1: let each state in before the next
            spin_until(executor, received(monitor, 'impactor_state', states))
        # best-effort samples: let the monitor take each chunk before its queue would overflow
        spin_until(executor, received(monitor, 'accel', sent['accel']))
    spin_until(executor, received(monitor, 'impacts', sent['impacts']))
    spin_until(executor, lambda: latest_status(sim, '/hpotp/monitor: /hpotp/impacts')[1].get(
        'window_end_s') == f'{T0 + 1.4995:.6g}')

    array = sim.arrays[-1]
    assert array.header.stamp.sec > 0 or array.header.stamp.nanosec > 0
    tip, values = status(array, '/hpotp/monitor: /hpotp/tip')
    assert tip.level == DiagnosticStatus.OK, tip.message
    assert tip.hardware_id == 'hpotp/tip_frame'   # no vibration_node status seen
    assert values.pop('frame_id') == 'tip_frame'
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

    imp, values = status(array, '/hpotp/monitor: /hpotp/impacts')
    assert imp.level == DiagnosticStatus.OK, imp.message
    assert imp.hardware_id == 'hpotp/housing'
    assert values.pop('frame_id') == 'housing'
    value = {key: float(text) for key, text in values.items()}
    assert value['impacts_in_window'] == 25
    assert value['span_s'] == pytest.approx(window, rel=TEXT_REL)
    assert value['impacts_per_s'] == pytest.approx(25.0, rel=TEXT_REL)
    # window (T0 + 0.4995, T0 + 1.4995]: stuck fraction 0 for 0.3005 s, 1/2 for 0.4 s,
    # 1 for 0.2 s, 1/2 for 0.0995 s
    assert value['stuck_fraction'] == pytest.approx(0.2 + 0.2 + 0.0995 / 2, rel=TEXT_REL)
    assert (value['impactors'], value['stuck_impactors']) == (2, 1)


def test_same_samples_as_imu_or_as_batches_give_the_same_statistics(setup):
    """Sensor ``a`` gets Imu messages, ``b`` batches of the same samples (noise, a tone, a
    20-sample gap): every statistic of the two is the same to 1e-12."""
    window = 0.5
    monitor, sim, executor = setup(
        dict(parameter_overrides=[
            Parameter('sensors', value=['a', 'b']), Parameter('window', value=window),
            Parameter('report_period', value=0.05), Parameter('log_reports', value=False)]),
        batch=('b',), imu=('a',))
    spin_until(executor, reading(monitor, sim, 'a', 'b'))
    keep = np.ones(700, dtype=bool)
    keep[300:320] = False                                    # dropped samples
    ns = ns_of(T0 + np.flatnonzero(keep) / FS + 1.3e-7)      # off the ms grid
    t = ns // 1_000_000_000 + 1e-9 * (ns % 1_000_000_000)
    rng = np.random.default_rng(24)
    acc = rng.normal(0.0, 0.3 * G0, (t.size, 3))
    acc[:, 0] += 2 * G0 * np.sin(2 * np.pi * 77.3 * t)
    for start in range(0, t.size, 50):
        part = slice(start, start + 50)
        for x, a in zip(t[part], acc[part]):
            sim.imu('a', x, a)
        for k in range(start, min(start + 50, t.size), CHUNK):
            sim.batch('b', ns[k:k + CHUNK], acc[k:k + CHUNK])
        done = min(start + 50, t.size)             # samples sent to each sensor so far
        spin_until(executor, received(monitor, 'accel', done + math.ceil(done / CHUNK)))
    monitor.report()
    a, b = monitor.last_report.sensors['a'], monitor.last_report.sensors['b']
    inside = t > t[-1] - window
    assert a.samples == b.samples == np.count_nonzero(inside)
    assert a.rms_g == pytest.approx(
        np.sqrt(np.mean(np.sum(acc[inside] ** 2, axis=1))) / G0, rel=1e-12)
    # every field but the name: counts, rate, RMS, peaks, frequencies, last stamp
    numbers = [np.hstack([np.ravel(v) for v in astuple(s)[1:]]).astype(float) for s in (a, b)]
    np.testing.assert_allclose(numbers[1], numbers[0], rtol=1e-12, atol=0.0)
    assert math.isfinite(a.dominant_hz) and abs(a.dominant_hz_axes[0] - 77.3) <= a.resolution_hz


def test_reads_the_batch_when_published_else_the_imu(setup):
    """Discovered ``tip`` has a decimated Imu and a full-rate batch: the batch is read, and
    ``tip`` is one sensor. ``old`` has only an Imu: it is read, until a batch appears; then
    the batch is read and the Imu history is dropped."""
    monitor, sim, executor = setup(
        dict(parameter_overrides=[Parameter('window', value=1.0),
                                  Parameter('report_period', value=0.05),
                                  Parameter('log_reports', value=False)]),
        batch=('tip',), imu=('tip', 'old'))
    spin_until(executor, lambda: monitor.topics == {
        'tip': 'accel/tip/batch', 'old': 'accel/old', 'impacts': 'impacts'})
    spin_until(executor, lambda: (sim.batches['tip'].get_subscription_count(),
                                  sim.imus['tip'].get_subscription_count(),
                                  sim.imus['old'].get_subscription_count()) == (1, 0, 1))
    assert sorted(monitor.sensors) == ['old', 'tip']
    ns = ns_of(T0 + (np.arange(20) + 0.5) / FS)
    sim.batch('tip', ns[:10], np.tile([G0, 0.0, 0.0], (10, 1)))
    sim.batch('tip', ns[10:], np.tile([G0, 0.0, 0.0], (10, 1)))
    for k in range(0, 20, 2):                      # the decimated stream, 3 g: not read
        sim.imu('tip', T0 + (k + 0.5) / FS, [3 * G0, 0.0, 0.0])
    for k in range(20):
        sim.imu('old', T0 + (k + 0.5) / FS, [G0, 0.0, 0.0])
    spin_until(executor, received(monitor, 'accel', 22))
    monitor.report()
    tip, old = monitor.last_report.sensors['tip'], monitor.last_report.sensors['old']
    assert (tip.samples, old.samples) == (20, 20)
    assert tip.peak_g == pytest.approx(1.0, rel=1e-12)

    sim.add_batch('old')
    spin_until(executor, lambda: monitor.topics['old'] == 'accel/old/batch'
               and sim.batches['old'].get_subscription_count() == 1)
    later = ns_of(T0 + (np.arange(20, 35) + 0.5) / FS)
    sim.batch('old', later, np.tile([0.0, 2 * G0, 0.0], (later.size, 1)))
    spin_until(executor, received(monitor, 'accel', 23))
    monitor.report()
    old = monitor.last_report.sensors['old']
    assert old.samples == 15                       # the Imu's 20 samples were dropped
    assert old.peak_g == pytest.approx(2.0, rel=1e-12)


def test_empty_impact_batches_count_in_the_impact_rate(setup):
    """Batches every 10 ms for 1 s, 10 impacts all within 0.2 s of it: 10 impacts/s (the
    empty batches say that nothing hit the rest of the time), not 10 / 0.2 s."""
    monitor, sim, executor = setup(
        dict(parameter_overrides=[Parameter('sensors', value=['tip']),
                                  Parameter('window', value=2.0),
                                  Parameter('report_period', value=3600.0),
                                  Parameter('log_reports', value=False)]))
    spin_until(executor, reading(monitor, sim, 'tip'))
    impact_ns = ns_of(T0 + 0.4 + 0.02 * np.arange(10) + 0.001)
    for k in range(101):                           # stamps T0 .. T0 + 1 s
        lo, hi = ns_of(T0 + np.array([k, k + 1]) * CHUNK / FS)
        sim.impact_batch(lo, impact_ns[(impact_ns >= lo) & (impact_ns < hi)])
        spin_until(executor, received(monitor, 'impacts', k + 1))    # keep last 100
    _, values = status(monitor.report(), '/monitor: /impacts')
    assert values['impacts_in_window'] == '10'
    assert float(values['span_s']) == pytest.approx(1.0, rel=TEXT_REL)
    assert float(values['impacts_per_s']) == pytest.approx(10.0, rel=TEXT_REL)


def test_discovers_sensors_and_flags_stale_ones(setup):
    """Empty ``sensors``: accel/* topics are found at start and later; silence gives WARN."""
    monitor, sim, executor = setup(
        dict(parameter_overrides=[Parameter('window', value=0.1),
                                  Parameter('report_period', value=0.05)]),
        batch=('a',))
    assert monitor.sensors == ('a',)
    late = sim.node.create_publisher(PointCloud2, interface.accel_topic('b') + BATCH_SUFFIX,
                                     interface.BATCH_QOS)
    spin_until(executor, lambda: monitor.sensors == ('a', 'b'))
    spin_until(executor, lambda: late.get_subscription_count() == 1
               and reading(monitor, sim, 'a')())
    sim.batch('a', ns_of(1.0 + np.arange(20) / FS), np.tile([G0, 0.0, 0.0], (20, 1)))
    spin_until(executor, lambda: latest_status(sim, '/monitor: /a')[1].get(
        'samples_in_window') == '20')
    a, _ = latest_status(sim, '/monitor: /a')
    assert a.level == DiagnosticStatus.OK, a.message
    # b is silent: within the start-up grace period an OK 'waiting', not a WARN
    b, _ = latest_status(sim, '/monitor: /b')
    assert b.level == DiagnosticStatus.OK and b.message == 'waiting for the first sample on accel/b'
    # no sample for more than two windows (0.2 s on the node clock): stale
    spin_until(executor, lambda: latest_status(sim, '/monitor: /a')[0].message.startswith(
        'stale'))
    assert latest_status(sim, '/monitor: /a')[0].level == DiagnosticStatus.WARN


def test_bad_messages_are_counted_not_fatal(setup):
    monitor, sim, executor = setup(
        dict(parameter_overrides=[Parameter('sensors', value=['tip']),
                                  Parameter('report_period', value=0.05)]))
    spin_until(executor, reading(monitor, sim, 'tip'))
    bad = [[math.nan, 0.0, 0.0], [0.0, math.inf, 0.0], [0.0, 0.0, -math.inf], [1e300, 0, 0]]
    acc = np.array([bad[k // 10] if k % 10 == 9 else [0.5 * G0, 0.0, 0.0]
                    for k in range(40)])
    good = 36
    ns = ns_of(2.0 + np.arange(40) / FS)
    for k in range(0, 40, CHUNK):
        sim.batch('tip', ns[k:k + CHUNK], acc[k:k + CHUNK])
    # a batch of 3 rows without ax, ay, az (the impact layout), on the accelerometer topic
    wrong = np.zeros(3, IMPACT_DTYPE)
    sim.batches['tip'].publish(BatchEncoder('tip_frame', IMPACT_FIELDS, IMPACT_POINT_STEP)
                               .encode(int(ns[-1]), wrong))
    # an impact batch of 2 rows without the time field t
    sim.impacts.publish(BatchEncoder('housing', (('x', 0, FLOAT64),), 8).encode(
        int(ns[0]), np.zeros(2, [('x', '<f8')])))
    sim.stuck(2.0, ['i0/x', 'i1/x'], [math.nan, 0.0])   # non-finite flag
    spin_until(executor, received(monitor, 'impactor_state', 1))
    sim.stuck(2.01, ['i0/x', 'i1/x'], [1.0])            # fewer efforts than names
    spin_until(executor, received(monitor, 'impactor_state', 2))
    spin_until(executor, received(monitor, 'accel', 5))
    spin_until(executor, received(monitor, 'impacts', 1))
    spin_until(executor, lambda: latest_status(sim, '/monitor: /tip')[1].get(
        'rejected_samples') == '7')
    tip, values = latest_status(sim, '/monitor: /tip')
    assert tip.level == DiagnosticStatus.WARN and 'rejected' in tip.message
    assert int(values['samples_in_window']) == good
    assert float(values['peak_g']) == pytest.approx(0.5, rel=TEXT_REL)
    imp, values = latest_status(sim, '/monitor: /impacts')
    assert values['rejected_states'] == '2'
    assert values['rejected_impacts'] == '2'
    assert values['stuck_fraction'] == 'nan'
    # still alive and reporting: a later report has no new rejections, so tip is OK
    count = len(sim.arrays)
    spin_until(executor, lambda: len(sim.arrays) > count)
    assert latest_status(sim, '/monitor: /tip')[0].level == DiagnosticStatus.OK


def test_parameters_are_ranged_and_window_is_live(setup):
    monitor, _, _ = setup(dict(parameter_overrides=[Parameter('sensors', value=['tip'])]))
    monitor.report()
    assert monitor.last_report.window == 2.0
    assert not monitor.set_parameters([Parameter('window', value=100.0)])[0].successful
    assert monitor.set_parameters([Parameter('window', value=0.5)])[0].successful
    array = monitor.report()
    assert monitor.last_report.window == 0.5
    assert status(array, '/monitor: /tip')[1]['window_s'] == '0.5'
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
    # no publisher: the node's format, the batch, is read
    assert 'watching /rbs/accel/tip/batch' in output
    assert 'impacts:' in output
    assert process.returncode == 0, output
    assert 'Traceback' not in output


def test_a_report_cut_by_ctrl_c_is_not_an_error(ros_context):
    """Ctrl-C shuts the context down, and a report the report thread is publishing then fails
    ("publisher's context is invalid"; a newcomer's Ctrl-C printed it as an ERROR). With the
    context down the thread ends quietly; with it up, a failed report is still logged."""
    import rclpy
    monitor = VibrationMonitor(context=ros_context)
    logged = []
    monitor.get_logger().error = lambda text, **_: logged.append(text)

    def fail(jobs):
        raise RuntimeError("Failed to publish: publisher's context is invalid")

    monitor._process = fail

    def queue_job():
        with monitor._queue:
            monitor._jobs.append(None)
            monitor._queue.notify()

    try:
        queue_job()
        deadline = time.monotonic() + 5.0
        while not logged and time.monotonic() < deadline:
            time.sleep(0.01)
        assert len(logged) == 1 and 'report failed' in logged[0]   # context up: an error
        rclpy.try_shutdown(context=ros_context)
        queue_job()
        monitor._worker.join(timeout=5.0)
        assert not monitor._worker.is_alive()
        assert len(logged) == 1, logged   # context down: no error, the thread ended
    finally:
        monitor.destroy_node()


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
            # spin_once would raise if the callback raised
            answer = call_service(ex, client, SetParameters.Request(parameters=[ParameterMsg(
                name='window', value=ParameterValue(type=kind, double_value=1.0))]))
            assert not answer.results[0].successful
        assert monitor.get_parameter('window').value == 2.0
    finally:
        client_node.destroy_node()
        monitor.destroy_node()


def test_a_topic_of_another_type_is_not_adopted(setup):
    """A String on ``accel/fake_sensor`` (issue 29) is not an accelerometer: not watched, no
    diagnostics status, no warning each period; the Imu and batch sensors still are."""
    from std_msgs.msg import String
    monitor, sim, executor = setup(
        dict(parameter_overrides=[Parameter('window', value=0.1),
                                  Parameter('report_period', value=0.05)]),
        batch=('a',))
    fake = sim.node.create_publisher(String, interface.accel_topic('fake_sensor'), 10)
    fake_batch = sim.node.create_publisher(
        String, interface.accel_topic('fake_batch') + BATCH_SUFFIX, 10)
    start = len(sim.arrays)
    deadline = time.monotonic() + 1.5
    while time.monotonic() < deadline:
        fake.publish(String(data='not an Imu'))
        fake_batch.publish(String(data='not a PointCloud2'))
        executor.spin_once(timeout_sec=0.01)
    assert len(sim.arrays) > start + 5   # the monitor reported meanwhile
    assert 'a' in monitor.sensors   # (other processes on the domain may add their own)
    assert not {'fake_sensor', 'fake_batch'} & set(monitor.sensors), monitor.sensors
    names = {s.name for array in sim.arrays for s in array.status}
    assert not any('fake' in name for name in names), names
    assert fake.get_subscription_count() == 0 and fake_batch.get_subscription_count() == 0


def test_truth_and_tachometer_topics_are_not_accelerometers(setup):
    """``accel/<name>/truth`` (PointCloud2, the node's ground truth) and ``rotor/tach`` and
    ``rotor/keyphasor`` (PointCloud2) are in the graph: the monitor watches the accelerometer
    ``a`` only, and subscribes to none of them."""
    monitor, sim, executor = setup({}, batch=('a',))
    extra = [sim.node.create_publisher(PointCloud2, topic, interface.BATCH_QOS)
             for topic in (interface.accel_truth_topic('a'), interface.ROTOR_TACH,
                           interface.ROTOR_KEYPHASOR)]
    names = {monitor.resolve_topic_name(p.topic_name) for p in extra}
    spin_until(executor, lambda: names <= {t for t, _ in monitor.get_topic_names_and_types()})
    monitor.discover()
    deadline = time.monotonic() + 0.5
    while time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.01)
    assert 'a' in monitor.sensors
    assert not [s for s in monitor.sensors if 'truth' in s or 'tach' in s], monitor.sensors
    assert all(p.get_subscription_count() == 0 for p in extra)


# --- several machines (issue 39): namespaces, one line per machine, told apart ---------------

def capture_lines(monitor):
    """Collect the monitor's INFO and WARN log lines as ``(level, text)``."""
    lines = []
    logger = monitor.get_logger()
    logger.info = lambda text, **_: lines.append(('info', text))
    logger.warning = lambda text, **_: lines.append(('warn', text))
    return lines


@pytest.fixture
def plant(ros_context):
    """Build ``(monitor, {namespace: simulator}, executor)``; destroy them afterwards."""
    made = []

    def make(monitor_parameters, namespaces, **sim_kwargs):
        sims = {ns: Simulator(ros_context, namespace=ns, **sim_kwargs) for ns in namespaces}
        monitor = VibrationMonitor(context=ros_context, parameter_overrides=[
            Parameter(name, value=value) for name, value in monitor_parameters.items()])
        executor = SingleThreadedExecutor(context=ros_context)
        for node in [monitor, *(sim.node for sim in sims.values())]:
            executor.add_node(node)
        made.append((monitor, sims, executor))
        return monitor, sims, executor

    yield make
    for monitor, sims, executor in made:
        executor.shutdown()
        monitor.destroy_node()
        for sim in sims.values():
            sim.node.destroy_node()


def send_tone(sim, start_ms, count, amplitude_g, hz=40.0):
    """``count`` ms of a ``amplitude_g`` g sine at ``hz`` on ``tip`` (x), from T0 +
    ``start_ms``, in CHUNK batches, with the empty impact batch of each chunk."""
    for k in range(start_ms, start_ms + count, CHUNK):
        ns = ns_of(T0 + (np.arange(k, k + CHUNK) + 0.5) / FS)
        t = ns * 1e-9
        acc = np.zeros((CHUNK, 3))
        acc[:, 0] = amplitude_g * G0 * np.sin(2 * np.pi * hz * t)
        sim.batch('tip', ns, acc)
        lo, hi = ns_of(T0 + np.array([k, k + CHUNK]) / FS)
        sim.impact_batch(lo, [])
    return count // CHUNK


def test_two_machines_one_line_each_and_distinct_statuses(plant):
    """``namespaces: [pump1, /plant/pump2]``: a 1 g and a 3 g tone. One line per machine per
    report, its namespace first and padded so the figures line up, with that machine's RMS;
    statuses and hardware_ids name the machine; each machine has its own core."""
    monitor, sims, executor = plant(
        dict(namespaces=['pump1', '/plant/pump2'], sensors=['tip'], window=0.5,
             report_period=3600.0), ['/pump1', '/plant/pump2'])
    assert list(monitor.machines) == ['/pump1', '/plant/pump2']
    for sim in sims.values():
        spin_until(executor, reading(monitor, sim, 'tip'))
    sent = send_tone(sims['/pump1'], 0, 500, 1.0) + send_tone(sims['/plant/pump2'], 0, 500, 3.0)
    spin_until(executor, received(monitor, 'accel', sent))
    lines = capture_lines(monitor)
    array = monitor.report()

    assert [level for level, _ in lines] == ['warn', 'warn']   # no impactor_state: WARN
    (one, two) = [text for _, text in lines]
    assert one.startswith('/pump1        accel/tip: rms 0.7071 g')   # padded to 12 + 2
    assert two.startswith('/plant/pump2  accel/tip: rms 2.121 g')
    assert 'impacts: 0 /s' in one and 'impacts: 0 /s' in two
    names = [s.name for s in array.status]
    assert names == ['/monitor: /pump1/tip', '/monitor: /pump1/impacts',
                     '/monitor: /plant/pump2/tip', '/monitor: /plant/pump2/impacts']
    assert [s.hardware_id for s in array.status] == [
        'pump1/tip_frame', 'pump1/housing', 'plant/pump2/tip_frame', 'plant/pump2/housing']
    rms = {s.name: float(status(array, s.name)[1]['rms_g']) for s in array.status[::2]}
    assert rms['/monitor: /pump1/tip'] == pytest.approx(1 / np.sqrt(2), rel=TEXT_REL)
    assert rms['/monitor: /plant/pump2/tip'] == pytest.approx(3 / np.sqrt(2), rel=TEXT_REL)
    # a second report: again exactly one line per machine
    monitor.report()
    assert len(lines) == 4 and lines[2][1].startswith('/pump1 ')


def test_hardware_id_is_the_machines_own(plant):
    """A ``vibration_node`` status ``/pump1/vibration_node: simulation`` with hardware_id
    SN-1042 (the plant's name for the pump): pump1's monitor statuses carry it; pump2, with
    no such status, keeps ``pump2/<frame>``; other statuses on /diagnostics change nothing."""
    from diagnostic_msgs.msg import DiagnosticStatus as Status
    monitor, sims, executor = plant(
        dict(namespaces=['/pump1', '/pump2'], sensors=['tip'], report_period=3600.0),
        ['/pump1', '/pump2'])
    sim = sims['/pump1']
    diagnostics = sim.node.create_publisher(DiagnosticArray, interface.DIAGNOSTICS,
                                            interface.DIAGNOSTICS_QOS)
    spin_until(executor, lambda: diagnostics.get_subscription_count() >= 2)
    diagnostics.publish(DiagnosticArray(status=[
        Status(name='/pump2/other_node: simulation_x', hardware_id='not-a-machine'),
        Status(name='/pump1/vibration_node: simulation', hardware_id='SN-1042')]))
    spin_until(executor, lambda: monitor.machines['/pump1'].node_hardware_id == 'SN-1042')
    array = monitor.report()
    assert {s.name: s.hardware_id for s in array.status} == {
        '/monitor: /pump1/tip': 'SN-1042', '/monitor: /pump1/impacts': 'SN-1042',
        '/monitor: /pump2/tip': 'pump2', '/monitor: /pump2/impacts': 'pump2'}


def test_a_machine_that_stops_publishing_is_reported_stale(plant):
    """Both machines publish, then pump1 stops: after two windows of node clock pump1's
    status turns WARN 'stale' and its line is a WARN naming it; pump2 stays OK."""
    monitor, sims, executor = plant(
        dict(namespaces=['pump1', 'pump2'], sensors=['tip'], window=0.1,
             report_period=0.05), ['/pump1', '/pump2'])
    for sim in sims.values():
        spin_until(executor, reading(monitor, sim, 'tip'))
        sim.stuck(T0, ['i0/x'], [0.0])
    spin_until(executor, received(monitor, 'impactor_state', 2))
    sent = send_tone(sims['/pump1'], 0, 100, 1.0) + send_tone(sims['/pump2'], 0, 100, 1.0)
    spin_until(executor, received(monitor, 'accel', sent))
    lines = capture_lines(monitor)
    start = time.monotonic()
    ms = 100
    pump2 = sims['/pump2']
    while time.monotonic() - start < 0.6 or not latest_status(
            pump2, '/monitor: /pump1/tip')[0].message.startswith('stale'):
        assert time.monotonic() - start < 10.0, 'pump1 never reported stale'
        sent += send_tone(pump2, ms, CHUNK, 1.0)   # pump2 goes on, in real time or so
        ms += CHUNK
        spin_until(executor, received(monitor, 'accel', sent))
        time.sleep(0.01)
    pump1, _ = latest_status(pump2, '/monitor: /pump1/tip')
    assert pump1.level == DiagnosticStatus.WARN and 'no sample for' in pump1.message
    other, _ = latest_status(pump2, '/monitor: /pump2/tip')
    assert other.level == DiagnosticStatus.OK, other.message
    # its impacts batches stopped too: the impacts status says so, pump2's does not
    impacts, _ = latest_status(pump2, '/monitor: /pump1/impacts')
    assert impacts.level == DiagnosticStatus.WARN
    assert impacts.message.startswith('stale: no impacts batch for'), impacts.message
    other, _ = latest_status(pump2, '/monitor: /pump2/impacts')
    assert other.level == DiagnosticStatus.OK, other.message
    last = [(level, text) for level, text in lines if text.startswith('/pump1 ')][-1]
    assert last[0] == 'warn' and 'stale: no sample for' in last[1]
    assert [level for level, text in lines if text.startswith('/pump2 ')][-1] == 'info'


def test_star_follows_the_machines_in_the_graph(plant):
    """``namespaces: ['*']``: the machines with accelerometer topics are followed, a later one
    too; a namespace with only another topic (a String ``accel/x``) is not a machine."""
    from std_msgs.msg import String
    monitor, sims, executor = plant(dict(namespaces=['*'], report_period=0.05),
                                    ['/pump1', '/pump2'])
    spin_until(executor, lambda: {'/pump1', '/pump2'} <= set(monitor.machines))
    stranger = sims['/pump1'].node.create_publisher(String, '/stranger/accel/x', 10)
    late = sims['/pump1'].node.create_publisher(
        PointCloud2, '/pump3/accel/tip' + BATCH_SUFFIX, interface.BATCH_QOS)
    spin_until(executor, lambda: '/pump3' in monitor.machines)
    spin_until(executor, lambda: monitor.machines['/pump3'].accel_streams.keys() == {'tip'})
    assert '/stranger' not in monitor.machines
    assert stranger.get_subscription_count() == 0
    assert late.get_subscription_count() == 1


@pytest.mark.parametrize('entry', ['pump 1', '/1pump', 'plant//pump1', 'pump1/', '', '~/x'])
def test_an_invalid_namespace_is_refused_naming_the_parameter(ros_context, entry):
    from impact_damper_sim.ros.monitor_machine import MonitorParameterError
    with pytest.raises(MonitorParameterError) as refused:
        VibrationMonitor(context=ros_context, parameter_overrides=[
            Parameter('namespaces', value=['pump0', entry])])
    text = str(refused.value)
    assert text.startswith(f'namespaces: {entry!r} is not ') and "'*'" in text, text
    assert '\n' not in text


def test_main_refuses_an_invalid_namespace_in_one_line():
    env = dict(os.environ, ROS_DOMAIN_ID=str(next_domain_id()),
               ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    done = subprocess.run(
        [sys.executable, '-c',
         'import sys; from impact_damper_sim.ros.monitor import main; sys.exit(main())',
         '--ros-args', '-p', "namespaces:=['pump1', 'pump 2']"],
        env=env, capture_output=True, text=True, timeout=60)
    assert done.returncode == 2, done.stdout + done.stderr
    assert done.stderr.startswith("monitor: namespaces: 'pump 2' is not an absolute '/pump1'")
    assert done.stderr.count('\n') == 1 and 'Traceback' not in done.stderr


def test_batches_read_from_their_bytes_as_rclpy_reads_them():
    """The monitor reads its batch subscriptions' raw bytes itself (monitor_cdr): for both
    layouts and frame names of every length mod 4 (alignment), the same header, layout and
    rows as rclpy's deserialization; cut bytes are a ValueError, not a crash."""
    from rclpy.serialization import deserialize_message

    from impact_damper_sim.recording.batches import rows_of
    from impact_damper_sim.ros.monitor_cdr import read_cloud, rows_in
    rng = np.random.default_rng(7)
    layouts = {}   # a reader's cache: from the second message of a layout on, a hit
    for frame in ('a', 'ab', 'abc', 'abcd', 'pump3/casing'):
        for fields, step, dtype, n in ((ACCEL_FIELDS, ACCEL_POINT_STEP, ACCEL_DTYPE, 20),
                                       (IMPACT_FIELDS, IMPACT_POINT_STEP, IMPACT_DTYPE, 0),
                                       (IMPACT_FIELDS, IMPACT_POINT_STEP, IMPACT_DTYPE, 35)):
            rows = np.zeros(n, dtype)
            for name in dtype.names:
                rows[name] = rng.integers(0, 1000, n)
            data = BatchEncoder(frame, fields, step).encode(1_234_567_890_123, rows)
            want = deserialize_message(data, PointCloud2)
            for got in (read_cloud(data), read_cloud(data, layouts)):
                assert_same_cloud(got, want)
            assert rows_in(data) == n
            for cut in (3, 20, len(data) - 2):
                with pytest.raises(ValueError):
                    rows_of(read_cloud(data[:cut], layouts))
    assert len(layouts) == 2   # one per layout, whatever the frame


def assert_same_cloud(got, want):
    """``got`` (monitor_cdr) has ``want``'s (rclpy's) header, layout and rows."""
    from impact_damper_sim.recording.batches import rows_of
    assert (got.header.stamp.sec, got.header.stamp.nanosec, got.header.frame_id) == (
        want.header.stamp.sec, want.header.stamp.nanosec, want.header.frame_id)
    assert (got.height, got.width, got.point_step, got.row_step) == (
        want.height, want.width, want.point_step, want.row_step)
    assert [(f.name, f.offset, f.datatype, f.count) for f in got.fields] == [
        (f.name, f.offset, f.datatype, f.count) for f in want.fields]
    np.testing.assert_array_equal(rows_of(got), rows_of(want))


def test_a_publisher_with_incompatible_qos_is_named(setup):
    """A best-effort publisher on ``impacts`` (the monitor reads it reliable): one WARN names
    the topic and the policy, as rclpy's default handler would."""
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    monitor, sim, executor = setup(dict(parameter_overrides=[
        Parameter('sensors', value=['tip']), Parameter('report_period', value=3600.0)]))
    lines = capture_lines(monitor)
    sim.node.create_publisher(PointCloud2, interface.IMPACTS, QoSProfile(
        depth=10, reliability=ReliabilityPolicy.BEST_EFFORT))
    spin_until(executor, lambda: any('incompatible QoS' in text for _, text in lines))
    (line,) = [(level, text) for level, text in lines if 'incompatible QoS' in text]
    assert line[0] == 'warn' and '/impacts' in line[1] and 'RELIABILITY' in line[1], line
