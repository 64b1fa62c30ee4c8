"""The compiled live chain (``kernels/channel_chunk.py``, issue 39) gives the NumPy chain's bytes.

Each kernel and its plain twin (``.py_func``) against the NumPy code it replaces, bit for bit,
not within a tolerance: the sections-first low-pass against ``sosfilt``; the range and ADC
against ``SensorChannel._limit``; a channel's compiled chunk (``_process_chunk``) against its
NumPy twin (``_process_into``) for every preset and stage, chunk after chunk with the state
carried, with live white noise and with a fault between the chain and the limit; the step's
inputs against ``np.diff``; the decimator fed by groups against the concatenated chunk; the
Imu split and limit against the reshape and ``_limit``.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from impact_damper_sim.integrate.kernels import channel_chunk as cc
from impact_damper_sim.integrate.kernels.filters import sosfilt
from impact_damper_sim.live.channel import SensorChannel
from impact_damper_sim.live.channel_keys import SPEC_KEYS
from impact_damper_sim.live.filters import StreamingDecimator, butter_lowpass_sos
from impact_damper_sim.scene.channel_spec import PRESETS, preset_channel

G = 9.80665
SPECIAL = (np.nan, np.inf, -np.inf, 0.0, -0.0, 5e-324, -5e-324, 1e308, -1e308)


def _spec(**stages):
    out = {k: None for k in SPEC_KEYS}
    out.update(stages)
    return out


def _with_specials(x, rng, count=12):
    x = x.copy()
    flat = x.reshape(-1)
    for v in SPECIAL:
        flat[rng.integers(0, flat.size, count // len(SPECIAL) + 1)] = v
    return x


@pytest.mark.parametrize('twin, reference', [(cc.sosfilt_sections, sosfilt),
                                              (cc.sosfilt_sections.py_func, sosfilt.py_func)])
@pytest.mark.parametrize('sections, width, n', [(2, 6, 100), (1, 3, 7), (3, 3, 50),
                                                (2, 1, 0), (0, 3, 5)])
def test_sections_first_filter_is_sosfilts_bytes(twin, reference, sections, width, n):
    # compiled against compiled, twin against twin: Python's and the machine code's
    # arithmetic may give a NaN a different sign bit, each the same one every time
    rng = np.random.default_rng(sections * 100 + width)
    sos = (butter_lowpass_sos(2 * sections, 800.0, 10000.0) if sections
           else np.empty((0, 6)))
    x = rng.normal(0.0, 1.0, (n, width)) * 10.0 ** rng.integers(-300, 300, (n, width))
    if n > 20:
        x = _with_specials(x, rng)
    zi = rng.normal(0.0, 1.0, (sections, 2, width))
    want_y, want_zi = np.empty_like(x), zi.copy()
    got_y, got_zi = np.empty_like(x), zi.copy()
    inplace, inplace_zi = x.copy(), zi.copy()   # y may be x
    with np.errstate(all='ignore'):   # the twins' NumPy scalars warn of the inf and NaN
        reference(sos, x, want_zi, want_y)
        twin(sos, x, got_zi, got_y)
        twin(sos, inplace, inplace_zi, inplace)
    assert got_y.tobytes() == want_y.tobytes()
    assert got_zi.tobytes() == want_zi.tobytes()
    assert inplace.tobytes() == want_y.tobytes()


def _channels(stages, seed=5, dec=5, fs=10000.0, lp=1000.0):
    """Two channels of one spec and seed: the same streams, one for each path."""
    return [SensorChannel(stages, step_rate_hz=fs, decimation=dec, lowpass_hz=lp, seed=seed,
                          name='acc') for _ in range(2)]


CASES = {
    **{f'preset {name}': preset_channel(name) for name in PRESETS},
    'ideal (None)': None,
    'mounting': _spec(orientation=[0.1, -0.2, 0.3], sensitivity_error=[0.01, 0.0, -0.02]),
    'noise only': _spec(noise_density=2e-3),
    'turn-on and random walk': _spec(bias={'turn_on': 0.05, 'gauss_markov': None,
                                           'random_walk': 1e-3}),
    'gauss-markov': _spec(bias={'turn_on': None, 'random_walk': None,
                                'gauss_markov': {'sigma': 0.02, 'tau': 0.5}}),
    'range only': _spec(range=2.0),
    'adc without noise': _spec(sensitivity=0.01, adc={'bits': 8, 'full_scale': 0.05,
                                                      'noise': 0.0}),
    'range and noisy adc': _spec(sensitivity=0.01, range=3.0, adc={'bits': 6,
                                                                   'full_scale': 0.04,
                                                                   'noise': 2e-4}),
    'adc of 1 bit (NumPy)': _spec(sensitivity=0.01, adc={'bits': 1, 'full_scale': 0.05,
                                                         'noise': 1e-4}),
}


@pytest.mark.parametrize('white', [0.0, 0.3])
@pytest.mark.parametrize('case', sorted(CASES))
def test_compiled_chunk_is_the_numpy_chains_bytes(case, white):
    compiled, plain = _channels(CASES[case])
    for ch in (compiled, plain):
        ch.set_white_noise(white, 11 if white else None)
    rng = np.random.default_rng(3)
    scale = 0.5 * (compiled.range or 8.0)
    clips = 0
    for k in (20, 20, 1, 0, 7, 20, 13, 40):
        a = rng.normal(0.0, scale, (5 * k, 3))
        a[rng.random((5 * k, 3)) < 0.1] *= 4.0   # now and then beyond the range
        samples, truth = np.empty((k, 2, 3)), np.empty((k, 2, 3))
        got = compiled._process_chunk(a, None, samples, truth, 1)
        want_s, want_t = np.empty((k, 3)), np.empty((k, 3))
        want = plain._process_into(a, None, want_s, want_t)
        assert got == want
        assert samples[:, 1].tobytes() == want_s.tobytes()
        assert truth[:, 1].tobytes() == want_t.tobytes()
        clips += got
    if compiled.range is not None or compiled.lsb is not None:
        assert clips > 0   # the clipping and its count were exercised


@pytest.mark.parametrize('case', ['preset iepe_10mv_500g', 'preset mems_16g',
                                  'range and noisy adc'])
def test_a_fault_between_chain_and_limit_gives_the_numpy_bytes(case):
    compiled, plain = _channels(CASES[case])

    def gain(x):   # a sensor fault in place before the range and ADC
        x *= 40.0
        x[0, 1] = np.nan

    rng = np.random.default_rng(8)
    scale = 0.2 * compiled.range
    for k in (20, 3, 20):
        a = rng.normal(0.0, scale, (5 * k, 3))
        samples, truth = np.empty((k, 1, 3)), np.empty((k, 1, 3))
        got = compiled._process_chunk(a, gain, samples, truth, 0)
        want_s, want_t = np.empty((k, 3)), np.empty((k, 3))
        want = plain._process_into(a, gain, want_s, want_t)
        assert got == want and got > 0
        assert samples[:, 0].tobytes() == want_s.tobytes()
        assert truth[:, 0].tobytes() == want_t.tobytes()


def test_the_chunk_kernels_twin_gives_the_kernels_bytes():
    spec = preset_channel('mems_16g')
    spec['resonance'] = None
    spec['highpass'] = {'corner': 2.0}
    spec['bias']['random_walk'] = 1e-3
    out = []
    for fn in (cc.channel_chunk, cc.channel_chunk.py_func):
        ch = _channels(spec)[0]
        ch.set_white_noise(0.2, 4)
        ch._load_chain()
        ch._kernels = (fn, ch._kernels[1])
        rng = np.random.default_rng(1)
        for k in (20, 9):
            samples, truth = np.empty((k, 1, 3)), np.empty((k, 1, 3))
            n = ch._process_chunk(rng.normal(0.0, 30.0, (5 * k, 3)), None, samples, truth, 0)
            out.append((n, samples.tobytes(), truth.tobytes()))
    assert out[:2] == out[2:]


@pytest.mark.parametrize('twin', [cc.limit, cc.limit.py_func])
@pytest.mark.parametrize('stages', [
    _spec(range=2.0), _spec(sensitivity=0.01, adc={'bits': 5, 'full_scale': 0.03,
                                                   'noise': 1e-4}),
    _spec(sensitivity=0.01, range=1.5, adc={'bits': 4, 'full_scale': 0.02, 'noise': 0.0})])
def test_limit_is_the_numpy_limits_bytes(twin, stages):
    ch = _channels(stages)[0]
    rng = np.random.default_rng(2)
    x = _with_specials(rng.normal(0.0, 2.5, (60, 3)), rng)
    lsb = ch.lsb or 1.0
    x[:6, 0] = np.array([0.5, -0.5, 1.5, -1.5, 2.5, -2.5]) * lsb   # ties of the rounding
    x[6:8, 1] = [ch.range or 0.0, -(ch.range or 0.0)]
    noise = rng.normal(0.0, 0.3, (60, 3)) if ch._adc and ch._adc[3] > 0 else np.empty((0, 3))
    want = x.copy()
    # _limit draws its own noise: give it these values
    adc = ch._adc
    if adc is not None:
        ch._adc = (*adc[:4], _Fixed(noise))
    with np.errstate(all='ignore'):   # 1e308 / lsb overflows to inf, which is clipped
        n_want = ch._limit(want, noise.shape[0] > 0)
    got = np.empty((60, 3, 3))
    got[:, 2] = x
    with np.errstate(all='ignore'):   # the twin's NumPy scalars warn of the inf and NaN
        n_got = twin(got, 2, noise, ch._limits)
    assert n_got == n_want and n_got > 0
    assert got[:, 2].tobytes() == want.tobytes()


class _Fixed:
    """A stand-in generator whose ``normal`` returns given values."""

    def __init__(self, values):
        self.values = values

    def normal(self, loc, scale, size):
        assert loc == 0.0 and self.values.shape == size
        return self.values


@pytest.mark.parametrize('twin', [cc.step_inputs, cc.step_inputs.py_func])
def test_step_inputs_are_the_difference_over_dt_and_the_picked_rates(twin):
    rng = np.random.default_rng(4)
    dt, dec, n_acc = 1.0 / 10000.0, 5, 2
    vel = rng.normal(0.0, 1.0, (100, 6 * n_acc))
    v_prev = rng.normal(0.0, 1.0, 6 * n_acc)
    for a in range(n_acc):
        c = 6 * a
        mean, ang = np.empty((100, 3)), np.zeros((20, n_acc, 3))
        assert twin(vel, v_prev, c, dt, dec, mean, ang, a) is True
        want = np.diff(np.vstack([v_prev[None, c:c + 3], vel[:, c:c + 3]]), axis=0) / dt
        assert mean.tobytes() == want.tobytes()
        assert ang[:, a].tobytes() == np.ascontiguousarray(vel[dec - 1::dec, c + 3:c + 6]
                                                           ).tobytes()
    for bad in (np.nan, np.inf):
        v = vel.copy()
        v[37, 6 + 4] = bad   # the second accelerometer's rates: only its call sees it
        mean, ang = np.empty((100, 3)), np.zeros((20, n_acc, 3))
        assert twin(v, v_prev, 0, dt, dec, mean, ang, 0) is True
        assert twin(v, v_prev, 6, dt, dec, mean, ang, 1) is False
    assert twin(vel[:0], v_prev, 0, dt, dec, np.empty((0, 3)), np.empty((0, 2, 3)), 0)


@pytest.mark.parametrize('factor, groups', [(2, 1), (20, 3), (5, 2)])
def test_decimator_fed_by_groups_gives_the_concatenated_chunks_bytes(factor, groups):
    rng = np.random.default_rng(factor)
    fs = 1000.0 * factor
    by_groups = StreamingDecimator(factor, fs, 6 * groups)
    whole = StreamingDecimator(factor, fs, 6 * groups)
    n_out = 0
    for k in (20, 20, 0, 1, 3, 57, 20, 300, 20, 900, 20):
        lin, ang = rng.normal(0.0, 3.0, (k, groups, 3)), rng.normal(0.0, 1.0, (k, groups, 3))
        i_got, y_got = by_groups._apply_groups(lin, ang)
        i_want, y_want = whole.apply(np.concatenate([lin, ang], axis=2).reshape(k, 6 * groups))
        assert np.array_equal(i_got, i_want)
        assert y_got.tobytes() == y_want.tobytes()
        n_out += len(i_got)
    assert n_out > 30
    assert by_groups._history.tobytes() == whole._history.tobytes()


@pytest.mark.parametrize('twin', [cc.split_decimated, cc.split_decimated.py_func])
def test_imu_split_and_limit_are_the_reshape_and_numpy_limit(twin):
    chans = [_channels(s)[0] for s in (_spec(range=2.0), None,
                                       _spec(sensitivity=0.01, range=1.0,
                                             adc={'bits': 7, 'full_scale': 0.02,
                                                  'noise': 1e-3}))]
    rng = np.random.default_rng(6)
    j = 10
    y = rng.normal(0.0, 1.5, (6 * len(chans), j)).T   # as the decimator returns it
    dec = y.reshape(j, len(chans), 6)
    want_lin = dec[:, :, :3].copy()
    want_clipped = [ch._limit(want_lin[:, a], False) for a, ch in enumerate(chans)]
    lin, ang = np.empty((j, len(chans), 3)), np.empty((j, len(chans), 3))
    clipped = np.zeros(len(chans), dtype=np.int64)
    twin(np.ascontiguousarray(y.T), lin, ang, np.array([ch._limits for ch in chans]), clipped)
    assert lin.tobytes() == want_lin.tobytes()
    assert ang.tobytes() == np.ascontiguousarray(dec[:, :, 3:]).tobytes()
    assert clipped.tolist() == want_clipped and sum(want_clipped) > 0


def test_a_one_bit_adc_takes_the_numpy_path():
    # its codes are -1 and 0: NumPy's minimum may order -0.0 and 0.0 either way
    ch = _channels(CASES['adc of 1 bit (NumPy)'])[0]
    assert not ch._compiled
    assert all(c._compiled for name, s in CASES.items() if '1 bit' not in name
               for c in _channels(s)[:1])
    assert math.isfinite(ch.lsb)
