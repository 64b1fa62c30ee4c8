"""The accelerometer channel through the node (issue 36): what a subscriber and /diagnostics
see of it. The chain's physics is tested in test_channel.py, its keys in
test_scene_channel.py."""
import numpy as np
import pytest

pytest.importorskip('rclpy')

from impact_damper_sim.scene.units import G0  # noqa: E402
from node_helpers import make_node  # noqa: E402

pytestmark = pytest.mark.ros


def _run(node, seconds):
    """Step ``seconds`` of sim time on the fake clock; return the batches stepped."""
    batches = []
    step = node.live.step

    def spy(n):
        batch = step(n)
        batches.append(batch)
        return batch

    node.live.step = spy
    for _ in range(int(round(seconds / 0.01))):
        node._wall.now += 0.01
        node.tick()
    node.live.step = step
    return batches


def test_clipping_is_counted_in_diagnostics_and_the_samples_stay_in_range(ros_context):
    """sdof rattles at up to ~100 g; with a 2 g range every clipped value is counted per
    accelerometer in the period and since start, the status says so (WARN), and no sample
    leaves the range by more than the DAQ noise added after the sensor; with the scene's own
    500 g sensor nothing clips."""
    node = make_node(ros_context, 'sdof', ['channel.range=2 g'])
    try:
        node.publish_diagnostics()
        batches = _run(node, 0.5)
        node.publish_diagnostics()
        d = node.last_diagnostics
        name = node.live.accelerometers[0].name
        clipped = sum(int(b.clipped[0]) for b in batches)
        assert clipped > 0 and d[f'clipped_values_{name}'] == clipped
        assert d[f'clipped_values_total_{name}'] == clipped
        assert d['level'] == 1 and f"clipped by the sensor's range or ADC: {name} " \
            f'{clipped} values' in d['message'], d['message']
        lin = np.concatenate([b.linear_acceleration for b in batches])
        imu = np.concatenate([b.imu_linear_acceleration for b in batches])
        # the sensor saturates at its range; the DAQ's own noise (50 uV rms at 10 mV/g:
        # 5 mg) comes after it, as on a real test stand
        adc_noise = node.live.channels[0]._adc[3]
        assert np.max(np.abs(lin)) <= 2 * G0 + 6 * adc_noise
        assert np.max(np.abs(imu)) <= 2 * G0 + 6 * adc_noise
        truth = np.concatenate([b.truth for b in batches])
        assert np.max(np.abs(truth)) > 5 * G0   # the model went well beyond it
        node.publish_diagnostics()   # a quiet period after: counted since start only
        assert node.last_diagnostics[f'clipped_values_{name}'] == 0
        assert node.last_diagnostics[f'clipped_values_total_{name}'] == clipped
    finally:
        node.destroy_node()
    node = make_node(ros_context, 'sdof')
    try:
        node.publish_diagnostics()
        batches = _run(node, 0.5)
        node.publish_diagnostics()
        assert not any(b.clipped.any() for b in batches)
        assert node.last_diagnostics['level'] == 0, node.last_diagnostics['message']
    finally:
        node.destroy_node()


def test_published_samples_are_on_the_adc_grid_with_the_channels_covariance(ros_context):
    """hpotp's preset (10 mV/g on a 24-bit +-5 V DAQ): every full-rate and every Imu sample
    is a whole number of LSBs, and the Imu covariance is the channel's decimated noise
    variance, not noise_std^2."""
    node = make_node(ros_context, 'hpotp', ['impactors=[]'], noise_std=0.05)
    try:
        channel = node.live.channels[0]
        lsb = channel.lsb
        assert lsb == pytest.approx(2 * 5.0 / 2 ** 24 / (0.010 / G0), rel=1e-12)
        batches = _run(node, 0.2)
        for values in (np.concatenate([b.linear_acceleration for b in batches]),
                       np.concatenate([b.imu_linear_acceleration for b in batches])):
            codes = values / lsb
            assert np.max(np.abs(codes - np.round(codes))) < 1e-6
        variance = node.live.imu_noise_variances()[0]
        assert variance == channel.decimated_noise_variance(node.live._decimator.taps)
        assert variance != pytest.approx(0.05 ** 2, rel=0.1)
        from rclpy.serialization import deserialize_message
        from sensor_msgs.msg import Imu
        imu_stream = node._messages.streams.index(next(
            s for s in node._messages.streams if s.type_name.endswith('Imu')))
        data = next(d for _, i, d in node._messages.batch_items(node.live.step(20))
                    if i == imu_stream)
        covariance = deserialize_message(data, Imu).linear_acceleration_covariance
        assert list(covariance) == [variance, 0, 0, 0, variance, 0, 0, 0, variance]
    finally:
        node.destroy_node()
