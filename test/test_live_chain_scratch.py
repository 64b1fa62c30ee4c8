"""The live step's scratch arrays and fast paths (issue 39) keep the numbers of the plain path.

``StreamingDecimator`` keeps two buffers per chunk length that take turns and its gather
positions per chunk pattern; a chunk length that repeats, alternates or changes must still give
the windows of a fresh concatenation, bit for bit. ``LiveSimulation.step`` skips the fault hooks
of an accelerometer without faults; the injector must still know the last value read, which a
``stuck`` fault added later holds.
"""
from __future__ import annotations

import numpy as np
import pytest

from decimator_reference import decimate_reference
from impact_damper_sim.live.filters import StreamingDecimator
from impact_damper_sim.live.realtime import LiveSimulation
from impact_damper_sim.live.streams import live_scene


@pytest.mark.parametrize('factor, channels', [(2, 6), (5, 3), (20, 12)])
def test_decimator_reused_buffers_give_the_fresh_windows(factor, channels):
    rng = np.random.default_rng(11)
    # steady lengths (the buffers take turns), alternating ones, one-offs, empty chunks, and
    # more lengths than the caches keep (they are cleared and refilled)
    sizes = [20] * 6 + [7, 20, 7, 20, 0, 1, 1, 1] + list(range(30, 50)) + [20] * 4
    chunks = [rng.normal(0.0, 2.0, (k, channels)) for k in sizes]
    dec = StreamingDecimator(factor, 1000.0 * factor, channels)
    got = [dec.apply(x) for x in chunks]
    want = decimate_reference(StreamingDecimator(factor, 1000.0 * factor, channels), chunks)
    assert sum(len(i) for i, _ in got) > 20
    for (i_got, y_got), (i_want, y_want) in zip(got, want):
        assert np.array_equal(i_got, i_want)
        assert y_got.tobytes() == y_want.tobytes()   # bit for bit, not within a tolerance
    # an output is not overwritten by the next chunk's (the kept arrays are scratch only)
    first = dec.apply(chunks[0])[1].copy()
    again = dec.apply(chunks[0])
    dec.apply(chunks[1])
    assert not np.shares_memory(first, again[1])


def test_stuck_added_to_a_fault_free_stream_holds_the_last_published_value():
    scene, target = live_scene('sdof', ())
    live = LiveSimulation(scene, initial_target=target, noise_std=0.05, seed=4)
    live.step(0)
    name = live.accelerometers[0].name
    for _ in range(5):   # fault-free chunks: the fast path, no fault hooks
        batch = live.step(20)
    assert batch is not None and batch.valid is not None and batch.valid.all()
    last = batch.linear_acceleration[-1, 0].copy()
    assert np.all(last != 0.0)   # noise: a held value is not a coincidence
    live.add_fault({'kind': 'stuck', 'accelerometer': name})   # from the next sample on
    held = live.step(20)
    assert held is not None and held.truth is not None
    assert np.array_equal(held.linear_acceleration[:, 0], np.broadcast_to(last, (20, 3)))
    # the truth is the model's and goes on
    assert not np.array_equal(held.truth[0, 0], held.truth[-1, 0])
