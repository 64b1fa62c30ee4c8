"""Command schedules and ``study record``: checked schedules, deterministic offline logs that
the node's readers read, and a live node playing the same schedule stepping the same samples.
"""
import json
import math
from collections import Counter

import numpy as np
import pytest

from impact_damper_sim.live.schedule import Schedule, ScheduleError
from impact_damper_sim.recording import node_topics as nt
from impact_damper_sim.recording.batches import rows_of, sample_times_ns
from impact_damper_sim.scene.schema import SceneError
from impact_damper_sim.scene.units import G0
from impact_damper_sim.studies.record import record_log

RPM = 2 * math.pi / 60
#: HPOTP (with its impactors): noise from the start, then the unbalance, a faster ramp to a
#: new speed, and the dampers off; every kind of entry
SCHEDULE = """\
schedule:
  - {at: 0 s, noise_std: 0.05 g, noise_seed: 3}
  - {at: 0.2 s, unbalance: 2.5}
  - {at: 0.3 s, speed_rate: 20000 rpm/s, speed: 20000 rpm}
  - {at: 0.6 s, dampers: false}
"""
DURATION = 0.8   # s of sim time


@pytest.fixture(scope='module')
def schedule_file(tmp_path_factory):
    path = tmp_path_factory.mktemp('schedule') / 'run.yaml'
    path.write_text(SCHEDULE)
    return path


@pytest.fixture(scope='module')
def recorded(schedule_file, tmp_path_factory):
    """Two offline recordings of the HPOTP with the schedule, and their results."""
    out = tmp_path_factory.mktemp('record')
    results = [record_log('hpotp', out / f'run{i}.mcap', DURATION, schedule=schedule_file,
                          seed=11) for i in range(2)]
    return [out / 'run0.mcap', out / 'run1.mcap'], results


def _messages(path, decode=False):
    """(topic, log_time, publish_time, data[, decoded]) of every message, in file order."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    with open(path, 'rb') as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        if decode:
            return [(c.topic, m.log_time, m.publish_time, bytes(m.data), d) for _, c, m, d
                    in reader.iter_decoded_messages(log_time_order=False)]
        return [(c.topic, m.log_time, m.publish_time, bytes(m.data)) for _, c, m
                in reader.iter_messages(log_time_order=False)]


def _channels(path):
    from mcap.reader import make_reader
    with open(path, 'rb') as f:
        summary = make_reader(f).get_summary()
    return {c.topic: c for c in summary.channels.values()}, summary


def _samples(path, topic='/accel/hpotp_casing_bottom/batch'):
    """Times (ns) and ax, ay, az (m/s^2) of an accelerometer's full-rate batches."""
    times, values = [], []
    for t, _, _, _, msg in _messages(path, decode=True):
        if t == topic:
            rows = rows_of(msg)
            times.append(sample_times_ns(msg, rows))
            values.append(np.stack([rows['ax'], rows['ay'], rows['az']], axis=1))
    return np.concatenate(times), np.concatenate(values)


# -- the schedule --------------------------------------------------------------------------

def test_a_schedule_is_read_in_si_and_sorted(schedule_file):
    sched = Schedule.load(schedule_file)
    assert [e.at for e in sched.entries] == [0.0, 0.2, 0.3, 0.6]
    assert sched.entries[0].commands == (('noise_std', 'parameter', 'noise_std', 0.05 * G0),
                                         ('noise_seed', 'parameter', 'noise_seed', 3))
    # a rate limit applies before the speed command it governs
    (k1, _, n1, rate), (k2, _, n2, speed) = sched.entries[2].commands
    assert (k1, n1, k2, n2) == ('speed_rate', 'speed_rate_limit', 'speed',
                                'rotor/speed_command')
    assert rate == pytest.approx(20000 * RPM) and speed == pytest.approx(20000 * RPM)
    assert sched.text == SCHEDULE


def test_every_problem_of_a_schedule_names_its_key(tmp_path):
    bad = tmp_path / 'bad.yaml'
    bad.write_text('schedule:\n'
                   '  - {at: -1 s, speed: 3000 furlongs}\n'
                   '  - {at: 1 s}\n'
                   '  - {at: 1 s, dampers: 3, noise_seed: -2, noise_std: 1 m}\n')
    with pytest.raises(ScheduleError) as info:
        Schedule.load(bad)
    lines = str(info.value).splitlines()
    assert lines[0] == f'invalid schedule {bad} (6 errors):'
    assert lines[1] == "key 'schedule[0].at': -1 s is out of range [0, 1000000] s"
    assert lines[2].startswith("key 'schedule[0].speed': unknown unit 'furlongs'")
    assert lines[3].startswith("key 'schedule[1]': an entry needs at least one of speed_rate")
    assert lines[4] == "key 'schedule[2].dampers': expected true or false, got int 3"
    assert lines[5] == ("key 'schedule[2].noise_std': unit 'm' is not an acceleration (it "
                        'is a length); use one of m/s^2, mm/s^2, g, mg, ug, in/s^2, ft/s^2')
    assert lines[6] == "key 'schedule[2].noise_seed': -2 is out of range [0, 2147483647]"


def test_a_schedule_file_of_the_wrong_shape_is_named_a_schedule(tmp_path):
    # A bare list (the entries without the `schedule:` key) was reported as "a scene must be
    # a mapping": the message names what the file is meant to be.
    bad = tmp_path / 'list.yaml'
    bad.write_text('- {at: 0.5 s, unbalance: 3}\n')
    with pytest.raises(SceneError) as info:
        Schedule.load(bad)
    assert str(info.value).startswith(f'{bad}: a schedule must be a mapping at top level; '
                                      'got list')
    (tmp_path / 'dir.yaml').mkdir()
    with pytest.raises(SceneError, match='not a schedule file'):
        Schedule.load(tmp_path / 'dir.yaml')


def test_entries_apply_at_the_next_sample_boundary():
    from impact_damper_sim.live.schedule import Entry
    cmd = (('unbalance', 'topic', 'rotor/unbalance_command', 1.0),)
    sched = Schedule([Entry(0.01234, cmd), Entry(0.0, cmd), Entry(0.02, cmd)])
    fs = 1000.0
    assert [e.at for e in sched.due(0.0, fs)] == [0.0]
    assert sched.samples_to_next(0.0, fs) == 13          # 12.34 ms -> the 13th sample
    assert sched.due(0.012, fs) == []
    assert [e.at for e in sched.due(0.013, fs)] == [0.01234]
    assert sched.samples_to_next(0.013, fs) == 7         # 20 ms is a boundary itself
    assert [e.at for e in sched.due(0.02, fs)] == [0.02] and sched.done
    assert sched.samples_to_next(0.02, fs) is None


def test_a_schedule_the_scene_cannot_take_is_refused_before_the_run(schedule_file, tmp_path):
    out = tmp_path / 'sdof.mcap'
    with pytest.raises(ScheduleError) as info:
        record_log('sdof', out, 0.1, schedule=schedule_file)
    text = str(info.value)
    assert "schedule[1].unbalance (at 0.2 s): scene 'sdof' has no rotor unbalance" in text
    assert "schedule[2].speed (at 0.3 s): scene 'sdof' has no commanded rotor" in text
    assert not out.exists()


# -- study record ----------------------------------------------------------------------------

def test_recording_twice_gives_the_same_message_bytes(recorded):
    (a, b), results = recorded
    first, second = _messages(a), _messages(b)
    assert len(first) == results[0]['messages'] > 1000
    assert first == second   # topics, log and publish times, CDR bytes, order


def test_the_schedule_is_applied_and_logged_as_commands_and_parameter_changes(recorded):
    (path, _), results = recorded
    msgs = _messages(path, decode=True)
    counts = Counter(m[0] for m in msgs)
    assert counts['/rotor/speed_command'] == counts['/rotor/unbalance_command'] == 1
    assert counts['/parameter_events'] == 4   # noise_std, noise_seed, speed_rate, dampers
    assert results[0]['commands'] == 6
    events = [(m[1] * 1e-9, p.name, p.value) for m in msgs if m[0] == '/parameter_events'
              for p in m[4].changed_parameters]
    assert [(t, name) for t, name, _ in events] == [
        (0.0, 'noise_std'), (0.0, 'noise_seed'), (pytest.approx(0.3), 'speed_rate_limit'),
        (pytest.approx(0.6), 'dampers_enabled')]
    assert events[0][2].double_value == pytest.approx(0.05 * G0)
    assert events[1][2].integer_value == 3 and events[3][2].bool_value is False
    speed_cmd = next(m for m in msgs if m[0] == '/rotor/speed_command')
    assert speed_cmd[1] == pytest.approx(0.3e9) and speed_cmd[4].data == pytest.approx(
        20000 * RPM)
    # the physics: from 0.3 s the speed ramps at the new rate towards the new target
    speed = [(m[1] * 1e-9, m[4].vector) for m in msgs if m[0] == '/rotor/speed']
    ramp = [(t, v) for t, v in speed if 0.31 <= t <= 0.5]
    assert all(v.y == pytest.approx(20000 * RPM) for _, v in ramp)
    (t0, v0), (t1, v1) = ramp[0], ramp[-1]
    assert (v1.x - v0.x) / (t1 - t0) == pytest.approx(20000 * RPM, rel=1e-9)
    assert all(v.z == 2.5 for t, v in speed if t > 0.2)   # the unbalance multiplier
    # the noise variance is in every Imu from the start: the channel's (its sensor and DAQ
    # noise, and the 0.05 g, through the 2 -> 1 kHz decimation, which keeps sum(taps^2) =
    # 0.4404 of a white noise); the dampers stop hitting at 0.6 s
    from impact_damper_sim.live.realtime import LiveSimulation
    from impact_damper_sim.live.streams import live_scene
    model, target = live_scene('hpotp')
    variance = LiveSimulation(model, initial_target=target,
                              noise_std=0.05 * G0).imu_noise_variances()[0]
    assert variance == pytest.approx((0.05 * G0) ** 2 * 0.4404, rel=0.02)   # the 0.05 g rules
    imu = [m[4] for m in msgs if m[0] == '/accel/hpotp_casing_bottom']
    assert all(msg.linear_acceleration_covariance[0] == variance for msg in imu)
    impacts = [(m[1] * 1e-9, m[4].width) for m in msgs if m[0] == '/impacts']
    assert sum(w for t, w in impacts if t <= 0.6 + 1e-9) > 100
    assert sum(w for t, w in impacts if t > 0.6 + 1e-9) == 0


def test_the_log_has_the_nodes_topics_types_and_qos(recorded):
    pytest.importorskip('rclpy')
    from impact_damper_sim.recording.bag_metadata import qos_dict
    from impact_damper_sim.ros import interface as itf
    (path, _), _ = recorded
    channels, summary = _channels(path)
    expect = {'/accel/hpotp_casing_bottom': ('sensor_msgs/msg/Imu', itf.SENSOR_QOS),
              '/accel/hpotp_casing_bottom/batch': ('sensor_msgs/msg/PointCloud2',
                                                   itf.BATCH_QOS),
              '/impacts': ('sensor_msgs/msg/PointCloud2', itf.EVENT_QOS),
              '/impactor_state': ('sensor_msgs/msg/JointState', itf.LATCHED_QOS),
              '/rotor/speed': ('geometry_msgs/msg/Vector3Stamped', itf.COMMAND_QOS),
              '/rotor/joint_states': ('sensor_msgs/msg/JointState', itf.COMMAND_QOS),
              '/rotor/tach': ('sensor_msgs/msg/PointCloud2', itf.BATCH_QOS),
              '/rotor/keyphasor': ('sensor_msgs/msg/PointCloud2', itf.EVENT_QOS),
              '/clock': ('rosgraph_msgs/msg/Clock', itf.CLOCK_QOS),
              '/rotor/speed_command': ('std_msgs/msg/Float64', itf.COMMAND_QOS),
              '/rotor/unbalance_command': ('std_msgs/msg/Float64', itf.COMMAND_QOS),
              '/parameter_events': ('rcl_interfaces/msg/ParameterEvent',
                                    itf.PARAMETER_EVENTS_QOS)}
    assert set(channels) == set(expect)
    schemas = summary.schemas
    for topic, (type_name, qos) in expect.items():
        channel = channels[topic]
        assert schemas[channel.schema_id].name == type_name and \
            channel.message_encoding == 'cdr'
        assert channel.metadata['topic_type_hash'].startswith('RIHS01_')
        import yaml
        offered = yaml.safe_load(channel.metadata['offered_qos_profiles'])
        want = qos_dict(qos)
        assert {k: offered[0][k] for k in ('history', 'depth', 'reliability', 'durability')} \
            == {k: want[k] for k in ('history', 'depth', 'reliability', 'durability')}, topic


def test_every_message_reads_with_rosbags_mcap_ros2_and_rclpy(recorded):
    """The node's readers (test_node_recording.py, test_cdr.py) read the offline log."""
    pytest.importorskip('rclpy')
    pytest.importorskip('rosbags')
    from rclpy.serialization import deserialize_message
    from rosbags.highlevel import AnyReader

    # the replay's own type lookup (rosidl_runtime_py comes only with the ROS 2 command line)
    from impact_damper_sim.ros.replay_plan import message_class
    (path, _), _ = recorded
    ours = _messages(path, decode=True)
    with AnyReader([path]) as reader:
        bag = [(c.topic, raw, reader.deserialize(raw, c.msgtype)) for c, _, raw
               in reader.messages()]
    assert sorted((t, r) for t, r, _ in bag) == sorted((m[0], m[3]) for m in ours)
    by_bytes = {(t, r): msg for t, r, msg in bag}
    for topic, _, _, data, decoded in ours:
        via_bag = by_bytes[(topic, data)]
        type_name = via_bag.__msgtype__
        native = deserialize_message(data, message_class(type_name))
        stamp = getattr(getattr(native, 'header', None), 'stamp', None)
        if stamp is not None:   # the three readers agree on the stamp and the frame
            assert (stamp.sec, stamp.nanosec) == (via_bag.header.stamp.sec,
                                                  via_bag.header.stamp.nanosec) == (
                decoded.header.stamp.sec, decoded.header.stamp.nanosec)
            assert native.header.frame_id == via_bag.header.frame_id == \
                decoded.header.frame_id


def test_replay_plans_the_log_and_report_counts_the_commands(recorded):
    pytest.importorskip('rclpy')
    from impact_damper_sim.ros.replay_plan import prepare
    from impact_damper_sim.studies.report import analyze
    (path, _), results = recorded
    plan = prepare(path)
    assert not plan.warnings and not any(t.warnings for t in plan.tracks)
    topics = {t.topic for t in plan.tracks}
    assert {'/clock', '/rotor/speed_command', '/parameter_events'} <= topics
    report, _ = analyze(path)
    counts = {t['topic']: t['count'] for t in report['topics']}
    assert counts['/rotor/speed_command'] == 1 and counts['/parameter_events'] == 4
    assert report['impacts'][0]['count'] == results[0]['impacts']
    sensor = report['sensors'][0]
    assert sensor['samples'] == results[0]['samples'] == round(DURATION * 2000)
    assert sensor['peak_g']['magnitude'] == pytest.approx(results[0]['peak_g'], rel=0.8)


def test_summary_labels_match_the_log(recorded):
    (path, _), results = recorded
    r = results[0]
    t, values = _samples(path)
    assert r['peak_g'] == pytest.approx(np.max(np.abs(values)) / G0, rel=1e-12)
    assert r['rms_g'] == pytest.approx(np.sqrt(np.mean(values ** 2)) / G0, rel=1e-9)
    assert r['impacts_per_s'] == pytest.approx(r['impacts'] / DURATION)
    assert 0.0 <= r['stuck_fraction'] <= 1.0 and not r['diverged']
    assert r['sim_time_s'] == pytest.approx(DURATION)
    assert np.all(np.diff(t) == 500_000)   # every 2 kHz sample once, in order


# -- the command line --------------------------------------------------------------------------

def test_study_record_command(tmp_path, capsys, schedule_file):
    from impact_damper_sim.cli.study import main
    out = tmp_path / 'cli.mcap'
    assert main(['record', 'hpotp', '--duration', '100 ms', '--out', str(out), '--schedule',
                 str(schedule_file), '--seed', '4', '--json', '--progress']) == 0
    captured = capsys.readouterr()
    result = json.loads(captured.out)
    assert result['sim_time_s'] == pytest.approx(0.1) and result['commands'] == 2
    assert 'record' in captured.err and '100.0 %' in captured.err and 'x real time' in \
        captured.err
    before = out.read_bytes()
    assert main(['record', 'hpotp', '--duration', '0.1', '--out', str(out)]) == 2
    assert 'exists; pass --overwrite' in capsys.readouterr().err
    assert out.read_bytes() == before
    assert main(['record', 'hpotp', '--duration', '0.05', '--out', str(out),
                 '--overwrite', '--noise-std', '1 furlong']) == 2
    assert "--noise-std" in capsys.readouterr().err
    assert main(['record', 'hpotp', '--duration', '0.05', '--out', str(out),
                 '--overwrite']) == 0
    assert 'x real time' in capsys.readouterr().out


def _metadata(path):
    from mcap.reader import make_reader
    with open(path, 'rb') as f:
        return {m.name: dict(m.metadata) for m in make_reader(f).iter_metadata()}


def test_study_record_tick_period_batches_the_same_samples(tmp_path, capsys):
    """--tick-period 100ms: full-rate batches of 200 samples (HPOTP, 2000 Hz) instead of 20,
    the same samples and time stamps when concatenated, the per-sample Imu stream unchanged.

    The first 0.2 s of the ramp has no impacts: the response is linear, and the chunk split
    changes it by rounding only (~1e-14 of the peak). With impacts the rounding at a chunk
    boundary is amplified from impact to impact (about a decade per 5 ms at a fast ramp),
    so another tick_period gives other samples of the same dynamics (docs/study.md)."""
    import yaml

    from impact_damper_sim.cli.study import main
    logs, results = {}, {}
    for name, extra in (('default', []), ('coarse', ['--tick-period', '100ms'])):
        logs[name] = tmp_path / f'{name}.mcap'
        assert main(['record', 'hpotp', '--duration', '0.2', '--out', str(logs[name]),
                     '--json', *extra]) == 0
        results[name] = json.loads(capsys.readouterr().out)
        assert results[name]['sim_time_s'] == pytest.approx(0.2)
    topic = '/accel/hpotp_casing_bottom/batch'
    widths = {name: [m[4].width for m in _messages(path, decode=True) if m[0] == topic]
              for name, path in logs.items()}
    assert widths == {'default': [20] * 20, 'coarse': [200] * 2}
    t_fine, a_fine = _samples(logs['default'])
    t_coarse, a_coarse = _samples(logs['coarse'])
    np.testing.assert_array_equal(t_coarse, t_fine)   # every sample once, the same stamps
    assert t_fine.size == 400 and np.max(np.abs(a_fine)) > 0
    # 1e-9 of the peak: the same steps, a chunk split elsewhere may sum in another order
    assert np.max(np.abs(a_coarse - a_fine)) <= 1e-9 * np.max(np.abs(a_fine))
    assert results['coarse']['impacts'] == results['default']['impacts'] == 0
    # the per-sample Imu stream: the same messages at the same log times and stamps, the
    # same values to rounding (its decimation filter runs across the chunks)
    imu = {name: [m for m in _messages(path, decode=True) if m[0] == '/accel/hpotp_casing_bottom']
           for name, path in logs.items()}
    assert len(imu['default']) == len(imu['coarse']) > 100

    def stamps(msgs):
        return [(m[1], m[2], m[4].header.stamp.sec, m[4].header.stamp.nanosec) for m in msgs]

    def values(msgs):
        return np.array([[m[4].linear_acceleration.x, m[4].linear_acceleration.y,
                          m[4].linear_acceleration.z] for m in msgs])

    assert stamps(imu['coarse']) == stamps(imu['default'])
    fine_imu = values(imu['default'])
    assert np.max(np.abs(values(imu['coarse']) - fine_imu)) <= 1e-9 * np.max(np.abs(fine_imu))
    params = {name: yaml.safe_load(_metadata(path)['impact_damper_sim']['node_parameters'])
              for name, path in logs.items()}
    assert params['default']['tick_period'] == 0.01 and params['coarse']['tick_period'] == 0.1


@pytest.mark.parametrize('value', ['0', '0.5', 'abc', '5 kg'])
def test_study_record_refuses_a_tick_period_out_of_the_nodes_range(tmp_path, capsys, value):
    from impact_damper_sim.cli.study import main
    out = tmp_path / 'bad.mcap'
    assert main(['record', 'hpotp', '--duration', '0.1', '--out', str(out),
                 '--tick-period', value]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1, err
    assert err.startswith('study: error: --tick-period: ') and '[0.001, 0.1] s' in err, err
    assert not out.exists()


def test_record_log_checks_its_tick_period(tmp_path):
    out = tmp_path / 'bad.mcap'
    for value in (0.0005, 0.2, math.nan, 'x', True):
        with pytest.raises(SceneError, match=r'^tick_period: .* is out of range '
                                             r'\[0\.001, 0\.1\] s$'):
            record_log('sdof', out, 0.1, tick_period=value)
    assert not out.exists()


# -- a live node with the same schedule ----------------------------------------------------------

def test_a_live_node_playing_the_schedule_steps_the_same_samples(recorded, schedule_file,
                                                                ros_context, tmp_path):
    """The node at real time (a fake wall clock driving tick()) and study record give the
    same full-rate samples and the same command and parameter-change messages."""
    pytest.importorskip('rclpy')
    from rclpy.parameter import Parameter

    from impact_damper_sim.ros.vibration_node import VibrationNode

    class Clock:
        now = 1000.0

        def __call__(self):
            return self.now

    live_log = tmp_path / 'live.mcap'
    clock = Clock()
    node = VibrationNode(context=ros_context, start_stepping=False, clock=clock,
                         parameter_overrides=[
                             Parameter('scene', value='hpotp'),
                             Parameter('noise_seed', value=11),
                             Parameter('schedule', value=str(schedule_file)),
                             Parameter('record', value=str(live_log))])
    clock.now += 1e-7   # 80 steps of 0.01 s add up to just under 0.8 s in binary
    try:
        for _ in range(int(round(DURATION / 0.01))):
            clock.now += 0.01
            node.tick()
        assert node.live.t == pytest.approx(DURATION)
        node.stop()
        node.stop_recording()
    finally:
        node.destroy_node()
    (offline, _), _ = recorded
    t_live, a_live = _samples(live_log)
    t_off, a_off = _samples(offline)
    np.testing.assert_array_equal(t_live, t_off)
    # the integrator's tolerance: the same steps in the same order; 1e-9 of the peak allows
    # a different summation order in a chunk split elsewhere
    assert np.max(np.abs(a_live - a_off)) <= 1e-9 * np.max(np.abs(a_off))
    commands = {'/rotor/speed_command', '/rotor/unbalance_command', '/parameter_events'}

    def logged(path):
        return sorted((m[0], m[1], m[3]) for m in _messages(path) if m[0] in commands)

    assert logged(live_log) == logged(offline) and len(logged(offline)) == 6
    # the other streams carry the same bytes too (the node's log adds /diagnostics and
    # republishes impactor_state on its timer)
    for topic in ('/impacts', '/rotor/speed', '/accel/hpotp_casing_bottom'):
        live = [m[3] for m in _messages(live_log) if m[0] == topic]
        off = [m[3] for m in _messages(offline) if m[0] == topic]
        assert live == off, topic


def test_the_node_refuses_a_schedule_its_scene_cannot_take(ros_context, schedule_file):
    pytest.importorskip('rclpy')
    from rclpy.parameter import Parameter

    from impact_damper_sim.ros.vibration_node import VibrationNode
    from impact_damper_sim.scene.schema import SceneError
    with pytest.raises(SceneError, match=r"(?s)parameter 'schedule'.*sdof.*no rotor unbalance"):
        VibrationNode(context=ros_context, start_stepping=False, parameter_overrides=[
            Parameter('scene', value='sdof'), Parameter('schedule', value=str(schedule_file))])


def test_a_live_speed_rate_change_is_applied_and_logged(ros_context, tmp_path):
    """speed_rate_limit is dynamic now: the ramp under way continues at the new rate, and
    the change is in the log as a ParameterEvent at its sim time."""
    pytest.importorskip('rclpy')
    from rclpy.parameter import Parameter

    from impact_damper_sim.ros.vibration_node import VibrationNode
    path = tmp_path / 'rate.mcap'
    node = VibrationNode(context=ros_context, start_stepping=False, parameter_overrides=[
        Parameter('scene', value='hpotp'), Parameter('overrides', value=['impactors=[]']),
        Parameter('real_time_factor', value=0.0), Parameter('record', value=str(path))])
    try:
        start = node.live.profile.max_rate
        node.tick()
        assert node.set_parameters([Parameter('speed_rate_limit', value=2 * start)])[
            0].successful
        assert node.live.rotor_state()[1] == pytest.approx(2 * start)   # the ramp goes on
        assert node.set_parameters([Parameter('speed_rate_limit', value=0.0)])[0].successful
        assert node.live.profile.max_rate == start   # 0: back to the rate at start
        node.stop_recording()
    finally:
        node.destroy_node()
    events = [m[4] for m in _messages(path, decode=True) if m[0] == nt.PARAMETER_EVENTS]
    assert [(e.changed_parameters[0].name, e.changed_parameters[0].value.double_value)
            for e in events] == [('speed_rate_limit', 2 * start), ('speed_rate_limit', 0.0)]
    assert all(e.node == '/vibration_node' for e in events)


@pytest.mark.ros
def test_replay_plays_the_recorded_commands_with_clock(ros_context, recorded):
    """``replay`` publishes the offline log's commands, byte for byte, under its /clock."""
    pytest.importorskip('rclpy')
    from rclpy.qos import QoSProfile
    from rclpy.serialization import deserialize_message
    from rosgraph_msgs.msg import Clock
    from std_msgs.msg import Float64

    from impact_damper_sim.ros import interface as itf
    from impact_damper_sim.ros import replay_plan
    from test_replay import run_replay
    (path, _), _ = recorded
    commands = [m for m in _messages(path) if m[0] in ('/rotor/speed_command',
                                                      '/rotor/unbalance_command')]
    plan = replay_plan.prepare(path, topics=['rotor/speed_command', 'rotor/unbalance_command'],
                               rate=4.0)
    arrivals, stats, node = run_replay(
        ros_context, plan, [(Float64, '/rotor/speed_command', itf.COMMAND_QOS),
                            (Float64, '/rotor/unbalance_command', itf.COMMAND_QOS),
                            (Clock, '/clock', QoSProfile(depth=100))],
        len(commands) + 5, clock_hz=200.0)
    node.destroy_node()
    got = [(a[0], a[2]) for a in arrivals if a[0] != '/clock']
    assert got == [(m[0], m[3]) for m in commands]
    ticks = [deserialize_message(a[2], Clock).clock for a in arrivals if a[0] == '/clock']
    ns = [c.sec * 1_000_000_000 + c.nanosec for c in ticks]
    assert ns and all(b >= a for a, b in zip(ns, ns[1:]))
    assert ns[-1] == commands[-1][1]   # the log's sim time, up to the last command replayed
