"""The node's publish path: who reads a topic is asked once per refill, and the bytes go to
the middleware through :func:`~impact_damper_sim.ros.outlets.write_raw` (rclpy's
``Publisher.publish`` for bytes, without its per-call Python), never into a destroyed
publisher."""
import pytest

from node_helpers import FakeClock, make_node
from node_helpers import wake as _wake

LINEAR_HPOTP = ['impactors=[]']


def test_readers_are_asked_once_per_refill_and_a_new_reader_waits_one_refill(ros_context):
    """One subscription-count query per outlet and refill (1 + ``Outbox.REFILL`` chunks
    stepped back to back), not per outlet and chunk. Nobody reading, the samples are counted
    and never put on the wire; a reader that appears gets the samples of the next refill,
    each sent at its time (pairs at most, ``imu_group`` 2)."""
    clock = FakeClock()
    node = make_node(ros_context, 'hpotp', LINEAR_HPOTP, clock=clock, imu_rate=2000.0,
                     imu_group=2)
    out = node.publishing.accel[0]
    asked, reading, chunks = [0], [False], [0]

    def has_subscribers():
        asked[0] += 1
        return reading[0]

    out.has_subscribers = has_subscribers
    sent = []
    out.pub.publish = sent.append   # what goes on the wire
    step = node._step

    def counted(n):
        chunks[0] += 1
        return step(n)

    node._step = counted
    try:
        while clock.now < 1000.3:
            clock.now += _wake(node)
        assert asked[0] >= 5   # 0.3 s: a refill every 50 ms
        assert chunks[0] == (1 + node.outbox.REFILL) * asked[0]   # not once per chunk
        assert sent == [] and out.count >= 0.9 * 2000 * 0.3   # counted, never on the wire
        reading[0] = True
        n_asked = asked[0]
        while asked[0] == n_asked:   # up to the next refill
            clock.now += _wake(node)
        queued = [wire for _, key, _, wire in node.outbox.pending if key is out]
        assert len(queued) >= 90 and all(queued)   # that refill's samples wait for a reader
        groups = []
        end = clock.now + 0.2
        while clock.now < end:
            n0 = len(sent)
            clock.now += _wake(node)
            groups.append(len(sent) - n0)
        assert sum(groups) >= 0.9 * 2000 * 0.2 and max(groups) <= 2
    finally:
        node.destroy_node()


def test_a_replaced_publish_is_honoured_and_the_bytes_are_the_recorded_ones(ros_context):
    """Tests and benches watch the wire by replacing the rclpy publisher's ``publish`` on the
    instance (bench/node_realtime.py times the sends so): the outlet sends through it from the
    next refill on, and it gets the very bytes the recorder gets."""
    node = make_node(ros_context, 'sdof', imu_rate=2000.0)
    out = node.publishing.accel[0]
    sent, recorded = [], []
    out.pub.publish = sent.append
    out.has_subscribers = lambda: True
    out._record = lambda topic, type_name, qos, data, ns=None: recorded.append(data)
    try:
        for _ in range(3):
            node._wall.now += 0.01
            node.tick()
        assert len(sent) >= 40 and sent == recorded
    finally:
        node.destroy_node()


def test_write_raw_into_a_destroyed_publisher_raises_and_does_not_crash(ros_context):
    """A stepping thread that outlived ``destroy_node`` (stuck past ``STOP_WAIT``) and sends
    afterwards gets rclpy's InvalidHandle, as ``Publisher.publish`` would raise: the handle
    is held while the bytes are written, never used once destroyed."""
    from rclpy.exceptions import InvalidHandle
    from sensor_msgs.msg import Imu

    from impact_damper_sim.ros.cdr import serialize
    from impact_damper_sim.ros.outlets import write_raw
    node = make_node(ros_context, 'sdof')
    out = node.publishing.accel[0]
    handle = out.pub.handle
    data = serialize(Imu())
    write_raw(handle, data)   # alive: sent (nobody reads it)
    out.publish_raw(data)
    assert out.count == 1
    node.destroy_node()
    with pytest.raises(InvalidHandle):
        write_raw(handle, data)
    with pytest.raises(InvalidHandle):
        out.publish_raw(data)
