"""Sensor faults wired into the streams (issue 36, item 3): the schedule's ``fault`` and
``clear_fault`` keys in ``study record`` and the node, the ``accel/fault_command`` topic, the
data set's ``faults``, and what a subscriber and a log's reader see.

A gain fault clips at the rail only in its window (and the clip count rises only there), the
samples outside every window are the bytes of a run without faults; a dropout leaves exactly
its window's batch rows and Imu messages out; the node on a fake clock writes the bytes
``study record`` writes; a command on the topic is applied and recorded, a bad one refused in
one line; ``/diagnostics`` never mention a fault, the log's labels list each one's window.
The fault models themselves are tested in test_faults.py.
"""
import json

import numpy as np
import pytest
import yaml

from impact_damper_sim.live.realtime import CommandError, LiveSimulation
from impact_damper_sim.live.schedule import Schedule, ScheduleError
from impact_damper_sim.live.streams import live_scene
from impact_damper_sim.recording.batches import rows_of, sample_times_ns
from impact_damper_sim.recording.log_metadata import FAULTS_METADATA
from impact_damper_sim.scene.units import G0
from impact_damper_sim.studies.record import record_log

ACC = 'hpotp_casing_bottom'
#: a realistic +-50 g IEPE channel on the HPOTP, noise 0.05 g: a gain of 1000 puts about a
#: sixth of the window's values beyond the rail, none outside it
OVERRIDES = ['channel=iepe_100mv_50g']
NOISE = 0.05 * G0
SEED = 3
DURATION = 0.5
FS = 2000.0
#: entries on 10 ms boundaries: the node and study record step the same chunks
SCHEDULE = f"""\
schedule:
  - {{at: 0.1 s, fault: {{kind: gain, accelerometer: {ACC}, gain: 1000, duration: 100 ms,
                         name: overload}}}}
  - {{at: 0.3 s, fault: {{kind: dropout, accelerometer: {ACC}, duration: 50 ms, name: lost}}}}
  - {{at: 0.42 s, fault: {{kind: stuck, accelerometer: {ACC}, name: frozen}}}}
  - {{at: 0.45 s, clear_fault: frozen}}
"""
#: the windows (onset, end] in s, as the labels give them
WINDOWS = {'overload': (0.1, 0.2), 'lost': (0.3, 0.35), 'frozen': (0.42, 0.45)}
BATCH, IMU, COMMAND = f'/accel/{ACC}/batch', f'/accel/{ACC}', '/accel/fault_command'


def _in(t_ns, window):
    lo, hi = window
    return (t_ns > round(lo * 1e9)) & (t_ns <= round(hi * 1e9))


def _read(path):
    """topic -> [(log time ns, bytes, decoded)], and the metadata records."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    topics = {}
    with open(path, 'rb') as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        meta = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        for _, channel, message, decoded in reader.iter_decoded_messages(log_time_order=False):
            topics.setdefault(channel.topic, []).append(
                (message.log_time, bytes(message.data), decoded))
    return topics, meta


def _rows(messages):
    """Times (ns) and ax, ay, az (m/s^2) of every row of an accelerometer's batches."""
    times, values = [], []
    for _, _, msg in messages:
        rows = rows_of(msg)
        times.append(sample_times_ns(msg, rows))
        values.append(np.stack([rows['ax'], rows['ay'], rows['az']], axis=1))
    return np.concatenate(times), np.concatenate(values)


def _imu(messages):
    """Stamps (ns) and bytes of the Imu messages."""
    stamps = np.array([m.header.stamp.sec * 10**9 + m.header.stamp.nanosec
                       for _, _, m in messages])
    return stamps, [data for _, data, _ in messages]


def _rail():
    model, target = live_scene('hpotp', OVERRIDES)
    from impact_damper_sim.live.faults import channel_rail
    return channel_rail(LiveSimulation(model, initial_target=target).channels[0])


@pytest.fixture(scope='module')
def schedule_file(tmp_path_factory):
    path = tmp_path_factory.mktemp('faults') / 'faults.yaml'
    path.write_text(SCHEDULE)
    return path


@pytest.fixture(scope='module')
def logs(schedule_file, tmp_path_factory):
    """study record of the HPOTP with the fault schedule, and without it (same seed)."""
    out = tmp_path_factory.mktemp('fault_logs')
    common = dict(overrides=OVERRIDES, seed=SEED, noise_std=NOISE)
    faulted = record_log('hpotp', out / 'faulted.mcap', DURATION, schedule=schedule_file,
                         **common)
    clean = record_log('hpotp', out / 'clean.mcap', DURATION, **common)
    return out / 'faulted.mcap', out / 'clean.mcap', faulted, clean


# -- study record -------------------------------------------------------------------------------

def test_a_gain_fault_clips_only_in_its_window_and_the_rest_is_the_same_bytes(logs):
    faulted, clean, result, _ = logs
    (t, a), (t0, a0) = _rows(_read(faulted)[0][BATCH]), _rows(_read(clean)[0][BATCH])
    rail = _rail()
    assert rail == pytest.approx(50 * G0, rel=1e-6)
    gain = _in(t, WINDOWS['overload'])
    at_rail = np.abs(a) >= rail * (1 - 1e-12)
    assert at_rail[gain].mean() > 0.1   # 17 %: the signal's ~0.04 g rms x 1000 beyond 50 g
    assert not at_rail[~gain].any() and not (np.abs(a0) >= rail * (1 - 1e-12)).any()
    # nothing beyond the range (the ADC's lowest code is -50 g, its highest 50 g - 1 LSB)
    assert np.max(np.abs(a)) <= 50 * G0 * (1 + 1e-12)
    # every sample outside every window is the bytes of the run without faults
    outside = ~np.any([_in(t0, w) for w in WINDOWS.values()], axis=0)
    assert outside.sum() == 1000 - 200 - 100 - 60
    keep = np.isin(t, t0[outside])
    assert np.array_equal(t[keep], t0[outside])
    assert np.array_equal(a[keep].view(np.uint64), a0[outside].view(np.uint64))
    assert result['commands'] == 4


def test_the_clip_count_rises_only_in_the_gain_window():
    """Batch.clipped (the node's clipped_values_*) per 10 ms chunk: 0 outside the window."""
    model, target = live_scene('hpotp', OVERRIDES)
    live = LiveSimulation(model, initial_target=target, noise_std=NOISE, seed=SEED)
    live.add_fault({'kind': 'gain', 'accelerometer': ACC, 'gain': 1000, 'onset': '0.1 s',
                    'duration': '0.1 s'})
    clipped = [int(live.step(20).clipped[0]) for _ in range(30)]
    assert all(n > 0 for n in clipped[10:20]), clipped
    assert not any(clipped[:10]) and not any(clipped[20:]), clipped


def test_a_dropout_leaves_exactly_its_rows_and_imu_messages_out(logs):
    faulted, clean, result, base = logs
    topics, _ = _read(faulted)
    clean_topics, _ = _read(clean)
    t, _ = _rows(topics[BATCH])
    t0, _ = _rows(clean_topics[BATCH])
    lost = _in(t0, WINDOWS['lost'])
    assert lost.sum() == 100 and np.array_equal(t, t0[~lost])
    # one batch per chunk still: the five chunks inside the window are empty
    assert len(topics[BATCH]) == len(clean_topics[BATCH]) == 50
    assert sum(m.width == 0 for _, _, m in topics[BATCH]) == 5
    stamps, data = _imu(topics[IMU])
    stamps0, data0 = _imu(clean_topics[IMU])
    gone = _in(stamps0, WINDOWS['lost'])
    assert gone.sum() == 50 and np.array_equal(stamps, stamps0[~gone])
    # away from the gain and stuck windows (the decimation FIR spans +-26 ms) the Imu
    # messages that are sent are the bytes of the clean run
    quiet = (stamps0 > 0.26e9) & (stamps0 < 0.39e9) & ~gone
    sent = dict(zip(stamps.tolist(), data))
    assert quiet.sum() > 70
    assert [sent[s] for s in stamps0[quiet].tolist()] == [d for d, q in zip(data0, quiet) if q]
    # the summary counts what was published
    assert base['samples'] - result['samples'] == 100 == base['samples'] - 900


def test_stuck_holds_the_last_value_until_cleared(logs):
    faulted, _, _, _ = logs
    t, a = _rows(_read(faulted)[0][BATCH])
    held = _in(t, WINDOWS['frozen'])
    assert held.sum() == 60
    before = np.flatnonzero(held)[0] - 1
    assert np.array_equal(a[held].view(np.uint64),
                          np.repeat(a[before:before + 1], 60, axis=0).view(np.uint64))
    assert not np.array_equal(a[np.flatnonzero(held)[-1] + 1], a[before])   # cleared


def test_each_fault_entry_is_logged_as_the_command_it_stands_for(logs):
    faulted, clean, _, _ = logs
    topics, meta = _read(faulted)
    commands = [(ns, msg.data) for ns, _, msg in topics[COMMAND]]
    assert [ns for ns, _ in commands] == [100_000_000, 300_000_000, 420_000_000, 450_000_000]
    assert commands[0][1] == (f'{{kind: gain, accelerometer: {ACC}, name: overload, '
                              'duration: 0.1, axes: xyz, gain: 1000.0}')
    assert commands[3][1] == '{clear: frozen}'
    # what a live command with that text does: the same fault
    from impact_damper_sim.live.fault_spec import parse_command
    spec = parse_command(commands[0][1], [ACC]).spec
    assert (spec.kind, spec.name, spec.duration, spec.params) == (
        'gain', 'overload', 0.1, {'gain': 1000.0})
    # a log without faults has no such topic (and the bytes of before: test_record.py)
    assert COMMAND not in _read(clean)[0]


def test_the_labels_at_close_give_each_faults_window(logs):
    faulted, clean, result, _ = logs
    _, meta = _read(faulted)
    labels = yaml.safe_load(meta[FAULTS_METADATA]['faults'])
    assert [f['name'] for f in labels] == ['overload', 'lost', 'frozen']
    for f in labels:
        assert (f['onset_s'], f['end_s']) == pytest.approx(WINDOWS[f['name']]), f['name']
    frozen = labels[2]
    assert frozen['requested']['duration_s'] is None and frozen['cleared_at_s'] == 0.45
    assert [f['samples'] for f in labels] == [200, 100, 60]
    assert labels[0]['parameters'] == {'gain': 1000.0} and labels[0]['stage'] == \
        'before_limit'
    assert float(meta[FAULTS_METADATA]['sim_time_s']) == pytest.approx(DURATION)
    assert result['fault_labels'] == labels
    # the opening labels hold the faults known then: none; a run without has an empty list
    assert yaml.safe_load(meta['impact_damper_sim']['labels'])['faults'] == []
    assert yaml.safe_load(_read(clean)[1][FAULTS_METADATA]['faults']) == []


# -- the schedule ------------------------------------------------------------------------------

def test_the_schedule_refuses_faults_the_scene_cannot_take(tmp_path):
    bad = tmp_path / 'bad.yaml'
    bad.write_text('schedule:\n'
                   '  - {at: 0.1 s, fault: {kind: stuck, accelerometer: casing}}\n'
                   '  - {at: 1 s, fault: {kind: dropout, accelerometer: '
                   f'{ACC}, onset: 0.2 s, duration: 0.1 s}}}}\n'
                   '  - {at: 1 s, clear_fault: nope}\n'
                   '  - {at: 2 s, fault: {kind: gain, accelerometer: '
                   f'{ACC}, gain: 2, name: g}}}}\n'
                   '  - {at: 3 s, fault: {kind: gain, accelerometer: '
                   f'{ACC}, gain: 3, name: g}}}}\n')
    schedule = Schedule.load(bad)   # the keys are fine: the scene is what refuses them
    model, target = live_scene('hpotp')
    with pytest.raises(ScheduleError) as info:
        schedule.check(LiveSimulation(model, initial_target=target))
    assert info.value.errors == (
        "schedule[0].fault.accelerometer (at 0.1 s): 'casing' is not an accelerometer of this "
        f'scene; the accelerometers: {ACC}',
        'schedule[1].fault.onset (at 1 s): the window 0.2 s + 0.1 s has passed when the entry '
        'applies',
        "schedule[2].clear_fault (at 1 s): no earlier entry adds a fault named 'nope'; the "
        'faults: none',
        "schedule[4].fault.name (at 3 s): 'g' names an earlier fault of this run; give another "
        'name')
    wrong = tmp_path / 'wrong.yaml'
    wrong.write_text('schedule:\n  - {at: 1 s, fault: {kind: gain, accelerometer: x, '
                     'gain: 5 x}}\n  - {at: 2 s, clear_fault: "no way"}\n')
    with pytest.raises(ScheduleError) as info:
        Schedule.load(wrong)
    assert info.value.errors == (
        "key 'schedule[0].fault.gain': unknown unit 'x' for a dimensionless; use one of "
        '(no unit), %',
        "key 'schedule[1].clear_fault': 'no way' does not match "
        '[A-Za-z][A-Za-z0-9_.-]{0,63}')


def test_a_bad_fault_command_is_refused_in_one_line():
    model, target = live_scene('hpotp')
    live = LiveSimulation(model, initial_target=target)
    with pytest.raises(CommandError) as info:
        live.fault_command('{kind: gain, accelerometer: hpotp_casing, gain: 5}')
    assert str(info.value) == (
        "key 'fault command.accelerometer': 'hpotp_casing' is not an accelerometer of "
        f"this scene; did you mean '{ACC}'? the accelerometers: {ACC}")   # the node: its topic
    with pytest.raises(CommandError, match=r"^key 'fault.duration': .*; key 'fault.gain'"):
        live.add_fault({'kind': 'gain', 'accelerometer': ACC, 'gain': 5000, 'duration': -1})
    with pytest.raises(CommandError, match="^key 'clear': no fault named 'x'; the faults: "
                                           'none$'):
        live.clear_faults('x')
    assert len(live.faults) == 0


# -- the node -----------------------------------------------------------------------------------

def _run_node(node, seconds):
    node._wall.now += 1e-7   # 10 ms steps add up to just under the total in binary
    for _ in range(int(round(seconds / 0.01))):
        node._wall.now += 0.01
        node.tick()


@pytest.mark.ros
def test_the_node_plays_the_fault_schedule_as_study_record_does(logs, schedule_file,
                                                               ros_context, tmp_path):
    pytest.importorskip('rclpy')
    from node_helpers import make_node
    path = tmp_path / 'live.mcap'
    node = make_node(ros_context, 'hpotp', OVERRIDES, noise_seed=SEED, noise_std=NOISE,
                     schedule=str(schedule_file), record=str(path))
    try:
        _run_node(node, DURATION)
        assert node.live.t == pytest.approx(DURATION)
        node.stop()
        published = node.stats_total['samples']
        node.stop_recording()
    finally:
        node.destroy_node()
    live, live_meta = _read(path)
    offline, off_meta = _read(logs[0])
    for topic in (BATCH, IMU, COMMAND, '/impacts', '/rotor/tach'):
        assert [d for _, d, _ in live[topic]] == [d for _, d, _ in offline[topic]], topic
    assert [ns for ns, _, _ in live[COMMAND]] == [ns for ns, _, _ in offline[COMMAND]]
    assert published == logs[2]['samples'] == sum(m.width for _, _, m in live[BATCH]) == 900
    assert yaml.safe_load(live_meta[FAULTS_METADATA]['faults']) == \
        yaml.safe_load(off_meta[FAULTS_METADATA]['faults'])


@pytest.mark.ros
def test_a_fault_command_on_the_topic_is_applied_recorded_and_not_diagnosed(ros_context,
                                                                            tmp_path):
    pytest.importorskip('rclpy')
    import time

    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from std_msgs.msg import String

    from impact_damper_sim.ros import interface as itf
    from node_helpers import make_node
    path = tmp_path / 'cmd.mcap'
    node = make_node(ros_context, 'hpotp', OVERRIDES, noise_std=NOISE, record=str(path))
    logged = []
    log = node._log
    node._log = lambda level, text, *args: (logged.append((level, text)),
                                            log(level, text, *args))
    tap = Node('fault_tap', context=ros_context)
    pub = tap.create_publisher(String, itf.FAULT_COMMAND, itf.COMMAND_QOS)
    executor = SingleThreadedExecutor(context=ros_context)
    executor.add_node(node)
    executor.add_node(tap)
    good = (f'{{"kind": "dropout", "accelerometer": "{ACC}", "duration": 0.05, '
            '"name": "cable"}')   # JSON is YAML too
    try:
        _run_node(node, 0.1)
        end = time.monotonic() + 30.0
        while not len(node.live.faults) and time.monotonic() < end:
            pub.publish(String(data=good))
            executor.spin_once(timeout_sec=0.05)
        assert len(node.live.faults) == 1
        applied_at = node.live.t
        _run_node(node, 0.1)
        bad = '{kind: stuck, accelerometer: hpotp_casing}'
        assert not node.on_fault_command(String(data=bad))
        assert not node.on_fault_command(String(data='{kind: spikes, accelerometer: '
                                                      f'{ACC}, rate: -2 Hz, amplitude: 1 g}}'))
        assert node.on_fault_command(String(data=f'{{kind: bias, accelerometer: {ACC}, '
                                                 'step: 2 g, name: offset}')) is True
        assert node.on_fault_command(String(data='{clear: all}')) is True
        _run_node(node, 0.05)
        node.publish_diagnostics()
        diagnostics = json.dumps({k: v for k, v in node.last_diagnostics.items()
                                  if k != 'record_path'}).lower()   # (tmp_path is ours)
        node.stop()
        node.stop_recording()
    finally:
        node.destroy_node()
        tap.destroy_node()
    info = [text for level, text in logged if level == 'info' and 'fault_command' in text]
    assert info[0] == (f"accel/fault_command: fault 'cable' added, accepted at sim time "
                       f'{applied_at:.3f} s')
    warnings = [text for level, text in logged if level == 'warning']
    assert warnings == [   # (the second is throttled in the node's log: within 1 s)
        "rejected: key 'accel/fault_command.accelerometer': 'hpotp_casing' is not an "
        f"accelerometer of this scene; did you mean '{ACC}'? the accelerometers: {ACC}",
        "rejected: key 'accel/fault_command.rate': -2 Hz is out of range (0, 100000] Hz"]
    assert all('\n' not in w for w in warnings)
    # /diagnostics: no word of a fault (a real sensor does not say it is faulty)
    assert 'fault' not in diagnostics and 'cable' not in diagnostics and \
        'dropout' not in diagnostics
    topics, meta = _read(path)
    received = [msg.data for _, _, msg in topics[COMMAND]]
    assert received[0] == good and received[-1] == '{clear: all}' and len(received) == 5
    labels = yaml.safe_load(meta[FAULTS_METADATA]['faults'])
    assert [(f['name'], f['kind']) for f in labels] == [('cable', 'dropout'),
                                                       ('offset', 'bias')]
    cable = labels[0]
    assert cable['onset_s'] == pytest.approx(applied_at)
    assert cable['end_s'] == pytest.approx(applied_at + 0.05)
    t, _ = _rows(topics[BATCH])
    missing = _in(t, (cable['onset_s'], cable['end_s']))
    assert not missing.any() and len(t) == round(0.25 * FS) - 100


# -- study dataset -----------------------------------------------------------------------------

def test_the_dataset_spec_takes_faults_and_the_manifest_lists_them(tmp_path):
    import csv

    from impact_damper_sim.studies.dataset import run_dataset
    from impact_damper_sim.studies.dataset_spec import DatasetError, load_spec
    text = 'scene: sdof\nduration: 100 ms\ngrid:\n  impactors.0.cor: [0.6]\n'
    faults = ('faults:\n'
              '  - {kind: dropout, accelerometer: sdof_primary, onset: 20 ms, '
              'duration: 10 ms, name: gap}\n'
              '  - {kind: spikes, accelerometer: sdof_primary, rate: 50 Hz, amplitude: 1 g}\n')
    spec = tmp_path / 'spec.yaml'
    spec.write_text(text + faults)
    plain = tmp_path / 'plain.yaml'
    plain.write_text(text)
    (run,) = load_spec(spec)
    (without,) = load_spec(plain)
    assert without['faults'] == [] and run['id'] != without['id']
    assert run['faults'][0] == {'kind': 'dropout', 'accelerometer': 'sdof_primary',
                                'name': 'gap', 'onset': 0.02, 'duration': 0.01}
    bad = tmp_path / 'bad.yaml'
    bad.write_text(text + 'faults:\n  - {kind: spikes, accelerometer: a, rate: 0 Hz, '
                          'amplitude: 1 g}\n')
    with pytest.raises(DatasetError, match=r"key 'faults\[0\]\.rate': 0 Hz is out of range"):
        load_spec(bad)
    out = tmp_path / 'data'
    assert run_dataset(str(spec), str(out), executor='serial')['failed'] == 0
    doc = json.loads((out / 'manifest.json').read_text())
    (row,) = doc['runs']
    assert row['faults'] == run['faults']
    gap, spikes = row['fault_labels']
    assert (gap['name'], gap['onset_s'], gap['end_s'], gap['samples']) == ('gap', 0.02, 0.03,
                                                                           20)
    assert spikes['name'] == 'spikes-2' and spikes['seed'] is not None
    assert spikes['events']['t_s'] and spikes['end_s'] is None
    with open(out / 'manifest.csv', newline='') as f:
        (cells,) = list(csv.DictReader(f))
    assert cells['fault_labels'] == 'gap dropout sdof_primary (0.02, 0.03]; spikes-2 spikes ' \
                                    'sdof_primary (0, end]'
    assert json.loads(cells['faults']) == run['faults']
    topics, meta = _read(out / row['file'])
    assert [ns for ns, _, _ in topics[COMMAND]] == [0, 0]
    t, _ = _rows(topics['/accel/sdof_primary/batch'])
    assert len(t) == 200 - 20 and not _in(t, (0.02, 0.03)).any()
    assert yaml.safe_load(meta[FAULTS_METADATA]['faults']) == row['fault_labels']
    # an accelerometer the scene lacks fails the run, in one line naming the ones it has
    wrong = tmp_path / 'wrong.yaml'
    wrong.write_text(text + 'faults:\n  - {kind: stuck, accelerometer: casing}\n')
    result = run_dataset(str(wrong), str(tmp_path / 'wrong'), executor='serial')
    (failed,) = result['rows']
    assert failed['status'] == 'failed' and failed['error'] == (
        "FaultError: key 'faults[0].accelerometer': 'casing' is not an accelerometer of this "
        'scene; the accelerometers: sdof_primary')
