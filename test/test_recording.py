"""The MCAP recorder writes what rosbag2 writes, survives crashes, and recovers cut-off files.

Every file is read back with an independent reader: ``mcap.reader.make_reader`` with
``mcap_ros2``'s decoder. The schema rule and the QoS encoding are re-derived here from
rosbag2's sources (jazzy), not taken from the module under test.
"""
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from impact_damper_sim.cli.study import main as study_main
from impact_damper_sim.recording import AsyncRecorder, RecoveryError, Rosbag2McapWriter, recover

HERE = Path(__file__).resolve().parent
os.environ.setdefault('AMENT_PREFIX_PATH', sys.prefix)   # the venv holds the .msg files

MAGIC = b'\x89MCAP0\r\n'


# --------------------------------------------------------------------------- helpers

def _reader(f):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    return make_reader(f, decoder_factories=[DecoderFactory()])


def _read_all(path):
    """Return (summary, [(topic, schema name, log, publish, raw, decoded)], {name: metadata})."""
    with open(path, 'rb') as f:
        reader = _reader(f)
        summary = reader.get_summary()
        messages = [(c.topic, s.name, m.log_time, m.publish_time, m.data, d)
                    for s, c, m, d in reader.iter_decoded_messages(log_time_order=False)]
        metadata = {r.name: r.metadata for r in reader.iter_metadata()}
    return summary, messages, metadata


def _same(decoded, msg, where='msg'):
    """Assert a decoded mcap_ros2 message equals an rclpy message, field by field."""
    if hasattr(msg, 'get_fields_and_field_types'):
        for field in msg.get_fields_and_field_types():
            _same(getattr(decoded, field), getattr(msg, field), f'{where}.{field}')
    elif isinstance(msg, bytes) and len(msg) == 1:   # ROS `byte`: rclpy bytes, mcap_ros2 int
        assert decoded == msg[0], where
    elif isinstance(msg, (str, bytes, int, float, bool)):
        assert decoded == msg, where
    else:   # sequences and arrays (array.array, numpy arrays, lists)
        msg, decoded = list(msg), list(decoded)
        assert len(decoded) == len(msg), where
        for i, (d, m) in enumerate(zip(decoded, msg)):
            _same(d, m, f'{where}[{i}]')


def _samples():
    """(topic, type, QoS, message) for each of the six message types, with non-trivial values."""
    from builtin_interfaces.msg import Time
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
    from geometry_msgs.msg import WrenchStamped
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import Imu, JointState
    from std_msgs.msg import Float64

    imu = Imu()
    imu.header.stamp = Time(sec=12, nanosec=345_000_000)
    imu.header.frame_id = 'casing/s1'
    imu.orientation_covariance[0] = -1.0
    imu.linear_acceleration.x, imu.linear_acceleration.y = 9.81, -0.125
    imu.linear_acceleration_covariance = [1e-4, 0.0, 0.0, 0.0, 1e-4, 0.0, 0.0, 0.0, 1e-4]
    wrench = WrenchStamped()
    wrench.header.frame_id = 'casing/impactor_1'
    wrench.wrench.force.y = 0.0375
    wrench.wrench.torque.x, wrench.wrench.torque.z = 0.8, 1.5e-3
    joints = JointState(name=['i1/y', 'i1/z'], position=[1e-4, -2e-4], velocity=[0.01, 0.0],
                        effort=[1.0, 0.0])
    diag = DiagnosticArray(status=[DiagnosticStatus(
        level=DiagnosticStatus.WARN, name='vibration_node: recorder', message='disk slow',
        hardware_id='sim', values=[KeyValue(key='dropped', value='3')])])
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
    return [
        ('/rotor/speed_command', 'std_msgs/msg/Float64', {'depth': 10}, Float64(data=837.5)),
        ('/accel/s1', 'sensor_msgs/msg/Imu', qos_profile_sensor_data, imu),
        ('/impacts', 'geometry_msgs/msg/WrenchStamped', {'depth': 1000}, wrench),
        ('/impactor_state', 'sensor_msgs/msg/JointState', latched, joints),
        ('/clock', 'rosgraph_msgs/msg/Clock', {'depth': 1, 'reliability': 'best_effort'},
         Clock(clock=Time(sec=3, nanosec=7))),
        ('/diagnostics', 'diagnostic_msgs/msg/DiagnosticArray', {'depth': 10}, diag),
    ]


T0 = 1_700_000_000_000_000_000   # ns since the epoch


def _record(path, kind, samples, repeats=5):
    """Write each sample ``repeats`` times; return the list of what was written, in order."""
    from rclpy.serialization import serialize_message
    writer = (Rosbag2McapWriter if kind == 'sync' else AsyncRecorder)(path)
    writer.add_metadata('impact_damper_sim', {'scene': 'structure: {}\n', 'version': '0.1.0'})
    written = []
    for r in range(repeats):
        for k, (topic, type_name, qos, msg) in enumerate(samples):
            data = serialize_message(msg)
            log = T0 + 1_000_000 * (r * len(samples) + k)
            publish = log - 1000 - k   # sent shortly before it was received
            assert writer.write(topic, type_name, qos, data, log, publish)
            written.append((topic, type_name, log, publish, data, msg))
    writer.close()
    return written


# --------------------------------------------------------------------------- (a) round trip

@pytest.mark.ros
@pytest.mark.parametrize('kind', ['sync', 'async'])
def test_round_trip_with_an_independent_reader(tmp_path, kind):
    """Topics, types, counts, log/publish times and payloads come back exactly (bytes equal)."""
    samples = _samples()
    path = tmp_path / 'run.mcap'
    written = _record(path, kind, samples)
    summary, messages, metadata = _read_all(path)
    assert len(messages) == len(written) == 30
    for (topic, type_name, log, publish, data, msg), got in zip(written, messages):
        assert got[:5] == (topic, type_name, log, publish, data)
        _same(got[5], msg)
    assert {c.topic for c in summary.channels.values()} == {s[0] for s in samples}
    counts = {summary.channels[cid].topic: n
              for cid, n in summary.statistics.channel_message_counts.items()}
    assert counts == {s[0]: 5 for s in samples}
    assert all(c.message_encoding == 'cdr' for c in summary.channels.values())
    assert {s.encoding for s in summary.schemas.values()} == {'ros2msg'}
    assert metadata['impact_damper_sim'] == {'scene': 'structure: {}\n', 'version': '0.1.0'}
    with open(path, 'rb') as f:
        assert _reader(f).get_header().profile == 'ros2'


# --------------------------------------------------------------------------- (b) schema text

_PRIMITIVES = {'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16',
               'int32', 'uint32', 'int64', 'uint64', 'string'}


def _rosbag2_rule(root):
    """rosbag2's LocalMessageDefinitionSource::get_full_text for a .msg type, re-implemented
    line by line: a field line's first token names the type; dependencies are visited depth
    first, in sorted order, each written once."""
    from ament_index_python.packages import get_package_share_directory

    def text_of(name):
        pkg, _, typ = name.replace('/msg/', '/').partition('/')
        path = Path(get_package_share_directory(pkg)) / 'msg' / f'{typ}.msg'
        return pkg, path.read_bytes().decode()

    def deps(pkg, text):
        found = set()
        for line in text.split('\n'):
            line = line.strip()
            if not line or line.startswith('#'):
                continue
            token = re.split(r'[\[<\s]', line, maxsplit=1)[0]
            if token not in _PRIMITIVES:
                found.add(token if '/' in token else f'{pkg}/{token}')
        return sorted(found)

    seen = set()

    def full(name):
        pkg, text = text_of(name)
        out = text
        for dep in deps(pkg, text):
            if dep not in seen:
                seen.add(dep)
                out += '\n' + '=' * 80 + '\n' + f'MSG: {dep}\n' + full(dep)
        return out
    return full(root)


@pytest.mark.ros
def test_schema_text_is_rosbag2_concatenation(tmp_path):
    """Each schema equals the rule applied to the installed .msg files; WrenchStamped's
    dependency order is also checked against the order worked out by hand."""
    path = tmp_path / 'run.mcap'
    _record(path, 'sync', _samples(), repeats=1)
    summary, _, _ = _read_all(path)
    assert len(summary.schemas) == 6
    for schema in summary.schemas.values():
        assert schema.data.decode() == _rosbag2_rule(schema.name), schema.name
    wrench = next(s for s in summary.schemas.values() if s.name.endswith('WrenchStamped'))
    assert re.findall(r'^MSG: (\S+)$', wrench.data.decode(), re.M) == [
        'geometry_msgs/Wrench', 'geometry_msgs/Vector3', 'std_msgs/Header',
        'builtin_interfaces/Time']


# --------------------------------------------------------------------------- (c) channels

def _qos(history='keep_last', depth=10, reliability='reliable', durability='volatile',
         deadline=(0, 0), lifespan=(0, 0), liveliness='system_default', lease=(0, 0)):
    """A QoS profile as rosbag2's qos.cpp encodes it (metadata version 9)."""
    def t(pair):
        return {'sec': pair[0], 'nsec': pair[1]}
    return {'history': history, 'depth': depth, 'reliability': reliability,
            'durability': durability, 'deadline': t(deadline), 'lifespan': t(lifespan),
            'liveliness': liveliness, 'liveliness_lease_duration': t(lease),
            'avoid_ros_namespace_conventions': False}


@pytest.mark.ros
def test_channel_metadata_qos_and_type_hash(tmp_path):
    """offered_qos_profiles parses to the QoS given (rclpy profile or dict, one or several);
    topic_type_hash is the RIHS01 string of share/<pkg>/msg/<Type>.json."""
    from ament_index_python.packages import get_package_share_directory
    from rclpy.duration import Duration
    from rclpy.qos import LivelinessPolicy, QoSProfile, qos_profile_sensor_data
    from rclpy.serialization import serialize_message
    from std_msgs.msg import Float64

    deadline = QoSProfile(depth=3, deadline=Duration(seconds=1, nanoseconds=500_000_000),
                          liveliness=LivelinessPolicy.AUTOMATIC)
    cases = {
        '/sensor': (qos_profile_sensor_data,
                    [_qos(depth=5, reliability='best_effort')]),
        '/deadline': (deadline, [_qos(depth=3, deadline=(1, 500_000_000),
                                      liveliness='automatic')]),
        '/dict': ({'depth': 1, 'durability': 'transient_local'},
                  [_qos(depth=1, durability='transient_local')]),
        '/two': ([{'depth': 7}, {'history': 'keep_all', 'reliability': 'best_effort'}],
                 [_qos(depth=7), _qos(history='keep_all', reliability='best_effort')]),
    }
    path = tmp_path / 'qos.mcap'
    data = serialize_message(Float64(data=1.0))
    with Rosbag2McapWriter(path) as writer:
        for topic, (qos, _) in cases.items():
            writer.write(topic, 'std_msgs/msg/Float64', qos, data, T0, T0)
    summary, _, _ = _read_all(path)
    share = Path(get_package_share_directory('std_msgs'))
    expected_hash = json.loads((share / 'msg' / 'Float64.json').read_text())['type_hashes'][0]
    assert expected_hash['type_name'] == 'std_msgs/msg/Float64'
    for channel in summary.channels.values():
        assert isinstance(channel.metadata['offered_qos_profiles'], str)
        assert yaml.safe_load(channel.metadata['offered_qos_profiles']) == \
            cases[channel.topic][1], channel.topic
        assert channel.metadata['topic_type_hash'] == expected_hash['hash_string']
        assert re.fullmatch(r'RIHS01_[0-9a-f]{64}', channel.metadata['topic_type_hash'])


def test_bad_topic_type_and_qos_raise(tmp_path):
    """Programming errors raise at once (unlike disk errors): relative name, unknown type,
    unknown QoS key, a topic reused with another type, negative time."""
    with Rosbag2McapWriter(tmp_path / 'x.mcap') as writer:
        with pytest.raises(ValueError, match='fully qualified'):
            writer.add_topic('accel/s1', 'sensor_msgs/msg/Imu')
        with pytest.raises(LookupError, match='no .msg definition'):
            writer.add_topic('/x', 'std_msgs/msg/NoSuchType')
        with pytest.raises(ValueError, match='unknown QoS keys'):
            writer.add_topic('/y', 'std_msgs/msg/Float64', {'dpeth': 3})
        writer.add_topic('/z', 'std_msgs/msg/Float64')
        with pytest.raises(ValueError, match='registered as std_msgs/msg/Float64'):
            writer.write('/z', 'std_msgs/msg/Int32', None, b'', T0, T0)
        with pytest.raises(ValueError, match='integers'):
            writer.write('/z', 'std_msgs/msg/Float64', None, b'\0\1\0\0' + bytes(8), -1, T0)


# --------------------------------------------------------------------------- (d) rosbag2 record

@pytest.mark.ros
def test_rosbag2_metadata_record(tmp_path):
    """The rosbag2 record is version-9 YAML with the counts, times and QoS (a sequence)."""
    samples = _samples()
    path = tmp_path / 'run_0.mcap'
    written = _record(path, 'async', samples, repeats=3)
    _, _, metadata = _read_all(path)
    meta = yaml.safe_load(metadata['rosbag2']['serialized_metadata'])
    assert meta['version'] == 9 and meta['storage_identifier'] == 'mcap'
    assert meta['message_count'] == 18
    logs = [w[2] for w in written]
    assert meta['starting_time'] == {'nanoseconds_since_epoch': min(logs)}
    assert meta['duration'] == {'nanoseconds': max(logs) - min(logs)}
    topics = {t['topic_metadata']['name']: t for t in meta['topics_with_message_count']}
    assert set(topics) == {s[0] for s in samples}
    for topic, type_name, _, _ in samples:
        entry = topics[topic]
        assert entry['message_count'] == 3
        assert entry['topic_metadata']['type'] == type_name
        assert entry['topic_metadata']['serialization_format'] == 'cdr'
        assert entry['topic_metadata']['type_description_hash'].startswith('RIHS01_')
        assert isinstance(entry['topic_metadata']['offered_qos_profiles'], list)
    assert topics['/impactor_state']['topic_metadata']['offered_qos_profiles'] == [
        _qos(depth=1, durability='transient_local')]
    assert meta['relative_file_paths'] == ['run_0.mcap']
    assert meta['files'] == [{'path': 'run_0.mcap', 'starting_time': meta['starting_time'],
                              'duration': meta['duration'], 'message_count': 18}]
    assert meta['compression_format'] == '' and meta['compression_mode'] == ''
    assert meta['ros_distro'] == os.environ.get('ROS_DISTRO', 'jazzy')


# --------------------------------------------------------------------------- (e), (f) crashes

def _start_child(tmp_path, rate=200):
    out, times = tmp_path / 'child.mcap', tmp_path / 'times.txt'
    env = dict(os.environ, PYTHONPATH=str(HERE.parent))
    child = subprocess.Popen([sys.executable, str(HERE / 'record_child.py'), str(out),
                              str(times), str(rate)], stdout=subprocess.PIPE, text=True,
                             env=env)
    assert child.stdout.readline().strip() == 'ready'
    return child, out, times


def _times(path):
    """Return {message index: write time (ns)} from the child's side file."""
    return {int(m.group(1)): int(m.group(2))
            for m in re.finditer(r'^(\d+) (\d+)$', path.read_text(), re.M)}


@pytest.mark.ros
def test_kill_9_loses_at_most_the_last_second(tmp_path, capsys):
    """SIGKILL after ~3 s at 200 msg/s: `study recover` writes a file holding every message
    written more than 1 s before the kill, a gap-free prefix, with its log time and payload."""
    child, out, times_path = _start_child(tmp_path)
    time.sleep(3.0)
    kill_ns = time.time_ns()
    child.send_signal(signal.SIGKILL)
    child.wait(timeout=10)
    written = _times(times_path)
    assert len(written) > 400   # the child really ran at about 200 msg/s

    recovered = tmp_path / 'recovered.mcap'
    assert study_main(['recover', str(out), str(recovered), '--json']) == 0
    report = json.loads(capsys.readouterr().out)
    assert not report['complete'] and report['metadata'] == ['impact_damper_sim']
    summary, messages, metadata = _read_all(recovered)
    assert summary is not None and 'rosbag2' in metadata
    got = {int(d.data): log for _, _, log, _, _, d in messages}
    assert report['messages'] == len(got) == report['topics']['/counter']
    assert sorted(got) == list(range(len(got)))   # a prefix without gaps
    assert all(written[i] == log for i, log in got.items())
    must_have = {i for i, t in written.items() if t < kill_ns - 1_000_000_000}
    assert must_have <= set(got), f'lost {sorted(must_have - set(got))[:5]}...'
    loss_s = (kill_ns - max(got.values())) / 1e9
    print(f'\nkill -9: {len(got)} of {len(written)} messages recovered; data lost: the '
          f'last {loss_s:.3f} s')


@pytest.mark.ros
@pytest.mark.parametrize('signum', [signal.SIGINT, signal.SIGTERM])
def test_sigint_sigterm_finalize_the_file(tmp_path, signum):
    """SIGINT (closed by the main code) and SIGTERM (closed inside the signal handler): the
    file has a summary and the rosbag2 record, and holds every message the child logged as
    written (at most one more)."""
    child, out, times_path = _start_child(tmp_path)
    try:
        time.sleep(0.7)
        child.send_signal(signum)
        stdout, _ = child.communicate(timeout=30)
    finally:
        if child.poll() is None:   # never leave a recording process behind
            child.kill()
            child.wait()
    assert child.returncode == 0
    stats = json.loads(stdout.strip().splitlines()[-1])
    written = _times(times_path)
    with open(out, 'rb') as f:
        reader = _reader(f)
        summary = reader.get_summary()
        assert summary is not None
        assert {m.name for m in reader.iter_metadata()} == {'impact_damper_sim', 'rosbag2'}
    n = summary.statistics.message_count
    assert len(written) <= n <= len(written) + 1
    assert stats['messages_written'] == n and stats['messages_dropped'] == 0
    assert stats['error'] is None and stats['closed']


def test_recorder_left_open_is_finalized_at_exit(tmp_path):
    """A program that forgets close() still leaves a finished file (atexit closes it)."""
    path = tmp_path / 'forgot.mcap'
    code = ('import sys; from impact_damper_sim.recording import AsyncRecorder; '
            'r = AsyncRecorder(sys.argv[1]); '
            "[r.write('/v', 'std_msgs/msg/Float64', None, b'\\0\\1\\0\\0' + bytes(8), i, i) "
            'for i in range(1000)]')
    env = dict(os.environ, PYTHONPATH=str(HERE.parent))
    subprocess.run([sys.executable, '-c', code, str(path)], check=True, env=env, timeout=30)
    with open(path, 'rb') as f:
        summary = _reader(f).get_summary()
    assert summary is not None and summary.statistics.message_count == 1000


# --------------------------------------------------------------------------- (g) overwrite

def test_existing_file_is_not_overwritten(tmp_path):
    """Writer, recorder and `study recover` refuse an existing file, naming it; it is
    unchanged; overwrite=True replaces it."""
    path = tmp_path / 'keep.mcap'
    path.write_bytes(b'precious')
    for make in (Rosbag2McapWriter, AsyncRecorder):
        with pytest.raises(FileExistsError, match=re.escape(str(path))):
            make(path)
    assert path.read_bytes() == b'precious'
    Rosbag2McapWriter(path, overwrite=True).close()
    assert path.read_bytes().startswith(MAGIC)


def test_recover_cli_refuses_existing_output(tmp_path, capsys):
    src, out = tmp_path / 'src.mcap', tmp_path / 'out.mcap'
    Rosbag2McapWriter(src).close()
    out.write_bytes(b'precious')
    assert study_main(['recover', str(src), str(out)]) == 2
    err = capsys.readouterr().err
    assert str(out) in err and '--overwrite' in err and 'Traceback' not in err
    assert out.read_bytes() == b'precious'
    assert study_main(['recover', str(src), str(out), '--overwrite']) == 0
    assert 'recovered 0 messages' in capsys.readouterr().out


# --------------------------------------------------------------------------- (h) disk errors

@pytest.mark.skipif(not os.path.exists('/dev/full'), reason='needs /dev/full')
def test_disk_full_is_reported_not_raised():
    """On /dev/full every write fails with ENOSPC: reported once (attribute and callback),
    never raised; write() returns False and counts the drop; close() does not raise."""
    errors = []
    writer = Rosbag2McapWriter('/dev/full', overwrite=True, on_error=errors.append)
    assert isinstance(writer.error, OSError) and writer.error.errno == 28   # ENOSPC
    assert writer.write('/x', 'std_msgs/msg/Float64', None, bytes(12), T0, T0) is False
    writer.add_metadata('a', {'b': 'c'})
    writer.poll()
    writer.close()
    writer.close()
    assert errors == [writer.error] and writer.stats()['messages_dropped'] == 1


@pytest.mark.ros
@pytest.mark.skipif(not os.path.exists('/dev/full'), reason='needs /dev/full')
def test_disk_full_mid_run_keeps_earlier_messages(tmp_path):
    """The disk fills up mid-run (the recorder's fd is redirected to /dev/full): the error is in
    stats(), write() keeps returning without raising, and everything flushed before is
    recoverable, payloads intact."""
    from rclpy.serialization import serialize_message
    from std_msgs.msg import Float64
    path = tmp_path / 'full.mcap'
    recorder = AsyncRecorder(path, flush_period=0.05)
    for i in range(100):
        recorder.write('/v', 'std_msgs/msg/Float64', None,
                       serialize_message(Float64(data=float(i))), T0 + i, T0 + i)
    deadline = time.monotonic() + 5   # wait until the time-based flush has put all 100 on disk
    while recover(path, tmp_path / 'probe.mcap', overwrite=True).messages < 100:
        assert time.monotonic() < deadline, 'the first 100 messages never reached the file'
        time.sleep(0.02)
    full = os.open('/dev/full', os.O_WRONLY)
    os.dup2(full, recorder._writer._fd)
    os.close(full)
    accepted = [recorder.write('/v', 'std_msgs/msg/Float64', None,
                               serialize_message(Float64(data=-1.0)), T0 + 1000 + i, T0)
                for i in range(2000)]
    stats = recorder.close()
    assert 'No space left' in stats['error'] and stats['messages_dropped'] > 0
    assert accepted[0] is True   # the failure shows in stats(), the caller is never blocked
    report = recover(path, tmp_path / 'rec.mcap')
    _, messages, _ = _read_all(tmp_path / 'rec.mcap')
    assert [d.data for *_, d in messages] == [float(i) for i in range(100)]
    assert report.messages == 100


# --------------------------------------------------------------------------- (i) recovery

@pytest.mark.ros
def test_recover_every_cut_keeps_exactly_the_complete_chunks(tmp_path):
    """Cut a finished file at many byte offsets: recovery keeps exactly the messages of the
    chunks that end before the cut (from the file's own chunk index), never a partial one."""
    from rclpy.serialization import serialize_message
    from std_msgs.msg import Float64
    full = tmp_path / 'full.mcap'
    with Rosbag2McapWriter(full, chunk_size=2048) as writer:
        writer.add_metadata('impact_damper_sim', {'k': 'v'})
        for i in range(600):
            writer.write('/v', 'std_msgs/msg/Float64', None,
                         serialize_message(Float64(data=float(i))), T0 + i, T0 + i)
    blob = full.read_bytes()
    summary, _, _ = _read_all(full)
    chunks = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
    assert len(chunks) > 5
    # message i has log time T0 + i, so a chunk's time range gives its message count
    per_chunk = [c.message_end_time - c.message_start_time + 1 for c in chunks]
    assert sum(per_chunk) == 600
    cuts = sorted({len(blob) * k // 40 for k in range(1, 40)}
                  | {c.chunk_start_offset + c.chunk_length for c in chunks}
                  | {c.chunk_start_offset + c.chunk_length - 1 for c in chunks})
    for cut in cuts:
        src = tmp_path / 'cut.mcap'
        src.write_bytes(blob[:cut])
        try:
            report = recover(src, tmp_path / 'out.mcap', overwrite=True)
        except RecoveryError as exc:   # only a cut inside the header is unrecoverable
            assert 'no complete MCAP header' in str(exc) and cut < 120, cut
            continue
        expected = sum(n for c, n in zip(chunks, per_chunk)
                       if c.chunk_start_offset + c.chunk_length <= cut)
        assert report.messages == expected, cut
        _, messages, metadata = _read_all(tmp_path / 'out.mcap')
        assert [d.data for *_, d in messages] == [float(i) for i in range(expected)]
        assert 'rosbag2' in metadata and 'impact_damper_sim' in metadata
    assert recover(full, tmp_path / 'same.mcap').complete


@pytest.mark.parametrize('content, fragment', [
    (b'', 'empty'),
    (b'this is not an mcap file at all', 'not an MCAP file'),
    (MAGIC[:5], 'too short'),
    (MAGIC, 'no complete MCAP header'),
    (MAGIC + b'\x01\xff\xff', 'no complete MCAP header'),
])
def test_recover_bad_input_is_a_clear_error(tmp_path, capsys, content, fragment):
    """Garbage, empty and truncated-header inputs: RecoveryError, and exit 2 from the CLI with
    one message and no traceback; no output file is created."""
    src, out = tmp_path / 'bad.mcap', tmp_path / 'out.mcap'
    src.write_bytes(content)
    with pytest.raises(RecoveryError, match=fragment):
        recover(src, out)
    assert study_main(['recover', str(src), str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith('study: error: ') and fragment in err and 'Traceback' not in err
    assert not out.exists()


def test_recover_refuses_non_ros2_mcap_and_missing_file(tmp_path, capsys):
    from mcap.writer import CompressionType, Writer
    other = tmp_path / 'other.mcap'
    with open(other, 'wb') as f:
        w = Writer(f, compression=CompressionType.NONE)
        w.start(profile='', library='x')
        w.finish()
    with pytest.raises(RecoveryError, match="not a ROS 2 MCAP file"):
        recover(other, tmp_path / 'o.mcap')
    assert study_main(['recover', str(tmp_path / 'missing.mcap'), str(tmp_path / 'o.mcap')]) == 2
    assert 'no such file' in capsys.readouterr().err


# --------------------------------------------------------------------------- flushing, queue

def test_low_rate_chunk_reaches_the_file_after_flush_period(tmp_path):
    """One message at a low rate: not in the file before flush_period has passed, in it (and
    recoverable from the unfinished file) after poll() past the period."""
    clock = [100.0]
    path = tmp_path / 'slow.mcap'
    writer = Rosbag2McapWriter(path, clock=lambda: clock[0], flush_period=0.5)
    writer.write('/v', 'std_msgs/msg/Float64', None, b'\0\1\0\0' + bytes(8), T0, T0)
    clock[0] += 0.4
    writer.poll()
    assert recover(path, tmp_path / 'a.mcap').messages == 0
    clock[0] += 0.11
    writer.poll()
    assert recover(path, tmp_path / 'b.mcap').messages == 1
    writer.close()


def test_async_recorder_counts_drops_and_closes_twice(tmp_path):
    """A full queue drops (counted, never blocks); written + dropped = offered; close() is
    idempotent; writes after close are dropped; the high-water mark respects the bound."""
    recorder = AsyncRecorder(tmp_path / 'q.mcap', max_queue=50, wake_period=0.5)
    payload = b'\0\1\0\0' + bytes(8)
    offered = 3000
    for i in range(offered):
        recorder.write('/v', 'std_msgs/msg/Float64', None, payload, T0 + i, T0 + i)
    first = recorder.close()
    assert recorder.close() == first
    assert recorder.write('/v', 'std_msgs/msg/Float64', None, payload, T0, T0) is False
    stats = recorder.stats()
    assert stats['messages_written'] + stats['messages_dropped'] == offered + 1
    assert stats['messages_dropped'] > 0 and 0 < stats['queue_high_water'] <= 50
    with open(tmp_path / 'q.mcap', 'rb') as f:
        assert _reader(f).get_summary().statistics.message_count == stats['messages_written']


@pytest.mark.ros
def test_async_write_leaves_the_encoding_to_the_writer_thread(tmp_path, monkeypatch):
    """The stepping loop pays for a queue append, not for MCAP encoding: every call of the
    MCAP writer's ``write`` runs on the recorder's own thread, none on the caller's. (Its
    caller-side cost, about 3 us per message, is a benchmark figure, not a test.)"""
    import threading

    from rclpy.qos import qos_profile_sensor_data
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import Imu

    from impact_damper_sim.recording import async_recorder
    threads = []
    original = async_recorder.Rosbag2McapWriter.write

    def spy(self, *args, **kwargs):
        threads.append(threading.get_ident())
        return original(self, *args, **kwargs)

    monkeypatch.setattr(async_recorder.Rosbag2McapWriter, 'write', spy)
    data = serialize_message(Imu())
    n = 2000
    recorder = AsyncRecorder(tmp_path / 'perf.mcap', max_queue=n + 1)
    for i in range(n):
        recorder.write('/accel/s1', 'sensor_msgs/msg/Imu', qos_profile_sensor_data, data,
                       T0 + i, T0 + i)
    stats = recorder.close()
    assert stats['messages_written'] == n and stats['messages_dropped'] == 0
    assert len(threads) == n
    assert threading.get_ident() not in threads
    assert set(threads) == {recorder._thread.ident}


@pytest.mark.ros
def test_recover_skips_a_corrupt_chunk_and_keeps_what_follows(tmp_path):
    """One chunk's contents broken, its framing and everything after it intact: recovery keeps
    every other chunk and says how many messages the broken one held (it stopped there and
    kept 23,912 of 74,423 messages before)."""
    import struct

    from rclpy.serialization import serialize_message
    from std_msgs.msg import Float64
    full = tmp_path / 'full.mcap'
    with Rosbag2McapWriter(full, chunk_size=2048) as writer:
        for i in range(600):
            writer.write('/v', 'std_msgs/msg/Float64', None,
                         serialize_message(Float64(data=float(i))), T0 + i, T0 + i)
    summary, _, _ = _read_all(full)
    chunks = sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset)
    bad = chunks[len(chunks) // 2]
    lost = bad.message_end_time - bad.message_start_time + 1
    blob = bytearray(full.read_bytes())
    # the first record inside the chunk: opcode, then its length; make that length absurd
    first = bad.chunk_start_offset + 1 + 8 + 8 + 8 + 8 + 4 + 4 + len(bad.compression) + 8
    blob[first + 1:first + 9] = struct.pack('<Q', 2**40)
    src = tmp_path / 'corrupt.mcap'
    src.write_bytes(bytes(blob))
    report = recover(src, tmp_path / 'out.mcap')
    assert report.corrupt_chunks == 1 and report.corrupt_chunk_messages == lost
    assert report.messages == 600 - lost and report.complete
    _, messages, _ = _read_all(tmp_path / 'out.mcap')
    kept = [d.data for *_, d in messages]
    missing = set(range(bad.message_start_time - T0, bad.message_end_time - T0 + 1))
    assert kept == [float(i) for i in range(600) if i not in missing]
