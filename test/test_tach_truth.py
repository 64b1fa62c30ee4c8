"""The tachometer, the ground truth and the run's labels (issue 36 items 4 and 5).

``rotor/tach`` carries the rotor angle the unbalance force uses at every full-rate sample and
``rotor/keyphasor`` the times it reaches whole turns; ``accel/<name>/truth`` the model's
acceleration before the channel; the log's metadata the labels a detector is scored with.
Each is read back from the bytes the node and ``study record`` write (rclpy here; rosbags and
mcap_ros2 in test_streams.py and test_record.py), and checked against the model.
"""
import math

import numpy as np
import pytest
import yaml

from impact_damper_sim.live.realtime import LiveSimulation
from impact_damper_sim.live.streams import live_scene
from impact_damper_sim.recording import node_topics as nt
from impact_damper_sim.recording.batches import rows_of, sample_times_ns
from impact_damper_sim.recording.node_messages import NodeMessages
from impact_damper_sim.scene.excitation import (
    CommandedSpeed,
    ConstantSpeed,
    PaperRamp,
    PiecewiseLinearSpeed,
)
from impact_damper_sim.studies.record import record_log

TWO_PI = 2.0 * math.pi


# -- the keyphasor's solver ---------------------------------------------------------------------

def _commanded():
    """Up at 400 rad/s^2, down, a stop and a restart: every kind of segment."""
    p = CommandedSpeed(0.0, 400.0)
    p.command(0.0, 300.0)
    p.command(1.5, 120.0)
    p.command(3.0, 0.0)
    p.command(4.0, 200.0)
    return p


@pytest.mark.parametrize('profile', [PaperRamp(2400.0, 5.0), ConstantSpeed(100.0),
                                     PiecewiseLinearSpeed([0, 1, 2, 3], [0, 50, 50, 10]),
                                     CommandedSpeed(30.0, 10.0, t0=0.5), _commanded()],
                         ids=['ramp', 'constant', 'piecewise', 'held_then_commanded',
                              'commanded'])
def test_time_at_angle_is_where_the_angle_first_reaches_it(profile):
    end = float(profile.angle(12.0))
    angles = TWO_PI * np.arange(1, int(end // TWO_PI) + 1)
    assert angles.size > 10
    t = profile.time_at_angle(angles)
    np.testing.assert_allclose(profile.angle(t), angles, rtol=0, atol=1e-9 * end)
    assert np.all(np.diff(t) > 0)
    assert np.all(profile.angle(t - 1e-6) < angles)   # the first time: below just before
    stopped = _commanded()
    assert stopped.time_at_angle(float(stopped.angle(3.5))) <= 3.5   # held at 0 rad/s


# -- a live run, packed as the node packs it ----------------------------------------------------

def _pointcloud(data):
    pytest.importorskip('rclpy')
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import PointCloud2
    return deserialize_message(data, PointCloud2)


def _step(scene, overrides, chunks, commands=None, truth=False, spy=False, n=20):
    """Step a live scene ``chunks`` chunks of ``n`` samples and pack them with NodeMessages.

    ``commands``: {chunk index: callable(live)} applied before that chunk. ``spy``: record
    every (t, forces) the integrator asks the unbalance for. Returns the simulation, the bytes
    per topic (relative names), the batches and the spied forces.
    """
    model, target = live_scene(scene, overrides)
    live = LiveSimulation(model, initial_target=target)
    messages = NodeMessages(live, model, truth=truth)
    forces = []
    if spy:
        model_forces = live.unbalance.forces

        def recorded(t, n_inputs=None):
            out = model_forces(t, n_inputs)
            forces.append((np.array(t, dtype=float, copy=True), out.copy()))
            return out
        live.unbalance.forces = recorded
    topics, batches = {}, []
    for k in range(chunks):
        if commands and k in commands:
            commands[k](live)
        batch = live.step(n)
        batches.append(batch)
        for _, stream, data in messages.batch_items(batch) + messages.time_items():
            topics.setdefault(messages.streams[stream].topic.lstrip('/'), []).append(data)
    return live, topics, batches, forces


def _rows(datas):
    """Every row of a list of batch bytes, with their absolute times (ns) and the stamps."""
    msgs = [_pointcloud(d) for d in datas]
    rows = [rows_of(m) for m in msgs]
    times = np.concatenate([sample_times_ns(m, r) for m, r in zip(msgs, rows)])
    stamps = [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in msgs]
    return np.concatenate(rows), times, msgs, stamps


#: HPOTP without its impactors (the tachometer does not depend on them): its ramp from rest,
#: then a faster ramp up, a ramp down, more unbalance, each at a chunk boundary
COMMANDS = {30: lambda live: live.set_speed_rate(4000.0),
            31: lambda live: live.command_speed(900.0),
            60: lambda live: live.command_speed(300.0),
            70: lambda live: live.command_unbalance(2.5)}


@pytest.fixture(scope='module')
def hpotp_run():
    return _step('hpotp', ['impactors=[]'], 100, COMMANDS, spy=True)


def test_tach_is_the_angle_whose_derivative_is_the_published_speed(hpotp_run):
    live, topics, batches, _ = hpotp_run
    rows, t_ns, msgs, _ = _rows(topics[nt.ROTOR_TACH])
    assert all(m.header.frame_id == 'hpotp_rotor' and m.point_step == 24 for m in msgs)
    assert [f.name for f in msgs[0].fields] == ['t', 'angle', 'speed']
    # the accelerometer batch's sample times, every one once
    _, batch_ns, _, _ = _rows(topics[nt.accel_batch_topic(live.accelerometers[0].name)])
    np.testing.assert_array_equal(t_ns, batch_ns)
    angle, speed = rows['angle'], rows['speed']
    t = np.concatenate([b.t for b in batches])
    np.testing.assert_array_equal(angle, live.profile.angle(t))   # phi(t), unwrapped
    assert np.all(np.diff(angle) >= 0) and angle[-1] > 50 * TWO_PI
    # d(angle)/dt = speed: a step's increment is the trapezoid of the speed, exact for a
    # speed linear over the step; a knot inside a step (a ramp's start or end) leaves at most
    # |slope change| dt^2 / 8
    dt = np.diff(t)
    error = np.abs(np.diff(angle) - 0.5 * (speed[1:] + speed[:-1]) * dt)
    assert np.all(error <= 2 * 4000.0 * dt ** 2 / 8 + 1e-9)
    assert np.count_nonzero(error > 1e-9) <= 6   # the knots only
    # the published speed of rotor/speed and the angle of rotor/joint_states at each chunk end
    from geometry_msgs.msg import Vector3Stamped
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import JointState
    ends = [sample_times_ns(m)[-1] for m in msgs]
    at_end = np.searchsorted(t_ns, ends)
    published = [deserialize_message(d, Vector3Stamped) for d in topics[nt.ROTOR_SPEED]]
    assert [v.header.stamp.sec * 10**9 + v.header.stamp.nanosec for v in published] == ends
    np.testing.assert_array_equal([v.vector.x for v in published], speed[at_end])
    joints = [deserialize_message(d, JointState) for d in topics[nt.ROTOR_JOINT_STATES]]
    np.testing.assert_array_equal([j.position[0] for j in joints],
                                  np.mod(angle[at_end], TWO_PI))


def test_keyphasor_times_are_where_phi_crosses_2_pi_k(hpotp_run):
    live, topics, _, _ = hpotp_run
    rows, t_ns, msgs, stamps = _rows(topics[nt.ROTOR_KEYPHASOR])
    tach, tach_ns, _, _ = _rows(topics[nt.ROTOR_TACH])
    assert [f.name for f in msgs[0].fields] == ['t', 'revolution', 'speed']
    # one batch per chunk, tiling sim time from 0; each turn in the batch of its interval
    ends = [int(sample_times_ns(m)[-1]) for m in _rows(topics[nt.ROTOR_TACH])[2]]
    assert len(ends) == 100 and stamps == [0] + ends[:-1]
    n = int(tach['angle'][-1] // TWO_PI)
    np.testing.assert_array_equal(rows['revolution'], np.arange(1, n + 1))
    for m, start, end in zip(msgs, stamps, ends):
        r = rows_of(m)
        assert np.all((r['t'] >= 0) & (r['t'] <= (end - start) * 1e-9))
    # the exact crossings: the float times (stamp + t), on the model's profile
    t = np.concatenate([m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 + rows_of(m)['t']
                        for m in msgs])
    target = TWO_PI * rows['revolution']
    np.testing.assert_allclose(live.profile.angle(t), target, rtol=0, atol=1e-9)
    np.testing.assert_allclose(rows['speed'], live.profile.speed(t), rtol=1e-12)
    # ... and bracketed by the published angle: below it before, reached at the next sample
    after = np.searchsorted(tach_ns, t_ns, side='left')
    assert np.all(tach['angle'][after] >= target - 1e-9)
    assert np.all(tach['angle'][after - 1] < target)


def test_the_unbalance_force_from_the_published_angle_is_the_models(hpotp_run):
    """F_y = X m e (phi'^2 cos(phi + p) + phi'' sin(phi + p)), F_z = X m e (phi'^2 sin(phi
    + p) - phi'' cos(phi + p)) with phi, phi' and phi'' (the difference of phi') read from
    rotor/tach, X from rotor/speed, m e and p from the scene: the forces the integrator was
    given at the same times. Left out: the samples where phi'' jumps (a command, a ramp's end:
    its differences before and after differ), which have two phi''."""
    from geometry_msgs.msg import Vector3Stamped
    from rclpy.serialization import deserialize_message
    live, topics, batches, forces = hpotp_run
    rows, _, msgs, _ = _rows(topics[nt.ROTOR_TACH])
    t = np.concatenate([b.t for b in batches])
    x = np.repeat([deserialize_message(d, Vector3Stamped).vector.z
                   for d in topics[nt.ROTOR_SPEED]], [m.width for m in msgs])
    assert x[0] == 1.0 and x[-1] == 2.5
    asked_t = np.concatenate([f[0] for f in forces])
    asked = np.concatenate([f[1] for f in forces])
    first = {v: i for i, v in reversed(list(enumerate(asked_t.tolist())))}
    model = asked[[first[v] for v in t.tolist()]]   # every sample time was asked for
    phi, w = rows['angle'], rows['speed']
    slope = np.diff(w) / np.diff(t)
    alpha = np.concatenate([[np.nan], slope])   # phi'', the difference before each sample
    keep = np.concatenate([[False], np.abs(slope[1:] - slope[:-1]) < 1e-6, [False]])
    assert np.count_nonzero(~keep) <= 12
    unbalance = live.scene.scene['rotor']['unbalance']
    assert len(unbalance) == 2
    for u, (iy, iz) in zip(unbalance, live.unbalance.input_pairs):
        angle = phi + u['phase']
        a = x * u['amount']
        fy = a * (w * w * np.cos(angle) + alpha * np.sin(angle))
        fz = a * (w * w * np.sin(angle) - alpha * np.cos(angle))
        scale = np.max(np.abs(model[:, iy]))
        assert scale > 100.0   # N: the forces are there
        np.testing.assert_allclose(fy[keep], model[keep, iy], rtol=0, atol=1e-12 * scale)
        np.testing.assert_allclose(fz[keep], model[keep, iz], rtol=0, atol=1e-12 * scale)


def test_only_scenes_with_a_rotor_have_a_tachometer():
    model, _ = live_scene('sdof')
    messages = NodeMessages(LiveSimulation(model), model)
    assert messages.tach is None and messages.keyphasor is None
    assert not [s for s in messages.streams if s.topic in ('/rotor/tach', '/rotor/keyphasor')]
    batch = messages.live.step(20)
    assert batch.shaft_angle is None and batch.keyphasor is None
    items = messages.batch_items(batch)
    assert items and not [i for _, i, _ in items if messages.streams[i].topic.startswith(
        '/rotor/')]


# -- ground truth -------------------------------------------------------------------------------

def test_with_the_ideal_channel_the_truth_is_the_batch_byte_for_byte():
    live, topics, batches, _ = _step('sdof', ['channel=ideal'], 20, truth=True)
    name = live.accelerometers[0].name
    truth, batch = topics[nt.accel_truth_topic(name)], topics[nt.accel_batch_topic(name)]
    assert len(truth) == 20 and truth == batch
    assert all(np.array_equal(b.truth, b.linear_acceleration) for b in batches)
    assert np.max(np.abs(batches[-1].truth)) > 1.0   # m/s^2: a signal, not zeros


def test_with_a_channel_the_truth_differs_by_it():
    """A sensitivity error of (5, -3, 2) %: the samples are the truth scaled per axis. The
    scene's preset (a 10 mV/g IEPE sensor on a 24-bit DAQ): the samples are on the ADC's grid
    and near the truth, the truth is not on it."""
    live, topics, batches, _ = _step(
        'sdof', ['channel={preset: ideal, sensitivity_error: [0.05, -0.03, 0.02]}'], 20,
        truth=True)
    name = live.accelerometers[0].name
    rows, _, msgs, _ = _rows(topics[nt.accel_truth_topic(name)])
    samples, _, batch_msgs, _ = _rows(topics[nt.accel_batch_topic(name)])
    assert [m.header.frame_id for m in msgs] == [m.header.frame_id for m in batch_msgs]
    for axis, gain in zip(('ax', 'ay', 'az'), (1.05, 0.97, 1.02)):
        np.testing.assert_allclose(samples[axis], gain * rows[axis], rtol=1e-12, atol=1e-300)
    for axis in ('t', 'wx', 'wy', 'wz'):
        np.testing.assert_array_equal(samples[axis], rows[axis])
    live, topics, _, _ = _step('sdof', [], 50, truth=True)
    assert live.channels[0].spec['preset'] == 'iepe_10mv_500g'
    truth, _, _, _ = _rows(topics[nt.accel_truth_topic(name)])
    samples, _, _, _ = _rows(topics[nt.accel_batch_topic(name)])
    lsb = live.channels[0].lsb
    a, b = samples['ay'], truth['ay']
    assert np.max(np.abs(a / lsb - np.round(a / lsb))) < 1e-6
    assert np.mean(np.abs(b / lsb - np.round(b / lsb)) > 0.01) > 0.9
    difference = np.sqrt(np.mean((a - b) ** 2) / np.mean(b ** 2))
    assert 1e-4 < difference < 0.1, difference


# -- the node and study record --------------------------------------------------------------------

def _log(path):
    """(topic -> [message bytes]) and the impact_damper_sim metadata of a log."""
    from mcap.reader import make_reader
    topics = {}
    with open(path, 'rb') as f:
        reader = make_reader(f)
        meta = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        for _, channel, message in reader.iter_messages(log_time_order=False):
            topics.setdefault(channel.topic, []).append(bytes(message.data))
    return topics, meta['impact_damper_sim']


@pytest.mark.ros
def test_the_node_and_study_record_write_the_same_truth_tach_and_labels(ros_context, tmp_path):
    """The node on a fake clock with publish_truth and study record --truth, same seed and
    noise: the same bytes on every topic of items 4 and 5 and the same labels; without
    publish_truth the node has no truth topic, and its labels say what it started with."""
    pytest.importorskip('rclpy')
    from node_helpers import make_node
    live_log, offline = tmp_path / 'live.mcap', tmp_path / 'offline.mcap'
    node = make_node(ros_context, 'hpotp', publish_truth=True, noise_seed=5, noise_std=0.05,
                     record=str(live_log))
    node._wall.now += 1e-7   # 30 steps of 0.01 s add up to just under 0.3 s in binary
    try:
        for _ in range(30):
            node._wall.now += 0.01
            node.tick()
        assert node.live.t == pytest.approx(0.3)
        node.stop()
        node.stop_recording()
    finally:
        node.destroy_node()
    record_log('hpotp', offline, 0.3, seed=5, noise_std=0.05, truth=True)
    live, live_meta = _log(live_log)
    off, off_meta = _log(offline)
    name = '/accel/hpotp_casing_bottom'
    for topic in (name + '/truth', name + '/batch', name, '/rotor/tach', '/rotor/keyphasor'):
        assert len(live[topic]) >= 30 and live[topic] == off[topic], topic
    truth, _, _, _ = _rows(off[name + '/truth'])
    samples, _, _, _ = _rows(off[name + '/batch'])
    assert not np.array_equal(truth['ax'], samples['ax'])   # hpotp's preset is not ideal
    labels = yaml.safe_load(off_meta['labels'])
    assert yaml.safe_load(live_meta['labels']) == labels
    assert labels['seed'] == 5 and labels['noise_std'] == 0.05
    assert labels['dampers_enabled'] is True and labels['unbalance_multiplier'] == 1.0
    assert labels['accelerometers']['hpotp_casing_bottom']['channel']['preset'] == \
        'iepe_10mv_500g'
    assert yaml.safe_load(off_meta['node_parameters'])['publish_truth'] is True
    # off by default; the labels hold the start's state
    default_log = tmp_path / 'default.mcap'
    node = make_node(ros_context, 'hpotp', dampers_enabled=False, record=str(default_log))
    try:
        assert not [o for o in node.outlets if o.topic.endswith('/truth')]
        assert {'/rotor/tach', '/rotor/keyphasor'} <= {o.topic for o in node.outlets}
        node.stop_recording()
    finally:
        node.destroy_node()
    topics, meta = _log(default_log)
    assert yaml.safe_load(meta['labels'])['dampers_enabled'] is False
    assert yaml.safe_load(meta['node_parameters'])['publish_truth'] is False


# -- labels -----------------------------------------------------------------------------------

def test_a_recorded_log_holds_the_labels_a_detector_is_scored_with(tmp_path):
    """rbs_kcc with X = 3: Kcc (11,250 lb/in at node 4), X, the dampers, the seed and the
    channel of each accelerometer, every stage as applied, read with the mcap reader and
    YAML only; the schedule's changes are in the log as commands."""
    pytest.importorskip('rclpy')
    from impact_damper_sim.scene.accelerometers import channel_of
    from impact_damper_sim.scene.units import parse_quantity
    schedule = tmp_path / 's.yaml'
    schedule.write_text('schedule:\n  - {at: 10 ms, unbalance: 4}\n')
    out = tmp_path / 'kcc.mcap'
    result = record_log('rbs_kcc', out, 0.02, seed=7, overrides=['rotor.multiplier=3'],
                        schedule=schedule)
    topics, meta = _log(out)
    labels = yaml.safe_load(meta['labels'])
    kcc = parse_quantity('11250 lb/in', 'stiffness')
    assert labels['kcc_n_per_m'] == pytest.approx(kcc, rel=1e-12)
    assert labels['cross_couplings'] == [{'node': 4, 'kcc': pytest.approx(kcc, rel=1e-12),
                                          'dofs': ['uy', 'uz']}]
    assert labels['unbalance_multiplier'] == 3.0 and labels['seed'] == 7
    assert labels['dampers_enabled'] is True and labels['sim_time_s'] == 0.0
    model, target = live_scene('rbs_kcc', ['rotor.multiplier=3'])
    live = LiveSimulation(model, initial_target=target, seed=7)
    assert list(labels['accelerometers']) == [a.name for a in live.accelerometers]
    presets = set()
    for acc, channel in zip(live.accelerometers, live.channels):
        got = labels['accelerometers'][acc.name]
        assert (got['node'], got['frame_id']) == (acc.node, acc.frame_id)
        assert got['channel'] == yaml.safe_load(yaml.safe_dump(channel.labels()))
        spec = channel_of(model, acc.node)
        assert got['channel']['preset'] == spec['preset']
        for stage in ('sensitivity', 'range', 'noise_density', 'highpass'):
            assert got['channel'][stage] == spec[stage], stage
        assert got['channel']['adc']['bits'] == spec['adc']['bits']
        presets.add(spec['preset'])
    assert result['channel_preset'] == presets.pop() == 'iepe_10mv_500g'
    from rclpy.serialization import deserialize_message
    from std_msgs.msg import Float64
    assert [deserialize_message(d, Float64).data
            for d in topics['/rotor/unbalance_command']] == [4.0]
