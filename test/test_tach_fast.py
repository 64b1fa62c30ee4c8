"""The live step's Python-number paths return what the array paths return, bit for bit.

``SpeedProfile.angle_speed`` and ``SpeedProfile.keyphasor`` (the tachometer of
``LiveSimulation.step``) against ``state``, ``time_at_angle``, ``np.clip`` and ``speed``; and
``FaultInjector.follow`` against ``after_limit`` (the state kept, the errors). Compared as bit
patterns: equal floats are not enough (-0 vs +0).
"""
import math

import numpy as np
import pytest

from impact_damper_sim.live.faults import FaultInjector
from impact_damper_sim.live.realtime import KEYPHASOR_DTYPE, LiveSimulation, _turns
from impact_damper_sim.live.streams import live_scene
from impact_damper_sim.scene.excitation import (
    ConstantSpeed,
    PaperRamp,
)
from speed_profile_cases import speed_profiles

TWO_PI = 2.0 * math.pi


def _bits(value):
    a = np.asarray(value, dtype=float)
    return a.shape, a.view(np.uint64).tolist()


def _profiles():
    return speed_profiles(11)


PROFILES = list(_profiles())


def _chunks(profile):
    """Chunks of 20 output times: inside segments, across knots, before and after them."""
    knots = profile._knots().t
    for start in (knots[0] - 0.7, knots[0], knots[-1] - 0.004, knots[-1], knots[-1] + 4.0,
                  0.5 * (knots[0] + knots[-1]), 0.0):
        yield start + 5e-4 * np.arange(1, 21)


@pytest.mark.parametrize('profile', PROFILES)
def test_angle_speed_is_state_without_the_acceleration(profile):
    for t in _chunks(profile):
        angle, speed = profile.angle_speed(t)
        ref_angle, ref_speed, _ = profile.state(t)
        assert _bits(angle) == _bits(ref_angle)
        assert _bits(speed) == _bits(ref_speed)
        assert type(angle) is np.ndarray and type(speed) is np.ndarray


def _keyphasor_arrays(profile, first, last, t_lo, t_hi):
    """What the tachometer computed before the lists: the profile's array methods."""
    revolution = np.arange(first, last + 1, dtype=np.int64)
    at = np.clip(profile.time_at_angle(TWO_PI * revolution), t_lo, t_hi)
    return at, np.atleast_1d(profile.speed(at))


@pytest.mark.parametrize('profile', PROFILES)
def test_keyphasor_lists_are_the_array_methods_bits(profile):
    checked = 0
    for t in _chunks(profile):
        t_lo = float(t[0]) - 5e-4
        phi_lo = float(profile.angle(np.asarray(t_lo)))
        phi_hi = float(profile.angle(t)[-1])
        first, last = _turns(phi_lo) + 1, _turns(phi_hi)
        # the chunk's own turns, and wider ranges whose clipped times pile up at the bounds
        for lo, hi in ((first, last), (max(first - 3, 1), last + 3), (1, 4)):
            if hi < lo:
                continue
            at, speed = profile.keyphasor(lo, hi, t_lo, float(t[-1]))
            ref_at, ref_speed = _keyphasor_arrays(profile, lo, hi, t_lo, float(t[-1]))
            assert type(at) is list and type(speed) is list
            assert _bits(at) == _bits(ref_at)
            assert _bits(speed) == _bits(ref_speed)
            checked += 1
    assert checked >= 7


def test_keyphasor_takes_the_array_methods_where_the_lists_cannot():
    # an angle a rotor at rest never reaches: time_at_angle says inf, clipped to the bound
    profile = ConstantSpeed(0.0)
    assert profile._knots().time_list([TWO_PI]) is None
    at, speed = profile.keyphasor(1, 2, 0.5, 0.6)
    assert at == [0.6, 0.6] and speed == [0.0, 0.0]
    # the turn at the first knot's angle (0 rad: before any segment) is solved by the arrays
    ramp = PaperRamp(2400.0, 5.0)
    assert ramp._knots().time_list([0.0]) is None
    assert _bits(ramp.keyphasor(0, 2, 0.0, 1.0)[0]) == _bits(
        _keyphasor_arrays(ramp, 0, 2, 0.0, 1.0)[0])


def _reference_tachometer(profile, t, phi_end, t_end):
    """LiveSimulation._tachometer as it was: every value from the array methods."""
    angle, speed, _ = profile.state(t)
    angle, speed = np.atleast_1d(angle), np.atleast_1d(speed)
    first, last = _turns(phi_end) + 1, _turns(float(angle[-1]))
    revolution = np.arange(first, last + 1, dtype=np.int64)
    keyphasor = np.empty(revolution.size, KEYPHASOR_DTYPE)
    if revolution.size:
        at = np.clip(profile.time_at_angle(TWO_PI * revolution), t_end, t[-1])
        keyphasor['t'], keyphasor['revolution'] = at, revolution
        keyphasor['speed'] = np.atleast_1d(profile.speed(at))
    return angle, speed, keyphasor


def test_the_live_tachometer_is_the_array_methods_bytes_through_commands():
    scene, target = live_scene('hpotp', ())
    live = LiveSimulation(scene, initial_target=target)
    live.step(0)
    turns = 0
    for i in range(120):
        if i == 40:
            live.command_speed(0.5 * target)   # a ramp down from here: new knots
        if i == 80:
            live.set_speed_rate(5000.0)
            live.command_speed(target)
        phi_end, t_end = live._phi_end, live._t_end
        batch = live.step(7 if i % 3 else 20)
        angle, speed, keyphasor = _reference_tachometer(live.profile, batch.t, phi_end, t_end)
        assert batch.shaft_angle.tobytes() == angle.tobytes()
        assert batch.shaft_speed.tobytes() == speed.tobytes()
        assert batch.keyphasor.dtype == KEYPHASOR_DTYPE
        assert batch.keyphasor.tobytes() == keyphasor.tobytes()
        turns += batch.keyphasor.size
    assert turns > 10   # the runs turned: keyphasor events were compared


def _state(inj):
    return inj._done[:], [None if v is None else v.tobytes() for v in inj._last]


@pytest.mark.parametrize('with_fault', [False, True])
def test_follow_keeps_what_after_limit_keeps(with_fault):
    fs = 2000.0
    rng = np.random.default_rng(3)
    a, b = FaultInjector(['a', 'b'], fs), FaultInjector(['a', 'b'], fs)
    if with_fault:
        for inj in (a, b):
            inj.add({'accelerometer': 'b', 'kind': 'stuck', 'onset': 0.01})
    n = 1
    for k in (20, 0, 7, 20, 1):
        t = n / fs + np.arange(k) / fs
        for acc in (0, 1):
            x = rng.normal(size=(k, 3))
            y = x.copy()
            a.after_limit(t, x, acc)
            b.follow(t[0] if k else t, y, acc)
            assert x.tobytes() == y.tobytes()
        assert _state(a) == _state(b)
        n += k
    assert b._done == [n, n] and b._last[0] is not None


def test_follow_refuses_a_gap_as_after_limit_does():
    inj = FaultInjector(['a'], 2000.0)
    inj.follow(np.float64(1 / 2000.0), np.zeros((20, 3)), 0)
    with pytest.raises(ValueError, match='chunks must follow each other') as gap:
        inj.follow(np.float64(22 / 2000.0), np.zeros((20, 3)), 0)
    ref = FaultInjector(['a'], 2000.0)
    ref.after_limit(1 / 2000.0, np.zeros((20, 3)), 0)
    with pytest.raises(ValueError) as ref_gap:
        ref.after_limit(22 / 2000.0, np.zeros((20, 3)), 0)
    assert str(gap.value) == str(ref_gap.value)
    with pytest.raises(OverflowError):
        inj.follow(np.float64(np.inf), np.zeros((1, 3)), 0)
