"""Undecodable payloads are skipped with one warning per topic, never republished silently."""
import pytest

pytest.importorskip('rclpy')

from rclpy.serialization import deserialize_message, serialize_message  # noqa: E402
from sensor_msgs.msg import Imu  # noqa: E402
from std_msgs.msg import Float64  # noqa: E402

from impact_damper_sim.recording.payload import PayloadCheck  # noqa: E402


def test_good_payload_passes_and_bad_ones_warn_once_per_topic():
    lines = []
    check = PayloadCheck(deserialize_message, warn=lines.append)
    good = serialize_message(Imu())
    assert check.ok('/imu', Imu, good)
    assert not check.ok('/imu', Imu, good[:10], log_time_ns=123)
    assert not check.ok('/imu', Imu, b'garbage!' * 3)
    assert not check.ok('/imu', Imu, serialize_message(Float64(data=1.0)))   # wrong type
    assert check.ok('/x', Float64, serialize_message(Float64(data=2.0)))
    assert check.skipped == {'/imu': 3}
    assert len(lines) == 1
    assert lines[0].startswith('/imu: skipping a payload that does not decode as '
                               'sensor_msgs/msg/Imu at log time 123 ns (10 bytes')
    assert check.summary() == 3
    assert lines[-1] == '/imu: skipped 3 undecodable payload(s)'


def test_summary_is_silent_without_skips():
    lines = []
    check = PayloadCheck(deserialize_message, warn=lines.append)
    assert check.ok('/x', Float64, serialize_message(Float64(data=2.0)))
    assert check.summary() == 0 and lines == []
