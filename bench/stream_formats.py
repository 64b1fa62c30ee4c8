"""Accelerometer stream formats on ROS 2: publisher cost, Python subscriber, wire size, readers.

One triaxial accelerometer stream (linear acceleration and angular velocity, 6 channels) of
``--seconds`` s (default 10) at ``--rate`` Hz (default 20000; the RBS rig; also run it at
50000), sent in each of these forms (issue 24, item 3):

``imu``
    one ``sensor_msgs/Imu`` per sample at the full rate, packed the way vibration_node packs
    them (:class:`impact_damper_sim.ros.wire.ImuPacker`: one NumPy pass per 10 ms block);
``imu2k``, ``imu1k``
    one ``sensor_msgs/Imu`` per sample at 2 kHz and 1 kHz: the stream decimated by a
    linear-phase Kaiser FIR (pass band to 0.4 of the output rate, >= 60 dB from its Nyquist
    frequency on, stamps corrected for the group delay), the filter's cost included;
``pc2``
    ``sensor_msgs/PointCloud2`` batches, one per 10 ms of signal (100 messages/s): stamp = first
    sample, height 1, width n, point_step 56, FLOAT64 fields ``t`` (s, sample time minus
    stamp) at 0, ``ax ay az`` (m/s^2) at 8/16/24, ``wx wy wz`` (rad/s) at 32/40/48,
    little-endian rows (the layout of impact_damper_sim/recording/batches.py), built as an
    rclpy message and serialized by ``rclpy.serialization.serialize_message``;
``f64``
    ``std_msgs/Float64MultiArray`` batches, 100 messages/s, layout dims ``sample`` (n) x
    ``t,ax,ay,az,wx,wy,wz`` (7), data flat; it has no header, so ``t`` is the absolute
    sample time (s) and the frame is not carried.

``trajectory_msgs/JointTrajectory`` batches are left out: ``ros-jazzy-trajectory-msgs`` is not
a dependency of the project (requirements.txt names five message packages), so using it
would add a runtime dependency (and it holds one Python ``JointTrajectoryPoint`` per sample).

Every live figure comes from separate processes started here, on a random ``ROS_DOMAIN_ID``
with ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``: a publisher that sends each message at its
own time (the stream's time from the start, with a sleep before every message that is not
yet due: no bursts beyond the sleep granularity; the table's ``late p99`` column says how
late messages went out), and one subscriber. Per form:

* **publisher CPU** (% of one core: process CPU time, all threads, over wall time, from the
  first message to the last) to build, serialize and publish the stream while one raw
  subscriber (``create_subscription(..., raw=True)``: no deserialization, what a C++ client
  costs the publisher) listens; ``x RT`` is signal seconds over wall seconds (1.00: the
  publisher kept up);
* **stock Python subscriber** (rclpy, ``qos_profile_sensor_data``, ``SingleThreadedExecutor``,
  normal deserialization; per Imu it reads the stamp and the six values, per batch it makes
  a NumPy array of the samples with ``np.frombuffer`` and their times): its CPU (% of one
  core, its CPU time over the stream's wall time) and the fraction of the *samples* sent that
  it received, on a quiet machine and with the other core busy (a Python busy loop runs
  beside publisher and subscriber);
* **wire**: serialized (CDR) bytes per message and per second of signal (DDS adds its own
  headers, a few tens of bytes per message);
* **readability**: 1 s of each form written to an MCAP file by the project's rosbag2 writer
  (:class:`impact_damper_sim.recording.Rosbag2McapWriter`, payloads from
  ``serialize_message`` or the ImuPacker), then read back with ``rosbags``
  (``AnyReader``, ``get_typestore(Stores.ROS2_JAZZY)``), ``mcap_ros2.decoder.DecoderFactory``
  and ``rclpy.serialization.deserialize_message``; ``yes`` when every message reads back with
  the stamps, sample times and values written (exactly), the reason otherwise. ``MCAP kB/s``
  is the file's size per second of signal.

Usage::

    .venv/bin/python bench/stream_formats.py [--rate 20000] [--seconds 10]
        [--options imu,imu2k,imu1k,pc2,f64] [--no-busy] [--repeat N] [--json]
        [--wait-quiet S]

(``AMENT_PREFIX_PATH`` must point at the venv, as for every ROS command here; it defaults to
this interpreter's prefix.) A default run takes about 3 minutes: three measurements of
``seconds`` s plus about 2 s of start-up per form. ``--repeat N`` repeats each measurement
and prints the median with the range; ``--json`` prints the results as JSON on stdout (the
table then goes to stderr). Figures depend on the load of the machine, printed in the
header: the publisher, the subscriber and everything else share the cores. The ``others``
column is the CPU other processes took during the runs (% of one core, the largest of the
form's runs); on a shared machine ``--wait-quiet S`` waits up to S s before each run for
the others to go quiet.
"""
from __future__ import annotations

import argparse
import array
import datetime
import json
import math
import os
import platform
import queue
import random
import subprocess
import sys
import tempfile
import threading
import time

os.environ.setdefault('AMENT_PREFIX_PATH', sys.prefix)
os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

import numpy as np  # noqa: E402

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


def left_out():
    import importlib.util
    there = importlib.util.find_spec('trajectory_msgs') is not None
    return ('(e) trajectory_msgs/JointTrajectory batches: left out. ros-jazzy-trajectory-msgs '
            'is not a project dependency (requirements.txt names std, std_srvs, sensor, '
            'geometry, diagnostic and rosgraph msgs)' + (' (installed here by hand)' if there
                                                         else ' and is not installed')
            + ', so it would be a new runtime dependency; it would also hold one '
            'JointTrajectoryPoint object per sample, the per-sample Python cost batching '
            'removes.')


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
                from impact_damper_sim.ros.wire import ImuPacker
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


# ------------------------------------------------------------------------------- children
QOS_DEPTH = 100   # the node's SENSOR_QOS: best effort, volatile, keep last 100


def _timer_slack(ns):
    """Ask Linux for a fine sleep granularity (default slack 50 us; periods are 20-50 us)."""
    try:
        import ctypes
        ctypes.CDLL(None, use_errno=True).prctl(29, int(ns), 0, 0, 0)   # PR_SET_TIMERSLACK
    except (OSError, AttributeError):
        pass


def child_publisher(a):
    import rclpy
    from rclpy.qos import (DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy)
    _timer_slack(1000)
    opt = OPTIONS[a.option]
    rclpy.init(domain_id=a.domain)
    node = rclpy.create_node('stream_formats_pub')
    qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=QOS_DEPTH,
                     reliability=ReliabilityPolicy.BEST_EFFORT,
                     durability=DurabilityPolicy.VOLATILE)
    pub = node.create_publisher(msg_class(opt['type']), topic_of(a.option), qos)
    enc = Encoder(a.option, a.rate)
    t_ns, sig = make_signal(a.rate, a.seconds)   # the simulator's output (not timed)
    deadline = time.monotonic() + 60.0
    while pub.get_subscription_count() < 1:
        if time.monotonic() > deadline:
            print(json.dumps({'error': 'no subscriber matched in 60 s'}), flush=True)
            return 1
        time.sleep(0.02)
    time.sleep(0.5)   # let the subscriber's side match the writer too
    print('start', flush=True)
    sleep, mono, publish = time.sleep, time.monotonic, pub.publish
    limit = 1.5 * a.seconds + 2.0
    late, n_msgs, n_samples, n_bytes, truncated = [], 0, 0, 0, False
    c0 = time.process_time()
    w0 = mono()
    for tb, sb in blocks(t_ns, sig, a.rate):
        first_due = w0 + enc.ready_ns(tb) * 1e-9
        now = mono()
        if first_due > now:
            sleep(first_due - now)
        msgs = enc.encode(tb, sb)
        for due_ns, data in msgs:
            due = w0 + due_ns * 1e-9
            now = mono()
            if due > now:
                sleep(due - now)
                now = mono()
            late.append(now - due)
            publish(data)
            n_bytes += len(data)
        n_msgs += len(msgs)
        n_samples += len(tb)
        if mono() - w0 > limit:
            truncated = True
            break
    w1 = mono()
    c1 = time.process_time()
    lat = np.array(late) if late else np.zeros(1)
    out = {'cpu_s': c1 - c0, 'wall_s': w1 - w0, 'messages': n_msgs,
           'signal_s': n_samples / a.rate, 'input_samples': n_samples,
           'samples': (n_msgs if opt['kind'] == 'imu' else n_samples), 'bytes': n_bytes,
           'late_p50_ms': 1e3 * float(np.percentile(lat, 50)),
           'late_p99_ms': 1e3 * float(np.percentile(lat, 99)),
           'late_max_ms': 1e3 * float(lat.max()), 'truncated': truncated, 'note': enc.note}
    print(json.dumps(out), flush=True)
    time.sleep(0.3)   # the last messages leave before the writer goes
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


def child_subscriber(a):
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import qos_profile_sensor_data
    opt = OPTIONS[a.option]
    rclpy.init(domain_id=a.domain)
    node = rclpy.create_node('stream_formats_sub')
    state = {'messages': 0, 'samples': 0, 'bytes': 0, 'before_start': 0}
    kept = []
    if a.mode == 'raw':
        def callback(data):
            state['messages'] += 1
            state['bytes'] += len(data)
    elif opt['kind'] == 'imu':
        def callback(msg, out=kept.append):
            st, la, av = msg.header.stamp, msg.linear_acceleration, msg.angular_velocity
            out((st.sec * 1_000_000_000 + st.nanosec, la.x, la.y, la.z, av.x, av.y, av.z))
            state['messages'] += 1
            state['samples'] += 1
    elif opt['kind'] == 'pc2':
        types = {1: 'i1', 2: 'u1', 3: 'i2', 4: 'u2', 5: 'i4', 6: 'u4', 7: 'f4', 8: 'f8'}

        def callback(msg, out=kept.append):
            fields = msg.fields
            dtype = np.dtype({'names': [f.name for f in fields],
                              'formats': ['<' + types[f.datatype] for f in fields],
                              'offsets': [f.offset for f in fields],
                              'itemsize': msg.point_step})
            rows = np.frombuffer(msg.data, dtype, count=msg.width * msg.height)
            st = msg.header.stamp
            times = st.sec * 1_000_000_000 + st.nanosec + np.rint(rows['t'] * 1e9)
            out((times, rows))
            state['messages'] += 1
            state['samples'] += len(rows)
    else:
        def callback(msg, out=kept.append):
            cols = msg.layout.dim[1].size
            rows = np.frombuffer(msg.data, '<f8').reshape(-1, cols)
            out(rows)
            state['messages'] += 1
            state['samples'] += len(rows)
    node.create_subscription(msg_class(opt['type']), topic_of(a.option), callback,
                             qos_profile_sensor_data, raw=(a.mode == 'raw'))
    ex = SingleThreadedExecutor()
    ex.add_node(node)
    marks = {}
    stop = threading.Event()

    def control():
        for line in sys.stdin:
            word = line.strip()
            if word == 'start':
                marks['c0'] = time.process_time()
                state['before_start'] = state['messages']
            elif word == 'stop':
                marks['c1'] = time.process_time()
                break
        stop.set()

    threading.Thread(target=control, daemon=True).start()
    print('ready', flush=True)
    while not stop.is_set():
        ex.spin_once(timeout_sec=0.1)
    c1 = marks.get('c1', time.process_time())
    out = dict(state, cpu_s=c1 - marks.get('c0', c1))
    print(json.dumps(out), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


class Child:
    """A child process whose stdout lines arrive in a queue (reads with a timeout)."""

    def __init__(self, args, env, stdin=False):
        self.proc = subprocess.Popen(args, env=env, text=True, stdout=subprocess.PIPE,
                                     stdin=subprocess.PIPE if stdin else subprocess.DEVNULL)
        self.lines = queue.Queue()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self):
        for line in self.proc.stdout:
            self.lines.put(line.rstrip('\n'))
        self.lines.put(None)

    def expect(self, timeout):
        """The next line that is 'ready', 'start' or JSON (other output is passed on)."""
        end = time.monotonic() + timeout
        while True:
            try:
                line = self.lines.get(timeout=max(0.01, end - time.monotonic()))
            except queue.Empty:
                raise TimeoutError(f'no answer from {self.proc.args[3:6]} in {timeout} s')
            if line is None:
                raise RuntimeError(f'{self.proc.args[3:6]} ended '
                                   f'(exit {self.proc.wait()}) without an answer')
            if line in ('ready', 'start') or line.startswith('{'):
                return line
            print(line, file=sys.stderr)

    def send(self, text):
        self.proc.stdin.write(text + '\n')
        self.proc.stdin.flush()

    def end(self):
        if self.proc.poll() is None:
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()


def _cpu_snapshot(pids=()):
    """(busy CPU s of the machine, total CPU s, {pid: CPU s}) from /proc (None off Linux)."""
    try:
        with open('/proc/stat') as f:
            v = [int(x) for x in f.readline().split()[1:]]
        tick = os.sysconf('SC_CLK_TCK')
        own = {}
        for pid in pids:
            with open(f'/proc/{pid}/stat') as f:
                fields = f.read().rsplit(')', 1)[1].split()
            own[pid] = (int(fields[11]) + int(fields[12])) / tick   # utime + stime
        idle = v[3] + (v[4] if len(v) > 4 else 0)
        return (sum(v[:8]) - idle) / tick, sum(v[:8]) / tick, own
    except (OSError, ValueError, IndexError):
        return None


def wait_quiet(limit_s, threshold=25.0):
    """Wait up to ``limit_s`` s for a 1 s window in which the machine's busy CPU is below
    ``threshold`` % of one core; return the last window's busy CPU (%)."""
    end = time.monotonic() + limit_s
    while True:
        a = _cpu_snapshot()
        time.sleep(1.0)
        b = _cpu_snapshot()
        if a is None or b is None or b[1] <= a[1]:
            return float('nan')
        busy = 100.0 * (os.cpu_count() or 1) * (b[0] - a[0]) / (b[1] - a[1])
        if busy < threshold or time.monotonic() >= end:
            return busy


def measure(key, mode, busy, args, domain):
    """One live run: publisher + one subscriber (``mode`` raw or py), optionally a CPU hog."""
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    me = [sys.executable, os.path.abspath(__file__), '--child']
    common = ['--option', key, '--rate', repr(args.rate), '--seconds', repr(args.seconds),
              '--domain', str(domain)]
    hog = sub = pub = None
    t_spawn = time.monotonic()
    try:
        if busy:
            hog = subprocess.Popen([sys.executable, '-c', 'while True: pass'], env=env)
        sub = Child(me[:2] + ['--child', 'sub', '--mode', mode] + common, env, stdin=True)
        pub = Child(me[:2] + ['--child', 'pub'] + common, env)
        if sub.expect(60) != 'ready':
            raise RuntimeError('subscriber did not start')
        if pub.expect(90) != 'start':
            raise RuntimeError('publisher did not start')
        t_start = time.monotonic()
        hog_pid = [hog.pid] if hog is not None else []
        snap0 = _cpu_snapshot(hog_pid)
        sub.send('start')
        p = json.loads(pub.expect(3 * args.seconds + 60))
        snap1 = _cpu_snapshot(hog_pid)
        if 'error' in p:
            raise RuntimeError(p['error'])
        time.sleep(0.3)   # what is still in flight arrives
        sub.send('stop')
        s = json.loads(sub.expect(30))
        t_done = time.monotonic()
        pub.end()
        sub.end()
        t_end = time.monotonic()
    finally:
        for child in (pub, sub):
            if child is not None and child.proc.poll() is None:
                child.proc.kill()
                child.proc.wait()
        if hog is not None:
            hog.kill()
            hog.wait()
    d = {'pub_cpu_percent': 100.0 * p['cpu_s'] / p['wall_s'],
         'pub_real_time': p['signal_s'] / p['wall_s'],
         # the same cost per second of signal (differs when the publisher fell behind)
         'pub_cpu_per_signal_s_percent': 100.0 * p['cpu_s'] / max(p['signal_s'], 1e-9),
         'late_p50_ms': p['late_p50_ms'], 'late_p99_ms': p['late_p99_ms'],
         'late_max_ms': p['late_max_ms'], 'truncated': p['truncated'],
         'messages_sent': p['messages'], 'samples_sent': p['samples'],
         'bytes_sent': p['bytes'], 'signal_s': p['signal_s'], 'wall_s': p['wall_s'],
         'note': p['note'], 'setup_s': t_start - t_spawn, 'teardown_s': t_end - t_done,
         'sub_cpu_percent': 100.0 * s['cpu_s'] / p['wall_s'],
         'messages_received': s['messages'], 'samples_received': s['samples'],
         'received_before_start': s['before_start']}
    d['messages_received_percent'] = 100.0 * s['messages'] / max(p['messages'], 1)
    if snap0 and snap1 and snap1[1] > snap0[1]:
        # the machine's busy CPU over the stream (% of one core) less publisher, subscriber
        # and busy loop: what other processes took meanwhile
        cores = os.cpu_count() or 1
        busy_pct = 100.0 * cores * (snap1[0] - snap0[0]) / (snap1[1] - snap0[1])
        hog_pct = sum(100.0 * (snap1[2][q] - snap0[2][q]) / p['wall_s'] for q in snap0[2])
        d['machine_busy_percent'] = busy_pct
        d['hog_cpu_percent'] = hog_pct if hog is not None else None
        d['others_cpu_percent'] = max(0.0, busy_pct - d['pub_cpu_percent']
                                      - d['sub_cpu_percent'] - hog_pct)
    if mode == 'py':
        d['samples_received_percent'] = 100.0 * s['samples'] / max(p['samples'], 1)
    return d


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
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    from rclpy.qos import qos_profile_sensor_data
    from rclpy.serialization import deserialize_message
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore
    from impact_damper_sim.recording import Rosbag2McapWriter
    from pathlib import Path
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

        def rosbags_read():
            with AnyReader([Path(path)], default_typestore=typestore) as reader:
                conns = [c for c in reader.connections if c.topic == topic]
                return [reader.deserialize(raw, c.msgtype)
                        for c, _, raw in reader.messages(connections=conns)]

        def mcap_ros2_read():
            with open(path, 'rb') as f:
                reader = make_reader(f, decoder_factories=[DecoderFactory()])
                return [m for _, _, _, m in reader.iter_decoded_messages(topics=[topic])]

        def rclpy_read():
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


# ------------------------------------------------------------------------------- report
def machine():
    model = ''
    try:
        with open('/proc/cpuinfo') as f:
            model = next((line.split(':', 1)[1].strip() for line in f
                          if line.startswith('model name')), '')
    except OSError:
        pass
    from importlib.metadata import PackageNotFoundError, version

    def ver(name):
        try:
            return version(name)
        except PackageNotFoundError:
            return '-'
    return {'date': datetime.datetime.now().astimezone().isoformat(timespec='seconds'),
            'host': platform.node(), 'cores': os.cpu_count(), 'cpu': model,
            'load_average_before': os.getloadavg(), 'python': platform.python_version(),
            'rmw': os.environ.get('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp (default)'),
            'versions': {n: ver(n) for n in ('ros-rclpy', 'numpy', 'mcap', 'mcap-ros2-support',
                                             'rosbags')}}


def _median(values):
    values = [v for v in values if v is not None and not math.isnan(v)]
    return float(np.median(values)) if values else float('nan')


def _cell(values, fmt, width):
    values = [v for v in values if v is not None and not math.isnan(v)]
    if not values:
        return f'{"-":>{width}s}'
    text = format(float(np.median(values)), fmt)
    if len(values) > 1:
        text += f' [{format(min(values), fmt)}-{format(max(values), fmt)}]'
    return f'{text:>{width}s}'


def table(result, out):
    m = result['machine']
    rep = result['repeat']
    w = 7 if rep == 1 else 19    # a cell with a range is wider
    load = ' '.join(f'{x:.2f}' for x in m['load_average_before'])
    load_after = ' '.join(f'{x:.2f}' for x in result['load_average_after'])
    print(f'stream_formats: {result["rate"]:g} Hz x {result["seconds"]:g} s, one triaxial '
          f'accelerometer (6 channels), repeat {rep}', file=out)
    print(f'{m["date"]}  {m["cores"]} cores ({m["cpu"]}), load average {load} before, '
          f'{load_after} after; Python {m["python"]}, rclpy {m["versions"]["ros-rclpy"]}, '
          f'{m["rmw"]}, ROS_DOMAIN_ID {result["domains"]}', file=out)
    print('CPU in % of one core; recv = samples received / sent by a stock Python subscriber; '
          'busy = a busy loop runs beside; others = CPU other processes took during the '
          'runs (max); readable = rosbags/mcap_ros2/rclpy', file=out)
    head = (f'{"option":30s} {"msg/s":>7s} {"B/msg":>6s} {"wire kB/s":>9s} '
            f'{"pub CPU":>{w}s} {"x RT":>5s} {"late p99":>8s} '
            f'{"sub CPU":>{w}s} {"recv %":>{w}s} {"busy CPU":>{w}s} {"busy rcv%":>{w}s} '
            f'{"others":>6s} {"MCAP kB/s":>9s} readable')
    print(head, file=out)
    print(f'{"":30s} {"":7s} {"":6s} {"":9s} {"raw sub":>{w}s} {"":5s} {"ms":>8s} '
          f'{"quiet":>{w}s} {"quiet":>{w}s} {"":{w}s} {"":{w}s} {"max %":>6s}', file=out)
    reasons = []
    for key, r in result['options'].items():
        runs = r['runs']
        pub = [x['pub'] for x in runs if 'pub' in x]
        quiet = [x['quiet'] for x in runs if 'quiet' in x]
        busy = [x['busy'] for x in runs if 'busy' in x]
        rd = r.get('readability')
        if rd:
            flags = '/'.join('yes' if rd['readers'][n]['ok'] else 'NO'
                             for n in ('rosbags', 'mcap_ros2', 'rclpy'))
            reasons += [f'  {key} {n}: {v["reason"]}' for n, v in rd['readers'].items()
                        if not v['ok']]
            mcap = f'{rd["mcap_bytes_per_s"] / 1e3:9.1f}'
        else:
            flags, mcap = '-', f'{"-":>9s}'
        seen = [x['others_cpu_percent'] for x in pub + quiet + busy
                if x.get('others_cpu_percent') is not None]
        others = max(seen) if seen else float('nan')
        print(f'{OPTIONS[key]["label"]:30s} {r["messages_per_s"]:7.0f} '
              f'{r["bytes_per_message"]:6.0f} {r["wire_bytes_per_s"] / 1e3:9.1f} '
              f'{_cell([x["pub_cpu_percent"] for x in pub], ".1f", w)} '
              f'{_median([x["pub_real_time"] for x in pub]):5.2f} '
              f'{_median([x["late_p99_ms"] for x in pub]):8.2f} '
              f'{_cell([x["sub_cpu_percent"] for x in quiet], ".1f", w)} '
              f'{_cell([x["samples_received_percent"] for x in quiet], ".1f", w)} '
              f'{_cell([x["sub_cpu_percent"] for x in busy], ".1f", w)} '
              f'{_cell([x["samples_received_percent"] for x in busy], ".1f", w)} '
              f'{others:6.0f} {mcap} {flags}', file=out)
    worst = [x.get('others_cpu_percent') or 0.0 for r in result['options'].values()
             for run in r['runs'] for x in run.values() if isinstance(x, dict)]
    if worst and max(worst) > 25.0:
        print(f'WARNING: other processes took up to {max(worst):.0f} % of a core during the '
              f'runs: the quiet figures are not from a quiet machine', file=out)
    for key, r in result['options'].items():
        if r.get('note'):
            print(f'  {key}: {r["note"]}', file=out)
    if reasons:
        print('not readable:', file=out)
        for line in reasons:
            print(line, file=out)
    for line in result['left_out']:
        print(line, file=out)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--rate', type=float, default=20000.0, help='sample rate (Hz)')
    parser.add_argument('--seconds', type=float, default=10.0, help='stream length (s)')
    parser.add_argument('--options', default=','.join(OPTIONS),
                        help=f'comma-separated subset of {",".join(OPTIONS)}')
    parser.add_argument('--repeat', type=int, default=1, help='runs per measurement')
    parser.add_argument('--no-busy', action='store_true', help='skip the busy-core runs')
    parser.add_argument('--no-live', action='store_true', help='only the readability check')
    parser.add_argument('--json', action='store_true', help='JSON on stdout, table on stderr')
    parser.add_argument('--wait-quiet', type=float, default=0.0, metavar='S',
                        help='before each run wait up to S s for a second in which the '
                             'machine is below 25 %% of a core busy (a shared machine)')
    # children (started by this script)
    parser.add_argument('--child', choices=('pub', 'sub'), help=argparse.SUPPRESS)
    parser.add_argument('--mode', choices=('raw', 'py'), default='py', help=argparse.SUPPRESS)
    parser.add_argument('--option', help=argparse.SUPPRESS)
    parser.add_argument('--domain', type=int, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child == 'pub':
        return child_publisher(args)
    if args.child == 'sub':
        return child_subscriber(args)

    keys = [k.strip() for k in args.options.split(',') if k.strip()]
    unknown = [k for k in keys if k not in OPTIONS]
    if unknown:
        parser.error(f'unknown options {unknown}; choose from {list(OPTIONS)}')
    skipped = []
    for k in list(keys):
        q = OPTIONS[k]['out_rate']
        if q and (args.rate / q != int(args.rate / q) or args.rate <= q):
            skipped.append(f'{k}: {args.rate:g} Hz is not a whole multiple above {q} Hz')
            keys.remove(k)
    out = sys.stderr if args.json else sys.stdout
    result = {'machine': machine(), 'rate': args.rate, 'seconds': args.seconds,
              'repeat': args.repeat, 'left_out': [left_out()] + skipped, 'options': {}}
    # one random domain per live run (DDS ports stay valid up to 232); tests use 1..100
    needed = len(keys) * args.repeat * (1 if args.no_busy else 3) + 1
    domains = random.sample(range(101, 233), min(needed, 132))
    result['domains'] = f'{min(domains)}..{max(domains)} (random)'
    period = 1.0 / args.rate
    from rclpy.serialization import serialize_message  # noqa: F401  (fail early without ROS)
    with tempfile.TemporaryDirectory() as tmp:
        read = readability(keys, args.rate, tmp)
    for key in keys:
        opt = OPTIONS[key]
        # sizes from the encoder over 1 s (what the publisher sends)
        enc = Encoder(key, args.rate)
        t_ns, sig = make_signal(args.rate, 1.0, seed=3)
        msgs = [m for tb, sb in blocks(t_ns, sig, args.rate) for m in enc.encode(tb, sb)]
        size = sum(len(d) for _, d in msgs)
        result['options'][key] = {
            'label': opt['label'], 'type': opt['type'], 'topic': topic_of(key),
            'messages_per_s': len(msgs), 'bytes_per_message': size / len(msgs),
            'wire_bytes_per_s': size, 'note': enc.note,
            'samples_per_s': opt['out_rate'] or 1.0 / period,
            'readability': read[key], 'runs': []}
    if not args.no_live:
        cases = [('pub', 'raw', False), ('quiet', 'py', False)]
        if not args.no_busy:
            cases.append(('busy', 'py', True))
        i = 0
        for rep in range(args.repeat):
            for key in keys:
                run = {}
                for name, mode, busy in cases:
                    print(f'[{time.strftime("%H:%M:%S")}] {key} {name} '
                          f'(run {rep + 1}/{args.repeat})', file=sys.stderr, flush=True)
                    before = wait_quiet(args.wait_quiet) if args.wait_quiet else None
                    try:
                        run[name] = measure(key, mode, busy, args, domains[i % len(domains)])
                        run[name]['machine_busy_before_percent'] = before
                    except (RuntimeError, TimeoutError) as exc:
                        print(f'  failed: {exc}', file=sys.stderr)
                        run[name + '_error'] = str(exc)
                    i += 1
                result['options'][key]['runs'].append(run)
    result['load_average_after'] = os.getloadavg()
    table(result, out)
    if args.json:
        json.dump(result, sys.stdout, indent=1, default=float)
        print()
    return 0


if __name__ == '__main__':
    sys.exit(main())
