"""vibration_node memory soak: RSS over a long run with recording on.

Runs the node in this process (HPOTP, default parameters: the paper's ramp, then full speed
with dampers on) at real time, recording every topic to an MCAP file in a temporary
directory, and samples the resident set size (``VmRSS``) every ``--every`` seconds. After a
warm-up (``--warmup``, default a fifth of the run) it fits a straight line to RSS against
time and prints the slope (MB/min) next to what the recorder must keep by design: the MCAP
summary (one chunk index per closed chunk, about ``chunk index bytes``/min), which only the
end of the file can hold.

Usage::

    python bench/node_soak.py [--minutes 30] [--every 10] [--scene hpotp]

A flat RSS is a slope within a few hundredths of a MB/min of the summary's growth.
"""
from __future__ import annotations

import argparse
import os
import tempfile
import time

os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')

import numpy as np  # noqa: E402
import rclpy  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402

from impact_damper_sim.ros.vibration_node import VibrationNode  # noqa: E402


def rss_mb():
    """Resident set size of this process (MB)."""
    with open('/proc/self/status') as f:
        for line in f:
            if line.startswith('VmRSS:'):
                return int(line.split()[1]) / 1024.0
    return float('nan')


def _chunk_indexes(rec):
    """Chunk indexes the MCAP writer holds for the summary (int), or '?'."""
    try:
        return len(rec._writer._mcap._Writer__chunk_indices)   # mcap.writer.Writer internals
    except AttributeError:
        return '?'


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--minutes', type=float, default=30.0)
    parser.add_argument('--every', type=float, default=10.0, help='RSS sample period (s)')
    parser.add_argument('--warmup', type=float, default=None,
                        help='minutes left out of the fit (default a fifth of the run)')
    parser.add_argument('--scene', default='hpotp')
    parser.add_argument('--domain', type=int, default=83)
    args = parser.parse_args(argv)
    warmup = args.minutes / 5.0 if args.warmup is None else args.warmup
    print(f'load before: {os.getloadavg()[0]:.2f} (1-min average, {os.cpu_count()} cores)')
    ctx = rclpy.Context()
    rclpy.init(context=ctx, domain_id=args.domain)
    rows = []
    try:
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, 'soak.mcap')
            node = VibrationNode(context=ctx, parameter_overrides=[
                Parameter('scene', value=args.scene), Parameter('record', value=path)])
            ex = SingleThreadedExecutor(context=ctx)
            ex.add_node(node)
            w0 = time.monotonic()
            end = w0 + 60.0 * args.minutes
            next_sample = w0
            print(f'{"min":>6s} {"RSS MB":>8s} {"sim s":>8s} {"written":>10s} {"dropped":>8s} '
                  f'{"chunks":>7s} {"file MB":>8s}')
            while time.monotonic() < end:
                ex.spin_once(timeout_sec=0.1)
                if time.monotonic() >= next_sample:
                    next_sample += args.every
                    rec = node.recorder
                    stats = rec.stats() if rec is not None else {}
                    chunks = _chunk_indexes(rec)
                    size = os.path.getsize(path) / 1e6 if os.path.exists(path) else 0.0
                    row = ((time.monotonic() - w0) / 60.0, rss_mb(), node.live.t,
                           stats.get('messages_written', 0), stats.get('messages_dropped', 0),
                           chunks, size)
                    rows.append(row)
                    print(f'{row[0]:6.2f} {row[1]:8.1f} {row[2]:8.1f} {row[3]:10d} {row[4]:8d} '
                          f'{row[5]!s:>7s} {row[6]:8.1f}', flush=True)
            node.destroy_node()
    finally:
        rclpy.try_shutdown(context=ctx)
    t = np.array([r[0] for r in rows])
    rss = np.array([r[1] for r in rows])
    keep = t >= warmup
    if keep.sum() >= 3:
        slope, _ = np.polyfit(t[keep], rss[keep], 1)
        print(f'RSS after {warmup:.1f} min warm-up: {rss[keep][0]:.1f} -> {rss[keep][-1]:.1f} '
              f'MB, slope {slope:+.3f} MB/min (least squares over {keep.sum()} samples); '
              f'max - min {rss[keep].max() - rss[keep].min():.1f} MB')
    print(f'load after: {os.getloadavg()[0]:.2f}')


if __name__ == '__main__':
    main()
