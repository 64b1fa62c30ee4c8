"""The accelerometer channel (issue 36): each stage's physics against its closed form.

Every test states its tolerance; the measured values are in the commit message. Rates are
modest (1-10 kHz) so the file runs in seconds; the stages are rate-independent by design.
"""
import json
import math

import numpy as np
import pytest

from impact_damper_sim.live.channel import SensorChannel
from impact_damper_sim.live.channel_design import rotation_matrix, transverse_matrix
from impact_damper_sim.live.channel_keys import SPEC_KEYS
from impact_damper_sim.live.filters import StreamingDecimator, StreamingLowpass
from impact_damper_sim.live.resonance_design import analog_resonance, design_resonance
from impact_damper_sim.scene.channel_spec import preset_channel

G = 9.80665


def spec(**stages):
    """A resolved spec: every key, the given stages on."""
    out = {k: None for k in SPEC_KEYS}
    out.update(stages)
    return out


def channel(stages=None, *, fs=10000.0, dec=1, lp=4000.0, seed=0, name='acc'):
    return SensorChannel(None if stages is None else spec(**stages), step_rate_hz=fs,
                         decimation=dec, lowpass_hz=lp, seed=seed, name=name)


def welch(x, fs, nperseg):
    """One-sided PSD (unit^2/Hz), Hann window, 50 % overlap, as ``scipy.signal.welch(x, fs,
    nperseg=nperseg, detrend=False)``."""
    w = np.hanning(nperseg + 1)[:-1]   # periodic Hann, as scipy's
    step = nperseg // 2
    starts = range(0, len(x) - nperseg + 1, step)
    segs = np.stack([x[s:s + nperseg] for s in starts])   # no detrending: zero-mean noise
    p = np.abs(np.fft.rfft(segs * w, axis=1)) ** 2 / (fs * np.sum(w ** 2))
    p[:, 1:-1] *= 2.0
    return np.fft.rfftfreq(nperseg, 1.0 / fs), p.mean(axis=0)


def allan_deviation(y, m):
    """Overlapping Allan deviation of rate samples ``y`` at a cluster of ``m`` samples."""
    c = np.concatenate([[0.0], np.cumsum(y)])
    avg = (c[m:] - c[:-m]) / m
    d = avg[m:] - avg[:-m]
    return math.sqrt(0.5 * np.mean(d ** 2))


def gain_at(out, ref, f, fs):
    """Complex gain of ``out`` over ``ref`` at ``f`` (least-squares sine fit of each)."""
    t = np.arange(len(out)) / fs
    basis = np.stack([np.cos(2 * np.pi * f * t), np.sin(2 * np.pi * f * t)], axis=1)
    co = np.linalg.lstsq(basis, out, rcond=None)[0]
    cr = np.linalg.lstsq(basis, ref, rcond=None)[0]
    return complex(co[0], -co[1]) / complex(cr[0], -cr[1])


FULL = spec(preset='test', sensitivity=0.1 / G, sensitivity_error=[0.02, -0.03, 0.01],
            orientation=[0.01, -0.02, 0.3], transverse={'fraction': 0.03, 'angle': 0.4},
            resonance={'frequency': 30000.0, 'q': 30.0}, highpass={'corner': 0.5},
            noise_density=20e-6 * G,
            bias={'turn_on': 0.01, 'gauss_markov': {'sigma': 1e-3, 'tau': 10.0},
                  'random_walk': 1e-4},
            range=5 * G, adc={'bits': 16, 'full_scale': 5.0, 'noise': 50e-6})


# -- the ideal channel and streaming --------------------------------------------------------
@pytest.mark.parametrize('dec', [1, 5])
def test_ideal_channel_is_todays_lowpass_then_pick_bit_for_bit(dec):
    fs = 10000.0
    a = np.random.default_rng(1).normal(0.0, 30.0, (400 * dec, 3))
    ref = StreamingLowpass(800.0, fs, 3).apply(a)[dec - 1::dec]
    ch = SensorChannel(None, step_rate_hz=fs, decimation=dec, lowpass_hz=800.0)
    out = ch.process(a)
    assert np.array_equal(out.samples, ref) and np.array_equal(out.truth, ref)
    assert out.clipped == 0 and ch.delay_steps == 0
    # plus the live white noise: today's rng.normal(0, std) at the output rate
    ch = SensorChannel(None, step_rate_hz=fs, decimation=dec, lowpass_hz=800.0)
    ch.set_white_noise(0.3, seed=7)
    out = ch.process(a)
    assert np.array_equal(out.samples, ref + np.random.default_rng(7).normal(0.0, 0.3, ref.shape))
    assert np.array_equal(out.truth, ref)


def _run(stages, chunks, a, dec, fs=10000.0, lp=800.0, seed=3):
    ch = SensorChannel(stages, step_rate_hz=fs, decimation=dec, lowpass_hz=lp, seed=seed,
                       name='casing')
    ch.set_white_noise(0.02, seed=11)
    deci = StreamingDecimator(4, fs / dec, 3)
    samples, truth, imu, clipped, imu_clipped, i = [], [], [], 0, 0, 0
    for n in chunks:
        out = ch.process(a[i:i + n * dec])
        i += n * dec
        samples.append(out.samples)
        truth.append(out.truth)
        clipped += out.clipped
        x, c = ch.process_decimated(8.0 * deci.apply(out.samples)[1])   # 8: some clip
        imu.append(x)
        imu_clipped += c
    return (np.vstack(samples), np.vstack(truth), np.vstack(imu), clipped, imu_clipped)


@pytest.mark.parametrize('resonance', [{'frequency': 30000.0, 'q': 30.0},    # far above
                                       {'frequency': 2500.0, 'q': 10.0}])    # at 0.25 fs
def test_chunked_equals_one_pass_bit_for_bit(resonance):
    dec = 5
    stages = dict(FULL, resonance=resonance)
    a = np.random.default_rng(2).normal(0.0, 20.0, (3000 * dec, 3))
    a[1000:1010] *= 40.0   # an impact that clips
    one = _run(stages, [3000], a, dec)
    split = _run(stages, [1, 0, 17, 500, 999, 1483], a, dec)
    for x, y in zip(one, split):
        assert np.array_equal(x, y)
    assert one[3] > 0 and one[4] > 0   # the clip paths ran


# -- noise and bias --------------------------------------------------------------------------
def test_noise_psd_equals_the_density():
    """Welch PSD of a noise-only run = density^2 within 10 % from 5 Hz to half the cutoff."""
    fs, dec, lp, density = 10000.0, 2, 2000.0, 100e-6 * G
    ch = channel({'noise_density': density, 'highpass': {'corner': 0.5}}, fs=fs, dec=dec, lp=lp)
    y = ch.process(np.zeros((int(40 * fs), 3))).samples
    f = welch(y[:, 0], fs / dec, 256)[0]
    psd = np.mean([welch(y[:, i], fs / dec, 256)[1] for i in range(3)], axis=0)
    band = (f >= 5.0) & (f <= 0.5 * lp)
    ratio = psd[band] / density ** 2
    assert np.max(np.abs(ratio - 1.0)) < 0.10, ratio
    assert ch.noise_std_per_step == pytest.approx(density * math.sqrt(fs / 2), rel=1e-15)


def test_random_walk_allan_deviation():
    """Allan deviation rw sqrt(tau/3): slope +1/2 (within 0.05) and value within 10 %."""
    fs, rw = 1000.0, 1e-3
    ch = channel({'bias': {'turn_on': None, 'gauss_markov': None, 'random_walk': rw}}, fs=fs,
                 lp=400.0)
    y = ch.process(np.zeros((int(1000 * fs), 3))).samples
    taus = np.array([0.1, 0.3, 1.0, 3.0, 10.0])
    adev = np.sqrt(np.mean([[allan_deviation(y[:, i], int(t * fs)) ** 2 for t in taus]
                            for i in range(3)], axis=0))
    ratio = adev / (rw * np.sqrt(taus / 3.0))
    slope = np.polyfit(np.log(taus), np.log(adev), 1)[0]
    assert np.max(np.abs(ratio - 1.0)) < 0.10, ratio
    assert abs(slope - 0.5) < 0.05, slope


def test_gauss_markov_bias_settles_at_sigma_sqrt_tau_over_2():
    """Steady spread sigma sqrt(tau/2) within 10 %, from the first sample (started steady);
    correlation e^-1 at a lag of tau (within 0.05)."""
    fs, sigma, tau = 2000.0, 0.02, 0.05
    stages = {'bias': {'turn_on': None, 'gauss_markov': {'sigma': sigma, 'tau': tau},
                       'random_walk': None}}
    y = channel(stages, fs=fs, lp=800.0).process(np.zeros((int(60 * fs), 3))).samples
    steady = sigma * math.sqrt(tau / 2)
    assert np.std(y) == pytest.approx(steady, rel=0.10)
    lag = int(tau * fs)
    rho = np.mean(y[lag:] * y[:-lag]) / np.mean(y * y)
    assert rho == pytest.approx(math.exp(-1.0), abs=0.05)
    # the start is steady too: 10 ms (0.2 tau, the low-pass settled) into 300 channels the
    # spread is the same (from b = 0 it would be 0.57 of it)
    early = [channel(stages, fs=fs, lp=800.0, seed=s).process(np.zeros((21, 3))).samples[20]
             for s in range(300)]
    assert np.std(early) == pytest.approx(steady, rel=0.10)


def test_turn_on_bias_and_independent_streams():
    """Each stage draws from its own stream: adding one moves no other's numbers."""
    a = np.zeros((20000, 3))
    gm = {'sigma': 0.01, 'tau': 0.1}
    only_gm = channel({'bias': {'turn_on': None, 'gauss_markov': gm, 'random_walk': None}})
    only_on = channel({'bias': {'turn_on': 0.05, 'gauss_markov': None, 'random_walk': None}})
    both = channel({'bias': {'turn_on': 0.05, 'gauss_markov': gm, 'random_walk': None},
                    'noise_density': 0.0, 'adc': None})
    y_gm, y_on, y_both = (c.process(a).samples for c in (only_gm, only_on, both))
    np.testing.assert_allclose(y_both, y_gm + y_on, rtol=0, atol=1e-15)
    assert np.array_equal(only_on.turn_on_bias, both.turn_on_bias)
    # the turn-on bias is its constant, through the low-pass's unit DC gain
    np.testing.assert_allclose(y_on[-1], only_on.turn_on_bias, rtol=1e-12)
    # same seed, other accelerometer: other numbers
    other = channel({'noise_density': 1e-3}, name='other').process(a).samples
    mine = channel({'noise_density': 1e-3}, name='acc').process(a).samples
    assert not np.allclose(other, mine)


# -- filters ---------------------------------------------------------------------------------
def test_highpass_is_minus_3_db_at_its_corner():
    """-3 dB at the corner within 2 % (the -3 dB frequency interpolated from measured gains)."""
    fs, fc = 1000.0, 0.5
    freqs = [0.9 * fc, fc, 1.1 * fc]
    gains = []
    for f in freqs:
        t = np.arange(int(80 * fs)) / fs
        a = np.zeros((len(t), 3))
        a[:, 0] = np.sin(2 * np.pi * f * t)
        out = channel({'highpass': {'corner': fc}}, fs=fs, lp=400.0).process(a)
        keep = slice(int(40 * fs), None)   # 40 s = 125 time constants: steady
        gains.append(abs(gain_at(out.samples[keep, 0], out.truth[keep, 0], f, fs)))
    assert gains[1] == pytest.approx(2 ** -0.5, rel=0.005)
    f3 = np.interp(2 ** -0.5, gains, freqs)
    assert f3 == pytest.approx(fc, rel=0.02)


def _multisine_response(stages, fs, freqs, lp):
    """Complex gain samples/truth at ``freqs`` (whole Hz) from two periods of a multisine,
    and the channel."""
    n = int(fs)   # 1 s period: 1 Hz bins
    t = np.arange(n) / fs
    phases = np.random.default_rng(5).uniform(0, 2 * np.pi, len(freqs))
    x = np.sum(np.cos(2 * np.pi * np.outer(t, freqs) + phases), axis=1)
    a = np.zeros((2 * n, 3))
    a[:, 2] = np.tile(x, 2)
    ch = channel(stages, fs=fs, lp=lp)
    out = ch.process(a)
    s = np.fft.rfft(out.samples[n:, 2])
    r = np.fft.rfft(out.truth[n:, 2])
    k = np.round(freqs).astype(int)
    return s[k] / r[k], ch


HPOTP = preset_channel('iepe_10mv_500g')['resonance']       # hpotp, rbs_kcc, sdof
CANTILEVER = preset_channel('iepe_100mv_50g')['resonance']  # cantilever, rbs
RESONANCE_CASES = [
    # (fn, q, step rate, lowpass): the presets at the shipped scenes' rates ...
    (HPOTP['frequency'], HPOTP['q'], 10000.0, 800.0),              # hpotp, sdof
    (CANTILEVER['frequency'], CANTILEVER['q'], 10000.0, 800.0),    # cantilever
    (CANTILEVER['frequency'], CANTILEVER['q'], 20000.0, 5000.0),   # rbs
    (HPOTP['frequency'], HPOTP['q'], 20000.0, 5000.0),             # rbs_kcc
    # ... the node at sample_rate = the step rate (lowpass 0.4 x it) ...
    (CANTILEVER['frequency'], CANTILEVER['q'], 10000.0, 4000.0),
    # ... and 0.1-0.3 fn inside the band: fn 5 kHz, 2 kHz low-pass, 50 kHz step
    (5000.0, 25.0, 50000.0, 2000.0),
    (5000.0, 5.0, 50000.0, 2000.0),
    (5000.0, 200.0, 50000.0, 2000.0),
]


@pytest.mark.parametrize('fn, q, fs, lp', RESONANCE_CASES)
def test_resonance_matches_the_second_order_response(fn, q, fs, lp):
    """Through the channel, samples over truth: gain within 0.5 % and phase within 0.5 deg
    of wn^2/(s^2 + wn/Q s + wn^2) from 10 Hz to min(lowpass, 0.45 fs), 0.1-0.3 fn included
    where they are in that band; the lift | |H| - 1 | within 10 % of the analog one where
    it is at least 1e-4, and within 10 % of (f/fn)^2 (where that is at least 1e-4) when fn
    is far enough above the band for (f/fn)^2 to be the lift (top of the band at most
    0.17 fn: the analog's own departure from it is then 3 % at most)."""
    top = min(lp, 0.45 * fs)
    freqs = np.unique(np.round(np.concatenate([
        np.linspace(10.0, top, 60), [f for f in (0.1 * fn, 0.2 * fn, 0.3 * fn) if f <= top]])))
    g, ch = _multisine_response({'resonance': {'frequency': fn, 'q': q}}, fs, freqs, lp)
    h = analog_resonance(freqs, fn, q)
    assert ch.delay_steps == 0 and ch.resonance.band_hz == pytest.approx(top)
    assert np.max(np.abs(np.abs(g) / np.abs(h) - 1.0)) < 0.005
    assert np.max(np.abs(np.angle(g / h, deg=True))) < 0.5
    lift = np.abs(h) - 1.0
    big = np.abs(lift) >= 1e-4
    assert big.any()
    np.testing.assert_allclose(np.abs(g[big]) - 1.0, lift[big], rtol=0.10)
    r2 = (freqs / fn) ** 2
    if (top / fn) ** 2 <= 0.03:
        np.testing.assert_allclose(np.abs(g[r2 >= 1e-4]) - 1.0, r2[r2 >= 1e-4], rtol=0.10)


@pytest.mark.parametrize('fn, q, fs, lp', RESONANCE_CASES + [
    (30000.0, 30.0, 10000.0, 800.0), (2500.0, 10.0, 10000.0, 800.0), (1e6, 0.5, 10000.0, 4000.0),
    (2000.0, 1000.0, 10000.0, 1000.0), (2000.0, 0.51, 10000.0, 1000.0)])
def test_resonance_design_against_the_closed_form(fn, q, fs, lp):
    """The section's own response on a dense grid of its band, zero latency: the tolerances
    as above, unit DC gain, poles inside the unit circle, and above the band a gain below
    1.5 x max(1, |H|) and within 5 % of |H| through the anti-alias filter."""
    d = design_resonance(fn, q, fs, lp)
    top = min(lp, 0.45 * fs)
    assert d.band_hz == pytest.approx(top)
    f = np.linspace(0.0, top, 4001)
    h = analog_resonance(f, fn, q)
    hd = d.response(f, fs)
    r = hd / h
    assert np.max(np.abs(np.abs(r) - 1.0)) < 0.005
    assert np.max(np.abs(np.angle(r, deg=True))) < 0.5
    lift = np.abs(np.abs(h) - 1.0)
    big = lift >= 1e-4
    assert np.all(np.abs(np.abs(hd) - np.abs(h))[big] <= 0.1 * lift[big])
    assert np.all(np.abs(np.abs(hd) - 1.0)[~big] <= 1.1e-4)
    assert abs(d.response(0.0, fs) - 1.0) < 1e-12
    for row in d.sos:
        assert row[3] == 1.0 and np.all(np.abs(np.roots(row[3:])) < 1.0)
    above = np.linspace(top, 0.5 * fs, 4001)
    ha, hda = np.abs(analog_resonance(above, fn, q)), np.abs(d.response(above, fs))
    assert np.all(hda <= 1.5 * np.maximum(1.0, ha))
    assert np.all(np.abs(hda / ha - 1.0) / np.sqrt(1.0 + (above / lp) ** 8) <= 0.05)


def test_hpotp_1x_phase_is_the_sensors_and_the_truth_is_not_delayed():
    """hpotp's channel with only its preset's resonance (fn 50 kHz, Q 25; 10 kHz steps,
    800 Hz low-pass, 2 kHz output): the samples' 1X phase at 2400 rad/s (382 Hz) against the
    truth is the sensor's -(f/fn)/Q = -3.1e-4 rad within 5e-5, so within 1e-3 rad of 0
    (a 3-step look-ahead made it 0.72 rad against the tachometer); the truth is the model's
    acceleration through the low-pass and pick, bit for bit (no delay); an impulse peaks at
    the same sample in both."""
    fs, dec, lp, w = 10000.0, 5, 800.0, 2400.0
    ch = channel({'resonance': dict(HPOTP)}, fs=fs, dec=dec, lp=lp)
    assert ch.delay_steps == 0 and ch.delay_s == 0.0
    t = (np.arange(int(4 * fs)) + 1) / fs
    a = np.zeros((len(t), 3))
    a[:, 0] = 30.0 * np.sin(w * t + 0.3)
    a[:, 1] = 10.0 * np.cos(w * t)
    out = ch.process(a)
    ref = StreamingLowpass(lp, fs, 3).apply(a)[dec - 1::dec]
    assert np.array_equal(out.truth, ref)
    keep = slice(int(fs / dec), None)   # the low-pass settled
    f = w / (2 * np.pi)
    g = gain_at(out.samples[keep, 0], out.truth[keep, 0], f, fs / dec)
    analog = analog_resonance(f, HPOTP['frequency'], HPOTP['q'])
    assert abs(np.angle(g)) < 1e-3
    assert abs(np.angle(g) - np.angle(analog)) < 5e-5
    assert abs(abs(g) / abs(analog) - 1.0) < 1e-6
    # an impulse: the same peak sample in samples and truth
    ch = channel({'resonance': dict(HPOTP)}, fs=fs, dec=1, lp=lp)
    a = np.zeros((400, 3))
    a[100] = 1.0
    out = ch.process(a)
    assert np.argmax(out.samples[:, 0]) == np.argmax(out.truth[:, 0])


@pytest.mark.parametrize('q', [0.51, 0.707, 2.0, 25.0, 1000.0])
def test_resonance_is_stable_from_q_0_5_to_1000_and_fn_0_2_to_100_step_rates(q):
    """A stable cascade (every pole inside the unit circle) for fn from 0.2 to 100 x the step
    rate, the low-pass at min(fn / 2, 0.2 x the step rate)."""
    fs = 10000.0
    for ratio in (0.2, 0.35, 0.6, 1.0, 2.0, 5.0, 20.0, 100.0):
        fn = ratio * fs
        d = design_resonance(fn, q, fs, min(0.5 * fn, 0.2 * fs))
        radius = max((np.max(np.abs(np.roots(row[3:]))) for row in d.sos), default=0.0)
        assert radius < 1.0 and d.pole_radius == pytest.approx(radius)
        assert d.gain_error <= 0.005 and d.phase_error_deg <= 0.5


def test_a_resonance_no_causal_section_matches_is_refused():
    """fn just above a band reaching 0.45 x the step rate, Q 1000: one ValueError naming the
    key and the reason."""
    with pytest.raises(ValueError, match=r"^accelerometer 'acc': spec key 'resonance': fn = "
                                         r'5500 Hz, Q = 1000 cannot be realised causally with '
                                         r'zero latency .* over 0 \.\. 4500 Hz'):
        channel({'resonance': {'frequency': 5500.0, 'q': 1000.0}}, fs=10000.0, lp=4500.0)


# -- mounting --------------------------------------------------------------------------------
def _steady_ratio(stages, direction):
    """Per output axis: sample / truth-along-``direction`` for a random signal along it."""
    a = np.outer(np.random.default_rng(4).normal(0.0, 10.0, 2000), direction)
    out = channel(stages).process(a)
    along = out.truth @ np.asarray(direction, dtype=float)
    return np.array([np.dot(out.samples[:, i], along) / np.dot(along, along)
                     for i in range(3)])


def test_transverse_sensitivity_shows_the_stated_fraction():
    """Along u_x (the direction of the maximum) axis x reads the fraction (1 %); a pure y
    excitation reads fraction cos(angle) on x and fraction sin(angle) on z."""
    f, angle = 0.04, 0.3
    stages = {'transverse': {'fraction': f, 'angle': angle}}
    u_x = [0.0, math.cos(angle), math.sin(angle)]
    r = _steady_ratio(stages, u_x)
    assert r[0] == pytest.approx(f, rel=0.01)
    r = _steady_ratio(stages, [0.0, 1.0, 0.0])
    assert r == pytest.approx([f * math.cos(angle), 1.0, f * math.sin(angle)], rel=0.01)
    np.testing.assert_allclose(np.diag(transverse_matrix(f, angle)), 0.0)


def test_orientation_90_deg_yaw_swaps_x_and_y():
    a = np.random.default_rng(6).normal(0.0, 10.0, (1000, 3))
    out = channel({'orientation': [0.0, 0.0, math.pi / 2]}).process(a)
    # the sensor's x axis is the model's y: it reads a_y; its y axis is -x
    assert np.array_equal(out.samples[:, 0], out.truth[:, 1])
    assert np.array_equal(out.samples[:, 1], -out.truth[:, 0])
    assert np.array_equal(out.samples[:, 2], out.truth[:, 2])
    # a general tilt reads R.T a; sensitivity errors scale each axis
    rpy = [0.1, -0.2, 0.7]
    out = channel({'orientation': rpy, 'sensitivity_error': [0.05, 0.0, -0.1]}).process(a)
    expect = (out.truth @ rotation_matrix(rpy)) * [1.05, 1.0, 0.9]
    np.testing.assert_allclose(out.samples, expect, rtol=0, atol=1e-12)


# -- range and ADC ---------------------------------------------------------------------------
def test_range_clips_and_counts():
    """No sample beyond the range; the count = the truth's values beyond it."""
    t = np.arange(20000) / 10000.0
    a = 30.0 * np.stack([np.sin(2 * np.pi * 50 * t), np.cos(2 * np.pi * 70 * t),
                         np.sin(2 * np.pi * 5 * t) / 3.0], axis=1)
    ch = channel({'range': 20.0}, dec=2, lp=2000.0)
    clipped, beyond, worst = 0, 0, 0.0
    for part in np.split(a, 4):
        out = ch.process(part)
        clipped += out.clipped
        beyond += int(np.count_nonzero(np.abs(out.truth) > 20.0))
        worst = max(worst, float(np.abs(out.samples).max()))
    assert worst == 20.0 and clipped == beyond > 0


def test_every_sample_on_the_adc_grid():
    """Every sample (and every decimated one) on the grid, within LSB/2 of its input."""
    sens, fs_v, bits = 0.01, 5.0, 12
    ch = channel({'sensitivity': sens, 'adc': {'bits': bits, 'full_scale': fs_v,
                                               'noise': 0.0}}, dec=2, lp=2000.0)
    lsb = 2 * fs_v / 2 ** bits / sens
    assert ch.lsb == lsb
    a = np.random.default_rng(8).normal(0.0, 300.0, (40000, 3))   # 2.6 sigma after the LP
    out = ch.process(a)
    codes = out.samples / lsb
    assert np.array_equal(codes, np.round(codes))
    inside = np.abs(out.truth) < fs_v / sens - lsb
    err = np.abs(out.samples - out.truth)[inside]
    assert err.max() <= 0.5 * lsb
    # codes -2^(bits-1) .. 2^(bits-1) - 1: clipped beyond half an LSB past the end codes
    top, bottom = fs_v / sens - lsb, -fs_v / sens
    beyond = (out.truth > top + lsb / 2) | (out.truth < bottom - lsb / 2)
    assert out.clipped == np.count_nonzero(beyond) > 0
    assert np.abs(out.samples).max() <= fs_v / sens
    deci = StreamingDecimator(5, 5000.0, 3)
    imu, clipped = ch.process_decimated(deci.apply(out.samples)[1] * 3.0)   # 3: some clip
    assert np.array_equal(imu / lsb, np.round(imu / lsb)) and clipped > 0
    assert np.abs(imu).max() <= fs_v / sens


# -- noise bookkeeping -----------------------------------------------------------------------
def test_noise_variances_equal_measured_ones():
    """output_noise_variance and decimated_noise_variance within 5 % of a noise-only run."""
    fs, dec = 10000.0, 2
    stages = {'sensitivity': 0.01, 'noise_density': 2e-3,
              'adc': {'bits': 16, 'full_scale': 5.0, 'noise': 300e-6}}
    ch = channel(stages, fs=fs, dec=dec, lp=1500.0)
    ch.set_white_noise(0.02, seed=1)
    out = ch.process(np.zeros((int(30 * fs), 3))).samples
    assert np.var(out) == pytest.approx(ch.output_noise_variance(), rel=0.05)
    deci = StreamingDecimator(5, fs / dec, 3)
    imu, _ = ch.process_decimated(deci.apply(out)[1][100:])
    expect = ch.decimated_noise_variance(deci.taps)
    assert np.var(imu) == pytest.approx(expect, rel=0.05)
    # the coloured sensor noise keeps more than sum(taps^2) of its variance
    assert expect > ch.output_noise_variance() * deci.white_noise_gain * 1.2


# -- spec handling ---------------------------------------------------------------------------
def test_bad_specs_are_refused_naming_the_key():
    with pytest.raises(ValueError, match="'adc' needs 'sensitivity'"):
        channel({'adc': {'bits': 24, 'full_scale': 5.0, 'noise': 0.0}})
    with pytest.raises(ValueError, match="unknown spec key.*'lowpass'"):
        SensorChannel({'lowpass': 3.0}, step_rate_hz=1e4, decimation=1, lowpass_hz=1e3)
    with pytest.raises(ValueError, match="'highpass.corner'"):
        channel({'highpass': {'corner': 0.0}})
    with pytest.raises(ValueError, match="'adc.bits'"):
        channel({'sensitivity': 0.01, 'adc': {'bits': 0, 'full_scale': 5.0, 'noise': 0.0}})
    with pytest.raises(ValueError, match=r'shape \(k \* 5, 3\)'):
        channel(dec=5, lp=800.0).process(np.zeros((7, 3)))


def test_labels_are_json_and_complete():
    ch = SensorChannel(FULL, step_rate_hz=20000.0, decimation=1, lowpass_hz=5000.0, seed=2,
                       name='casing')
    ch.set_white_noise(0.01, seed=3)
    labels = json.loads(json.dumps(ch.labels()))
    for key in SPEC_KEYS:
        assert key in labels
    assert labels['delay_steps'] == ch.delay_steps == 0 and labels['delay_s'] == 0.0
    sos = np.array(labels['resonance']['sos'])
    assert sos.shape == (len(ch.resonance.sos), 6) and len(sos) >= 1
    assert labels['resonance']['band_hz'] == 5000.0
    assert labels['adc']['lsb'] == ch.lsb and labels['white_noise'] == {'std': 0.01, 'seed': 3}
    assert len(labels['bias']['turn_on_values']) == 3
    assert json.loads(json.dumps(SensorChannel(None, step_rate_hz=1e4, decimation=1,
                                               lowpass_hz=1e3).labels()))['ideal'] is True
