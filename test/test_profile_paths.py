"""The speed profile's one-segment paths return the general path's bits.

Times that share a segment of the piecewise-linear speed (a chunk's output times, one
instant) are evaluated with the segment's values as Python floats, and the unbalance forces
of all bearings at once; both must give exactly the numbers of the general path (one knot
search per element, a loop over bearings), which the tests here force by switching the
one-segment paths off. Compared as bit patterns: equal floats are not enough (-0 vs +0).
"""
import math

import numpy as np
import pytest

from impact_damper_sim.integrate.forcing import Forcing
from impact_damper_sim.scene import excitation
from impact_damper_sim.scene.excitation import (
    CommandedSpeed,
    UnbalanceForce,
    unbalance_forcing,
)
from speed_profile_cases import speed_profiles


def _bits(value):
    a = np.asarray(value, dtype=float)
    return type(value), a.shape, a.view(np.uint64).tolist()


def _profiles():
    return speed_profiles(7, signed_zero=True)


def _times(profile):
    """Scalars and chunks inside segments, across knots, before and after, and bad ones."""
    knots = profile._knots().t
    out = [0.0, np.asarray(float(knots[-1])), np.asarray(-0.0), np.nan, np.inf, -1e200]
    for start in (knots[0] - 0.7, knots[0], knots[-1], knots[-1] + 4.0,
                  0.5 * (knots[0] + knots[-1])):
        out.append(np.asarray(start + 1e-4))
        grid = start + 5e-4 * np.arange(21)
        out += [grid, grid[::-1].copy(), grid - 0.005, start + 5e-4 * np.arange(100)]
    for knot in knots:
        out += [np.asarray(np.nextafter(knot, -np.inf)), knot + 5e-4 * np.arange(-3, 4)]
    out += [np.empty(0), np.array([1.0, np.nan]), np.array([2.0, -np.inf, 1.0]),
            np.linspace(-1.0, 9.0, 7).reshape(7, 1)]
    return out


def _angles(profile):
    phi = profile._knots().phi
    top = float(profile.angle(profile._knots().t[-1] + 3.0))
    out = [np.asarray(0.0), -1.0, np.nan, 2 * math.pi * np.arange(1, 6)]
    out += [np.asarray(float(p)) for p in phi] + [np.asarray(np.nextafter(p, np.inf)) for p in phi]
    for a0 in np.linspace(0.0, top, 9):
        out += [np.asarray(a0 + 0.3), a0 + 2 * math.pi * np.arange(4), a0 + np.arange(30.0)]
    return out


def _general(monkeypatch):
    """Switch the one-segment paths off: every query takes the general path."""
    monkeypatch.setattr(excitation._Knots, '_segment', lambda self, t: None)
    monkeypatch.setattr(excitation._Knots, '_time_one', lambda self, a: None)


def _all_queries(profile):
    results = []
    for t in _times(profile):
        for name in ('angle', 'speed', 'acceleration', 'state'):
            value = getattr(profile, name)(t)
            results.append([_bits(v) for v in value] if name == 'state' else _bits(value))
    for angle in _angles(profile):
        with np.errstate(all='ignore'):
            results.append(_bits(profile.time_at_angle(angle)))
    return results


@pytest.mark.parametrize('index', range(10))
def test_one_segment_queries_match_the_general_path(index, monkeypatch):
    profile = list(_profiles())[index]
    with np.errstate(all='ignore'):
        fast = _all_queries(profile)
        _general(monkeypatch)
        general = _all_queries(profile)
    assert len(fast) == len(general) > 100
    for i, (a, b) in enumerate(zip(fast, general)):
        assert a == b, f'query {i}: {a} != {b}'


def test_the_fast_paths_are_taken_for_a_chunk_and_an_instant():
    drive = CommandedSpeed(0.0, 480.0)
    drive.command(0.0, 2400.0)
    knots = drive._knots()
    grid = 1.0 + 5e-4 * np.arange(21)
    assert knots._segment(grid) == (0, 480.0)   # the ramp
    assert knots._segment(grid + 9.0) == (1, 0.0)   # the hold
    assert knots._segment(np.asarray(7.0)) == (1, 0.0)
    assert knots._segment(grid + 3.995) is None   # across the knot at 5 s
    assert knots._segment(np.array([1.0, np.nan])) is None
    assert knots._time_one(np.array([300.0, 306.0])) is not None   # ramp from rest
    assert knots._time_one(np.array([1e5, 1e5 + 6.0])) is not None   # hold


@pytest.mark.parametrize('pairs, n_inputs', [([[0, 1], [2, 3]], None), ([[3, 0], [1, 5]], 7),
                                             ([[0, 1], [1, 2]], None)])
def test_unbalance_forces_match_the_bearing_loop(pairs, n_inputs, monkeypatch):
    """All bearings at once (steady, ramp, across a knot) = the loop over bearings."""
    cases = []
    for profile in list(_profiles())[::2]:
        for multiplier in (1.0, 0.0):
            force = UnbalanceForce(profile, [[4.7e-4, 0.0], [3.8e-4, -0.0]], pairs, multiplier,
                                   n_inputs=n_inputs)
            for t in _times(profile)[6:-4]:   # the chunks and instants
                times = np.atleast_1d(np.asarray(t, dtype=float)).ravel()
                got = force.forces(times)
                phi, omega, alpha = profile.state(times)
                want = force._summed(times, force.n_inputs, phi, omega * omega, alpha)
                cases.append((_bits(got), _bits(want)))
                assert got.flags.c_contiguous and got.shape == (times.size, force.n_inputs)
    _general(monkeypatch)   # and the general path's state gives the same forces again
    for (got, want) in cases:
        assert got == want


def test_sampled_unbalance_is_the_forces_added_to_zeros():
    drive = CommandedSpeed(0.0, 480.0)
    drive.command(0.0, 2400.0)
    force = UnbalanceForce(drive, [[4.7e-4, 0.0], [3.8e-4, 1.0]], [[0, 1], [2, 3]], 0.0)
    forcing = unbalance_forcing(4, force)
    grid = 6.0 + 5e-4 * np.arange(21)
    value = force.forces(grid)
    assert _bits(forcing.sample(grid)) == _bits(np.zeros((21, 4)) + value)
    negative = Forcing(2, [lambda t: np.stack([-0.0 * t, np.asfortranarray(-t)], axis=1)])
    sampled = negative.sample(grid)
    assert not np.signbit(sampled[:, 0]).any() and sampled.flags.c_contiguous
    with pytest.raises(ValueError, match='non-finite'):
        Forcing(1, [lambda t: np.where(t > 6.005, np.inf, t)[:, None]]).sample(grid)
    with pytest.raises(ValueError, match='shape'):
        Forcing(2, [lambda t: t[:, None]]).sample(grid)
