"""Rolling vibration statistics (impact_damper_sim.live.monitoring) against closed-form values.

Samples are stamped ``t_k = t0 + (k + 1/2) / fs``; a window of W s ending on a sample holds
exactly ``W fs`` of them (the one stamped ``now - W`` is outside).
"""
import doctest
import math
from dataclasses import astuple

import numpy as np
import pytest

from impact_damper_sim.live import monitoring
from impact_damper_sim.live.monitor_text import impactor_stuck_flags
from impact_damper_sim.live.monitoring import (
    G0,
    MAX_ACCELERATION,
    RollingVibrationStats,
)

FS = 1000.0   # sample rate (Hz)
#: Largest bias of the Hann-windowed FFT peak refined by a parabola on the log-power
#: (QIFFT without zero padding), in bins; measured 0.016 over a sweep of the bin fraction.
QIFFT_BIAS_BINS = 0.02


def stamps(duration, t0=0.0, fs=FS):
    """Sample stamps (s) of ``duration`` s at ``fs`` Hz, half a period off the grid."""
    return t0 + (np.arange(int(round(duration * fs))) + 0.5) / fs


def tone(t, amplitude, hz, phase=0.0):
    return amplitude * np.sin(2 * np.pi * hz * t + phase)


def test_sine_rms_and_peak_closed_form():
    """x = A sin, y = A cos: RMS A/sqrt(2) per axis over whole periods, |a| = A exactly."""
    a_g, hz, window = 2.0, 40.0, 1.0          # 40 whole periods in the window
    t = stamps(3.0)
    acc = np.zeros((t.size, 3))
    acc[:, 0] = tone(t, a_g * G0, hz, 0.3)
    acc[:, 1] = tone(t, a_g * G0, hz, 0.3 + np.pi / 2)
    stats = RollingVibrationStats(window)
    stats.add_samples('tip', t, acc)
    s = stats.report().sensors['tip']
    assert s.samples == 1000
    # a whole number of periods, 25 samples each: mean(sin^2) = 1/2 exactly (to rounding)
    np.testing.assert_allclose(s.rms_g_axes, [a_g / np.sqrt(2), a_g / np.sqrt(2), 0.0],
                               rtol=1e-12, atol=1e-15)
    assert s.rms_g == pytest.approx(a_g, rel=1e-12)
    assert s.peak_g == pytest.approx(a_g, rel=1e-12)
    # the sample maximum of a sine lies within A (1 - cos(pi f / fs)) below A
    floor = a_g * np.cos(np.pi * hz / FS)
    for peak in s.peak_g_axes[:2]:
        assert floor - 1e-12 <= peak <= a_g + 1e-12
    assert s.samples_per_s == pytest.approx(FS, rel=1e-9)
    assert s.resolution_hz == pytest.approx(1.0 / window, rel=1e-9)


def test_rms_of_partial_periods_within_closed_form_bound():
    """Over a window of W s the mean of sin^2 differs from 1/2 by at most 1/(2 omega W)."""
    a_g, hz, window = 1.5, 40.3, 1.0
    t = stamps(2.0)
    acc = np.zeros((t.size, 3))
    acc[:, 2] = tone(t, a_g * G0, hz, 1.1)
    stats = RollingVibrationStats(window)
    stats.add_samples('s', t, acc)
    rms = stats.report().sensors['s'].rms_g_axes[2]
    bound = 1.0 / (2 * 2 * np.pi * hz * window)
    assert abs(rms ** 2 / a_g ** 2 - 0.5) <= bound
    assert rms == pytest.approx(a_g / np.sqrt(2), rel=bound)


@pytest.mark.parametrize('fraction', np.linspace(0.0, 1.0, 11))
@pytest.mark.parametrize('phase', [0.0, 2.0])
def test_dominant_frequency_within_a_fraction_of_a_bin(fraction, phase):
    hz = 40.0 + fraction      # bin width 1 Hz (1 s window)
    t = stamps(1.5)
    acc = np.zeros((t.size, 3))
    acc[:, 1] = tone(t, 3.0, hz, phase)
    stats = RollingVibrationStats(1.0)
    stats.add_samples('s', t, acc)
    s = stats.report().sensors['s']
    assert s.resolution_hz == pytest.approx(1.0)
    assert abs(s.dominant_hz - hz) <= QIFFT_BIAS_BINS * s.resolution_hz
    assert abs(s.dominant_hz_axes[1] - hz) <= QIFFT_BIAS_BINS * s.resolution_hz
    assert np.isnan(s.dominant_hz_axes[0])        # a zero signal has no dominant frequency


def test_dominant_frequency_per_axis_and_of_the_sensor():
    """Each axis finds its own tone; the sensor's is the strongest one."""
    t = stamps(2.5)
    tones = [(5.0, 40.3), (2.0, 123.7), (1.0, 250.55)]   # (amplitude m/s^2, Hz) per axis
    acc = np.column_stack([tone(t, amp, hz, 0.4) for amp, hz in tones])
    stats = RollingVibrationStats(2.0)
    stats.add_samples('s', t, acc)
    s = stats.report().sensors['s']
    assert s.resolution_hz == pytest.approx(0.5)
    tol = QIFFT_BIAS_BINS * s.resolution_hz
    np.testing.assert_allclose(s.dominant_hz_axes, [hz for _, hz in tones], atol=tol)
    assert s.dominant_hz == pytest.approx(40.3, abs=tol)


def test_dropped_samples_are_interpolated_and_lower_the_rate():
    t = stamps(1.5)
    acc = np.zeros((t.size, 3))
    acc[:, 0] = tone(t, 2.0, 61.4)
    keep = np.random.default_rng(5).random(t.size) > 0.05   # drop about 5 %, not the last
    keep[-1] = True
    stats = RollingVibrationStats(1.0)
    stats.add_samples('s', t[keep], acc[keep])
    s = stats.report().sensors['s']
    inside = t[keep] > t[-1] - 1.0
    assert s.samples == np.count_nonzero(inside)
    first = t[keep][inside][0]
    assert s.samples_per_s == pytest.approx((s.samples - 1) / (t[-1] - first), rel=1e-12)
    assert s.samples_per_s < 0.97 * FS
    assert s.dominant_hz == pytest.approx(61.4, abs=0.05 * s.resolution_hz)


def test_impacts_per_second_of_a_known_train():
    """25 impacts a second: 25 in a 1 s window; before a window has passed, per span."""
    t = stamps(3.0)
    impacts = 0.013 + np.arange(75) / 25.0         # off the sample grid and window ends
    stats = RollingVibrationStats(1.0)
    stats.add_samples('s', t[t < 0.4], np.zeros((np.count_nonzero(t < 0.4), 3)))
    stats.add_impacts(impacts[impacts < 0.4])
    early = stats.report()
    assert early.span == pytest.approx(0.3995 - 0.0005)
    assert early.impacts == 10
    assert early.impacts_per_s == pytest.approx(10 / early.span)
    stats.add_samples('s', t[t >= 0.4], np.zeros((np.count_nonzero(t >= 0.4), 3)))
    stats.add_impacts(impacts[impacts >= 0.4])
    report = stats.report()
    assert report.span == pytest.approx(1.0)
    assert report.impacts == 25
    assert report.impacts_per_s == pytest.approx(25.0, rel=1e-12)


def test_impact_batches_cover_their_interval_even_when_empty():
    """Batches every 10 ms over 1 s, 10 impacts all in 0.4..0.58 s: 10 impacts/s over the
    covered second, where the same impacts one by one cover only 0.18 s."""
    impacts = 0.4 + 0.02 * np.arange(10)
    batched = RollingVibrationStats(2.0)
    starts = 0.01 * np.arange(101)                          # the last batch at 1.0 s
    for start in starts:
        inside = impacts[(impacts >= start) & (impacts < start + 0.01)]
        assert batched.add_impacts(inside, start=start) == inside.size
    report = batched.report()
    assert report.impacts == 10
    assert report.t == pytest.approx(1.0, abs=1e-12)
    assert report.span == pytest.approx(1.0, abs=1e-12)
    assert report.impacts_per_s == pytest.approx(10.0, rel=1e-12)
    single = RollingVibrationStats(2.0)
    single.add_impacts(impacts)
    assert single.report().impacts_per_s == pytest.approx(10 / 0.18, rel=1e-12)


def test_rejections_counted_outside_and_a_sensor_cleared():
    """A malformed batch's rows count as rejected; a sensor that changes source starts over."""
    t = stamps(1.0)
    stats = RollingVibrationStats(1.0)
    stats.add_samples('s', t, np.full((t.size, 3), G0))
    stats.reject_samples('s', 7)
    stats.reject_impacts(3)
    stats.clear_sensor('s')
    later = stamps(0.2, t0=1.0)
    stats.add_samples('s', later, np.full((later.size, 3), 2 * G0))
    report = stats.report()
    assert (report.rejected_samples, report.sensors['s'].rejected_samples) == (7, 7)
    assert report.rejected_impacts == 3
    assert report.sensors['s'].samples == later.size == 200
    assert report.sensors['s'].peak_g == pytest.approx(2 * np.sqrt(3), rel=1e-12)


def test_stuck_fraction_of_a_known_schedule():
    """Two impactors: free, then 0 stuck at 1.0 s, 1 stuck at 1.5 s, 0 free at 2.2 s."""
    stats = RollingVibrationStats(2.0)
    for time, flags in [(0.0, [False, False]), (1.0, [True, False]), (1.5, [True, True]),
                        (2.2, [False, True])]:
        assert stats.update_stuck(time, flags)
    stats.add_impacts([2.5])                       # now = 2.5 s, window (0.5, 2.5]
    report = stats.report()
    # 0 over 0.5 s, 1/2 over 0.5 s, 1 over 0.7 s, 1/2 over 0.3 s, in 2 s
    assert report.stuck_fraction == pytest.approx((0.25 + 0.7 + 0.15) / 2.0, rel=1e-12)
    assert (report.impactors, report.stuck_impactors) == (2, 1)


def test_stuck_fraction_latched_old_state_and_unknown_start():
    stats = RollingVibrationStats(2.0)
    assert np.isnan(stats.report().stuck_fraction)          # nothing known yet
    stats.update_stuck(-10.0, [True, False, False, False])   # a latched state, long ago
    stats.add_samples('s', [2.5], [[0.0, 0.0, 0.0]])
    report = stats.report()
    assert report.stuck_fraction == pytest.approx(0.25)
    # an old state does not widen the span over which impacts are counted
    assert report.span == 0.0 and np.isnan(report.impacts_per_s)

    later = RollingVibrationStats(2.0)
    later.add_samples('s', stamps(3.0), np.zeros((3000, 3)))
    later.update_stuck(2.0, [True])            # known only over the last 0.9995 s: all stuck
    assert later.report().stuck_fraction == pytest.approx(1.0)
    none = RollingVibrationStats(1.0)
    none.update_stuck(0.0, [])                 # a scene without impactors
    assert none.report().stuck_fraction == 0.0


def test_window_eviction():
    """After 2 s at 1 g and 1 s at 3 g, a 1 s window holds only the 3 g part."""
    t = stamps(3.0)
    acc = np.zeros((t.size, 3))
    acc[:, 0] = np.where(t < 2.0, 1.0, 3.0) * G0
    stats = RollingVibrationStats(1.0)
    stats.add_samples('s', t, acc)
    stats.add_impacts([0.5, 1.9, 2.1, 2.9])
    report = stats.report()
    s = report.sensors['s']
    assert s.samples == 1000
    assert s.rms_g == pytest.approx(3.0) and s.peak_g == pytest.approx(3.0)
    assert report.impacts == 2
    stats.window = 0.5                              # shrinking the window evicts at once
    report = stats.report()
    assert report.sensors['s'].samples == 500
    assert report.impacts == 1
    assert report.impacts_per_s == pytest.approx(1 / 0.5)


def test_batches_in_any_chunking_and_order_give_the_same_report():
    t = stamps(1.2)
    acc = np.column_stack([tone(t, 2.0, 40.3), tone(t, 1.0, 80.0), np.cos(t)])
    whole = RollingVibrationStats(1.0)
    whole.add_samples('s', t, acc)
    chunked = RollingVibrationStats(1.0)
    for start in range(0, t.size, 7):
        chunked.add_samples('s', t[start:start + 7], acc[start:start + 7])
    late = RollingVibrationStats(1.0)
    # each block of 50 samples (50 ms) arrives shuffled: late, but by less than a window
    order = np.concatenate([start + np.random.default_rng(start).permutation(50)
                            for start in range(0, t.size, 50)])
    late.add_samples('s', t[order], acc[order])
    expected = whole.report().sensors['s']
    assert chunked.report().sensors['s'] == expected
    assert late.report().sensors['s'] == expected


def test_non_finite_and_absurd_samples_are_rejected_and_counted():
    t = stamps(1.5)
    acc = np.column_stack([tone(t, 2.0, 40.3), np.zeros(t.size), np.zeros(t.size)])
    clean = RollingVibrationStats(1.0)
    clean.add_samples('s', t, acc)
    bad_t = np.concatenate([t, [np.nan, 0.7, 0.8, 0.9]])
    bad_acc = np.concatenate([acc, [[0, 0, 0], [np.nan, 0, 0], [0, np.inf, 0],
                                    [0, 0, -2 * MAX_ACCELERATION]]])
    dirty = RollingVibrationStats(1.0)
    assert dirty.add_samples('s', bad_t, bad_acc) == t.size
    assert dirty.add_impacts([np.nan, 1.2, np.inf]) == 1
    assert not dirty.update_stuck(np.nan, [True])
    report = dirty.report()
    assert report.rejected_samples == 4 and report.sensors['s'].rejected_samples == 4
    assert (report.rejected_impacts, report.rejected_states) == (2, 1)
    stats = report.sensors['s']
    assert stats.rms_g == clean.report().sensors['s'].rms_g
    assert stats.dominant_hz == clean.report().sensors['s'].dominant_hz


def test_clock_going_back_by_more_than_a_window_resets():
    """A restarted simulator: stamps from 0 again after 100 s."""
    stats = RollingVibrationStats(1.0)
    stats.add_samples('s', stamps(1.0, t0=99.0), np.full((1000, 3), G0))
    stats.add_impacts([99.5])
    stats.update_stuck(99.0, [True])
    restart = stamps(0.5)
    stats.add_samples('s', restart, np.full((restart.size, 3), 2 * G0))
    report = stats.report()
    assert report.time_resets == 1
    assert report.t == pytest.approx(restart[-1])
    assert report.sensors['s'].samples == restart.size
    assert report.sensors['s'].peak_g == pytest.approx(2 * np.sqrt(3))
    assert report.impacts == 0 and np.isnan(report.stuck_fraction)

    # the same restart inside one batch: only the samples after the jump are kept
    mixed = RollingVibrationStats(1.0)
    t = np.concatenate([stamps(1.0, t0=99.0), restart])
    acc = np.concatenate([np.full((1000, 3), G0), np.full((restart.size, 3), 2 * G0)])
    assert mixed.add_samples('s', t, acc) == restart.size
    np.testing.assert_equal(astuple(mixed.report().sensors['s']), astuple(report.sensors['s']))


def test_sensor_without_data_reports_nan():
    stats = RollingVibrationStats(1.0, sensors=['quiet'])
    s = stats.report().sensors['quiet']
    assert s.samples == 0 and s.last_sample_t is None
    assert np.isnan(s.rms_g) and np.isnan(s.dominant_hz) and np.isnan(s.samples_per_s)


@pytest.mark.parametrize('window', [0.0, -1.0, np.nan, np.inf])
def test_bad_window_is_refused(window):
    with pytest.raises(ValueError, match='window'):
        RollingVibrationStats(window)


def test_bad_shapes_are_refused():
    with pytest.raises(ValueError, match='shape'):
        RollingVibrationStats(1.0).add_samples('s', [0.0, 1.0], [[0.0, 0.0, 0.0]])


def test_impactor_stuck_flags_groups_joint_names():
    names = ['a/y', 'a/z', 'b/x', 'c']
    impactors, stuck = impactor_stuck_flags(names, [0.0, 1.0, 0.0, 1.0])
    assert impactors == ('a', 'b', 'c')
    assert stuck.tolist() == [True, False, True]
    with pytest.raises(ValueError, match='efforts'):
        impactor_stuck_flags(names, [])
    with pytest.raises(ValueError, match='non-finite'):
        impactor_stuck_flags(['a/x'], [np.nan])


def test_docstring_examples():
    assert doctest.testmod(monitoring).failed == 0


# --- the monitor's words (issue 38) ------------------------------------------------------------

def test_waiting_for_the_first_sample_is_info_then_warn():
    from impact_damper_sim.live.monitor_text import FIRST_SAMPLE_GRACE_S, waiting_text
    assert waiting_text('accel/s1', 0.0) == (False, 'waiting for the first sample on accel/s1')
    assert waiting_text('accel/s1', FIRST_SAMPLE_GRACE_S)[0] is False
    assert waiting_text('accel/s1', 7.5) == (
        True, 'no valid sample received on accel/s1 in 7.5 s')
    assert waiting_text('accel/s1', 1.0, grace_s=0.5)[0] is True


def test_impacts_text_says_dampers_off_and_never_nan():
    from impact_damper_sim.live.monitor_text import dampers_off, impacts_text
    # the node's -1 efforts: dampers off, which 'stuck fraction 0 (0 of 12)' hid
    assert dampers_off([-1.0] * 24) and not dampers_off([0.0, -1.0]) and not dampers_off([])
    off = impacts_text(0.0, 0.0, 0, 12, off=True)
    assert off == 'impacts: 0 /s, dampers off: no impactor can stick'
    start = impacts_text(math.nan, math.nan, 0, 0)
    assert start == 'impacts: no impacts received yet, no impactor_state received yet'
    on = impacts_text(12345.6, 0.25, 3, 12)
    assert on == 'impacts: 1.235e+04 /s, stuck fraction 0.25 (3 of 12 impactors stuck now)'
    assert not any('nan' in t for t in (off, start, on))
