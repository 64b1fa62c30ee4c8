"""The live streams' core, without ROS: decimation filter, batch layout, one stream per node.

The decimated per-sample stream is checked against closed forms (a sine's amplitude and phase
at the stamp it is given for, an alias's attenuation, the filter's frequency response), the
batch encoder by round trips through rclpy, rosbags and mcap_ros2 readers.
"""
import numpy as np
import pytest

from impact_damper_sim.live.filters import (
    DECIMATION_PASSBAND_FRACTION,
    DECIMATION_STOPBAND_DB,
    StreamingDecimator,
)
from impact_damper_sim.live.realtime import LiveSimulation
from impact_damper_sim.live.streams import accelerometers, default_imu_rate, live_scene
from impact_damper_sim.recording.batches import (
    ACCEL_FIELDS,
    ACCEL_POINT_STEP,
    IMPACT_FIELDS,
    IMPACT_POINT_STEP,
    KEYPHASOR_FIELDS,
    KEYPHASOR_POINT_STEP,
    TACH_FIELDS,
    TACH_POINT_STEP,
    BatchEncoder,
    rows_of,
    sample_times_ns,
)
from impact_damper_sim.scene.build import load
from impact_damper_sim.scene.schema import SceneError


def _response(taps, f, fs):
    """|H(f)| of an FIR at frequencies f (Hz) for sample rate fs (Hz)."""
    return np.abs(np.exp(-2j * np.pi * np.outer(f / fs, np.arange(len(taps)))) @ taps)


@pytest.mark.parametrize('fs, factor', [(20000.0, 10), (50000.0, 25), (4000.0, 2)])
def test_decimation_filter_is_flat_in_band_and_80_db_down_from_the_output_nyquist(fs, factor):
    dec = StreamingDecimator(factor, fs, 1)
    fo = fs / factor
    f = np.linspace(0.0, fs / 2, 20001)
    h = _response(dec.taps, f, fs)
    assert np.max(np.abs(h[f <= DECIMATION_PASSBAND_FRACTION * fo] - 1)) < 2e-4   # 0.002 dB
    assert 20 * np.log10(np.max(h[f >= 0.5 * fo])) <= -DECIMATION_STOPBAND_DB
    assert len(dec.taps) % 2 == 1 and np.allclose(dec.taps, dec.taps[::-1])   # linear phase


def test_decimated_sine_is_exact_at_its_stamp_and_an_alias_vanishes():
    """A 600 Hz sine comes out at 2 kHz with its amplitude and phase at the stamped sample
    (the filter's delay is compensated, not hidden); a 1400 Hz one, which would fold onto
    600 Hz, is 80 dB down."""
    fs, factor = 20000.0, 10
    dec = StreamingDecimator(factor, fs, 2)
    t = np.arange(40000) / fs
    x = np.column_stack([np.sin(2 * np.pi * 600.0 * t + 0.3), np.sin(2 * np.pi * 1400.0 * t)])
    index, y = dec.apply(x)
    assert np.all(index % factor == 0) and index[-1] == (len(t) - 1 - dec.delay) // 10 * 10
    settled = index >= 2 * dec.delay   # past the start-up transient (zeros before t = 0)
    expect = np.sin(2 * np.pi * 600.0 * t[index[settled]] + 0.3)
    np.testing.assert_allclose(y[settled, 0], expect, rtol=0, atol=2e-4)
    assert np.max(np.abs(y[settled, 1])) < 10 ** (-DECIMATION_STOPBAND_DB / 20)


def test_decimation_in_chunks_equals_one_pass():
    """The filter keeps its history: any chunking gives the one-pass output (to round-off)."""
    fs, factor = 20000.0, 10
    x = np.random.default_rng(3).normal(size=(6000, 3))
    i_one, y_one = StreamingDecimator(factor, fs, 3).apply(x)
    dec = StreamingDecimator(factor, fs, 3)
    rng = np.random.default_rng(4)
    parts, start = [], 0
    while start < len(x):
        k = int(rng.integers(0, 700))   # empty chunks too
        parts.append(dec.apply(x[start:start + k]))
        start += k
    i_chunked = np.concatenate([p[0] for p in parts])
    y_chunked = np.concatenate([p[1] for p in parts])
    np.testing.assert_array_equal(i_chunked, i_one)
    np.testing.assert_allclose(y_chunked, y_one, rtol=0, atol=1e-13)


def test_factor_one_passes_the_signal_through():
    x = np.random.default_rng(5).normal(size=(50, 2))
    index, y = StreamingDecimator(1, 2000.0, 2).apply(x)
    np.testing.assert_array_equal(index, np.arange(50))
    np.testing.assert_array_equal(y, x)


def test_default_live_rates():
    assert default_imu_rate(2000.0) == 1000.0
    assert default_imu_rate(20000.0) == 1000.0
    assert default_imu_rate(50000.0) == 1000.0
    assert default_imu_rate(3000.0) == 1000.0
    assert default_imu_rate(1500.0) == 750.0
    assert default_imu_rate(800.0) == 800.0


def test_live_imu_stream_is_the_decimated_batch_stream():
    """RBS: 20 kHz batches, 1 kHz Imu. The Imu samples are the full-rate signal through the
    FIR, stamped on the 1 kHz grid of the full-rate sample times."""
    model, target = live_scene('rbs', ['channel=ideal'])   # the decimation alone
    live = LiveSimulation(model, initial_target=target)
    assert (live.sample_rate, live.imu_rate) == (20000.0, 1000.0)
    batches = [live.step(200) for _ in range(10)]
    t = np.concatenate([b.t for b in batches])
    full = np.concatenate([b.linear_acceleration for b in batches])[:, 0, :]
    imu_t = np.concatenate([b.imu_t for b in batches])
    imu = np.concatenate([b.imu_linear_acceleration for b in batches])[:, 0, :]
    np.testing.assert_allclose(imu_t, t[::20][:len(imu_t)], rtol=0, atol=1e-12)
    assert len(imu_t) == (len(t) - 1 - live._decimator.delay) // 20 + 1
    assert live.imu_delay == pytest.approx(live._decimator.delay / 20000.0)
    expect = StreamingDecimator(20, 20000.0, 3).apply(full)[1]
    np.testing.assert_allclose(imu, expect, rtol=0, atol=1e-9 * np.abs(full).max())


SHIPPED = sorted(p.stem for p in (__import__('pathlib').Path(__file__).resolve().parents[1]
                                  / 'config' / 'scenes').glob('*.yaml'))


@pytest.mark.parametrize('scene', SHIPPED)
def test_imu_covariance_is_the_variance_of_the_noise_in_the_samples(scene):
    """The Imu covariance is the variance of the white noise actually in each decimated
    sample, with the scene's own channel (sensor noise density, the live noise_std, ADC noise
    and quantization), not noise_std^2: the decimation FIR keeps sum(taps^2) of a white
    full-rate noise (0.44 at hpotp's 2 -> 1 kHz, 0.044 at rbs's 20 -> 1 kHz) and the sensor
    noise is coloured by the anti-alias filter before it. Measured on the noise alone: two
    runs that differ only in their seed carry the same signal (the noise does not act on the
    structure), so half the variance of their difference (each axis less its mean: the
    turn-on biases differ) is the noise's; 3 axes x 3,300 samples, within 5 % (the
    estimate's spread is 1.4 %)."""
    if load(scene).scene['offline_only']:
        pytest.skip(f'{scene} is an offline stress test: the node refuses it')
    model, target = live_scene(scene)
    runs = [LiveSimulation(model, initial_target=target, noise_std=0.3, seed=seed)
            for seed in (11, 12)]
    predicted = runs[0].imu_noise_variances()
    assert predicted == runs[1].imu_noise_variances() and len(predicted) == 1
    if runs[0]._decimator.factor > 1:   # the defect: noise_std^2 was published
        assert predicted[0] < 0.5 * 0.3 ** 2
    chunk = int(round(0.1 * runs[0].sample_rate))
    difference = []
    while sum(len(d) for d in difference) < 3300:
        first, second = (live.step(chunk) for live in runs)
        difference.append(first.imu_linear_acceleration - second.imu_linear_acceleration)
    difference = np.concatenate(difference)[:, 0, :]
    difference -= difference.mean(axis=0)
    assert 0.5 * float(np.mean(difference ** 2)) == pytest.approx(predicted[0], rel=0.05)


def test_the_ideal_channels_imu_variance_is_the_decimators_share_of_noise_std():
    """With the ideal channel the Imu variance is noise_std^2 x sum(taps^2), closed form."""
    for scene, gain in (('hpotp', 0.4404), ('rbs', 0.04403)):
        model, target = live_scene(scene, ['channel=ideal'])
        live = LiveSimulation(model, initial_target=target, noise_std=0.3, seed=1)
        taps = live._decimator.taps
        assert live.imu_noise_variances() == [pytest.approx(0.09 * np.sum(taps ** 2),
                                                            rel=1e-9)]
        assert np.sum(taps ** 2) == pytest.approx(gain, rel=1e-3)


def test_imu_rate_must_divide_the_sample_rate():
    model, target = live_scene('sdof')
    with pytest.raises(SceneError, match=r"imu rate: .* whole number"):
        LiveSimulation(model, sample_rate=2000.0, imu_rate=1500.0)
    assert LiveSimulation(model, sample_rate=2000.0, imu_rate=500.0).imu_rate == 500.0


def test_sensors_at_one_node_are_one_accelerometer():
    """RBS's y and z sensors at the lower bearing are one stream, not two of the same data."""
    assert [(a.name, a.node) for a in accelerometers(load('rbs'), 20000.0)] == [
        ('rbs_lower_brg', 4)]
    # without frame_id: named by the node
    scene = load('rbs', overrides=['sensors=[{name: a, node: 4, dof: uy}, '
                                   '{name: b, node: 4, dof: uz}, {name: c, node: 14, dof: uy}]'])
    assert [(a.name, a.node) for a in accelerometers(scene, 20000.0)] == [
        ('rbs_node4', 4), ('rbs_c', 14)]
    clash = load('rbs', overrides=['sensors=[{name: a, node: 4, dof: uy, frame_id: f}, '
                                   '{name: b, node: 4, dof: uz, frame_id: g}]'])
    with pytest.raises(SceneError, match="node 4 has sensors with frame_id 'f' and 'g'"):
        accelerometers(clash, 20000.0)


def test_offline_only_scene_is_refused_live_with_its_reason():
    with pytest.raises(SceneError, match=r"'hpotp_x10' is for offline studies only: "
                                         r'offline stress test: X = 10'):
        live_scene('hpotp_x10')
    assert load('hpotp').scene['offline_only'] == ''


def test_growth_rate_is_zero_within_rounding_and_positive_when_unstable():
    """ross_rotor is conservative (no damping): its largest real part is eigensolver round-off
    (1e-13 1/s), reported as 0. rbs_kcc (Kcc above onset) grows."""
    model, target = live_scene('ross_rotor')
    assert LiveSimulation(model, initial_target=target).linear_growth_rate() == 0.0
    model, target = live_scene('rbs_kcc')
    assert LiveSimulation(model, initial_target=target).linear_growth_rate() > 0.1


def _batch(fields, step, n, seed):
    rows = np.zeros(n, BatchEncoder('', fields, step).dtype)
    rng = np.random.default_rng(seed)
    for name in rows.dtype.names:
        rows[name] = (rng.integers(0, 7, n) if name in ('impactor', 'revolution')
                      else rng.normal(size=n))
    rows['t'] = np.arange(n) / 20000.0
    return rows


@pytest.mark.parametrize('fields, step', [(ACCEL_FIELDS, ACCEL_POINT_STEP),
                                          (IMPACT_FIELDS, IMPACT_POINT_STEP),
                                          (TACH_FIELDS, TACH_POINT_STEP),
                                          (KEYPHASOR_FIELDS, KEYPHASOR_POINT_STEP)])
@pytest.mark.parametrize('frame', ['', 'a', 'abc', 'hpotp_casing_bottom'])
@pytest.mark.parametrize('n', [0, 1, 200])
def test_batch_bytes_read_back_with_rclpy(fields, step, frame, n):
    """Every frame length (each pad before a uint32) and width: rclpy reads our bytes to the
    same values, and its own serialization of them has the same length (ours has zero pads
    where rclpy leaves garbage, so the bytes may differ only there)."""
    pytest.importorskip('rclpy')
    from rclpy.serialization import deserialize_message, serialize_message
    from sensor_msgs.msg import PointCloud2
    rows = _batch(fields, step, n, 1)
    data = BatchEncoder(frame, fields, step).encode(12_345_678_901, rows)
    msg = deserialize_message(data, PointCloud2)
    assert (msg.header.frame_id, msg.header.stamp.sec, msg.header.stamp.nanosec) == (
        frame, 12, 345_678_901)
    assert (msg.height, msg.width, msg.point_step, msg.row_step) == (1, n, step, n * step)
    assert msg.is_dense and not msg.is_bigendian
    assert [(f.name, f.offset, f.datatype, f.count) for f in msg.fields] == [
        (*f, 1) for f in fields]
    back = rows_of(msg)
    for name in rows.dtype.names:
        np.testing.assert_array_equal(back[name], rows[name])
    assert len(serialize_message(msg)) == len(data)
    np.testing.assert_array_equal(sample_times_ns(msg, back),
                                  12_345_678_901 + np.rint(rows['t'] * 1e9).astype(np.int64))


@pytest.mark.parametrize('fields, step', [(IMPACT_FIELDS, IMPACT_POINT_STEP),
                                          (KEYPHASOR_FIELDS, KEYPHASOR_POINT_STEP)])
def test_equal_batches_are_equal_bytes(fields, step):
    """No uninitialised padding: the impact and keyphasor layouts have a gap after their
    uint32 field."""
    rows = _batch(fields, step, 50, 2)
    messy = np.empty(50, rows.dtype)   # garbage in the gaps
    messy.view(np.uint8)[:] = 0xAB
    for name in rows.dtype.names:
        messy[name] = rows[name]
    enc = BatchEncoder('f', fields, step)
    assert enc.encode(5, messy) == enc.encode(5, rows)


def test_batches_read_with_rosbags_and_mcap_ros2(tmp_path):
    """A log of batches written as the node writes it reads, message by message, to the same
    rows with rosbags (typestore ROS2_JAZZY) and mcap_ros2's decoder."""
    pytest.importorskip('rclpy')
    pytest.importorskip('rosbags')
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    from impact_damper_sim.recording import Rosbag2McapWriter
    path = tmp_path / 'batches.mcap'
    written = []
    with Rosbag2McapWriter(path) as writer:
        for topic, fields, step in [('/accel/a/batch', ACCEL_FIELDS, ACCEL_POINT_STEP),
                                    ('/accel/a/truth', ACCEL_FIELDS, ACCEL_POINT_STEP),
                                    ('/impacts', IMPACT_FIELDS, IMPACT_POINT_STEP),
                                    ('/rotor/tach', TACH_FIELDS, TACH_POINT_STEP),
                                    ('/rotor/keyphasor', KEYPHASOR_FIELDS,
                                     KEYPHASOR_POINT_STEP)]:
            writer.add_topic(topic, 'sensor_msgs/msg/PointCloud2')
            enc = BatchEncoder('frame', fields, step)
            for k in range(5):
                rows = _batch(fields, step, k * 3, k)
                writer.write(topic, 'sensor_msgs/msg/PointCloud2', None,
                             enc.encode(k * 10_000_000, rows), k * 10_000_000, k * 10_000_000)
                written.append((topic, rows))
    with AnyReader([path], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        got = [(c.topic, rows_of(reader.deserialize(raw, c.msgtype)))
               for c, _, raw in reader.messages()]
    with open(path, 'rb') as f:
        got_mcap = [(ch.topic, rows_of(dec)) for _, ch, _, dec in make_reader(
            f, decoder_factories=[DecoderFactory()]).iter_decoded_messages()]
    for decoded in (got, got_mcap):
        assert sorted(len(r) for _, r in decoded) == sorted(len(r) for _, r in written)
        for topic, rows in written:
            match = [r for t, r in decoded if t == topic and len(r) == len(rows)
                     and all(np.array_equal(r[n], rows[n]) for n in rows.dtype.names)]
            assert match, topic
