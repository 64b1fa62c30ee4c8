"""Accelerometer stream formats on ROS 2: publisher cost, Python subscriber, wire size, readers.

One triaxial accelerometer stream (linear acceleration and angular velocity, 6 channels) of
``--seconds`` s (default 10) at ``--rate`` Hz (default 20000; the RBS rig; also run it at
50000), sent in each of these forms (issue 24, item 3):

``imu``
    one ``sensor_msgs/Imu`` per sample at the full rate, packed the way vibration_node packs
    them (:class:`impact_damper_sim.ros.outlets.ImuPacker`: one NumPy pass per 10 ms block);
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

This file holds the command line, the parent's side of a live run (:func:`measure`) and the
report; beside it, loaded from its folder: ``stream_formats_forms.py`` (signal, forms,
encoders, readability) and ``stream_formats_live.py`` (the child publisher and subscriber).
"""
from __future__ import annotations

import argparse
import datetime
import json
import math
import os
import platform
import random
import subprocess
import sys
import tempfile
import time

os.environ.setdefault('AMENT_PREFIX_PATH', sys.prefix)
os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'

import numpy as np  # noqa: E402

# Run as a script (its children too), never as a package: its parts beside it are found
# either way; after the environment above, which they need before numpy and rclpy load.
if os.path.dirname(os.path.abspath(__file__)) not in sys.path:
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from stream_formats_forms import OPTIONS, Encoder, blocks, make_signal, readability, topic_of  # noqa: E402
from stream_formats_live import Child, _cpu_snapshot, child_publisher, child_subscriber, wait_quiet  # noqa: E402


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
