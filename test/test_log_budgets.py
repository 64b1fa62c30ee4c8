"""Log readers under abuse (study report, replay): files that are not logs are refused in one
line before a byte is read from them, and so are absurd timestamps."""
import os
import threading
import time

from impact_damper_sim.recording import Rosbag2McapWriter
from impact_damper_sim.studies.log_reader import MAX_LOG_SPAN_NS, LogError, RosLog


def _refused_quickly(path, why):
    result = {}

    def open_it():
        try:
            RosLog(path)
        except LogError as exc:
            result['error'] = str(exc)

    t = threading.Thread(target=open_it, daemon=True)   # a FIFO would block the test
    t.start()
    t.join(5.0)
    assert not t.is_alive(), f'{path}: still reading after 5 s'
    assert why in result.get('error', ''), result


def test_non_regular_files_are_refused_before_reading(tmp_path):
    """/dev/zero read 4 GB in 7 s, a FIFO blocked report for good."""
    zero = tmp_path / 'zero.mcap'
    zero.symlink_to('/dev/zero')
    fifo = tmp_path / 'fifo.mcap'
    os.mkfifo(fifo)
    (tmp_path / 'dir.mcap').mkdir()
    for path in (zero, fifo, tmp_path / 'dir.mcap'):
        _refused_quickly(path, 'not a regular file')


def test_an_absurd_timestamp_is_refused(tmp_path):
    """One message at log time 2^63 - 1 made replay wait 292 years."""
    path = tmp_path / 'absurd.mcap'
    with Rosbag2McapWriter(path) as writer:
        writer.add_topic('/x', 'std_msgs/msg/Float64')
        data = b'\x00\x01\x00\x00' + bytes(8)
        writer.write('/x', 'std_msgs/msg/Float64', None, data, 1_000, 1_000)
        writer.write('/x', 'std_msgs/msg/Float64', None, data, 2**63 - 1, 2**63 - 1)
    _refused_quickly(path, 'absurd timestamp')
    ok = tmp_path / 'ok.mcap'
    with Rosbag2McapWriter(ok) as writer:   # a year of log time is still a log
        writer.add_topic('/x', 'std_msgs/msg/Float64')
        writer.write('/x', 'std_msgs/msg/Float64', None, data, 0, 0)
        writer.write('/x', 'std_msgs/msg/Float64', None, data, MAX_LOG_SPAN_NS,
                     MAX_LOG_SPAN_NS)
    t0 = time.process_time()   # CPU, not wall: another job on the machine does not count
    assert RosLog(ok).message_count == 2 and time.process_time() - t0 < 5.0
