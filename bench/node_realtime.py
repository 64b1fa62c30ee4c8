"""vibration_node at real time: achieved real-time factor, CPU use, command latency.

Runs the node in this process (no launch), for each case: the HPOTP scene with 3 accelerometers (casing bottom, pump-end and turbine-end
bearings, 800 Hz low-pass) at 2 kHz, dampers on and off, with and without recording to MCAP, and at
``real_time_factor`` 0 (the highest factor reachable). CPU use is this process's CPU time over wall time while the
node runs (all threads: stepping, executor, DDS), as a percentage of one core.

Command latency: a speed command is published while the rotor holds its speed; the latency
is the first ``rotor/speed`` stamp whose speed has changed minus the ``/clock`` stamp last
received before the command was sent (sim s), and the same in wall time.

Usage::

    python bench/node_realtime.py [--seconds 10] [--scene hpotp]

Figures depend on the machine's load: run it on a quiet machine (``uptime`` first).
"""
from __future__ import annotations

import argparse
import os
import tempfile
import threading
import time

os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')

import rclpy  # noqa: E402
from geometry_msgs.msg import Vector3Stamped  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from std_msgs.msg import Float64  # noqa: E402

from impact_damper_sim.ros import interface as itf  # noqa: E402
from impact_damper_sim.ros.vibration_node import VibrationNode  # noqa: E402

THREE_ACCELEROMETERS = (
    'sensors=[{name: bottom_y, node: 1, dof: uy, frame_id: casing_bottom, lowpass: 800 Hz}, '
    '{name: bottom_z, node: 1, dof: uz, frame_id: casing_bottom, lowpass: 800 Hz}, '
    '{name: pump_y, node: 4, dof: uy, frame_id: pump_bearing, lowpass: 800 Hz}, '
    '{name: turbine_y, node: 15, dof: uy, frame_id: turbine_bearing, lowpass: 800 Hz}]')


def _sec(stamp):
    return stamp.sec + 1e-9 * stamp.nanosec


def run_case(scene, overrides, seconds, rtf, dampers=True, domain=61, record=None):
    """Run one case; return a dict of measured figures."""
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=domain)
    try:
        node = VibrationNode(context=ctx, parameter_overrides=[
            Parameter('scene', value=scene), Parameter('overrides', value=list(overrides)),
            Parameter('real_time_factor', value=float(rtf)),
            Parameter('dampers_enabled', value=bool(dampers)),
            *([Parameter('record', value=record)] if record else [])])
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        warm = time.monotonic() + 1.0
        while time.monotonic() < warm:
            ex.spin_once(timeout_sec=0.05)
        # measured over the whole window here (the node's own diagnostics cover 1 s periods)
        t0, w0, c0 = node.live.t, time.monotonic(), time.process_time()
        i0, k0 = node.stats_total['impacts'], node.pacer.deficits
        end = w0 + seconds
        worst = 'ok'
        while time.monotonic() < end:
            ex.spin_once(timeout_sec=0.05)
            d = getattr(node, 'last_diagnostics', None)
            if d and d['level'] > 0:
                worst = d['message']
        with node._lock:
            t1, w1, c1 = node.live.t, time.monotonic(), time.process_time()
            i1, k1 = node.stats_total['impacts'], node.pacer.deficits
        d = {'real_time_factor_achieved': (t1 - t0) / (w1 - w0),
             'cpu_percent': 100.0 * (c1 - c0) / (w1 - w0),
             'impacts_per_s': (i1 - i0) / max(t1 - t0, 1e-9), 'late_ticks': node.stats.overruns,
             'schedule_deficits_dropped': k1 - k0, 'message': worst,
             'accelerometers': len(node.live.accelerometers)}
        node.destroy_node()
        return d
    finally:
        rclpy.try_shutdown(context=ctx)


def command_latency(scene, overrides, domain=62):
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
    args = parser.parse_args(argv)
    overrides = [THREE_ACCELEROMETERS] if args.scene == 'hpotp' else []
    full_speed = ['rotor.speed={kind: constant, speed: 2400 rad/s}']
    print(f'load before: {os.getloadavg()[0]:.2f} (1-min average, {os.cpu_count()} cores)')
    cases = [('ramp + full speed, dampers on', overrides, 1.0, True, False),
             ('full speed, dampers on', overrides + full_speed, 1.0, True, False),
             ('full speed, dampers off', overrides + full_speed, 1.0, False, False),
             ('full speed, dampers off, recording', overrides + full_speed, 1.0, False, True),
             ('full speed, dampers on, recording', overrides + full_speed, 1.0, True, True),
             ('full speed, dampers on, as fast as possible', overrides + full_speed, 0.0,
              True, False)]
    print(f'{"case":46s} {"acc":>3s} {"RTF":>7s} {"CPU %":>6s} {"impacts/s":>9s} '
          f'{"late":>4s} {"deficits":>8s}  worst status')
    for i, (name, ovr, rtf, dampers, record) in enumerate(cases):
        with tempfile.TemporaryDirectory() as tmp:
            d = run_case(args.scene, ovr, args.seconds, rtf, dampers, domain=61 + i,
                         record=os.path.join(tmp, 'bench.mcap') if record else None)
        print(f'{name:46s} {d["accelerometers"]:3d} {d["real_time_factor_achieved"]:7.3f} '
              f'{d["cpu_percent"]:6.1f} {d["impacts_per_s"]:9.0f} {d["late_ticks"]:4d} '
              f'{d["schedule_deficits_dropped"]:8d}  {d["message"][:60]}')
    lat = command_latency(args.scene, overrides + full_speed, domain=70)
    if lat:
        sims = sorted(x[0] for x in lat)
        walls = sorted(x[1] for x in lat)
        print(f'speed command -> first effect on rotor/speed, {len(lat)} commands: '
              f'median {1e3 * sims[len(sims) // 2]:.1f} ms sim (max {1e3 * sims[-1]:.1f}), '
              f'median {1e3 * walls[len(walls) // 2]:.1f} ms wall (max {1e3 * walls[-1]:.1f})')
    print(f'load after: {os.getloadavg()[0]:.2f}')


if __name__ == '__main__':
    main()
