"""The pacing and delivery rules of :mod:`impact_damper_sim.live.pacing`, on a fake clock.

No ROS and no simulation: items are plain tuples, the clock is a number the test moves.
"""
import math

import pytest

from impact_damper_sim.live.pacing import Outbox, Pacer, PacingError

IMU_RATE = 2000.0   # Hz: per-sample stream
PERIOD = 1.0 / IMU_RATE


class Clock:
    def __init__(self, now=1000.0):
        self.now = now

    def __call__(self):
        return self.now


def outbox(rtf=1.0, clock=None, seconds=0.2, wire=True, group=Outbox.GROUP):
    """An outbox holding ``seconds`` of one accelerometer's 2 kHz samples from t = 0, and
    what it sent: (ns, wall s)."""
    clock = clock or Clock()
    box = Outbox(Pacer(rtf, 0.0, clock=clock), imu_rate=IMU_RATE, lookahead=0.01,
                 chunk=0.01, limited=['acc'], group=group)
    for k in range(1, int(round(seconds * IMU_RATE)) + 1):
        box.put(k * 500_000, 'acc', b'', wire)
    sent = []
    return box, clock, sent, lambda ns, key, payload, wire: sent.append((ns, clock.now))


def test_items_never_leave_more_than_early_before_their_time():
    box, clock, sent, send = outbox()
    while clock.now < 1000.1:
        held = box.send_due(clock.now, 0.2, send)
        clock.now += box.wait(held, clock.now, 0.2, 0.01)
    assert len(sent) >= 190
    early = max(box.pacer.wall_at(ns * 1e-9) - wall for ns, wall in sent)
    assert early <= box.early + 1e-12


def test_a_backlog_drains_at_catch_up_rate_in_groups_of_max_burst():
    """After a 20 ms stall 40 samples are due: each wake-up CATCH_UP apart sends at most
    MAX_BURST, and over the catch-up they leave at no more than CATCH_UP_RATE x 2 kHz."""
    box, clock, sent, send = outbox()
    clock.now += 0.020
    groups, t_start = [], clock.now
    box._last_wake = clock.now   # the previous wake-up was just before the stall ended
    while True:
        n0 = len(sent)
        held = box.send_due(clock.now, 0.2, send)
        groups.append(len(sent) - n0)
        if not held:
            break
        clock.now += Outbox.CATCH_UP
    assert max(groups) <= Outbox.MAX_BURST
    assert sum(groups) >= 40
    # earned at CATCH_UP_RATE x the rate, plus the first wake-up's BURST-or-1-ms allowance
    assert sum(groups) <= Outbox.CATCH_UP_RATE * IMU_RATE * (clock.now - t_start) + 2 * (
        Outbox.MAX_BURST) + 1e-9 * IMU_RATE
    assert [ns for ns, _ in sent] == sorted(ns for ns, _ in sent)   # in order, once


def test_delivered_time_never_decreases_between_resets():
    box, clock, sent, send = outbox()
    delivered = []
    while clock.now < 1000.05:
        held = box.send_due(clock.now, 0.2, send)
        delivered.append(box.delivered_t(clock.now, 0.2))
        clock.now += max(box.wait(held, clock.now, 0.2, 0.01), 1e-4)
    assert all(b >= a for a, b in zip(delivered, delivered[1:]))
    assert delivered[-1] == pytest.approx(0.05, abs=2 * PERIOD)


def test_factor_zero_sends_everything_at_once():
    box, clock, sent, send = outbox(rtf=0.0)
    assert not box.send_due(clock.now, 0.2, send)
    assert len(sent) == 400 and not box.pending
    assert box.plan(clock.now, 0.2).step   # as fast as possible: always step


def test_a_reset_makes_no_deficit():
    """Time the outbox stood still (a changed factor, start-up) is not caught up."""
    box, clock, sent, send = outbox()
    clock.now += 5.0   # 5 s with nothing sent
    box.reset(1.0)
    plan = box.plan(clock.now, 0.2)
    assert plan.lag <= 0.0 and box.pacer.deficits == 0
    box.send_due(clock.now, 0.2, send)
    assert len(sent) <= box.burst   # on time again: a group, not 10 000 samples


def test_a_long_lag_is_dropped_as_one_deficit():
    box, clock, sent, send = outbox(seconds=0.0)
    clock.now += 1.0   # nothing was stepped for 1 s, max_lag 0.25 s
    plan = box.plan(clock.now, 0.0)
    assert plan.step and plan.late and plan.lag == pytest.approx(1.0)
    assert box.pacer.deficits == 1
    assert box.pacer.target(0.0)[0] == pytest.approx(box.pacer.max_lag)


def test_items_nobody_receives_do_not_wait_for_their_time():
    box, clock, sent, send = outbox(wire=False)
    box.send_due(clock.now, 0.2, send)
    assert len(sent) == 400   # 0.2 s of samples at once: no wake-up per sample


def test_a_bad_factor_is_refused_naming_the_quantity():
    pacer = Pacer(1.0, 0.0, clock=Clock())
    with pytest.raises(PacingError, match=r'^real-time factor: must be finite and >= 0'):
        pacer.reset(math.nan, 0.0)
    assert pacer.real_time_factor == 1.0


def test_stepping_refills_refill_chunks_beyond_lookahead_then_waits():
    """A simulated stepping loop at factor 1 on an empty outbox: stepping starts when less
    than the lookahead (one chunk) is stepped ahead of the schedule and then steps 1 +
    REFILL chunks at once; it never runs more than lookahead + REFILL + 1 chunks ahead, and
    the stream is never short of stepped samples."""
    clock = Clock()
    box = Outbox(Pacer(1.0, 0.0, clock=clock), imu_rate=IMU_RATE, lookahead=0.01, chunk=0.01)
    t_stepped, bursts = 0.0, []
    while clock.now < 1001.0:
        plan = box.plan(clock.now, t_stepped)
        if plan.chunks:
            t_stepped += 0.01 * plan.chunks
            bursts.append(plan.chunks)
            continue             # the node loops at once after a step
        ahead = t_stepped - box.pacer.sim_at(clock.now)
        assert 0.0 <= ahead <= 0.01 * (2 + Outbox.REFILL) + 1e-9
        clock.now += 0.001
    assert set(bursts) == {1 + Outbox.REFILL}
    # 1 s of stream in refills of 5 chunks: about 20 of them, not 100 single chunks
    assert len(bursts) == pytest.approx(1.0 / (0.01 * (1 + Outbox.REFILL)), abs=1)


def test_factor_zero_steps_one_chunk_per_plan():
    box, clock, sent, send = outbox(rtf=0.0)
    assert box.plan(clock.now, 0.2).chunks == 1


@pytest.mark.parametrize('group', [1, 2, 4])
def test_on_time_a_wake_up_sends_one_group_each_sample_by_its_time(group):
    """At 1 kHz on time, each wake-up sends exactly ``group`` samples (so 1000 / group
    wake-ups a second; the first, at t = 0 with the first sample 1 ms away, fewer), none of
    them more than ``group - 1`` periods + 0.2 ms before its time and none after it."""
    clock = Clock()
    box = Outbox(Pacer(1.0, 0.0, clock=clock), imu_rate=1000.0, lookahead=0.01, chunk=0.01,
                 limited=['acc'], group=group)
    for k in range(1, 201):
        box.put(k * 1_000_000, 'acc', b'', True)
    sent, groups = [], []
    while box.pending:
        n0 = len(sent)
        held = box.send_due(clock.now, 0.2, lambda ns, *_: sent.append((ns, clock.now)))
        if len(sent) > n0:
            groups.append(len(sent) - n0)
        assert not held
        clock.now += box.wait(held, clock.now, 0.2, 0.01)
    assert set(groups[1:-1]) == {group} and max(groups) == group and sum(groups) == 200
    assert len(groups) <= 200 // group + 1
    lead = [box.pacer.wall_at(ns * 1e-9) - wall for ns, wall in sent]
    assert max(lead) == pytest.approx((group - 1) * 1e-3, abs=1e-9)
    assert max(lead) <= box.early and min(lead) >= -1e-12


@pytest.mark.parametrize('group', [0, 5, 2.0, True])
def test_a_bad_group_is_refused_naming_it_and_its_range(group):
    with pytest.raises(PacingError, match=r'Imu group: .*\[1, 4\], got'):
        Outbox(Pacer(1.0, 0.0), imu_rate=1000.0, lookahead=0.01, chunk=0.01, group=group)
