"""The plant ``recorder`` (issue 39 item 5): the namespaces' topics, raw, into one MCAP that an
independent reader (``mcap``) reads back, with the plant's labels in the metadata; every
message it took is in the file after SIGTERM."""
import os
import signal
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

import pytest

rclpy = pytest.importorskip('rclpy')

from mcap.reader import make_reader  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402
from sensor_msgs.msg import Imu, PointCloud2  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from impact_damper_sim.ros.recorder import (  # noqa: E402
    PLANT_METADATA,
    PlantRecorder,
    matches,
    plant_metadata,
)
from impact_damper_sim.scene.plant import load_plant  # noqa: E402

pytestmark = pytest.mark.ros
ROOT = Path(__file__).resolve().parents[1]
RELIABLE = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
BEST_EFFORT = QoSProfile(depth=100, reliability=ReliabilityPolicy.BEST_EFFORT)


def _read(path):
    with open(path, 'rb') as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        messages = list(reader.iter_messages(log_time_order=False))
    # log time = arrival, publish time = the sender's stamp: sent before it arrived
    assert all(0 < m.publish_time <= m.log_time for _, _, m in messages)
    assert any(m.publish_time < m.log_time for _, _, m in messages)
    return summary, metadata, Counter(ch.topic for _, ch, _ in messages)


def test_patterns_take_a_name_token_each():
    batch = ('accel/*/batch',)
    assert matches('/pump1/accel/s1/batch', 'pump1', batch)
    assert matches('/pump1/accel/s1/batch', '/pump1', batch)
    assert not matches('/pump10/accel/s1/batch', 'pump1', batch)   # another namespace
    assert not matches('/pump1/accel/s1', 'pump1', batch)
    assert not matches('/pump1/accel/s1/batch', 'pump1', ('accel/*',))   # one token only
    assert matches('/plant/pump1/impacts', 'plant/pump1', ('impacts',))
    assert matches('/x/y/accel/s1/batch', '/', batch)                     # any namespace


def _wait(until, timeout, step):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if until():
            return True
        step()
    return False


def test_one_log_of_two_namespaces_read_back(ros_context, tmp_path):
    tag = f'rt{os.getpid()}'
    src = rclpy.create_node('source', context=ros_context)
    pubs = {f'/{tag}a/accel/s1/batch': src.create_publisher(PointCloud2, f'/{tag}a/accel/s1/batch',
                                                             RELIABLE),
            f'/{tag}b/accel/s1/batch': src.create_publisher(PointCloud2, f'/{tag}b/accel/s1/batch',
                                                             RELIABLE),
            f'/{tag}a/accel/s1': src.create_publisher(Imu, f'/{tag}a/accel/s1', BEST_EFFORT)}
    # not recorded: another namespace, a topic no pattern matches
    other = [src.create_publisher(PointCloud2, f'/{tag}c/accel/s1/batch', RELIABLE),
             src.create_publisher(String, f'/{tag}a/chatter', RELIABLE)]
    node = rclpy.create_node('recorder', context=ros_context)
    path = tmp_path / 'plant.mcap'
    plant = load_plant(ROOT / 'config' / 'plants' / 'mixed.yaml')
    rec = PlantRecorder(node, path, [f'{tag}a', f'{tag}b'], diagnostics=False,
                        metadata=plant_metadata(plant, [f'{tag}a', f'{tag}b']))
    try:
        assert _wait(lambda: set(pubs) <= set(rec.counts), 15, rec.spin_once), rec.counts
        assert _wait(lambda: all(p.get_subscription_count() for p in pubs.values()), 15,
                     rec.spin_once)
        assert set(rec.counts) == set(pubs)   # nothing else
        n = 40
        for i in range(n):
            for topic, pub in pubs.items():
                pub.publish(Imu() if 'batch' not in topic else PointCloud2(width=i + 1))
            for p in other:
                p.publish(p.msg_type())
            rec.spin_once(0.0)
        _wait(lambda: sum(rec.counts.values()) >= 3 * n, 10, lambda: rec.spin_once(0.05))
        rec.take_all()
    finally:
        stats = rec.close()
        node.destroy_node()
        src.destroy_node()
    assert stats['finished'] and stats['error'] is None, stats
    summary, metadata, counts = _read(path)
    assert summary is not None
    # every message taken is in the file; the reliable topics lost none
    assert counts == Counter(stats['topic_counts']) == Counter(rec.counts), (counts, rec.counts)
    assert counts[f'/{tag}a/accel/s1/batch'] == counts[f'/{tag}b/accel/s1/batch'] == n
    assert counts[f'/{tag}a/accel/s1'] >= 0.9 * n          # best effort
    labels = metadata[PLANT_METADATA]
    assert labels['plant'] == 'mixed' and labels['seed'] == '200'
    assert 'machine: rbs1' in labels['machines'] and 'seed: 201' in labels['machines']
    assert 'rosbag2' in metadata                            # finished as rosbag2 does
    types = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
    assert types[f'/{tag}a/accel/s1'] == 'sensor_msgs/msg/Imu'


def test_sigterm_finishes_the_file_with_every_message_taken(ros_context, tmp_path):
    """The recorder as a process (``python -m``): SIGTERM after the messages went out gives a
    finished log holding them all, and exit status 0."""
    tag = f'rs{os.getpid()}'
    src = rclpy.create_node('source', context=ros_context)
    topic = f'/{tag}/accel/s1/batch'
    pub = src.create_publisher(PointCloud2, topic, RELIABLE)
    path = tmp_path / 'one.mcap'
    env = dict(os.environ, ROS_DOMAIN_ID=str(ros_context.get_domain_id()))
    proc = subprocess.Popen(
        [sys.executable, '-m', 'impact_damper_sim.ros.recorder', '--ros-args',
         '-p', f'output:={path}', '-p', f'namespaces:=[{tag}]', '-p', 'diagnostics:=false'],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        start_new_session=True)
    try:
        assert _wait(lambda: pub.get_subscription_count() > 0, 30,
                     lambda: time.sleep(0.1)), 'the recorder never subscribed'
        for i in range(200):
            pub.publish(PointCloud2(width=i + 1))
            time.sleep(0.002)
        time.sleep(1.0)   # delivered; what is in flight at a stop is not the recorder's
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
        src.destroy_node()
    assert proc.returncode == 0, err
    assert 'Traceback' not in err, err
    assert f'recorded 200 messages on 1 topics to {path}' in err + out, err
    summary, metadata, counts = _read(path)
    assert summary is not None and 'rosbag2' in metadata
    assert counts == Counter({topic: 200})


@pytest.mark.parametrize('given', [['-p', 'namespaces:=[nobody]'], []],
                         ids=['namespaces', 'no-namespaces'])
def test_a_file_that_exists_is_refused_in_one_line(tmp_path, given):
    """Refused in one line, the file untouched; also with ``namespaces`` not given (an
    uninitialised string array, which ``get_parameter`` refuses to read)."""
    path = tmp_path / 'kept.mcap'
    path.write_bytes(b'keep me')
    done = subprocess.run(
        [sys.executable, '-m', 'impact_damper_sim.ros.recorder', '--ros-args',
         '-p', f'output:={path}', *given],
        capture_output=True, text=True, timeout=60,
        env=dict(os.environ, ROS_DOMAIN_ID='79'))
    assert done.returncode == 2, done.stderr
    assert done.stderr.count('\n') == 1 and 'overwrite:=true' in done.stderr, done.stderr
    assert path.read_bytes() == b'keep me'
