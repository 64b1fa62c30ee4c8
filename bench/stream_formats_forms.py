"""The message forms of bench/stream_formats.py: the signal, how each is built and read back.

The signal (:func:`make_signal`: a sum of sines and noise on six channels), the forms
(:data:`OPTIONS`), the :class:`Decimator` of the 2 kHz and 1 kHz Imu streams, the
:class:`Encoder` that turns 10 ms blocks into serialized messages, and the readability check
(:func:`readability`: 1 s of each form written to MCAP, read back with rosbags, mcap_ros2 and
rclpy, compared with what was written by :func:`decode` and :func:`compare`). Apart from the
live measurement because the wire layout of each form, written and read, is one thing to
check against the other: nothing here starts a process.
"""
from __future__ import annotations

import array
import math
import os
import time

import numpy as np

#: sim time of the first sample (ns): > 0, so that the group-delay-corrected stamps of the
#: decimated streams stay positive
T0_NS = 1_000_000_000
BATCH_S = 0.01                 # one batch (and one build block) per 10 ms of signal
FRAME = 'bench_accel'
COLUMNS = ('t', 'ax', 'ay', 'az', 'wx', 'wy', 'wz')
POINT_STEP = 56
FLOAT64 = 8                    # sensor_msgs/PointField.FLOAT64

OPTIONS = {
    'imu': dict(label='(a) Imu per sample, full rate', kind='imu', out_rate=None,
                type='sensor_msgs/msg/Imu'),
    'imu2k': dict(label='(b) Imu per sample, 2 kHz', kind='imu', out_rate=2000,
                  type='sensor_msgs/msg/Imu'),
    'imu1k': dict(label='(b) Imu per sample, 1 kHz', kind='imu', out_rate=1000,
                  type='sensor_msgs/msg/Imu'),
    'pc2': dict(label='(c) PointCloud2 batch 10 ms', kind='pc2', out_rate=None,
                type='sensor_msgs/msg/PointCloud2'),
    'f64': dict(label='(d) Float64MultiArray 10 ms', kind='f64', out_rate=None,
                type='std_msgs/msg/Float64MultiArray'),
}


def topic_of(key):
    return f'/bench/accel/{key}'


def msg_class(type_name):
    import importlib
    pkg, _, name = type_name.split('/')
    return getattr(importlib.import_module(f'{pkg}.msg'), name)


# ------------------------------------------------------------------------------- the signal
def make_signal(rate, seconds, seed=24):
    """Sample times (ns, int64) and a (n, 6) signal: ax ay az (m/s^2), wx wy wz (rad/s)."""
    n = int(round(rate * seconds))
    period_ns = 1e9 / rate
    if abs(period_ns - round(period_ns)) > 1e-9:
        raise ValueError(f'--rate {rate} Hz has no whole-ns sample period')
    t_ns = T0_NS + np.arange(n, dtype=np.int64) * int(round(period_ns))
    t = (t_ns - T0_NS) * 1e-9
    rng = np.random.default_rng(seed)
    sig = np.empty((n, 6))
    for c in range(6):
        freqs = rng.uniform(20.0, 0.45 * rate, 6)
        amps = rng.uniform(0.5, 20.0, 6) * (1.0 if c < 3 else 0.01)
        phases = rng.uniform(0, 2 * np.pi, 6)
        sig[:, c] = (amps[:, None] * np.sin(2 * np.pi * freqs[:, None] * t + phases[:, None])
                     ).sum(0) + rng.normal(0.0, 0.05 * amps.mean(), n)
    return t_ns, sig


class Decimator:
    """Linear-phase Kaiser FIR low-pass and downsampling by ``q``, state kept between blocks.

    Pass band to 0.4 of the output rate, >= ``atten_db`` (dB) from 0.5 of it (the output's
    Nyquist frequency) on. Output ``m`` is computed at input index ``m q`` (from the inputs up
    to it) and stands for the signal at index ``m q - (ntaps - 1) / 2`` (the group delay).
    """

    def __init__(self, q, channels, atten_db=60.0):
        self.q = int(q)
        width = 0.1 / self.q                        # transition band, cycles per input sample
        ntaps = int(math.ceil((atten_db - 7.95) / (2.285 * 2 * math.pi * width))) + 1
        self.ntaps = ntaps + (ntaps % 2 == 0)       # odd: a whole-sample group delay
        beta = 0.1102 * (atten_db - 8.7)
        fc = 0.45 / self.q                          # cut-off mid-transition (cycles/sample)
        k = np.arange(self.ntaps) - (self.ntaps - 1) / 2
        h = 2 * fc * np.sinc(2 * fc * k) * np.kaiser(self.ntaps, beta)
        self.h = h / h.sum()                        # unit gain at DC; symmetric
        self.delay = (self.ntaps - 1) // 2          # samples
        self.hist = np.zeros((self.ntaps - 1, channels))
        self.next_index = 0                         # global index of the next input sample

    def process(self, x):
        """Filter the next block ``x`` (k, channels); return (global input indices, outputs)."""
        g0 = self.next_index
        k = len(x)
        buf = np.concatenate([self.hist, x])
        first = -g0 % self.q                        # first local index with g % q == 0
        idx = np.arange(first, k, self.q)
        if idx.size:
            windows = np.lib.stride_tricks.sliding_window_view(buf, self.ntaps, axis=0)
            y = np.einsum('mcn,n->mc', windows[first::self.q], self.h)
        else:
            y = np.empty((0, x.shape[1]))
        self.hist = buf[k:]
        self.next_index = g0 + k
        return g0 + idx, y


# ------------------------------------------------------------------------------- encoders
class Encoder:
    """Turns 10 ms blocks of the signal into (due time, serialized message) pairs.

    ``due`` (ns from the first sample): when the message exists in a live system (a sample at
    its own time, a decimated sample when its last input exists, a batch at the end of its
    10 ms). With ``keep`` every message's content is also kept as expected by a reader:
    (stamps/sample times ns, values (n, 6)).
    """

    def __init__(self, key, rate, keep=False):
        from rclpy.serialization import serialize_message
        self.key = key
        self.opt = OPTIONS[key]
        self.rate = rate
        self.period_ns = int(round(1e9 / rate))
        self.keep = keep
        self.expected = []
        self.serialize = serialize_message
        self.decimator = None
        kind = self.opt['kind']
        if kind == 'imu':
            from sensor_msgs.msg import Imu
            template = Imu()
            template.header.frame_id = FRAME
            template.orientation_covariance[0] = -1.0   # orientation not measured (REP-145)
            self.imu_template = template
            self.packer_error = None
            try:
                from impact_damper_sim.ros.outlets import ImuPacker
                self.packer = ImuPacker(template)
            except Exception as exc:   # noqa: BLE001 - any failure: message by message
                self.packer = None
                self.packer_error = f'{type(exc).__name__}: {exc}'

            if self.opt['out_rate']:
                q = rate / self.opt['out_rate']
                if abs(q - round(q)) > 1e-9:
                    raise ValueError(f'{rate} Hz is not a multiple of {self.opt["out_rate"]} Hz')
                self.decimator = Decimator(int(round(q)), 6)
        elif kind == 'pc2':
            from sensor_msgs.msg import PointCloud2, PointField
            msg = PointCloud2()
            msg.header.frame_id = FRAME
            msg.height = 1
            msg.fields = [PointField(name=name, offset=8 * i, datatype=FLOAT64, count=1)
                          for i, name in enumerate(COLUMNS)]
            msg.is_bigendian = False
            msg.point_step = POINT_STEP
            msg.is_dense = True
            self.msg = msg
        else:
            from std_msgs.msg import Float64MultiArray, MultiArrayDimension
            msg = Float64MultiArray()
            msg.layout.dim = [MultiArrayDimension(label='sample', size=0, stride=0),
                              MultiArrayDimension(label=','.join(COLUMNS), size=7, stride=7)]
            msg.layout.data_offset = 0
            self.msg = msg

    @property
    def note(self):
        notes = []
        if self.decimator is not None:
            notes.append(f'FIR {self.decimator.ntaps} taps, delay {self.decimator.delay} '
                         f'samples')
        if getattr(self, 'packer_error', None):
            notes.append(f'ImuPacker failed ({self.packer_error}): serialize_message per '
                         f'message')
        return '; '.join(notes)

    def _imu(self, t_ns, vals):
        if self.packer is not None:
            return self.packer.pack(t_ns, vals[:, :3], vals[:, 3:])
        out, msg = [], self.imu_template
        for stamp, v in zip(t_ns.tolist(), vals.tolist()):
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp, 1_000_000_000)
            la, av = msg.linear_acceleration, msg.angular_velocity
            la.x, la.y, la.z, av.x, av.y, av.z = v
            out.append(self.serialize(msg))
        return out

    def ready_ns(self, t_ns):
        """When a block can be encoded (ns from the stream start): a batch at its end, samples
        from the block's first sample on."""
        if self.opt['kind'] == 'imu':
            return int(t_ns[0] - T0_NS)
        return int(t_ns[-1] - T0_NS) + self.period_ns

    def encode(self, t_ns, sig):
        """Messages of one block: list of (due ns from the stream start, bytes)."""
        kind = self.opt['kind']
        if kind == 'imu':
            if self.decimator is None:
                stamps, vals, due = t_ns, sig, t_ns - T0_NS
            else:
                g, vals = self.decimator.process(sig)
                due = g * self.period_ns
                stamps = T0_NS + (g - self.decimator.delay) * self.period_ns
            data = self._imu(stamps, vals)
            if self.keep:
                self.expected.extend((np.array([s]), v[None, :]) for s, v in zip(stamps, vals))
            return list(zip(due.tolist(), data))
        n = len(t_ns)
        rows = np.empty((n, 7))
        rows[:, 1:] = sig
        msg = self.msg
        if kind == 'pc2':
            stamp = int(t_ns[0])
            rows[:, 0] = (t_ns - stamp) * 1e-9
            msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp, 1_000_000_000)
            msg.width = n
            msg.row_step = POINT_STEP * n
            msg.data = array.array('B', rows.tobytes())
        else:
            rows[:, 0] = t_ns * 1e-9
            msg.layout.dim[0].size = n
            msg.layout.dim[0].stride = 7 * n
            msg.data = array.array('d', rows.tobytes())
        if self.keep:
            self.expected.append((t_ns.copy(), sig.copy()))
        return [(self.ready_ns(t_ns), self.serialize(msg))]


def blocks(t_ns, sig, rate):
    """Split the stream into 10 ms blocks (the last may be shorter)."""
    b = max(1, int(round(rate * BATCH_S)))
    for i in range(0, len(t_ns), b):
        yield t_ns[i:i + b], sig[i:i + b]


# ------------------------------------------------------------------------------- readability
def _as_bytes(data):
    if isinstance(data, (bytes, bytearray, memoryview)):
        return bytes(data)
    if isinstance(data, array.array) or isinstance(data, np.ndarray):
        return data.tobytes()
    return bytes(bytearray(data))   # a list of ints


def _as_float64(data):
    if isinstance(data, array.array):
        return np.frombuffer(data, '<f8')
    return np.asarray(data, dtype=np.float64)


def _stamp_ns(header):
    st = header.stamp
    return int(st.sec) * 1_000_000_000 + int(st.nanosec)


def decode(kind, msg):
    """(sample times ns, values (n, 6)) of a decoded message (rclpy, mcap_ros2 or rosbags)."""
    if kind == 'imu':
        if msg.header.frame_id != FRAME:
            raise ValueError(f'frame_id {msg.header.frame_id!r}')
        la, av = msg.linear_acceleration, msg.angular_velocity
        return (np.array([_stamp_ns(msg.header)]),
                np.array([[la.x, la.y, la.z, av.x, av.y, av.z]]))
    if kind == 'pc2':
        if msg.header.frame_id != FRAME:
            raise ValueError(f'frame_id {msg.header.frame_id!r}')
        fields = [(f.name, int(f.offset), int(f.datatype), int(f.count)) for f in msg.fields]
        if fields != [(c, 8 * i, FLOAT64, 1) for i, c in enumerate(COLUMNS)]:
            raise ValueError(f'fields {fields}')
        if (msg.height, msg.point_step, msg.row_step, bool(msg.is_bigendian),
                bool(msg.is_dense)) != (1, POINT_STEP, POINT_STEP * msg.width, False, True):
            raise ValueError('height/point_step/row_step/is_bigendian/is_dense')
        dtype = np.dtype({'names': list(COLUMNS), 'formats': ['<f8'] * 7,
                          'offsets': [8 * i for i in range(7)], 'itemsize': POINT_STEP})
        rows = np.frombuffer(_as_bytes(msg.data), dtype, count=msg.width)
        times = _stamp_ns(msg.header) + np.rint(rows['t'] * 1e9).astype(np.int64)
        return times, np.stack([rows[c] for c in COLUMNS[1:]], axis=1)
    dims = [(d.label, int(d.size), int(d.stride)) for d in msg.layout.dim]
    n = dims[0][1] if dims else -1
    if dims != [('sample', n, 7 * n), (','.join(COLUMNS), 7, 7)] or msg.layout.data_offset:
        raise ValueError(f'layout {dims}, data_offset {msg.layout.data_offset}')
    rows = _as_float64(msg.data).reshape(n, 7)
    return np.rint(rows[:, 0] * 1e9).astype(np.int64), rows[:, 1:].copy()


def compare(kind, decoded, expected):
    """None when ``decoded`` (list of messages) equals ``expected``; else the reason."""
    if len(decoded) != len(expected):
        return f'{len(decoded)} messages read, {len(expected)} written'
    for i, (msg, (t_exp, v_exp)) in enumerate(zip(decoded, expected)):
        try:
            t, v = decode(kind, msg)
        except Exception as exc:   # any reader's surprise is a readability finding
            return f'message {i}: {type(exc).__name__}: {exc}'
        if t.shape != t_exp.shape or not np.array_equal(t, t_exp):
            return f'message {i}: sample times differ'
        if v.shape != v_exp.shape or not np.array_equal(v, v_exp):
            return f'message {i}: values differ'
    return None


def readability(keys, rate, tmp):
    """Write 1 s of each form with the project's rosbag2 MCAP writer; read it back 3 ways."""
    from pathlib import Path

    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from rclpy.qos import qos_profile_sensor_data
    from rclpy.serialization import deserialize_message
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    from impact_damper_sim.recording import Rosbag2McapWriter
    typestore = get_typestore(Stores.ROS2_JAZZY)
    t_ns, sig = make_signal(rate, 1.0, seed=7)
    results = {}
    for key in keys:
        opt = OPTIONS[key]
        kind, type_name, topic = opt['kind'], opt['type'], topic_of(key)
        enc = Encoder(key, rate, keep=True)
        path = os.path.join(tmp, f'{key}.mcap')
        payloads = []
        with Rosbag2McapWriter(path, overwrite=True) as writer:
            writer.add_topic(topic, type_name, qos_profile_sensor_data)
            for tb, sb in blocks(t_ns, sig, rate):
                for due, data in enc.encode(tb, sb):
                    payloads.append(data)
                    writer.write(topic, type_name, qos_profile_sensor_data, data,
                                 T0_NS + due, T0_NS + due)
            if writer.error is not None:
                raise writer.error
        res = {'mcap_bytes_per_s': os.path.getsize(path), 'messages': len(payloads)}
        readers = {}

        def rosbags_read(path=path, topic=topic):
            with AnyReader([Path(path)], default_typestore=typestore) as reader:
                conns = [c for c in reader.connections if c.topic == topic]
                return [reader.deserialize(raw, c.msgtype)
                        for c, _, raw in reader.messages(connections=conns)]

        def mcap_ros2_read(path=path, topic=topic):
            with open(path, 'rb') as f:
                reader = make_reader(f, decoder_factories=[DecoderFactory()])
                return [m for _, _, _, m in reader.iter_decoded_messages(topics=[topic])]

        def rclpy_read(path=path, topic=topic, type_name=type_name):
            cls = msg_class(type_name)
            with open(path, 'rb') as f:
                return [deserialize_message(m.data, cls)
                        for _, _, m in make_reader(f).iter_messages(topics=[topic])]

        for name, read in (('rosbags', rosbags_read), ('mcap_ros2', mcap_ros2_read),
                           ('rclpy', rclpy_read)):
            try:
                t0 = time.perf_counter()
                msgs = read()
                elapsed = time.perf_counter() - t0
                reason = compare(kind, msgs, enc.expected)
            except Exception as exc:   # a reader that cannot open the file is the finding
                reason, elapsed = f'{type(exc).__name__}: {exc}', float('nan')
            readers[name] = {'ok': reason is None, 'reason': reason, 'read_s': elapsed}
        res['readers'] = readers
        results[key] = res
    return results
