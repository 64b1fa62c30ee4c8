"""Streaming Butterworth low-pass of the accelerometer outputs (``sensors[].lowpass``)."""
import numpy as np
import pytest
from scipy.signal import butter, sosfilt, sosfreqz

from impact_damper_sim.cli.study import main
from impact_damper_sim.live.filters import SensorLowpass, StreamingLowpass
from impact_damper_sim.scene.schema import SceneError


@pytest.mark.parametrize('order', [2, 4])
def test_chunked_equals_one_shot(order):
    rng = np.random.default_rng(1)
    x = rng.standard_normal((5000, 3))
    whole = StreamingLowpass(800.0, 10e3, 3, order).apply(x)
    ref = sosfilt(butter(order, 800.0, output='sos', fs=10e3), x, axis=0)
    np.testing.assert_allclose(whole, ref, rtol=0, atol=1e-12)
    filt = StreamingLowpass(800.0, 10e3, 3, order)
    cuts = [0, 1, 2, 17, 17, 500, 1333, 4999, 5000]
    parts = [filt.apply(x[a:b]) for a, b in zip(cuts[:-1], cuts[1:])]
    np.testing.assert_allclose(np.vstack(parts), whole, rtol=0, atol=1e-12)


def test_single_channel_1d_and_gain():
    filt = StreamingLowpass(800.0, 4000.0, 1)
    fs, f = 4000.0, np.array([0.0, 100.0, 800.0, 1600.0])
    _, h = sosfreqz(filt.sos, worN=f, fs=fs)
    np.testing.assert_allclose(np.abs(h[:3]), [1.0, 1.0, 2 ** -0.5], atol=1e-6)
    assert np.abs(h[3]) < 0.05
    y = filt.apply(np.ones(4000))
    assert y.shape == (4000,) and y[-1] == pytest.approx(1.0, abs=1e-9)


@pytest.mark.parametrize('cutoff', [0.0, -1.0, 5000.0, 6000.0])
def test_cutoff_must_be_below_nyquist(cutoff):
    with pytest.raises(ValueError, match='Nyquist'):
        StreamingLowpass(cutoff, 10e3, 1)


def test_sensor_lowpass_per_sensor():
    sensors = [{'name': 'a', 'lowpass': 800.0}, {'name': 'b', 'lowpass': None},
               {'name': 'c', 'lowpass': 300.0}]
    x = np.random.default_rng(2).standard_normal((1000, 3))
    y = SensorLowpass(sensors, 1e-4).apply(x)
    np.testing.assert_array_equal(y[:, 1], x[:, 1])
    np.testing.assert_allclose(y[:, 0], StreamingLowpass(800.0, 1e4, 1).apply(x[:, 0]),
                               atol=1e-12)
    np.testing.assert_allclose(y[:, 2], StreamingLowpass(300.0, 1e4, 1).apply(x[:, 2]),
                               atol=1e-12)
    with pytest.raises(SceneError, match=r"sensors\[2\]\.lowpass.*Nyquist"):
        SensorLowpass(sensors, 1.0 / 600.0)


def test_simulate_rejects_a_cutoff_at_nyquist(capsys):
    # sdof samples at dt = 0.1 ms: Nyquist 5 kHz
    status = main(['simulate', 'sdof', '--duration', '0.1', '--window', '0.05', '--set',
                   'sensors.0.lowpass=5 kHz'])
    _, err = capsys.readouterr()
    assert status == 2 and "'sensors[0].lowpass'" in err and 'Nyquist' in err
    assert 'Traceback' not in err


def test_simulate_applies_the_lowpass(capsys):
    import json
    base = ['simulate', 'sdof', '--duration', '0.5', '--json']
    assert main(base) == 0
    raw = json.loads(capsys.readouterr()[0])['sensors']['primary']
    assert main(base + ['--set', 'sensors.0.lowpass=50 Hz']) == 0
    low = json.loads(capsys.readouterr()[0])['sensors']['primary']
    assert low['peak_displacement_m'] == raw['peak_displacement_m']
    assert low['peak_acceleration_m_s2'] < raw['peak_acceleration_m_s2']


@pytest.mark.parametrize('order', [1, 2, 3, 4, 5, 6])
@pytest.mark.parametrize('fc, fs', [(800.0, 10000.0), (25.0, 2000.0), (4000.0, 10000.0)])
def test_own_butterworth_equals_scipys(order, fc, fs):
    """Same filter as scipy.signal.butter + sosfilt, to round-off (1e-12 of the input)."""
    from scipy.signal import butter, sosfilt

    from impact_damper_sim.live.filters import butter_lowpass_sos
    x = np.random.default_rng(order).normal(size=(400, 2))
    ref = sosfilt(butter(order, fc, output='sos', fs=fs), x, axis=0)
    own = sosfilt(butter_lowpass_sos(order, fc, fs), x, axis=0)
    np.testing.assert_allclose(own, ref, rtol=0, atol=1e-12)
    # -3 dB at the cutoff, unit gain at DC
    sos = butter_lowpass_sos(order, fc, fs)
    z = np.exp(1j * 2 * np.pi * np.array([0.0, fc]) / fs)
    h = np.prod([(s[0] * z**2 + s[1] * z + s[2]) / (z**2 + s[4] * z + s[5]) for s in sos],
                axis=0)
    np.testing.assert_allclose(np.abs(h), [1.0, 2 ** -0.5], rtol=1e-12)


def test_sosfilt_kernel_and_twin_equal_scipy_across_chunks():
    from scipy.signal import sosfilt

    from impact_damper_sim.integrate.kernels.filters import sosfilt as kernel
    from impact_damper_sim.integrate.kernels.filters import sosfilt_py
    from impact_damper_sim.live.filters import butter_lowpass_sos
    sos = butter_lowpass_sos(4, 800.0, 10000.0)
    x = np.random.default_rng(3).normal(size=(300, 3))
    ref = sosfilt(sos, x, axis=0)
    for fn in (kernel, sosfilt_py):
        zi = np.zeros((sos.shape[0], 2, 3))
        parts = []
        for lo, hi in ((0, 1), (1, 120), (120, 300)):
            y = np.empty((hi - lo, 3))
            fn(sos, np.ascontiguousarray(x[lo:hi]), zi, y)
            parts.append(y)
        np.testing.assert_allclose(np.vstack(parts), ref, rtol=0, atol=1e-13)
