"""The live processes of bench/stream_formats.py: publisher, subscriber and the CPU they took.

The children the bench starts as ``stream_formats.py --child pub|sub`` (:func:`child_publisher`
sends the stream at its own time, :func:`child_subscriber` counts what it gets, raw or
deserialized), the parent's handle on them (:class:`Child`) and the machine's CPU counters
(:func:`_cpu_snapshot`, :func:`wait_quiet`). Apart from the forms because this is the
process side of a run; loaded by stream_formats.py, which puts bench/ on ``sys.path``.
"""
from __future__ import annotations

import json
import os
import queue
import subprocess
import sys
import threading
import time

import numpy as np

from stream_formats_forms import OPTIONS, Encoder, blocks, make_signal, msg_class, topic_of

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
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
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
                raise TimeoutError(f'no answer from {self.proc.args[3:6]} in {timeout} s') \
                    from None
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
