"""The cheaper per-chunk paths of vibration_node give the bytes and numbers the plain ones did.

Issue 39 cut the node's per-chunk Python (bench/node_cost.py measures it); each cut here is
checked against the form it replaced, bit for bit: the decimator's gathered windows against
``sliding_window_view``, the clock message's bytes against ``CdrWriter``'s, the rotor
state from one knot search against three, and the propagator's cached kernel arguments against
the state arrays they must stay views of.
"""
from __future__ import annotations

import numpy as np
import pytest

from decimator_reference import decimate_reference
from impact_damper_sim.live.filters import StreamingDecimator
from impact_damper_sim.recording.batches import CdrWriter
from impact_damper_sim.recording.message_cdr import clock_cdr
from impact_damper_sim.scene.excitation import CommandedSpeed


@pytest.mark.parametrize('factor, rate, channels', [(2, 2000.0, 6), (20, 20000.0, 12),
                                                     (3, 3000.0, 1)])
def test_decimator_windows_round_as_the_sliding_view(factor, rate, channels):
    rng = np.random.default_rng(7)
    sizes = [20, 1, 0, 37, 200, 5, 64, 1500, 333, 2]
    chunks = [rng.normal(0.0, 3.0, (k, channels)) * 10.0 ** rng.integers(-3, 4)
              for k in sizes]
    dec = StreamingDecimator(factor, rate, channels)
    got = [dec.apply(x) for x in chunks]
    want = decimate_reference(StreamingDecimator(factor, rate, channels), chunks)
    assert sum(len(i) for i, _ in got) > 10
    for (i_got, y_got), (i_want, y_want) in zip(got, want):
        assert np.array_equal(i_got, i_want)
        assert y_got.tobytes() == y_want.tobytes()   # bit for bit, not within a tolerance


@pytest.mark.parametrize('ns', [0, 1, 999_999_999, 1_000_000_000, 12_345_678_901_234])
def test_clock_bytes_are_the_writers(ns):
    w = CdrWriter()
    w.stamp(ns)
    assert clock_cdr(ns) == w.bytes()


def test_rotor_state_from_one_search_equals_three():
    profile = CommandedSpeed(0.0, 480.0)
    profile.command(0.0, 2400.0)
    profile.command(2.5, 600.0)
    for t in np.linspace(0.0, 9.0, 181):
        phi, speed, rate = profile.state(np.asarray(t))
        assert float(speed) == float(profile.speed(np.asarray(t)))
        assert float(rate) == float(profile.acceleration(np.asarray(t)))
        assert float(phi) == float(profile.angle(np.asarray(t)))


def test_cached_kernel_arguments_stay_views_of_the_state():
    from impact_damper_sim.live.realtime import LiveSimulation
    from impact_damper_sim.live.streams import live_scene
    scene, target = live_scene('sdof')
    live = LiveSimulation(scene, initial_target=target)
    prop = live.sim.integrator
    live.step(10)
    ni = len(prop._imp_dim)
    args = prop._impactor_args(ni)
    assert args is prop._impactor_args(ni)   # made once
    for array, view in ((prop._imp_z, args[7]), (prop._imp_v, args[8]),
                        (prop._stuck, args[9]), (prop._count_step, args[14])):
        assert np.shares_memory(array, view)
    # switching the dampers off and on again uses the other (empty) set, then this one
    live.set_dampers_enabled(False)
    live.step(10)
    live.set_dampers_enabled(True)
    live.step(10)
    assert prop._impactor_args(ni) is args
    assert prop._impactor_args(0) is not args
