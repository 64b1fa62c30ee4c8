"""One stepping thread for several machines of a process (``plant_host --stepping shared``).

The loop's contract (:class:`impact_damper_sim.ros.stepping.SharedStepping`): every member is
stepped in real time by the one thread; a member that stops is never cycled again while the
others go on; the thread ends with its last member; a member's parameter change ends the
shared wait; one member's failure is its own. Deadlines here are for a loaded machine, not
figures: what is asserted is that the sim clocks move or stand still.
"""
import threading
import time

import pytest

pytestmark = pytest.mark.ros


def _machines(ctx, n, tag, **params):
    from rclpy.parameter import Parameter

    from impact_damper_sim.ros.vibration_node import VibrationNode
    return [VibrationNode(context=ctx, start_stepping=False, namespace=f'{tag}{k}',
                          parameter_overrides=[
                              Parameter('scene', value='sdof'),
                              *[Parameter(name, value=v) for name, v in params.items()]])
            for k in range(n)]


def _until(condition, timeout=30.0):
    end = time.monotonic() + timeout
    while not condition() and time.monotonic() < end:
        time.sleep(0.01)
    return condition()


def test_wait_for_sleeps_short_waits_and_a_wake_ends_a_long_one():
    from impact_damper_sim.ros.stepping import LONG_WAIT, wait_for
    wake = threading.Event()
    t0 = time.monotonic()
    for delay in (0.0, -1.0, float('nan')):   # no wait at all
        wait_for(delay, wake, 10.0)
    wait_for(LONG_WAIT / 5, wake, 10.0)   # a plain sleep
    assert time.monotonic() - t0 >= LONG_WAIT / 5
    wake.set()
    t0 = time.monotonic()
    wait_for(1e6, wake, 1e6)   # a long wait that the set event ends at once, and clears
    assert time.monotonic() - t0 < 5.0 and not wake.is_set()
    t0 = time.monotonic()
    wait_for(1e6, wake, 0.1)   # never longer than `longest`
    assert 0.1 <= time.monotonic() - t0 < 5.0


def test_one_thread_steps_every_machine_and_a_stopped_one_stands_still(ros_context):
    """Three sdof machines on one SharedStepping: one thread, all three in real time; the
    first stopped stands still while the others go on; the thread ends with the last."""
    from impact_damper_sim.ros.stepping import SharedStepping
    nodes = _machines(ros_context, 3, f'st{id(ros_context) % 1000}_')
    stepping = SharedStepping(nodes[0].MAX_WAIT)
    try:
        for node in nodes:
            node.start(stepping)
        # each took its refill phase: chunks 0, 1 and 2 stepped ahead, nothing stepped since
        assert [round(n.live.t / n._tick_period) for n in nodes] == [0, 1, 2]
        stepping.start()
        assert {id(node._thread) for node in nodes} == {id(stepping.thread)}
        assert stepping.thread.name == 'vibration_stepping'
        assert _until(lambda: min(n.live.t for n in nodes) > 0.3), [n.live.t for n in nodes]
        # real time, not flat out: the sim clocks stay within a chunk or so of each other
        assert max(n.live.t for n in nodes) - min(n.live.t for n in nodes) < 0.25
        nodes[0].stop()
        assert nodes[0] not in stepping.members and nodes[0]._thread is None
        t_stopped = nodes[0].live.t
        others = [n.live.t for n in nodes[1:]]
        assert _until(lambda: all(n.live.t > t + 0.2 for n, t in zip(nodes[1:], others)))
        assert nodes[0].live.t == t_stopped   # never cycled again
        assert stepping.thread.is_alive()
        for node in nodes[1:]:
            node.stop()
        stepping.thread.join(10.0)
        assert not stepping.thread.is_alive()   # it ends with its last machine
    finally:
        for node in nodes:
            node.destroy_node()


def test_a_machines_new_real_time_factor_ends_the_shared_wait(ros_context):
    """A tiny factor asks the loop to wait for hours; with the longest wait made endless,
    the stream can only move again if setting 1.0 on that machine woke the shared thread."""
    from rclpy.parameter import Parameter

    from impact_damper_sim.ros.stepping import SharedStepping
    (node,) = _machines(ros_context, 1, f'sw{id(ros_context) % 1000}_')
    node.publishing.accel[0].has_subscribers = lambda: True   # each sample waits its time
    stepping = SharedStepping(longest=1e6)
    try:
        node.start(stepping)
        stepping.start()
        assert node._wake is stepping.wake
        assert _until(lambda: node.live.t > 0.2)
        assert node.set_parameters([Parameter('real_time_factor', value=1e-6)])[0].successful
        time.sleep(0.3)   # into the long wait
        t0 = node.live.t
        time.sleep(0.3)
        assert node.live.t == t0   # waiting: nothing stepped
        assert node.set_parameters([Parameter('real_time_factor', value=1.0)])[0].successful
        assert _until(lambda: node.live.t > t0 + 0.02), (t0, node.live.t)
    finally:
        node.destroy_node()


def test_one_machines_failure_is_its_own(ros_context):
    """A cycle that raises marks that machine's simulation failed (its diagnostics say so);
    the other machine of the thread goes on stepping."""
    from impact_damper_sim.ros.stepping import SharedStepping
    broken, fine = _machines(ros_context, 2, f'sf{id(ros_context) % 1000}_')
    stepping = SharedStepping(broken.MAX_WAIT)

    def fail():
        raise RuntimeError('a bug in the cycle')
    try:
        broken._cycle = fail
        broken.start(stepping)
        fine.start(stepping)
        stepping.start()
        assert _until(lambda: broken.live.failure is not None)
        assert 'RuntimeError: a bug in the cycle' in broken.live.failure
        t0 = fine.live.t
        assert _until(lambda: fine.live.t > t0 + 0.2)
        assert fine.live.failure is None
        broken.publish_diagnostics()
        assert broken.last_diagnostics['level'] == 2
    finally:
        broken.destroy_node()
        fine.destroy_node()


def test_a_refill_lets_the_other_machines_send_between_its_chunks(ros_context):
    """While one member steps its refill (REFILL + 1 chunks back to back), every other
    member's due items leave between two chunks, not after the whole refill."""
    from impact_damper_sim.live.pacing import Outbox
    from impact_damper_sim.ros.stepping import SharedStepping
    refilling, waiting = _machines(ros_context, 2, f'sr{id(ros_context) % 1000}_')
    stepping = SharedStepping(refilling.MAX_WAIT)
    calls = []
    try:
        refilling.start(stepping)
        waiting.start(stepping)   # (not started: the test drives the cycles itself)
        original_step, original_send = refilling._step, waiting._send_due

        def step(n):
            calls.append('step')
            return original_step(n)

        def send(now):
            calls.append('send')
            return original_send(now)
        refilling._step, waiting._send_due = step, send
        refilling.outbox.reset(refilling.pacer.real_time_factor, refilling.live.t + 1.0)
        refilling._cycle()   # its buffer is short: a whole refill
        assert calls.count('step') == Outbox.REFILL + 1, calls
        # a send of the other machine between every two chunks of the refill
        assert calls == ['step'] + ['send', 'step'] * Outbox.REFILL, calls
    finally:
        refilling.destroy_node()
        waiting.destroy_node()
