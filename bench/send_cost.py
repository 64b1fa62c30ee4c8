"""What one raw ``sensor_msgs/Imu`` send costs the sending thread, warm and after a sleep.

Issue 39 item 1 asks where a node's CPU goes. A node sends some 1,700 messages a second,
in groups: the Imu samples 4 at a time every 4 ms (``imu_group``), each group after a sleep
of the stepping thread. This bench times the send alone, in a publisher process of its own
(``rclpy``, the default middleware), with the readers in other processes:

* **back to back**: ``--sends`` sends of one serialized Imu through the publisher's handle
  (what :func:`impact_damper_sim.ros.outlets.write_raw` does), no sleep between them;
* **paced**: the same sends in groups of 4, each group after a 4 ms sleep, as a node at
  1 kHz sends them; less the CPU of the same loop with the sends left out (the sleeps and
  the loop alone), per send.

The CPU is the sending thread's own (``time.thread_time``), per send, in microseconds; each
case runs ``--rounds`` rounds of ``--sends`` sends, alternating paced and its baseline, and
the median round is given. Readers: none, one raw reader (``raw=True``: nothing
deserialized), and a raw reader with a Python reader (a callback per message), each a
process with ``qos_profile_sensor_data``, as the node's users read the stream.

Usage (quote figures only from a quiet machine: ``flock -x /tmp/bench.lock``)::

    .venv/bin/python bench/send_cost.py [--sends 1000] [--rounds 5] [--page [FILE]]
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import statistics
import subprocess
import sys

from node_scenes import ROOT, base_env
from node_scenes_figures import machine
from node_scenes_procs import pick_domain

PAGE = os.path.join(ROOT, 'docs', 'bench', 'send-cost.md')
READERS = {'none': [], 'raw': ['raw'], 'raw + python': ['raw', 'python']}

#: a reader: argv kind ('raw' or 'python'), seconds; counts what it gets
READER = r'''
import sys, time
import rclpy
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import Imu
kind, seconds = sys.argv[1], float(sys.argv[2])
rclpy.init()
node = rclpy.create_node('send_cost_reader')
got = [0]
def take(msg):
    got[0] += 1
node.create_subscription(Imu, 'send_cost_imu', take, qos_profile_sensor_data,
                         raw=(kind == 'raw'))
print('ready', flush=True)
end = time.monotonic() + seconds
while time.monotonic() < end:
    rclpy.spin_once(node, timeout_sec=0.1)
print(got[0], flush=True)
'''

#: the publisher: argv readers expected, sends, rounds; one JSON line of per-send CPU (us)
PUBLISHER = r'''
import json, statistics, sys, time
import rclpy
from rclpy.qos import qos_profile_sensor_data
from rclpy.serialization import serialize_message
from sensor_msgs.msg import Imu
readers, sends, rounds = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
rclpy.init()
node = rclpy.create_node('send_cost_publisher')
pub = node.create_publisher(Imu, 'send_cost_imu', qos_profile_sensor_data)
end = time.monotonic() + 30.0
while pub.get_subscription_count() < readers and time.monotonic() < end:
    time.sleep(0.05)
matched = pub.get_subscription_count()
time.sleep(1.0)
data = serialize_message(Imu())
handle = pub.handle

def send(h, d):
    with h:
        h.publish_raw(d)

def skip(h, d):
    pass

def loop(write, sleep):
    t0 = time.thread_time()
    for i in range(sends):
        write(handle, data)
        if sleep and i % 4 == 3:
            time.sleep(0.004)
    return (time.thread_time() - t0) / sends * 1e6

warm, paced, base = [], [], []
for _ in range(rounds):
    warm.append(loop(send, False))
    paced.append(loop(send, True))
    base.append(loop(skip, True))
print(json.dumps({'matched': matched, 'warm': warm, 'paced': paced, 'base': base}))
'''


def run_case(readers, sends, rounds, domain):
    """Per-send CPU of one case (dict of lists, us) with ``readers`` reader processes."""
    env = dict(base_env(), ROS_DOMAIN_ID=str(domain),
               ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    seconds = 40.0 + rounds * sends * 0.003
    procs = [subprocess.Popen([sys.executable, '-c', READER, kind, str(seconds)], env=env,
                              stdout=subprocess.PIPE, text=True) for kind in readers]
    try:
        for p in procs:
            p.stdout.readline()   # ready
        out = subprocess.run([sys.executable, '-c', PUBLISHER, str(len(readers)), str(sends),
                              str(rounds)], env=env, capture_output=True, text=True,
                             timeout=seconds + 60.0)
        if out.returncode != 0:
            raise RuntimeError(f'publisher failed: {out.stderr.strip()[-500:]}')
        return json.loads(out.stdout.strip().splitlines()[-1])
    finally:
        for p in procs:
            p.kill()
            p.wait()


def summary(case):
    """Medians (us per send): warm, paced less its baseline, and the baseline."""
    paced = [p - b for p, b in zip(case['paced'], case['base'])]
    return {'warm': statistics.median(case['warm']), 'paced': statistics.median(paced),
            'base': statistics.median(case['base']), 'matched': case['matched']}


def page(results, command, load):
    lines = ['# One raw Imu send: its CPU warm and after a sleep', '',
             '<!-- written by bench/send_cost.py --page; do not edit: run it again -->', '',
             f'- **Date**: {datetime.date.today().isoformat()}',
             f'- **Machine**: {machine()}',
             f'- **Command**: `{command}`',
             f"- **Load** (1-min average): {load:.2f} before", '',
             'CPU of the sending thread per send, microseconds (median round): **back to '
             'back** with no sleep; **after a sleep** in groups of 4 every 4 ms, as the node '
             'sends its 1 kHz Imu stream, less the same loop without the sends. How: '
             "`bench/send_cost.py`'s docstring.", '',
             '| readers | matched | back to back, us | after a sleep, us | ratio | '
             'the loop and its sleeps alone, us per send |',
             '|---|---|---|---|---|---|']
    for name, r in results.items():
        lines.append(f"| {name} | {r['matched']} | {r['warm']:.1f} | {r['paced']:.1f} | "
                     f"{r['paced'] / r['warm']:.1f} | {r['base']:.1f} |")
    lines += ['', 'A node that sends each group after a sleep pays the second column, not '
              'the first. Why a send costs more after a sleep (caches and branch predictors '
              'cold again, the core idle meanwhile) this bench does not separate; fewer '
              'wake-ups (groups of 4, not single samples) and one wake-up for several '
              "machines (`plant_host`'s shared stepping thread) are what lower it.", '']
    return '\n'.join(lines)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--sends', type=int, default=1000, help='sends per round')
    parser.add_argument('--rounds', type=int, default=5)
    parser.add_argument('--domain', type=int, default=None)
    parser.add_argument('--page', nargs='?', const=PAGE, default=None)
    args = parser.parse_args(argv)
    given = list(sys.argv[1:] if argv is None else argv)
    command = ' '.join(['bench/send_cost.py', *[a for a in given if a != '--domain']])
    domain = args.domain or pick_domain(101 + os.getpid() % 130)
    load = os.getloadavg()[0]
    results = {}
    for name, readers in READERS.items():
        results[name] = summary(run_case(readers, args.sends, args.rounds, domain))
        r = results[name]
        print(f"{name:14s} matched {r['matched']}: back to back {r['warm']:.1f} us, after a "
              f"sleep {r['paced']:.1f} us per send (the loop alone {r['base']:.1f})",
              flush=True)
    if args.page:
        with open(args.page, 'w') as f:
            f.write(page(results, command, load))
        print(f'wrote {args.page}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
