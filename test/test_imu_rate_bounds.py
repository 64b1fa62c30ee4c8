"""The per-sample Imu rate's lower bound: a valid-looking ``imu_rate`` never makes the node spin.

``imu_rate`` is ``sample_rate / k`` for a whole number k, decimated through an anti-alias FIR
of ~52 k taps whose history every stepped chunk copies: 1 mHz from 2 kHz (k = 2e6) was 1e8
taps, GBs copied per 10 ms chunk, the node at 100 % of a core. k is capped at
``MAX_DECIMATION_FACTOR`` and a lower rate is refused at start, naming the parameter and the
range; the pacing itself stays sane at the slowest rate left.
"""
import math

import pytest

from impact_damper_sim.live.filters import MAX_DECIMATION_FACTOR
from impact_damper_sim.live.pacing import Outbox, Pacer
from impact_damper_sim.live.realtime import LiveSimulation
from impact_damper_sim.live.streams import live_scene
from impact_damper_sim.scene.schema import SceneError
from node_helpers import FakeClock, make_node


@pytest.mark.parametrize('sample_rate, imu_rate', [
    (2000.0, 0.001),     # the reported value: k = 2e6
    (2000.0, 0.1),       # k = 2e4: 1e6 taps, 9 ms of a 10 ms chunk (measured)
    (2000.0, 0.5),       # k = 4000, a whole number, just beyond the cap
    (20000.0, 1.0),      # k = 2e4 at rbs's rate
])
def test_an_imu_rate_below_sample_rate_over_the_cap_is_refused_with_the_range(sample_rate,
                                                                                 imu_rate):
    model, target = live_scene('sdof')
    low = sample_rate / MAX_DECIMATION_FACTOR
    with pytest.raises(SceneError, match=rf'^imu rate: must be in \[{low:g}, '
                                         rf'{sample_rate:g}\] Hz .*got {imu_rate:g} Hz'):
        LiveSimulation(model, sample_rate=sample_rate, imu_rate=imu_rate,
                       initial_target=target)


@pytest.mark.parametrize('sample_rate', [100.0, 2000.0, 20000.0])
def test_the_lowest_imu_rate_left_has_a_bounded_filter(sample_rate):
    """At the cap (1 Hz from 2 kHz) the FIR has ~52 x k taps: ~1e5, not 1e8."""
    model, target = live_scene('sdof')
    live = LiveSimulation(model, sample_rate=sample_rate,
                          imu_rate=sample_rate / MAX_DECIMATION_FACTOR, initial_target=target)
    assert live.imu_rate == pytest.approx(sample_rate / MAX_DECIMATION_FACTOR, rel=1e-12)
    taps = len(live._decimator.taps)
    assert 50 * MAX_DECIMATION_FACTOR < taps < 54 * MAX_DECIMATION_FACTOR
    # delay ~26 Imu periods (s)
    assert live._decimator.delay / sample_rate * live.imu_rate == pytest.approx(25.8, abs=0.3)


def test_the_node_refuses_a_tiny_imu_rate_naming_the_parameter(ros_context):
    from impact_damper_sim.ros.parameters import ParameterError
    with pytest.raises(ParameterError) as refused:
        make_node(ros_context, 'sdof', sample_rate=2000.0, imu_rate=0.001)
    assert "parameter 'imu_rate': must be in [1, 2000] Hz" in str(refused.value)
    assert 'got 0.001 Hz' in str(refused.value)


def test_pacing_at_the_slowest_imu_rate_sends_on_time_and_sleeps_until_the_next_item():
    """At 1 Hz (the slowest Imu stream from 2 kHz) a wake-up's horizon is ``early`` (1.2 ms
    for pairs), not 1.1 Imu periods, it may send a group of samples, and the thread sleeps
    until the next full-rate item, never 0 (no spin) and never an Imu period (no stall)."""
    clock = FakeClock()
    box = Outbox(Pacer(1.0, 0.0, clock=clock), imu_rate=1.0, lookahead=0.01, chunk=0.01,
                 group=2)
    for i in range(1, 21):                      # a 10 ms chunk of 2 kHz batch items
        box.put(i * 500_000, 'batch', None, True)
    box.send_due(clock.now, 0.01, lambda *item: None)
    horizon, burst = box.allowance(clock.now)
    assert horizon - clock.now == pytest.approx(1.2e-3, abs=1e-9)
    assert burst == 2
    sent = []
    clock.now += 2e-3
    box.send_due(clock.now, 0.01, lambda *item: sent.append(item[0]))
    assert sent == [1_500_000, 2_000_000, 2_500_000, 3_000_000]
    sleep = box.wait(False, clock.now, 0.01, longest=0.1)
    assert sleep == pytest.approx(1.5e-3, abs=1e-12)
    assert math.isfinite(sleep) and sleep > 0


def test_imu_group_reaches_the_outbox_and_a_bad_one_is_refused_naming_it(ros_context):
    """``imu_group`` (default 4) is the group size of the node's outbox; 5 is refused at
    start naming the parameter and its range."""
    from impact_damper_sim.ros.parameters import ParameterError
    node = make_node(ros_context, 'sdof', sample_rate=2000.0)
    try:
        assert node.outbox.burst == 4 and node.outbox.early == pytest.approx(3.2e-3)
    finally:
        node.destroy_node()
    node = make_node(ros_context, 'sdof', sample_rate=2000.0, imu_group=1)
    try:
        assert node.outbox.burst == 1 and node.outbox.early == pytest.approx(2e-4)
    finally:
        node.destroy_node()
    with pytest.raises(ParameterError) as refused:
        make_node(ros_context, 'sdof', sample_rate=2000.0, imu_group=5)
    assert "parameter 'imu_group'" in str(refused.value) and '[1, 4]' in str(refused.value)
