"""Testing vibration_node's callbacks from plain pytest: no launch, no stepping thread, a
wall clock the test moves. docs/guides/testing-callbacks.md shows this file as it is."""
import pytest

rclpy = pytest.importorskip('rclpy')

from rclpy.parameter import Parameter  # noqa: E402
from std_msgs.msg import Float64  # noqa: E402

from impact_damper_sim.ros.vibration_node import VibrationNode  # noqa: E402


class WallClock:
    """The node's wall clock, moved by the test (s)."""

    def __init__(self):
        self.now = 0.0

    def __call__(self):
        return self.now


def make(context, clock, scene, *overrides, **parameters):
    """A node that steps only when the test calls ``tick()``."""
    return VibrationNode(
        context=context, start_stepping=False, clock=clock, parameter_overrides=[
            Parameter('scene', value=scene), Parameter('overrides', value=list(overrides)),
            *[Parameter(name, value=value) for name, value in parameters.items()]])


def advance(node, clock, seconds):
    """Move the wall clock in 10 ms steps; each tick steps and publishes up to it."""
    for _ in range(round(seconds / 0.01)):
        clock.now += 0.01
        node.tick()


def test_a_speed_command_is_reached_at_the_rate_limit(ros_context):
    clock = WallClock()
    node = make(ros_context, clock, 'hpotp', 'impactors=[]', speed_rate_limit=500.0)
    try:
        node.on_speed_command(Float64(data=100.0))     # rad/s: as if it came over the wire
        advance(node, clock, 0.1)
        speed, rate, unbalance = node.live.rotor_state()
        assert speed == pytest.approx(50.0, rel=1e-9)  # 500 rad/s^2 for 0.1 s
        assert rate == 500.0 and unbalance == 1.0
        advance(node, clock, 0.2)
        assert node.live.rotor_state()[:2] == (100.0, 0.0)   # reached, and held
        assert node.live.t == pytest.approx(0.3, abs=1e-9)   # sim s = wall s at factor 1
    finally:
        node.destroy_node()


def test_a_bad_command_is_counted_and_changes_nothing(ros_context):
    clock = WallClock()
    node = make(ros_context, clock, 'hpotp', 'impactors=[]')
    try:
        node.on_unbalance_command(Float64(data=2.5))
        node.on_unbalance_command(Float64(data=float('nan')))   # refused, logged once
        assert node.live.unbalance.multiplier == 2.5
        assert node.rejected == 1
    finally:
        node.destroy_node()


def test_a_refused_parameter_says_why(ros_context):
    node = make(ros_context, WallClock(), 'sdof')
    try:
        result = node.set_parameters([Parameter('real_time_factor', value=-1.0)])[0]
        assert not result.successful
        assert 'real_time_factor' in result.reason
        assert node.get_parameter('real_time_factor').value == 1.0
    finally:
        node.destroy_node()
