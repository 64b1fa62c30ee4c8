"""vibration_node at real time: achieved real-time factor, CPU, delivery, command latency.

Runs the node in this process (no launch) on the HPOTP scene with its default sensors (one
triaxial accelerometer, 800 Hz low-pass, 2 kHz), for each case:

* the paper's ramp with default parameters (dampers on): every 1 s diagnostics window's
  achieved real-time factor and CPU, the worst window and the peak reported, and the peak
  of CPU / achieved factor (the share of a core one real-time second needs: when the machine
  is loaded the factor drops with the CPU the node gets, not with what it needs);
* full speed (2400 rad/s) with dampers off and on, with and without recording, and at
  ``real_time_factor`` 0 (the highest factor reachable).

CPU is this process's CPU time over wall time (all threads: stepping, executor, DDS), in %
of one core. It is set against the **bare stepping cost measured in the same run**: the same
scene stepped by :class:`~impact_damper_sim.live.realtime.LiveSimulation` alone, as CPU per sim
second; ``node/bare`` is the ratio and ``overhead`` the difference (the cost of ROS).

Delivery: a stock subscriber in another process (``qos_profile_sensor_data``: best effort,
keep last 5, a ``SingleThreadedExecutor``) counts the accelerometer samples it receives,
against the count the stamps say were sent over the same span.

Command latency: a speed command is published while the rotor holds its speed; the latency
is the first ``rotor/speed`` stamp whose speed changed minus the ``/clock`` stamp last
received before the command was sent (sim s), and the same in wall time.

Usage::

    python bench/node_realtime.py [--seconds 10] [--scene hpotp] [--quick]

Figures depend on the machine's load (printed before and after): the subscriber, the node
and everything else share the cores.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import threading
import time

os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')

import numpy as np  # noqa: E402
import rclpy  # noqa: E402
from geometry_msgs.msg import Vector3Stamped  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from std_msgs.msg import Float64  # noqa: E402

from impact_damper_sim.live.realtime import LiveSimulation  # noqa: E402
from impact_damper_sim.live.streams import live_scene  # noqa: E402
from impact_damper_sim.ros import interface as itf  # noqa: E402
from impact_damper_sim.ros.vibration_node import VibrationNode  # noqa: E402

FULL_SPEED = 'rotor.speed={kind: constant, speed: 2400 rad/s}'

#: DDS domains 101..230 (the tests use 1..100), offset by the process id: two benches or a
#: test run on the same machine do not hear each other's nodes
DOMAIN0 = 101 + (os.getpid() % 12) * 10

#: the stock subscriber, run as a separate process: prints what it received as JSON
SUBSCRIBER = r'''
import json, sys, time
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import Imu
topic, seconds, domain = sys.argv[1], float(sys.argv[2]), int(sys.argv[3])
rclpy.init(domain_id=domain)
node = rclpy.create_node('sensor_data_reader')
stamps = []
node.create_subscription(
    Imu, topic, lambda m: stamps.append(m.header.stamp.sec * 10**9 + m.header.stamp.nanosec),
    qos_profile_sensor_data)
ex = SingleThreadedExecutor()
ex.add_node(node)
print('ready', flush=True)
while not stamps:
    ex.spin_once(timeout_sec=0.1)
end, c0 = time.monotonic() + seconds, time.process_time()
while time.monotonic() < end:
    ex.spin_once(timeout_sec=0.1)
print(json.dumps({'received': len(stamps), 'first_ns': stamps[0], 'last_ns': stamps[-1],
                  'cpu_s': time.process_time() - c0, 'seconds': seconds}), flush=True)
'''


def _sec(stamp):
    return stamp.sec + 1e-9 * stamp.nanosec


def bare_stepping_cpu(scene, overrides, dampers, seconds=5.0):
    """CPU (% of one core at real time) of stepping the scene with LiveSimulation alone."""
    model, target = live_scene(scene, overrides)
    live = LiveSimulation(model, initial_target=target, dampers_enabled=dampers)
    chunk = max(1, round(0.01 * live.sample_rate))
    live.step(chunk)   # compiled kernels loaded
    t0, c0 = live.t, time.process_time()
    while live.t - t0 < seconds:
        live.step(chunk)
    return 100.0 * (time.process_time() - c0) / (live.t - t0)


def run_case(scene, overrides, seconds, rtf, dampers=True, domain=DOMAIN0, record=None,
             subscriber=False):
    """Run one case; return a dict of measured figures."""
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=domain)
    proc = None
    try:
        node = VibrationNode(context=ctx, parameter_overrides=[
            Parameter('scene', value=scene), Parameter('overrides', value=list(overrides)),
            Parameter('real_time_factor', value=float(rtf)),
            Parameter('dampers_enabled', value=bool(dampers)),
            *([Parameter('record', value=record)] if record else [])])
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        sent_at = []
        if subscriber:
            # wall time of every sample put on the wire: how steady the stream is
            pub = node.publishing.accel[0].pub
            real_publish = pub.publish

            def timed(data, _publish=real_publish, _now=time.monotonic):
                sent_at.append(_now())
                _publish(data)

            pub.publish = timed
            topic = node.publishing.accel[0].topic
            env = dict(os.environ, ROS_DOMAIN_ID=str(domain))
            proc = subprocess.Popen([sys.executable, '-c', SUBSCRIBER, topic, str(seconds),
                                     str(domain)], stdout=subprocess.PIPE, text=True, env=env)
            proc.stdout.readline()   # 'ready'
        warm = time.monotonic() + 1.0
        while time.monotonic() < warm:
            ex.spin_once(timeout_sec=0.05)
        node.publish_diagnostics()   # windows start now
        # measured over the whole window here, and per 1 s diagnostics window
        t0, w0, c0 = node.live.t, time.monotonic(), time.process_time()
        i0, k0 = node.stats_total['impacts'], node.pacer.deficits
        end = w0 + seconds
        worst, windows, last = 'ok', [], None
        while time.monotonic() < end:
            ex.spin_once(timeout_sec=0.05)
            d = getattr(node, 'last_diagnostics', None)
            if d is not last and d is not None:
                last = d
                windows.append((d['real_time_factor_achieved'], d['cpu_percent']))
                if d['level'] > 0:
                    worst = d['message']
        with node._lock:
            t1, w1, c1 = node.live.t, time.monotonic(), time.process_time()
            i1, k1 = node.stats_total['impacts'], node.pacer.deficits
        windows = windows[1:]   # the first is the one closed at the start
        d = {'real_time_factor_achieved': (t1 - t0) / (w1 - w0),
             'cpu_percent': 100.0 * (c1 - c0) / (w1 - w0),
             'worst_window_rtf': min((w[0] for w in windows), default=float('nan')),
             'peak_window_cpu': max((w[1] for w in windows), default=float('nan')),
             'windows': len(windows),
             # CPU one sim second costs, per window: what real time needs of a free core
             'peak_window_demand': max((w[1] / w[0] for w in windows if w[0] > 0),
                                       default=float('nan')),
             'impacts_per_s': (i1 - i0) / max(t1 - t0, 1e-9), 'late_ticks': node.stats.overruns,
             'schedule_deficits_dropped': k1 - k0, 'message': worst,
             'accelerometers': len(node.live.accelerometers),
             'sample_rate': node.live.sample_rate}
        node.destroy_node()
        if len(sent_at) > 2:
            gaps = np.diff(np.array(sent_at))
            # a burst: samples sent less than 0.1 ms apart; over 5 overflows keep-last-5
            breaks = np.flatnonzero(gaps >= 1e-4)
            runs = np.diff(np.concatenate([[-1], breaks, [gaps.size]]))
            d['largest_burst'] = int(runs.max())
            d['in_bursts_over_5_percent'] = 100.0 * runs[runs > 5].sum() / runs.sum()
            d['gap_p99_ms'] = 1e3 * float(np.percentile(gaps, 99))
        if proc is not None:
            out = json.loads(proc.communicate(timeout=60)[0].strip().splitlines()[-1])
            sent = (out['last_ns'] - out['first_ns']) * 1e-9 * d['sample_rate'] + 1
            d['received_percent'] = 100.0 * out['received'] / sent
            d['subscriber_cpu_percent'] = 100.0 * out['cpu_s'] / out['seconds']
            proc = None
        return d
    finally:
        if proc is not None:
            proc.kill()
        rclpy.try_shutdown(context=ctx)


def command_latency(scene, overrides, domain=DOMAIN0 + 9):
    """Latency of a speed command to its first effect on ``rotor/speed`` (sim s, wall s)."""
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=domain)
    try:
        node = VibrationNode(context=ctx, parameter_overrides=[
            Parameter('scene', value=scene), Parameter('overrides', value=list(overrides))])
        client = Node('latency_client', context=ctx)
        clock, speeds = [], []
        client.create_subscription(Clock, itf.CLOCK, lambda m: clock.append(_sec(m.clock)),
                                   itf.CLOCK_QOS)
        client.create_subscription(
            Vector3Stamped, itf.ROTOR_SPEED,
            lambda m: speeds.append((_sec(m.header.stamp), m.vector.x, time.monotonic())),
            itf.COMMAND_QOS)
        pub = client.create_publisher(Float64, itf.SPEED_COMMAND, itf.COMMAND_QOS)
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        ex.add_node(client)
        spin = threading.Thread(target=ex.spin, daemon=True)
        spin.start()
        time.sleep(1.5)
        results = []
        for target in (2410.0, 2400.0, 2420.0, 2400.0, 2410.0):   # from a held speed
            held = speeds[-1][1]
            t_sim_sent, t_wall_sent = clock[-1], time.monotonic()
            n_before = len(speeds)
            pub.publish(Float64(data=target))
            deadline = time.monotonic() + 2.0
            while time.monotonic() < deadline:
                moved = [s for s in speeds[n_before:] if s[1] != held]
                if moved:
                    results.append((moved[0][0] - t_sim_sent, moved[0][2] - t_wall_sent))
                    break
                time.sleep(0.001)
            time.sleep(0.5)
        ex.shutdown(timeout_sec=1.0)
        node.destroy_node()
        client.destroy_node()
        return results
    finally:
        rclpy.try_shutdown(context=ctx)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seconds', type=float, default=10.0)
    parser.add_argument('--scene', default='hpotp')
    parser.add_argument('--quick', action='store_true',
                        help='only the ramp and the dampers-off case with the subscriber')
    args = parser.parse_args(argv)
    full = [FULL_SPEED]
    print(f'load before: {os.getloadavg()[0]:.2f} (1-min average, {os.cpu_count()} cores)')
    bare_off = bare_stepping_cpu(args.scene, full, False)
    bare_on = bare_stepping_cpu(args.scene, full, True)
    print(f'bare stepping (LiveSimulation alone, full speed): {bare_off:.1f} % of a core '
          f'dampers off, {bare_on:.1f} % dampers on')
    # name, overrides, real_time_factor, dampers, record, subscriber, bare cost
    cases = [('paper ramp, default parameters', [], 1.0, True, False, False, None),
             ('full speed, dampers off, subscriber', full, 1.0, False, False, True, bare_off)]
    if not args.quick:
        cases += [
            ('full speed, dampers off, recording', full, 1.0, False, True, False, bare_off),
            ('full speed, dampers on', full, 1.0, True, False, False, bare_on),
            ('full speed, dampers on, recording', full, 1.0, True, True, False, bare_on),
            ('full speed, dampers on, as fast as possible', full, 0.0, True, False, False,
             None)]
    print(f'{"case":44s} {"acc":>3s} {"RTF":>6s} {"worst":>6s} {"CPU %":>6s} {"peak":>6s} '
          f'{"node/bare":>9s} {"overhead":>8s} {"imp/s":>6s} {"recv %":>6s} {"late":>4s}'
          f'  worst status')
    for i, (name, ovr, rtf, dampers, record, sub, bare) in enumerate(cases):
        with tempfile.TemporaryDirectory() as tmp:
            d = run_case(args.scene, ovr, args.seconds, rtf, dampers, domain=DOMAIN0 + i,
                         record=os.path.join(tmp, 'bench.mcap') if record else None,
                         subscriber=sub)
        ratio = f'{d["cpu_percent"] / bare:9.2f}' if bare else f'{"":9s}'
        over = f'{d["cpu_percent"] - bare:8.1f}' if bare else f'{"":8s}'
        recv = f'{d["received_percent"]:6.1f}' if 'received_percent' in d else f'{"":6s}'
        print(f'{name:44s} {d["accelerometers"]:3d} {d["real_time_factor_achieved"]:6.3f} '
              f'{d["worst_window_rtf"]:6.3f} {d["cpu_percent"]:6.1f} '
              f'{d["peak_window_cpu"]:6.1f} {ratio} {over} {d["impacts_per_s"]:6.0f} {recv} '
              f'{d["late_ticks"]:4d}  {d["message"][:50]}')
        if name.startswith('paper ramp'):
            print(f'{"":44s} {d["windows"]} windows of 1 s: worst achieved RTF '
                  f'{d["worst_window_rtf"]:.3f}, peak CPU {d["peak_window_cpu"]:.1f} % of a '
                  f'core, peak CPU per real-time second {d["peak_window_demand"]:.1f} %')
        if sub:
            print(f'{"":44s} subscriber process: {d["subscriber_cpu_percent"]:.0f} % of a '
                  f'core; node sent samples in bursts of at most {d["largest_burst"]} '
                  f'(< 0.1 ms apart), {d["in_bursts_over_5_percent"]:.1f} % of them in bursts '
                  f'over 5; 99th percentile gap {d["gap_p99_ms"]:.2f} ms')
    if not args.quick:
        lat = command_latency(args.scene, full, domain=DOMAIN0 + 9)
        if lat:
            sims = sorted(x[0] for x in lat)
            walls = sorted(x[1] for x in lat)
            print(f'speed command -> first effect on rotor/speed, {len(lat)} commands: '
                  f'median {1e3 * sims[len(sims) // 2]:.1f} ms sim (max {1e3 * sims[-1]:.1f}), '
                  f'median {1e3 * walls[len(walls) // 2]:.1f} ms wall '
                  f'(max {1e3 * walls[-1]:.1f})')
    print(f'load after: {os.getloadavg()[0]:.2f}')


if __name__ == '__main__':
    main()
