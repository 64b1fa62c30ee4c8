"""``study report``: counts, rates, accelerations, spectra, impact rate, stuck fraction, errors.

The fixture logs are written with ``mcap_ros2.writer.Writer`` (its own CDR encoder, no
rclpy) with schemas concatenated by rosbag2's rule from the installed ``.msg`` files, so the
report reads them the way it reads a rosbag2 log. Logs in the node's batch format are written
with the project's writer (``Rosbag2McapWriter``), the PointCloud2 payloads by
``BatchEncoder`` and the other messages copied byte for byte from a ``Log`` file.
"""
import json
import math
import re
import subprocess
import sys

import numpy as np
import pytest

from impact_damper_sim.cli.study import main as study
from impact_damper_sim.recording import Rosbag2McapWriter
from impact_damper_sim.recording.batches import (
    ACCEL_DTYPE,
    ACCEL_FIELDS,
    ACCEL_POINT_STEP,
    IMPACT_DTYPE,
    IMPACT_FIELDS,
    IMPACT_POINT_STEP,
    POINTCLOUD2,
    BatchEncoder,
)
from impact_damper_sim.studies.report import G0, analyze
from impact_damper_sim.studies.report_output import csv_rows
from impact_damper_sim.studies.report_signals import impact_rate, stuck_fractions, welch

mcap_ros2_writer = pytest.importorskip('mcap_ros2.writer')

T0 = 1_700_000_000_000_000_000   # log_time epoch of the fixtures (ns)
LATENCY = 1_000_000              # log_time - stamp (ns)
FS = 1000.0                      # accelerometer sample rate (Hz)
N = 2000                         # samples (2 s)
AX, FX = 2.0, 50.0               # x: amplitude (g), frequency (Hz): peak sampled exactly
AY, FY = 1.5, 123.0              # y: whole periods, not on a Welch bin


# --- fixtures: rosbag2-style schemas from the installed .msg files ----------------------------

from rosbag2_rule import msgdef  # noqa: E402  (test/ helper)


def stamp(t_ns):
    return {'sec': t_ns // 1_000_000_000, 'nanosec': t_ns % 1_000_000_000}


class Log:
    """Write messages ``(topic, type, dict, stamp_ns)``; log_time = T0 + stamp + LATENCY."""

    def __init__(self, path):
        from mcap.writer import CompressionType
        self.w = mcap_ros2_writer.Writer(str(path), chunk_size=64 * 1024,
                                         compression=CompressionType.NONE)
        self.schemas = {}

    def write(self, topic, rtype, msg, t_ns):
        if rtype not in self.schemas:
            self.schemas[rtype] = self.w.register_msgdef(rtype, msgdef(rtype))
        self.w.write_message(topic, self.schemas[rtype], msg, log_time=T0 + t_ns + LATENCY,
                             publish_time=T0 + t_ns)

    def close(self, metadata=None):
        for name, data in (metadata or {}).items():
            self.w.add_metadata(name, data)
        self.w.finish()


class BatchLog:
    """Write CDR payloads with the project's writer; log_time = T0 + stamp + LATENCY."""

    def __init__(self, path):
        self.w = Rosbag2McapWriter(path)

    def write(self, topic, data, t_ns):
        """Write one PointCloud2 payload (CDR bytes) stamped ``t_ns`` (ns)."""
        self.w.write(topic, POINTCLOUD2, None, data, T0 + t_ns + LATENCY, T0 + t_ns)

    def copy(self, path, topics):
        """Write the messages of ``topics`` of the log at ``path``: bytes and times as they are."""
        from mcap.reader import make_reader
        with open(path, 'rb') as fh:
            for schema, channel, message in make_reader(fh).iter_messages(topics=topics):
                self.w.write(channel.topic, schema.name, None, message.data,
                             message.log_time, message.publish_time)

    def accel(self, topic, t_ns, acc, chunk, frame='s1'):
        """Write accelerometer samples as batches.

        Parameters
        ----------
        topic : str
            ``.../accel/<name>/batch``.
        t_ns : ndarray of int64, shape (n,)
            Sample stamps (ns).
        acc : ndarray, shape (n, 3)
            Accelerations (m/s^2).
        chunk : int
            Samples a batch (samples).
        frame : str
            ``header.frame_id``.
        """
        encoder = BatchEncoder(frame, ACCEL_FIELDS, ACCEL_POINT_STEP)
        for k in range(0, len(t_ns), chunk):
            rows = np.zeros(len(t_ns[k:k + chunk]), ACCEL_DTYPE)
            rows['t'] = (t_ns[k:k + chunk] - t_ns[k]) * 1e-9
            rows['ax'], rows['ay'], rows['az'] = np.asarray(acc[k:k + chunk]).T
            self.write(topic, encoder.encode(int(t_ns[k]), rows), int(t_ns[k]))

    def impacts(self, topic, starts_ns, t_ns, impactor):
        """Write impacts as one batch per interval, empty when nothing hit in it.

        Parameters
        ----------
        topic : str
            ``.../impacts``.
        starts_ns : sequence of int
            Interval starts (ns): each interval runs to the next start, the last one on.
        t_ns : sequence of int
            Impact stamps (ns).
        impactor : sequence of int
            Impactor index of each impact.
        """
        encoder = BatchEncoder('housing', IMPACT_FIELDS, IMPACT_POINT_STEP)
        t_ns, impactor = np.asarray(t_ns, dtype=np.int64), np.asarray(impactor)
        for start, stop in zip(starts_ns, list(starts_ns[1:]) + [np.iinfo(np.int64).max]):
            inside = (t_ns >= start) & (t_ns < stop)
            rows = np.zeros(np.count_nonzero(inside), IMPACT_DTYPE)
            rows['t'] = (t_ns[inside] - start) * 1e-9
            rows['impactor'] = impactor[inside]
            rows['jx'] = 1e-3
            self.write(topic, encoder.encode(int(start), rows), int(start))

    def close(self):
        self.w.close()


def _imu(t_ns, ax, ay, az):
    return {'header': {'stamp': stamp(t_ns), 'frame_id': 's1'},
            'linear_acceleration': {'x': ax * G0, 'y': ay * G0, 'z': az * G0}}


def without_summary(src, dst):
    """Copy a log record by record into a file with no summary section (a streamed file)."""
    from mcap.reader import make_reader
    from mcap.writer import CompressionType, IndexType, Writer
    with open(src, 'rb') as fin, open(dst, 'wb') as fout:
        reader = make_reader(fin)
        w = Writer(fout, compression=CompressionType.NONE, index_types=IndexType.NONE,
                   repeat_channels=False, repeat_schemas=False, use_statistics=False,
                   use_summary_offsets=False)
        w.start(profile=reader.get_header().profile, library='test')
        schemas, channels = {}, {}
        for schema, channel, message in reader.iter_messages():
            if schema.id not in schemas:
                schemas[schema.id] = w.register_schema(schema.name, schema.encoding,
                                                       schema.data)
            if channel.id not in channels:
                channels[channel.id] = w.register_channel(
                    channel.topic, channel.message_encoding, schemas[schema.id],
                    channel.metadata)
            w.add_message(channels[channel.id], message.log_time, message.data,
                          message.publish_time, message.sequence)
        for record in reader.iter_metadata():
            w.add_metadata(record.name, record.metadata)
        w.finish()


def write_synthetic(path):
    """Sine accelerations, 8 impacts in two 1 s bins, two impactors' stuck states."""
    log = Log(path)
    events = []
    for k in range(N):
        t = k / FS
        events.append((k * 1_000_000, '/accel/s1', 'sensor_msgs/msg/Imu',
                       _imu(k * 1_000_000, AX * math.sin(2 * math.pi * FX * t),
                            AY * math.sin(2 * math.pi * FY * t), 0.0)))
    for t_s, imp in [(0.1, 'imp_a'), (0.4, 'imp_a'), (0.9, 'imp_b'), (1.0, 'imp_a'),
                     (1.2, 'imp_b'), (1.3, 'imp_a'), (1.6, 'imp_a'), (1.95, 'imp_b')]:
        t_ns = round(t_s * 1e9)
        events.append((t_ns, '/impacts', 'geometry_msgs/msg/WrenchStamped',
                       {'header': {'stamp': stamp(t_ns), 'frame_id': f'housing/{imp}'},
                        'wrench': {'force': {'x': 1e-3}, 'torque': {'x': 0.5, 'y': 0.3}}}))
    names = ['imp_a/y', 'imp_a/z', 'imp_b/x']
    # imp_a stuck from 0.5 to 1.5 s; imp_b stuck from 0 to 2 s (freed by the last message)
    for t_s, eff in [(0.0, [0, 0, 1]), (0.5, [1, 1, 1]), (1.5, [0, 0, 1]), (2.0, [0, 0, 0])]:
        t_ns = round(t_s * 1e9)
        events.append((t_ns, '/impactor_state', 'sensor_msgs/msg/JointState',
                       {'header': {'stamp': stamp(t_ns)}, 'name': names,
                        'position': [0.0] * 3, 'velocity': [0.0] * 3,
                        'effort': [float(e) for e in eff]}))
    events.sort(key=lambda e: e[0])
    for t_ns, topic, rtype, msg in events:
        log.write(topic, rtype, msg, t_ns)
    log.close({'impact_damper_sim': {'scene': 'cantilever', 'version': '0.1.0',
                                     'overrides': '[]'}})
    return events


@pytest.fixture(scope='module')
def synthetic(tmp_path_factory):
    path = tmp_path_factory.mktemp('report') / 'run.mcap'
    events = write_synthetic(path)
    return path, events


# --- the numbers ------------------------------------------------------------------------------

def test_counts_and_rates_exact(synthetic):
    path, events = synthetic
    report, _ = analyze(path)
    log_times = [T0 + t + LATENCY for t, *_ in events]
    duration = (max(log_times) - min(log_times)) * 1e-9
    assert report['duration_s'] == pytest.approx(2.0, abs=1e-12)
    assert report['message_count'] == len(events)
    expected = {'/accel/s1': ('sensor_msgs/msg/Imu', N),
                '/impacts': ('geometry_msgs/msg/WrenchStamped', 8),
                '/impactor_state': ('sensor_msgs/msg/JointState', 4)}
    got = {t['topic']: t for t in report['topics']}
    assert set(got) == set(expected)
    for topic, (rtype, count) in expected.items():
        assert got[topic]['type'] == rtype
        assert got[topic]['count'] == count
        assert got[topic]['rate_hz'] == pytest.approx(count / duration, rel=1e-12)
    # the sensor's own frequency: 1999 intervals of 1 ms
    assert got['/accel/s1']['frequency_hz'] == pytest.approx(FS, rel=1e-9)
    assert report['metadata']['impact_damper_sim'] == {'scene': 'cantilever',
                                                       'version': '0.1.0', 'overrides': '[]'}
    assert report['warnings'] == []


def test_peak_rms_in_g_and_dominant_frequency(synthetic):
    report, _ = analyze(synthetic[0])
    (s,) = report['sensors']
    assert (s['sensor'], s['samples']) == ('s1', N)
    assert s['sample_rate_hz'] == pytest.approx(FS, rel=1e-9)
    # x peaks on a sample (50 Hz at 1 kHz); both sines run whole periods: RMS = A/sqrt(2)
    assert s['peak_g']['x'] == pytest.approx(AX, rel=1e-6)
    assert s['rms_g']['x'] == pytest.approx(AX / math.sqrt(2), rel=1e-6)
    assert s['rms_g']['y'] == pytest.approx(AY / math.sqrt(2), rel=1e-6)
    assert s['peak_g']['z'] == 0.0 and s['rms_g']['z'] == 0.0
    assert s['rms_g']['magnitude'] == pytest.approx(math.hypot(AX, AY) / math.sqrt(2), rel=1e-6)
    t = np.arange(N) / FS
    mag = np.hypot(AX * np.sin(2 * np.pi * FX * t), AY * np.sin(2 * np.pi * FY * t))
    assert s['peak_g']['magnitude'] == pytest.approx(mag.max(), rel=1e-6)
    spec = s['spectrum']
    bin_hz = spec['resolution_hz']
    assert bin_hz == pytest.approx(FS / spec['segment_samples'])
    assert FY / bin_hz % 1 == pytest.approx(0.49, abs=0.02)   # y sits between two bins
    assert abs(spec['dominant_hz']['x'] - FX) <= bin_hz
    assert abs(spec['dominant_hz']['y'] - FY) <= bin_hz
    assert abs(spec['dominant_hz']['total'] - FX) <= bin_hz   # x is the larger
    assert s['waterfall'] is None   # no rotor speed in this log


def test_impact_rate_per_second_bins(synthetic):
    report, _ = analyze(synthetic[0])
    (imp,) = report['impacts']
    assert imp['count'] == 8
    assert [b['count'] for b in imp['bins']] == [3, 5]
    assert [b['rate_hz'] for b in imp['bins']] == pytest.approx([3.0, 5.0], rel=1e-12)
    assert imp['mean_rate_hz'] == pytest.approx(4.0, rel=1e-12)
    assert imp['peak_rate_hz'] == pytest.approx(5.0, rel=1e-12)
    assert imp['per_impactor'] == {'imp_a': 5, 'imp_b': 3}


def test_impact_rate_partial_last_bin():
    entry, _ = impact_rate([0, 2_600_000_000], ['a', 'a'], 0, 2_500_000_000)
    assert [b['width_s'] for b in entry['bins']] == pytest.approx([1.0, 1.0, 0.5])
    assert [b['count'] for b in entry['bins']] == [1, 0, 1]
    assert entry['bins'][-1]['rate_hz'] == pytest.approx(2.0)
    assert entry['peak_rate_hz'] == pytest.approx(1.0)   # full bins only


def test_welch_parseval_and_peak():
    """A sine of whole periods per segment: the PSD integrates to A^2/2, peaks on its bin."""
    fs, seg = 1000.0, 256
    t = np.arange(1024) / fs
    f0 = 10 * fs / seg                        # 10 periods per segment
    freq, psd = welch(3.0 * np.sin(2 * np.pi * f0 * t)[:, None], fs, seg)
    assert psd.shape == (1, seg // 2 + 1)
    assert np.sum(psd[0]) * fs / seg == pytest.approx(4.5, rel=1e-9)
    assert freq[np.argmax(psd[0])] == pytest.approx(f0)


def test_stuck_fraction_time_weighted(synthetic):
    report, _ = analyze(synthetic[0])
    (state,) = report['impactor_state']
    a, b = state['impactors']['imp_a'], state['impactors']['imp_b']
    assert a['stuck_fraction'] == pytest.approx(0.5, rel=1e-12)
    assert a['stuck_s'] == pytest.approx(1.0, rel=1e-12)
    assert a['observed_s'] == pytest.approx(2.0, rel=1e-12)
    assert b['stuck_fraction'] == pytest.approx(1.0, rel=1e-12)
    assert (a['stick_events'], b['stick_events']) == (1, 1)


def test_stuck_fraction_last_state_holds_to_end():
    s = 1_000_000_000
    out, _ = stuck_fractions([0, 3 * s], [['a/x'], ['a/x']], [[0.0], [1.0]], 4 * s)
    assert out['a']['stuck_fraction'] == pytest.approx(0.25)


def test_dampers_off_is_its_own_lane_state(tmp_path, monkeypatch):
    """Efforts of -1 (the node's dampers off) are neither free nor stuck: their own state in
    the lanes' data, their own time, and a grey bar in the plot where the trace breaks."""
    from matplotlib.figure import Figure
    s = 1_000_000_000
    names = ['imp_a/y', 'imp_a/z', 'imp_b/x']
    # imp_a: free, stuck at 0.5 s, dampers off 1 to 2 s, free to the end (3 s); imp_b free
    states = [(0, [0, 0, 0]), (s // 2, [1, 1, 0]), (s, [-1, -1, -1]), (2 * s, [0, 0, 0])]
    out, steps = stuck_fractions([t for t, _ in states], [names] * 4,
                                 [[float(e) for e in eff] for _, eff in states], 3 * s)
    assert steps['imp_a'][1].tolist() == [0, 1, -1, 0, 0]
    assert steps['imp_b'][1].tolist() == [0, 0, -1, 0, 0]
    a = out['imp_a']
    assert (a['stuck_s'], a['dampers_off_s'], a['observed_s']) == pytest.approx((0.5, 1.0, 3.0),
                                                                               rel=1e-12)
    assert a['stuck_fraction'] == pytest.approx(0.5 / 3, rel=1e-12) and a['stick_events'] == 1
    path = tmp_path / 'off.mcap'
    log = Log(path)
    for t_ns, eff in states + [(3 * s, [0, 0, 0])]:
        log.write('/impactor_state', 'sensor_msgs/msg/JointState',
                  {'header': {'stamp': stamp(t_ns)}, 'name': names, 'position': [0.0] * 3,
                   'velocity': [0.0] * 3, 'effort': [float(e) for e in eff]}, t_ns)
    log.close()
    figs = []
    original = Figure.savefig
    monkeypatch.setattr(Figure, 'savefig',
                        lambda self, *a, **k: (figs.append(self), original(self, *a, **k)))
    assert study(['report', str(path), '--plot', str(tmp_path / 'off.png')]) == 0
    (ax,) = [ax for ax in figs[0].axes if ax.get_title().startswith('stuck state')]
    assert 'grey = dampers off' in ax.get_title()
    bars = {c.get_gid(): c for c in ax.collections if (c.get_gid() or '').startswith('dampers')}
    assert set(bars) == {'dampers-off:imp_a', 'dampers-off:imp_b'}
    for lane, gid in enumerate(('dampers-off:imp_a', 'dampers-off:imp_b')):
        (bar,) = bars[gid].get_paths()
        xs, ys = bar.vertices[:, 0], bar.vertices[:, 1]
        assert (xs.min(), xs.max()) == pytest.approx((1.0, 2.0), abs=1e-9)
        assert ys.min() < lane < lane + 0.6 < ys.max() < lane + 0.85   # inside its own lane
    (trace,) = [line for line in ax.get_lines()
                if line.get_gid() == 'lane:imp_a' and line.get_linestyle() == '-']
    x, y = trace.get_xdata(), trace.get_ydata()
    assert np.isnan(y[(x >= 1.0) & (x < 2.0)]).all() and np.isfinite(y[x < 1.0]).all()
    assert ax.get_legend() is None   # the title says it; a legend would cover the top lane


def test_waterfall_follows_rotor_speed(tmp_path):
    """A tone at the rotor frequency, speed ramped 60 -> 600 rad/s: the slices track it."""
    path = tmp_path / 'ramp.mcap'
    log = Log(path)
    fs, n = 1000.0, 4000
    t = np.arange(n) / fs
    w = 60 + (600 - 60) * t / t[-1]                       # rad/s
    phase = np.cumsum(w) / fs                              # rad
    events = [(k * 1_000_000, '/accel/s1', 'sensor_msgs/msg/Imu',
               _imu(k * 1_000_000, 0.0, 0.0, 0.3 * math.sin(phase[k]))) for k in range(n)]
    events += [(k * 10_000_000, '/rotor/speed', 'geometry_msgs/msg/Vector3Stamped',
                {'header': {'stamp': stamp(k * 10_000_000)},
                 'vector': {'x': float(60 + 540 * (k * 0.01) / t[-1])}})
               for k in range(int(t[-1] * 100) + 1)]
    for t_ns, topic, rtype, msg in sorted(events, key=lambda e: e[0]):
        log.write(topic, rtype, msg, t_ns)
    log.close()
    report, series = analyze(path)
    (sp,) = report['rotor_speed']
    assert sp['min_rad_s'] == pytest.approx(60) and sp['max_rad_s'] == pytest.approx(600, 1e-2)
    wf = report['sensors'][0]['waterfall']
    assert wf is not None and wf['slices'] >= 10
    # within a slice the tone sweeps this much (Hz); the slice's speed is its mean
    sweep = 540 / t[-1] * wf['segment_samples'] / fs / (2 * math.pi)
    for f, speed in zip(wf['dominant_hz'], wf['speed_rad_s']):
        assert abs(f - speed / (2 * math.pi)) <= wf['resolution_hz'] + sweep / 2
    assert np.diff(wf['speed_rad_s']).min() > 0
    out = tmp_path / 'wf.png'
    assert study(['report', str(path), '--plot', str(out)]) == 0
    assert out.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


def test_streamed_file_without_summary(tmp_path):
    events = write_synthetic(tmp_path / 'full.mcap')
    path = tmp_path / 'streamed.mcap'
    without_summary(tmp_path / 'full.mcap', path)
    report, _ = analyze(path)
    assert report['message_count'] == len(events)
    assert {t['topic']: t['count'] for t in report['topics']}['/accel/s1'] == N
    assert report['sensors'][0]['rms_g']['x'] == pytest.approx(AX / math.sqrt(2), rel=1e-6)
    assert report['metadata']['impact_damper_sim']['scene'] == 'cantilever'


# --- logs in the node's batch format ---------------------------------------------------------

FSB = 20000.0                    # full-rate sample rate of the batch logs (Hz)
NB = 40000                       # full-rate samples (2 s)
CHUNK = 200                      # samples a batch: the node's 10 ms chunk at FSB
FX_B, AY_B, FY_B = 1000.0, 0.5, 7000.0   # x: AX at 1 kHz; y: AY_B g cosine at 7 kHz
BATCH_IMPACTS = [(0.105, 0), (0.3, 1), (0.5, 0), (0.505, 1), (1.25, 0), (1.5, 1), (1.7, 1),
                 (1.9, 2)]       # (s, impactor index); index 2 is not in impactor_state
STATE_NAMES = ['imp_a/y', 'imp_a/z', 'imp_b/x']


def _state_and_imu_log(path, imu_fs):
    """A ``Log`` file with one ``impactor_state`` at 0 s and a decimated ``/accel/s1`` Imu at
    ``imu_fs`` Hz reading 3 g on z (which a report that reads the batch must not show)."""
    log = Log(path)
    log.write('/impactor_state', 'sensor_msgs/msg/JointState',
              {'header': {'stamp': stamp(0)}, 'name': STATE_NAMES, 'position': [0.0] * 3,
               'velocity': [0.0] * 3, 'effort': [0.0] * 3}, 0)
    for k in range(int(2 * imu_fs)):
        t_ns = round(k * 1e9 / imu_fs)
        log.write('/accel/s1', 'sensor_msgs/msg/Imu', _imu(t_ns, 0.0, 0.0, 3.0), t_ns)
    log.close()


def write_batch_log(path, tmp_path):
    """The node's format: 2 s of full-rate batches (x 2 g at 1 kHz, y 0.5 g cosine at 7 kHz:
    above the 1 kHz Nyquist of the decimated Imu), the decimated Imu of the same sensor,
    impact batches every 10 ms with BATCH_IMPACTS, one impactor_state."""
    scratch = tmp_path / 'messages.mcap'
    _state_and_imu_log(scratch, 2000.0)
    log = BatchLog(path)
    log.copy(scratch, ['/impactor_state', '/accel/s1'])
    t_ns = np.arange(NB, dtype=np.int64) * 50_000                 # 1 / FSB in ns
    t = np.arange(NB) / FSB
    acc = np.column_stack([AX * np.sin(2 * np.pi * FX_B * t), AY_B * np.cos(2 * np.pi * FY_B * t),
                           np.zeros(NB)]) * G0
    log.accel('/accel/s1/batch', t_ns, acc, CHUNK)
    log.impacts('/impacts', np.arange(200, dtype=np.int64) * 10_000_000,
                [round(s * 1e9) for s, _ in BATCH_IMPACTS], [i for _, i in BATCH_IMPACTS])
    log.close()
    return t, acc / G0


def test_batches_are_the_sensor_and_impacts_per_impactor(tmp_path):
    path = tmp_path / 'batches.mcap'
    t, a_g = write_batch_log(path, tmp_path)
    report, _ = analyze(path)
    assert report['warnings'] == []
    counts = {x['topic']: (x['type'], x['count']) for x in report['topics']}
    assert counts == {'/accel/s1/batch': ('sensor_msgs/msg/PointCloud2', NB // CHUNK),
                      '/accel/s1': ('sensor_msgs/msg/Imu', 4000),
                      '/impacts': ('sensor_msgs/msg/PointCloud2', 200),
                      '/impactor_state': ('sensor_msgs/msg/JointState', 1)}
    # one sensor, read from the batches at full rate (not also from its decimated Imu)
    (s,) = report['sensors']
    assert (s['topic'], s['sensor'], s['samples'], s['gaps']) == ('/accel/s1/batch', 's1', NB, 0)
    assert s['sample_rate_hz'] == pytest.approx(FSB, rel=1e-9)
    assert s['duration_s'] == pytest.approx((NB - 1) / FSB, abs=1e-12)
    # x peaks on a sample (1 kHz at 20 kHz), y at t = 0; both run whole periods (14,000 of
    # y: 2 f / fs is not an integer, so sum cos^2 = n/2 exactly): RMS = A / sqrt(2)
    assert s['peak_g']['x'] == pytest.approx(AX, rel=1e-12)
    assert s['peak_g']['y'] == pytest.approx(AY_B, rel=1e-12)
    assert s['peak_g']['z'] == 0.0 and s['rms_g']['z'] == 0.0
    assert s['rms_g']['x'] == pytest.approx(AX / math.sqrt(2), rel=1e-9)
    assert s['rms_g']['y'] == pytest.approx(AY_B / math.sqrt(2), rel=1e-9)
    assert s['rms_g']['magnitude'] == pytest.approx(math.hypot(AX, AY_B) / math.sqrt(2),
                                                    rel=1e-9)
    assert s['peak_g']['magnitude'] == pytest.approx(np.hypot(a_g[:, 0], a_g[:, 1]).max(),
                                                     rel=1e-12)
    spec = s['spectrum']
    assert spec['resolution_hz'] == pytest.approx(FSB / spec['segment_samples'], rel=1e-12)
    assert abs(spec['dominant_hz']['x'] - FX_B) <= spec['resolution_hz']
    assert abs(spec['dominant_hz']['y'] - FY_B) <= spec['resolution_hz']
    assert abs(spec['dominant_hz']['total'] - FX_B) <= spec['resolution_hz']
    # impacts: named through impactor_state (imp_a, imp_b), index 2 as impactor2; the stamped
    # span ends at the last sample, 1.99995 s, so the second 1 s bin is 0.99995 s wide
    (imp,) = report['impacts']
    end = (NB - 1) / FSB
    assert imp['count'] == len(BATCH_IMPACTS)
    assert imp['per_impactor'] == {'imp_a': 3, 'imp_b': 4, 'impactor2': 1}
    assert [b['count'] for b in imp['bins']] == [4, 4]
    assert [b['width_s'] for b in imp['bins']] == pytest.approx([1.0, end - 1.0], abs=1e-12)
    assert [b['rate_hz'] for b in imp['bins']] == pytest.approx([4.0, 4 / (end - 1.0)],
                                                                rel=1e-9)
    assert imp['mean_rate_hz'] == pytest.approx(8 / end, rel=1e-9)
    assert imp['peak_rate_hz'] == pytest.approx(4.0, rel=1e-12)


def test_impact_batches_without_impactor_state_and_empty_ones(tmp_path):
    """No impactor_state: impactors named by index. Empty batches extend the stamped span:
    batches from 0 to 0.99 s, impacts only in 0.2..0.29 s, mean = count / 0.99 s."""
    path = tmp_path / 'impacts.mcap'
    log = BatchLog(path)
    hits = [(0.2, 0), (0.21, 3), (0.25, 3), (0.29, 0), (0.29, 3)]
    log.impacts('/rig/impacts', np.arange(100, dtype=np.int64) * 10_000_000,
                [round(s * 1e9) for s, _ in hits], [i for _, i in hits])
    log.close()
    report, _ = analyze(path)
    assert report['warnings'] == [] and report['sensors'] == []
    assert report['stamped_span_s'] == pytest.approx(0.99, abs=1e-12)
    (imp,) = report['impacts']
    assert (imp['topic'], imp['count']) == ('/rig/impacts', 5)
    assert imp['per_impactor'] == {'impactor0': 2, 'impactor3': 3}
    assert imp['mean_rate_hz'] == pytest.approx(5 / 0.99, rel=1e-9)


def test_same_signal_as_imu_or_as_batches_gives_the_same_report(synthetic, tmp_path):
    """The synthetic log again, its samples in 10-sample batches and its impacts in 10 ms
    batches (impactor_state copied): the sensor and impact numbers agree to 1e-12."""
    path, events = synthetic
    samples = [(t_ns, msg['linear_acceleration']) for t_ns, topic, _, msg in events
               if topic == '/accel/s1']
    t_ns = np.array([t for t, _ in samples], dtype=np.int64)
    acc = np.array([[a['x'], a['y'], a['z']] for _, a in samples])
    order = ['imp_a', 'imp_b']                        # impactor_state's order
    hits = [(t, order.index(msg['header']['frame_id'].rsplit('/', 1)[-1]))
            for t, topic, _, msg in events if topic == '/impacts']
    batched = tmp_path / 'batched.mcap'
    log = BatchLog(batched)
    log.copy(path, ['/impactor_state'])
    log.accel('/accel/s1/batch', t_ns, acc, 10)
    log.impacts('/impacts', np.arange(200, dtype=np.int64) * 10_000_000,
                [t for t, _ in hits], [i for _, i in hits])
    log.close()
    per_sample, _ = analyze(path)
    per_batch, _ = analyze(batched)
    (a,), (b,) = per_sample['sensors'], per_batch['sensors']
    assert b['topic'] == '/accel/s1/batch' and a['sensor'] == b['sensor'] == 's1'
    for key in ('samples', 'gaps'):
        assert a[key] == b[key]
    for key in ('sample_rate_hz', 'duration_s'):
        assert b[key] == pytest.approx(a[key], rel=1e-12)
    # peaks, RMS, rate and dominant frequencies, as flattened for the CSV
    quantities = [{q: v for section, _, q, v, _ in csv_rows(r) if section == 'sensor'}
                  for r in (per_sample, per_batch)]
    assert len(quantities[0]) == 13
    assert quantities[1] == pytest.approx(quantities[0], rel=1e-12)
    (i,), (j,) = per_sample['impacts'], per_batch['impacts']
    assert (i['count'], i['per_impactor']) == (j['count'], j['per_impactor']) == (
        8, {'imp_a': 5, 'imp_b': 3})
    assert [x['count'] for x in i['bins']] == [x['count'] for x in j['bins']]
    assert [x['rate_hz'] for x in j['bins']] == pytest.approx([x['rate_hz'] for x in i['bins']],
                                                              rel=1e-12)
    assert j['mean_rate_hz'] == pytest.approx(i['mean_rate_hz'], rel=1e-12)
    assert per_batch['impactor_state'] == per_sample['impactor_state']


# --- the command ------------------------------------------------------------------------------

def test_json_schema(synthetic, capsys):
    assert study(['report', str(synthetic[0]), '--json']) == 0
    r = json.loads(capsys.readouterr().out)
    assert set(r) == {'file', 'profile', 'library', 'start_time_ns', 'end_time_ns',
                      'duration_s', 'message_count', 'time_origin_s', 'stamped_span_s',
                      'topics', 'sensors', 'rotor_speed', 'impacts', 'impactor_state',
                      'commands', 'metadata', 'warnings'}
    assert r['profile'] == 'ros2'
    assert set(r['topics'][0]) == {'topic', 'type', 'count', 'rate_hz', 'frequency_hz'}
    s = r['sensors'][0]
    assert set(s) == {'topic', 'sensor', 'samples', 'sample_rate_hz', 'gaps', 'duration_s',
                      'peak_g', 'rms_g', 'nonfinite_samples', 'spectrum', 'waterfall'}
    assert s['nonfinite_samples'] == {'x': 0, 'y': 0, 'z': 0}
    assert set(s['peak_g']) == set(s['rms_g']) == {'x', 'y', 'z', 'magnitude'}
    assert set(s['spectrum']) == {'method', 'segment_samples', 'resolution_hz', 'dominant_hz'}
    assert set(s['spectrum']['dominant_hz']) == {'x', 'y', 'z', 'total'}
    imp = r['impacts'][0]
    assert set(imp) == {'topic', 'count', 'mean_rate_hz', 'peak_rate_hz', 'bin_s', 'bins',
                        'per_impactor'}
    assert set(imp['bins'][0]) == {'start_s', 'width_s', 'count', 'rate_hz'}
    st = r['impactor_state'][0]
    assert set(st['impactors']['imp_a']) == {'stuck_fraction', 'stuck_s', 'dampers_off_s',
                                             'observed_s', 'stick_events'}


def test_text_plot_and_csv(synthetic, tmp_path, capsys):
    png, csv_path = tmp_path / 'r.png', tmp_path / 'r.csv'
    assert study(['report', str(synthetic[0]), '--plot', str(png), '--csv', str(csv_path)]) == 0
    out = capsys.readouterr().out
    assert 'scene: cantilever' in out and 'version: 0.1.0' in out   # the metadata record
    assert '/accel/s1' in out and 'stuck fraction' in out
    assert png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    lines = csv_path.read_text().splitlines()
    assert lines[0] == 'section,name,quantity,value,unit'
    assert 'topic,/impacts,count,8,' in lines
    assert any(line.startswith('stuck_fraction,/impactor_state:imp_a,stuck_fraction,0.5')
               for line in lines)


def _bad_files(tmp_path, synthetic_path):
    good = synthetic_path.read_bytes()
    files = {'empty': b'', 'garbage': bytes(range(256)) * 40,
             'truncated': good[:len(good) // 2], 'header only': good[:20]}
    from mcap.writer import Writer
    other = tmp_path / 'json.mcap'
    with open(other, 'wb') as fh:   # a valid MCAP, but not ROS 2
        w = Writer(fh)
        w.start(profile='', library='test')
        sid = w.register_schema('Thing', 'jsonschema', b'{}')
        cid = w.register_channel('/thing', 'json', sid)
        w.add_message(cid, log_time=1, publish_time=1, data=b'{}')
        w.finish()
    out = {}
    for name, data in files.items():
        p = tmp_path / (name.replace(' ', '_') + '.mcap')
        p.write_bytes(data)
        out[name] = p
    out['not ROS 2'] = other
    out['missing'] = tmp_path / 'nope.mcap'
    return out


@pytest.mark.parametrize('kind, pattern', [
    ('empty', 'empty file'), ('garbage', 'not an MCAP file'), ('truncated', 'truncated'),
    ('header only', 'truncated'), ('not ROS 2', 'not a ROS 2 log'), ('missing', 'cannot read')])
def test_bad_files_clear_error(kind, pattern, synthetic, tmp_path, capsys):
    path = _bad_files(tmp_path, synthetic[0])[kind]
    assert study(['report', str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith('study: error: ') and pattern in err
    assert len(err.strip().splitlines()) == 1 and 'Traceback' not in err


def test_bad_file_subprocess_no_traceback(synthetic, tmp_path):
    path = _bad_files(tmp_path, synthetic[0])['truncated']
    proc = subprocess.run([sys.executable, '-m', 'impact_damper_sim.cli.study', 'report',
                           str(path)], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2
    assert 'truncated' in proc.stderr and 'Traceback' not in proc.stderr
    assert proc.stdout == ''


def test_existing_plot_or_csv_needs_overwrite(synthetic, tmp_path, capsys):
    """An existing --plot/--csv file is refused (exit 2, file untouched) without --overwrite."""
    png, csv_path = tmp_path / 'r.png', tmp_path / 'r.csv'
    png.write_bytes(b'mine')
    assert study(['report', str(synthetic[0]), '--plot', str(png), '--csv', str(csv_path)]) == 2
    assert f'{png} exists; pass --overwrite' in capsys.readouterr().err
    assert png.read_bytes() == b'mine' and not csv_path.exists()
    assert study(['report', str(synthetic[0]), '--plot', str(png), '--csv', str(csv_path),
                  '--overwrite']) == 0
    assert png.read_bytes()[:4] == b'\x89PNG'


def test_short_last_bin_is_a_count_not_a_rate_and_silent_axes_are_named(tmp_path, capsys):
    """50 impacts/s for 3.1 s: the text gives the full 1 s bins as rates (50 50 50) and the
    last 0.1 s as a count (5 impacts), not as a 50/s bar that reads like a spike or a dip;
    the plot names the axes without signal (x, z) instead of drawing them at a floor."""
    path, png = tmp_path / 'bins.mcap', tmp_path / 'bins.png'
    log = Log(path)
    events = [(k * 1_000_000, '/accel/s1', 'sensor_msgs/msg/Imu',
               _imu(k * 1_000_000, 0.0, math.sin(2 * math.pi * 25 * k / FS), 0.0))
              for k in range(3100)]
    events += [(k * 20_000_000 + 10_000_000, '/impacts', 'geometry_msgs/msg/WrenchStamped',
                {'header': {'stamp': stamp(k * 20_000_000 + 10_000_000), 'frame_id': 'h/a'},
                 'wrench': {'force': {'x': 1e-3}}}) for k in range(155)]
    events.sort(key=lambda e: e[0])
    for t_ns, topic, rtype, msg in events:
        log.write(topic, rtype, msg, t_ns)
    log.close()
    assert study(['report', str(path), '--plot', str(png)]) == 0
    out = capsys.readouterr().out
    assert 'impacts/s per full 1 s bin: 50 50 50\n' in out
    assert re.search(r'last 0\.09\d* s \(partial bin\): 5 impact\(s\)', out)
    assert png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


# --- non-finite samples (issue 29) -------------------------------------------------------------

def write_nan_log(path, all_nan_axis='z'):
    """The synthetic sine log with 10 NaN x samples, 5 inf y samples and a NaN-only axis."""
    log = Log(path)
    for k in range(N):
        t = k / FS
        ax = math.nan if 500 <= k < 510 else AX * math.sin(2 * math.pi * FX * t)
        ay = math.inf if 700 <= k < 705 else AY * math.sin(2 * math.pi * FY * t)
        az = math.nan if all_nan_axis == 'z' else 0.0
        log.write('/accel/s1', 'sensor_msgs/msg/Imu', _imu(k * 1_000_000, ax, ay, az),
                  k * 1_000_000)
    log.close()


@pytest.mark.parametrize('fmt', ['text', 'json'])
def test_nan_samples_are_named_without_runtime_warnings(tmp_path, capsys, fmt):
    import warnings
    path = tmp_path / 'nan.mcap'
    write_nan_log(path)
    plot = tmp_path / 'nan.png'
    with warnings.catch_warnings():
        warnings.simplefilter('error')   # a NumPy RuntimeWarning fails the test
        args = ['report', str(path), '--plot', str(plot)] + (['--json'] if fmt == 'json' else [])
        assert study(args) == 0
    captured = capsys.readouterr()
    said = (r'/accel/s1: non-finite samples \(NaN or inf\): x 10 of 2000, y 5 of 2000, '
            r'z 2000 of 2000')
    assert re.search(said, captured.err), captured.err   # a warning, in either format
    if fmt == 'json':
        s = json.loads(captured.out)['sensors'][0]
        assert s['nonfinite_samples'] == {'x': 10, 'y': 5, 'z': N}
        assert s['peak_g']['z'] is None and s['rms_g']['z'] is None   # no finite sample
        # the finite samples' statistics: the sine's peak, and its spectrum's frequency
        assert s['peak_g']['x'] == pytest.approx(AX, rel=1e-9)
        assert s['spectrum']['dominant_hz']['x'] == pytest.approx(FX, abs=2.0)
    else:
        assert re.search(said, captured.out), captured.out
    assert plot.exists()


# --- issue 38: totals labelled, waterfall axis by the speed profile, commands marked -----------

def test_per_impactor_numbers_are_labelled_totals(synthetic, capsys):
    assert study(['report', str(synthetic[0])]) == 0
    line = next(x for x in capsys.readouterr().out.splitlines() if x.startswith('impacts '))
    # 8 impacts, imp_a 5 and imp_b 3 of them; the peak is a rate: 5 in the bin 1-2 s
    assert line == ('impacts /impacts: 8 in total, mean 4/s, peak 5/s; '
                    'totals per impactor: imp_a 5, imp_b 3'), line


def test_waterfall_axis_follows_the_speed_profile():
    from impact_damper_sim.studies.report_signals import waterfall_axis
    ramp = np.linspace(0, 600, 41)
    assert waterfall_axis(ramp[:-1], ramp[1:]) == ('speed', 1.0)
    # two held speeds, 2 of 40 slices ramping between them: against time
    held = np.r_[np.full(20, 100.0), [150.0, 250.0], np.full(18, 300.0)]
    ends = np.r_[np.full(19, 100.0), [150.0, 250.0, 300.0], np.full(18, 300.0)]
    axis, fraction = waterfall_axis(held, ends)
    assert axis == 'time' and fraction == pytest.approx(3 / 40)
    # a constant speed: against time (no speed range to read against)
    assert waterfall_axis(np.full(10, 50.0), np.full(10, 50.0)) == ('time', 0.0)


def _held_speed_log(path):
    """8 s of a 1x tone at 1 kHz, the speed held at 100 then (after a 0.2 s ramp from 3.9 s)
    at 300 rad/s, a speed command at 3.9 s and an unbalance command (x3) at 6 s."""
    log = Log(path)
    fs, n = 1000.0, 8000
    t = np.arange(n) / fs

    def speed(x):
        return np.interp(x, [0, 3.9, 4.1, 8.0], [100.0, 100.0, 300.0, 300.0])
    amp = np.where(t < 6.0, 0.2, 0.6)
    phase = np.cumsum(speed(t)) / fs
    events = [(k * 1_000_000, '/accel/s1', 'sensor_msgs/msg/Imu',
               _imu(k * 1_000_000, 0.0, float(amp[k] * math.sin(phase[k])), 0.0))
              for k in range(n)]
    events += [(k * 10_000_000, '/rotor/speed', 'geometry_msgs/msg/Vector3Stamped',
                {'header': {'stamp': stamp(k * 10_000_000), 'frame_id': 'rig_rotor'},
                 'vector': {'x': float(speed(k * 0.01))}}) for k in range(800)]
    events += [(3_900_000_000, '/rotor/speed_command', 'std_msgs/msg/Float64', {'data': 300.0}),
               (6_000_000_000, '/rotor/unbalance_command', 'std_msgs/msg/Float64',
                {'data': 3.0})]
    for t_ns, topic, rtype, msg in sorted(events, key=lambda e: e[0]):
        log.write(topic, rtype, msg, t_ns)
    log.close()


def test_held_speed_log_is_plotted_against_time_with_the_commands(tmp_path, capsys,
                                                                 monkeypatch):
    from matplotlib.figure import Figure
    path = tmp_path / 'held.mcap'
    _held_speed_log(path)
    report, _ = analyze(path)
    wf = report['sensors'][0]['waterfall']
    assert wf['axis'] == 'time' and wf['sweeping_fraction'] < 0.1
    # command times in stamp time (log_time - the fixture's T0 + LATENCY), within 1 ns
    assert [(c['time_s'], c['what']) for c in report['commands']] == [
        (pytest.approx(3.9, abs=1e-9), 'speed 300 rad/s (2864.8 rpm)'),
        (pytest.approx(6.0, abs=1e-9), 'unbalance x3')]
    figs = []
    original = Figure.savefig
    monkeypatch.setattr(Figure, 'savefig',
                        lambda self, *a, **k: (figs.append(self), original(self, *a, **k)))
    assert study(['report', str(path), '--plot', str(tmp_path / 'h.png')]) == 0
    out = capsys.readouterr().out
    assert 'plotted against time' in out and '3.9 s  speed 300 rad/s' in out
    assert '6 s  unbalance x3' in out
    ax = figs[0].axes[0]
    assert (ax.get_xlabel(), ax.get_ylabel()) == ('time (s)', 'frequency (Hz)')
    marks = sorted(line.get_xdata()[0] for line in ax.get_lines()
                   if line.get_linestyle() == ':')
    assert marks == pytest.approx([3.9, 6.0])
    labels = [t.get_text().strip() for t in ax.texts]
    assert labels == ['speed 300 rad/s', 'unbalance x3']


def test_ramp_log_is_plotted_against_speed(tmp_path, monkeypatch):
    """The run-up of test_waterfall_follows_rotor_speed sweeps all along: against speed."""
    from matplotlib.figure import Figure
    path = tmp_path / 'ramp.mcap'
    log = Log(path)
    fs, n = 1000.0, 4000
    t = np.arange(n) / fs
    w = 60 + 540 * t / t[-1]
    phase = np.cumsum(w) / fs
    events = [(k * 1_000_000, '/accel/s1', 'sensor_msgs/msg/Imu',
               _imu(k * 1_000_000, 0.0, 0.0, 0.3 * math.sin(phase[k]))) for k in range(n)]
    events += [(k * 10_000_000, '/rotor/speed', 'geometry_msgs/msg/Vector3Stamped',
                {'header': {'stamp': stamp(k * 10_000_000)},
                 'vector': {'x': float(60 + 540 * (k * 0.01) / t[-1])}}) for k in range(400)]
    for t_ns, topic, rtype, msg in sorted(events, key=lambda e: e[0]):
        log.write(topic, rtype, msg, t_ns)
    log.close()
    report, _ = analyze(path)
    assert report['sensors'][0]['waterfall']['axis'] == 'speed'
    figs = []
    original = Figure.savefig
    monkeypatch.setattr(Figure, 'savefig',
                        lambda self, *a, **k: (figs.append(self), original(self, *a, **k)))
    assert study(['report', str(path), '--plot', str(tmp_path / 'r.png')]) == 0
    ax = figs[0].axes[0]
    assert (ax.get_xlabel(), ax.get_ylabel()) == ('frequency (Hz)', 'rotor speed (rpm)')
