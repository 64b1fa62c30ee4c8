"""``replay``: pacing, QoS restoration, topic filter and remap, /clock, and bad files.

The fixture logs are written the way rosbag2 writes MCAP: profile ``ros2``, ``ros2msg``
schemas concatenated by rosbag2's rule from the installed ``.msg`` files, ``cdr`` payloads from
``rclpy.serialization.serialize_message``, and channel metadata ``offered_qos_profiles`` (a
YAML list, bag metadata version 9 spelling) and ``topic_type_hash``.

Timing tests replay into a subscriber in the same rclpy context (launch-free); arrival times
are taken in the subscription callbacks.
"""
import json
import math
import os
import statistics
import subprocess
import sys
import threading
import time

import pytest

pytest.importorskip('rclpy')
yaml = pytest.importorskip('yaml')

from geometry_msgs.msg import WrenchStamped  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from rclpy.serialization import serialize_message  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from sensor_msgs.msg import Imu, JointState  # noqa: E402
from std_msgs.msg import Float64  # noqa: E402

from impact_damper_sim.live import playback  # noqa: E402
from impact_damper_sim.ros import replay, replay_plan  # noqa: E402
from impact_damper_sim.ros.interface import EVENT_QOS, LATCHED_QOS, SENSOR_QOS  # noqa: E402

T0 = 1_700_000_000_000_000_000   # log_time of the first message (ns)
MS = 1_000_000


# --- fixture logs -----------------------------------------------------------------------------

from ament_index_python.packages import get_package_share_directory  # noqa: E402

from rosbag2_rule import msgdef  # noqa: E402  (test/ helper)


def rtype_of(msg):
    return f"{type(msg).__module__.split('.')[0]}/msg/{type(msg).__name__}"


def offered_yaml(q, history_known=True):
    """One publisher's offer as rosbag2 Jazzy stores it (version 9: policies as strings).

    Offers seen through DDS discovery carry no history: ``history_known=False`` writes them
    as rosbag2 does then (unknown, depth 0).
    """
    infinite = {'sec': 9223372036, 'nsec': 854775807}
    return yaml.safe_dump([{
        'history': q.history.name.lower() if history_known else 'unknown',
        'depth': q.depth if history_known else 0,
        'reliability': q.reliability.name.lower(), 'durability': q.durability.name.lower(),
        'deadline': infinite, 'lifespan': infinite, 'liveliness': 'automatic',
        'liveliness_lease_duration': infinite, 'avoid_ros_namespace_conventions': False}],
        sort_keys=False)   # rosbag2's key order


def write_log(path, entries, qos=None, profile='ros2', schema_names=None):
    """Write ``(log_time_ns, topic, msg)`` entries (sorted) into a rosbag2-style MCAP.

    ``qos`` maps topic to a QoSProfile (or a YAML string); a topic not in it has no
    ``offered_qos_profiles`` metadata. ``schema_names`` overrides a type's schema name.
    Returns the payloads written (serializing twice can differ in the CDR padding bytes).
    """
    from mcap.writer import CompressionType, Writer
    qos, schema_names = qos or {}, schema_names or {}
    with open(path, 'wb') as fh:
        w = Writer(fh, chunk_size=4096, compression=CompressionType.NONE)
        w.start(profile=profile, library='test_replay')
        schemas, channels, payloads = {}, {}, []
        for log_time, topic, msg in entries:
            rtype = rtype_of(msg)
            if rtype not in schemas:
                schemas[rtype] = w.register_schema(schema_names.get(rtype, rtype), 'ros2msg',
                                                   msgdef(rtype).encode())
            if topic not in channels:
                meta = {}
                if topic in qos:
                    q = qos[topic]
                    meta['offered_qos_profiles'] = q if isinstance(q, str) else offered_yaml(q)
                share = get_package_share_directory(rtype.split('/')[0])
                with open(os.path.join(share, 'msg', rtype.split('/')[-1] + '.json')) as jf:
                    meta['topic_type_hash'] = json.load(jf)['type_hashes'][0]['hash_string']
                channels[topic] = w.register_channel(topic, 'cdr', schemas[rtype], meta)
            payloads.append(serialize_message(msg))
            w.add_message(channels[topic], log_time=log_time, data=payloads[-1],
                          publish_time=log_time - 100_000)
        w.finish()
    return payloads


def imu(k):
    m = Imu()
    m.header.frame_id = f'sample {k}'
    m.header.stamp.sec, m.header.stamp.nanosec = divmod(k * 10 * MS, 1_000_000_000)
    m.linear_acceleration.x = float(k)
    m.orientation_covariance[0] = -1.0
    return m


def impact(k):
    m = WrenchStamped()
    m.header.frame_id = f'housing/imp_{k}'
    m.wrench.force.x = 1e-3 * k
    return m


def state(k, stuck):
    m = JointState()
    m.header.stamp.sec = k
    m.name = ['imp_a/y', 'imp_a/z']
    m.position, m.velocity, m.effort = [0.0, 0.0], [0.0, 0.0], [float(stuck)] * 2
    return m


@pytest.fixture
def mixed_log(tmp_path):
    """/accel/s1 (best effort) and /impacts (reliable) interleaved, with uneven intervals."""
    entries, t, k = [], T0, 0
    # intervals 6..18 ms, deterministic: exercises pacing on uneven timing
    while t - T0 < 1_200 * MS:
        topic, msg = ('/impacts', impact(k)) if k % 4 == 3 else ('/accel/s1', imu(k))
        entries.append((t, topic, msg))
        t += (6 + (7 * k) % 13) * MS
        k += 1
    path = tmp_path / 'mixed.mcap'
    payloads = write_log(path, entries, {'/accel/s1': SENSOR_QOS, '/impacts': EVENT_QOS})
    return path, entries, payloads


# --- replay into a subscriber in the same context ---------------------------------------------

def wait_for_discovery(node, topics, timeout=10.0):
    """Wait until each of ``node``'s publishers on ``topics`` has matched a subscription.

    A volatile publisher drops what it sends before that, and discovery takes longer on a
    loaded machine: without this wait the first ``/clock`` tick or sample went missing (seen
    with the 2 cores busy). Users have ``replay --delay`` for the same reason.
    """
    deadline = time.monotonic() + timeout
    waiting = [p for p in node.publishers if p.topic_name in topics]
    while waiting and time.monotonic() < deadline:
        waiting = [p for p in waiting if p.get_subscription_count() == 0]
        time.sleep(0.005)
    assert not waiting, f'no subscription matched on {[p.topic_name for p in waiting]}'


def run_replay(ctx, plan, subscribe, expected, timeout=20.0, **node_kwargs):
    """Play ``plan`` in a thread while spinning subscribers; return (arrivals, stats, node).

    ``subscribe`` is ``[(msg_class, topic, qos)]``; each arrival is (topic, wall_s, bytes).
    """
    arrivals = []
    sub_node = Node('listener', context=ctx)
    for cls, topic, qos in subscribe:
        sub_node.create_subscription(
            cls, topic, lambda data, topic=topic: arrivals.append(
                (topic, time.monotonic(), data)), qos, raw=True)
    node = replay.ReplayNode(plan, context=ctx, **node_kwargs)
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(sub_node)
    wait_for_discovery(node, {topic for _, topic, _ in subscribe})
    player = threading.Thread(target=node.play)
    player.start()
    deadline = time.monotonic() + timeout
    while (player.is_alive() or len(arrivals) < expected) and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.005)
    idle = time.monotonic() + 0.1   # drain what is still in flight (the last /clock)
    while time.monotonic() < idle:
        n = len(arrivals)
        executor.spin_once(timeout_sec=0.01)
        if len(arrivals) > n:
            idle = time.monotonic() + 0.1
    node.stop()
    player.join()
    executor.shutdown()
    sub_node.destroy_node()
    return arrivals, node.stats, node


@pytest.mark.ros
def test_rate_1_count_order_payload_and_timing(ros_context, mixed_log):
    path, entries, payloads = mixed_log
    plan = replay_plan.prepare(path)
    arrivals, stats, node = run_replay(
        ros_context, plan, [(Imu, '/accel/s1', SENSOR_QOS), (WrenchStamped, '/impacts',
                                                             EVENT_QOS)], len(entries),
        clock=False)
    node.destroy_node()
    assert stats.messages == len(entries) and not stats.stopped
    assert len(arrivals) == len(entries)
    # payloads and order: the raw CDR bytes arrive unchanged, each topic in log order (across
    # topics DDS keeps no order: an executor that wakes late takes the topics in its own
    # order, seen with the cores loaded; the player's own order is the fake-clock tests')
    for topic in ('/accel/s1', '/impacts'):
        assert [a[2] for a in arrivals if a[0] == topic] == [
            data for e, data in zip(entries, payloads) if e[1] == topic], topic
    log_dt = [(b[0] - a[0]) * 1e-9 for a, b in zip(entries, entries[1:])]
    wall_dt = [b[1] - a[1] for a, b in zip(arrivals, arrivals[1:])]
    jitter = statistics.median(abs(w - g) for w, g in zip(wall_dt, log_dt))
    print(f'rate 1: median inter-arrival jitter {jitter * 1e3:.3f} ms over {len(log_dt)} '
          f'intervals; publisher lateness median {stats.median_lateness_s * 1e3:.3f} ms, '
          f'max {stats.max_lateness_s * 1e3:.3f} ms')
    # Exact pacing is test_player_publishes_at_deadlines_with_clock_ticks (a fake clock).
    # Here, over DDS with the machine shared, only what load cannot cause is asserted: a
    # median jitter far below the 20 ms spacing (a player that ignored the schedule would
    # be off by whole intervals), and no running ahead of the log (the player waits for
    # each deadline; load only makes it late), nor behind it by more than 0.5 s (it drops
    # no time: no drift). The measured numbers are printed (typically 0.1 ms jitter and a
    # span within 5 ms).
    assert jitter < 5e-3
    span = (entries[-1][0] - entries[0][0]) * 1e-9
    wall = arrivals[-1][1] - arrivals[0][1]
    print(f'rate 1: {span:.3f} s of log in {wall:.4f} s of wall time')
    assert span - 0.02 <= wall <= span + 0.5


@pytest.mark.ros
def test_rate_10_runs_ten_times_faster(ros_context, tmp_path):
    entries = [(T0 + k * 20 * MS, '/accel/s1', imu(k)) for k in range(101)]   # 2 s of log
    path = tmp_path / 'steady.mcap'
    write_log(path, entries, {'/accel/s1': SENSOR_QOS})
    plan = replay_plan.prepare(path, rate=10.0)
    arrivals, stats, node = run_replay(ros_context, plan, [(Imu, '/accel/s1', SENSOR_QOS)],
                                       len(entries))
    node.destroy_node()
    assert len(arrivals) == len(entries)
    wall = arrivals[-1][1] - arrivals[0][1]
    speedup = 2.0 / wall
    print(f'rate 10: 2 s of log in {wall:.4f} s of wall time, speed-up {speedup:.2f}')
    # never faster than 10x (deadlines are waited for; 10 ms for a late delivery of the
    # first message), and not so slow that the rate is ignored (rate 1 would take 2 s) or
    # paced at another factor; load only lowers the speed-up (measured 9.9 when idle)
    assert wall >= 0.2 - 0.01
    assert speedup > 5.0


@pytest.mark.ros
def test_topic_filter_remap_and_clock(ros_context, mixed_log):
    path, entries, payloads = mixed_log
    plan = replay_plan.prepare(path, topics=['impacts'], remaps=['/impacts:=/replayed/impacts'],
                               rate=4.0)
    impacts = [e for e in entries if e[1] == '/impacts']
    impact_data = [d for e, d in zip(entries, payloads) if e[1] == '/impacts']
    arrivals, stats, node = run_replay(
        ros_context, plan, [(WrenchStamped, '/replayed/impacts', EVENT_QOS),
                            (WrenchStamped, '/impacts', EVENT_QOS),
                            (Imu, '/accel/s1', SENSOR_QOS),
                            (Clock, '/clock', QoSProfile(depth=100))],
        len(impacts) + 10, clock_hz=200.0)
    try:
        topics = {name for name, _ in node.get_publisher_names_and_types_by_node(
            'replay', '/')} - {'/rosout', '/parameter_events'}
        assert topics == {'/replayed/impacts', '/clock'}
    finally:
        node.destroy_node()
    got = [a for a in arrivals if a[0] == '/replayed/impacts']
    assert [a[2] for a in got] == impact_data
    assert not [a for a in arrivals if a[0] in ('/impacts', '/accel/s1')]
    # /clock: the log's time, from its first message to the last one replayed, never back
    from rclpy.serialization import deserialize_message
    clock = [deserialize_message(a[2], Clock).clock for a in arrivals if a[0] == '/clock']
    ns = [c.sec * 1_000_000_000 + c.nanosec for c in clock]
    # the first tick received is on the grid of the log's start (20 ms of log a tick, from
    # the first message, not the first impact), within a few ticks of it: a late player skips
    # ticks and a keep-last-1 reader keeps only the newest (both seen with 2 cores loaded)
    first_tick = (ns[0] - entries[0][0]) / (20 * MS)
    assert 0 <= first_tick <= 10 and abs(first_tick - round(first_tick)) < 1e-6, first_tick
    assert ns[-1] == impacts[-1][0]
    assert all(b >= a for a, b in zip(ns, ns[1:]))
    # 200 ticks per wall second at rate 4: one tick per 20 ms of log (late ticks are skipped)
    span_s = (impacts[-1][0] - entries[0][0]) * 1e-9
    # never more ticks than the wall-clock schedule allows (late ticks are skipped, so load
    # gives fewer, never more); a quarter of them at least, or /clock is not ticking
    expected = span_s / 4 * 200 + 2
    assert 0.25 * expected <= len(ns) <= expected + 1
    assert stats.clock_ticks == len(ns)


@pytest.mark.ros
def test_qos_restored_latched_state_reaches_late_joiner(ros_context, tmp_path):
    entries = [(T0 + k * 10 * MS, '/impactor_state', state(k, k % 2)) for k in range(5)]
    entries += [(T0 + 60 * MS, '/accel/s1', imu(0)), (T0 + 70 * MS, '/impacts', impact(0)),
                (T0 + 80 * MS, '/rotor/speed_command', Float64(data=3.0))]
    entries.sort(key=lambda e: e[0])
    path = tmp_path / 'latched.mcap'
    write_log(path, entries, {'/impactor_state': LATCHED_QOS, '/accel/s1': SENSOR_QOS,
                              '/impacts': offered_yaml(EVENT_QOS, history_known=False)})
    plan = replay_plan.prepare(path, rate=5.0)
    qos = {t.topic: t.qos for t in plan.tracks}
    assert (qos['/impactor_state'].reliability, qos['/impactor_state'].durability,
            qos['/impactor_state'].depth) == (ReliabilityPolicy.RELIABLE,
                                              DurabilityPolicy.TRANSIENT_LOCAL, 1)
    assert (qos['/accel/s1'].reliability, qos['/accel/s1'].durability,
            qos['/accel/s1'].depth) == (ReliabilityPolicy.BEST_EFFORT,
                                        DurabilityPolicy.VOLATILE, 100)
    # offered through discovery: no history recorded, so rosbag2's keep last 10
    assert (qos['/impacts'].reliability, qos['/impacts'].history, qos['/impacts'].depth) == (
        ReliabilityPolicy.RELIABLE, HistoryPolicy.KEEP_LAST, 10)
    # no QoS metadata at all: the fallback, with a warning
    fallback = next(t for t in plan.tracks if t.topic == '/rotor/speed_command')
    assert fallback.qos == replay_plan.FALLBACK_QOS
    assert 'no offered_qos_profiles' in fallback.warnings[0]
    node = replay.ReplayNode(plan, context=ros_context, clock=False)
    try:
        node.play()
        late = []
        listener = Node('late_joiner', context=ros_context)
        listener.create_subscription(JointState, '/impactor_state', late.append,
                                     QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                                                durability=DurabilityPolicy.TRANSIENT_LOCAL))
        executor = SingleThreadedExecutor(context=ros_context)
        executor.add_node(listener)
        end = time.monotonic() + 5.0
        while time.monotonic() < end and not late:
            executor.spin_once(timeout_sec=0.05)
        for _ in range(10):   # anything more would arrive now
            executor.spin_once(timeout_sec=0.01)
        executor.shutdown()
        listener.destroy_node()
    finally:
        node.destroy_node()
    # depth 1 restored: the late joiner gets only the latest state (k = 4, free)
    assert len(late) == 1 and late[0].header.stamp.sec == 4 and late[0].effort[0] == 0.0


# --- pacing without ROS -----------------------------------------------------------------------

def test_deadlines_scale_with_rate_and_offset():
    times = [0, 100 * MS, 250 * MS, 1_000 * MS]
    assert playback.deadlines(times) == [(0, 0, 0.0), (0, 1, 0.1), (0, 2, 0.25), (0, 3, 1.0)]
    got = playback.deadlines(times, rate=2.0, start_offset=0.1)
    assert [(k, i) for k, i, _ in got] == [(0, 1), (0, 2), (0, 3)]
    assert [d for *_, d in got] == pytest.approx([0.0, 0.075, 0.45], abs=1e-12)


def test_deadlines_loop_repeats_with_one_mean_interval_between_passes():
    times = [0, 100 * MS, 300 * MS]   # mean interval 150 ms
    got = playback.deadlines(times, rate=0.5, passes=3)
    assert [(k, i) for k, i, _ in got] == [(k, i) for k in range(3) for i in range(3)]
    d = [x for *_, x in got]
    period = (0.3 + 0.15) / 0.5
    for k in range(3):
        assert d[3 * k:3 * k + 3] == pytest.approx([period * k + x for x in (0, 0.2, 0.6)],
                                                   abs=1e-12)


@pytest.mark.parametrize('kwargs, match', [
    ({'rate': 0.0}, 'rate'), ({'rate': -1.0}, 'rate'), ({'rate': math.nan}, 'rate'),
    ({'rate': math.inf}, 'rate'), ({'start_offset': -0.1}, 'start-offset'),
    ({'start_offset': 1.5}, 'past the end')])
def test_schedule_rejects_bad_options(kwargs, match):
    with pytest.raises(ValueError, match=match):
        playback.Schedule(0, 1_000 * MS, 3, **kwargs)


class FakeTime:
    """A wall clock that advances only when waited on, for exact pacing checks."""

    def __init__(self):
        self.t = 100.0

    def now(self):
        return self.t

    def wait(self, timeout):   # the Event.wait of Player's stop event
        self.t += timeout
        return False

    def is_set(self):
        return False


def test_player_publishes_at_deadlines_with_clock_ticks():
    times = [0, 30 * MS, 45 * MS, 100 * MS]
    schedule = playback.Schedule(times[0], times[-1], len(times), rate=2.0)
    ft, published, clock = FakeTime(), [], []
    player = playback.Player(schedule, lambda: [(i, t, b'%d' % i) for i, t in enumerate(times)],
                             lambda key, data: published.append((ft.t - 100.0, key, data)),
                             clock=lambda t: clock.append((ft.t - 100.0, t)),
                             clock_period=0.01, stop=ft, now=ft.now)
    stats = player.run()
    assert [(k, d) for _, k, d in published] == [(i, b'%d' % i) for i in range(4)]
    assert [t for t, *_ in published] == pytest.approx([0.0, 0.015, 0.0225, 0.05], abs=1e-12)
    assert stats.messages == 4 and stats.passes == 1 and stats.max_lateness_s < 1e-12
    # ticks every 10 ms of wall time carry log time 20 ms apart (rate 2), then the end
    assert [w for w, _ in clock[:-1]] == pytest.approx([0.0, 0.01, 0.02, 0.03, 0.04, 0.05])
    assert [t for _, t in clock] == [0, 20 * MS, 40 * MS, 60 * MS, 80 * MS, 100 * MS, 100 * MS]


def test_player_loop_stops_on_event():
    times = [0, 10 * MS]
    schedule = playback.Schedule(0, 10 * MS, 2, rate=1.0, loop=True)
    stop, published = threading.Event(), []

    def publish(key, data):
        published.append(key)
        if len(published) == 7:
            stop.set()
    stats = playback.Player(schedule, lambda: [(i, t, b'') for i, t in enumerate(times)],
                            publish, stop=stop).run()
    assert stats.stopped and stats.messages == 7 and stats.passes == 3
    assert published == [0, 1] * 3 + [0]


# --- QoS parsing ------------------------------------------------------------------------------

def test_qos_from_offered_strings_ints_and_fallbacks():
    v9 = offered_yaml(LATCHED_QOS)
    q, problem = replay_plan.qos_from_offered(v9)
    assert problem is None
    assert (q.reliability, q.durability, q.history, q.depth) == (
        ReliabilityPolicy.RELIABLE, DurabilityPolicy.TRANSIENT_LOCAL, HistoryPolicy.KEEP_LAST,
        1)
    # bag metadata version <= 8 stored enum integers; Foxy-era "infinite" durations
    v8 = ('- {history: 1, depth: 5, reliability: 2, durability: 2, deadline: {sec: 0, nsec: 0},'
          ' lifespan: {sec: 2147483647, nsec: 4294967295}, liveliness: 1,'
          ' liveliness_lease_duration: {sec: 0, nsec: 0}, avoid_ros_namespace_conventions: false}')
    q, problem = replay_plan.qos_from_offered(v8)
    assert problem is None
    assert (q.reliability, q.durability, q.depth) == (ReliabilityPolicy.BEST_EFFORT,
                                                      DurabilityPolicy.VOLATILE, 5)
    assert q.lifespan.nanoseconds == 0   # infinite -> unspecified
    # a finite deadline is kept
    q, _ = replay_plan.qos_from_offered(v9.replace('sec: 9223372036\n    nsec: 854775807',
                                                   'sec: 2\n    nsec: 5', 1))
    assert q.deadline.nanoseconds == 2_000_000_005
    # the parsed list of the rosbag2 metadata record works too
    assert replay_plan.qos_from_offered(yaml.safe_load(v9))[1] is None
    mixed = yaml.safe_dump(yaml.safe_load(offered_yaml(SENSOR_QOS))
                           + yaml.safe_load(offered_yaml(EVENT_QOS)))
    for text, why in [(None, 'no offered'), ('', 'no offered'), ('[]', 'empty'),
                      (': : :', 'not valid YAML'), (mixed, 'different QoS'),
                      ('- {reliability: sometimes, durability: volatile}', 'not understood')]:
        q, problem = replay_plan.qos_from_offered(text)
        assert q == replay_plan.FALLBACK_QOS and why in problem


def test_parse_remaps():
    assert replay_plan.parse_remaps(['impacts:=/x', '/a/b:=c']) == {'/impacts': '/x', '/a/b': 'c'}
    for bad in (['impacts'], ['impacts:='], [':=x'], ['a:=b', '/a:=c']):
        with pytest.raises(ValueError, match='--remap'):
            replay_plan.parse_remaps(bad)


# --- bad input --------------------------------------------------------------------------------

@pytest.fixture
def bad_files(tmp_path, mixed_log):
    good = mixed_log[0].read_bytes()
    files = {'empty': b'', 'garbage': os.urandom(4096), 'truncated': good[:len(good) // 2]}
    out = {}
    for name, data in files.items():
        out[name] = tmp_path / f'{name}.mcap'
        out[name].write_bytes(data)
    entries = [(T0, '/impacts', impact(0))]
    out['not ROS 2'] = tmp_path / 'plain.mcap'
    write_log(out['not ROS 2'], entries, profile='')
    out['unknown type'] = tmp_path / 'unknown.mcap'
    write_log(out['unknown type'], entries,
              schema_names={'geometry_msgs/msg/WrenchStamped': 'no_such_msgs/msg/Thing'})
    out['missing'] = tmp_path / 'missing.mcap'
    return out


@pytest.mark.parametrize('kind, pattern', [
    ('empty', 'empty file'), ('garbage', 'not an MCAP file'), ('truncated', 'truncated'),
    ('not ROS 2', 'not a ROS 2 log'), ('unknown type', 'no_such_msgs/msg/Thing is not '
                                                       'installed'),
    ('missing', 'cannot read')])
def test_bad_files_one_line_error_exit_2(bad_files, kind, pattern, capsys):
    assert replay.main([str(bad_files[kind])]) == 2
    err = capsys.readouterr().err
    assert err.startswith('replay: error: ') and pattern in err
    assert len(err.strip().splitlines()) == 1 and 'Traceback' not in err


@pytest.mark.parametrize('args, pattern', [
    (['--rate', '0'], '--rate must be'), (['--topics', '/nope'], '--topics: not recorded'),
    (['--remap', '/nope:=/x'], '--remap: not recorded'), (['--remap', 'bad'], 'OLD:=NEW'),
    (['--start-offset', '99'], 'past the end')])
def test_bad_options_exit_2(mixed_log, args, pattern, capsys):
    assert replay.main([str(mixed_log[0])] + args) == 2
    err = capsys.readouterr().err
    assert err.startswith('replay: error: ') and pattern in err


def test_bad_file_subprocess(bad_files):
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    proc = subprocess.run([sys.executable, '-m', 'impact_damper_sim.ros.replay',
                           str(bad_files['garbage'])], capture_output=True, text=True,
                          timeout=60, env=env)
    assert proc.returncode == 2
    assert proc.stderr.startswith('replay: error: ') and 'Traceback' not in proc.stderr


# --- the executable ---------------------------------------------------------------------------

@pytest.mark.ros
def test_main_plays_and_exits_0(ros_context, mixed_log, monkeypatch, capfd):
    # the default context of main() joins this test's private domain
    monkeypatch.setenv('ROS_DOMAIN_ID', str(ros_context.get_domain_id()))
    path, entries, _ = mixed_log
    assert replay.main([str(path), '--rate', '50', '--no-clock', '--ros-args', '-r',
                        '__node:=replay_main']) == 0
    out, err = capfd.readouterr()
    assert 'Traceback' not in err
    # what plays, before it plays; what played, at the end (issue 38: it printed nothing)
    lines = out.splitlines()
    n_imu = sum(topic == '/accel/s1' for _, topic, _ in entries)
    assert lines[0].startswith(f'replay: playing {path}: {len(entries)} messages on 2 topic(s)')
    assert 'at rate 50 (real_time_factor 50' in lines[0]
    assert lines[1].split() == ['/accel/s1', 'sensor_msgs/msg/Imu', str(n_imu)]
    assert lines[2].split() == ['/impacts', 'geometry_msgs/msg/WrenchStamped',
                                str(len(entries) - n_imu)]
    assert lines[-1].startswith(f'replay: played {len(entries)} messages (1 pass(es)) in ')


@pytest.mark.ros
def test_process_loops_until_sigint(ros_context, tmp_path):
    """The real executable in its own process: it loops, and SIGINT ends it cleanly."""
    import signal
    entries = [(T0 + k * 10 * MS, '/impacts', impact(k)) for k in range(10)]
    path = tmp_path / 'short.mcap'
    write_log(path, entries, {'/impacts': EVENT_QOS})
    got = []
    listener = Node('listener', context=ros_context)
    listener.create_subscription(WrenchStamped, '/impacts', got.append, EVENT_QOS)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(listener)
    env = dict(os.environ, ROS_DOMAIN_ID=str(ros_context.get_domain_id()))
    proc = subprocess.Popen([sys.executable, '-m', 'impact_damper_sim.ros.replay', str(path),
                             '--loop', '--delay', '0.5'], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        def two_passes_seen():
            ids = [m.header.frame_id for m in got]
            first = next((i for i, f in enumerate(ids) if f.endswith('_0')), len(ids))
            return len(ids) >= max(25, first + 20)   # discovery may miss the first pass

        end = time.monotonic() + 20.0
        while not two_passes_seen() and time.monotonic() < end:
            executor.spin_once(timeout_sec=0.02)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
        executor.shutdown()
        listener.destroy_node()
    assert len(got) >= 25
    # every pass repeats the log: the impactor ids run 0..9 again and again
    ids = [int(m.header.frame_id.rsplit('_', 1)[1]) for m in got]
    first = ids.index(0)
    assert ids[first:first + 20] == list(range(10)) * 2
    assert proc.returncode == 0 and 'Traceback' not in err, err


def test_describe_names_file_topics_counts_duration_and_rate(mixed_log):
    from impact_damper_sim.ros.replay_plan import describe, prepare
    path, entries, _ = mixed_log
    plan = prepare(path, remaps=['/impacts:=/hits'], rate=2.0, start_offset=0.1)
    lines = describe(plan)
    span = (entries[-1][0] - entries[0][0]) * 1e-9 - 0.1   # s of log time after the offset
    head = lines[0]
    assert head.startswith(f'replay: playing {path}: {len(entries)} messages on 2 topic(s), ')
    assert f'{span:.6g} s of log time, at rate 2 (real_time_factor 2: {span / 2:.6g} s' in head
    assert head.endswith(', from 0.1 s on')
    n_impacts = sum(topic == '/impacts' for _, topic, _ in entries)
    assert lines[2].split() == ['/impacts', 'geometry_msgs/msg/WrenchStamped', str(n_impacts),
                                '->', '/hits']
