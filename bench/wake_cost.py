"""What code costs when it wakes: the same work after sleeps of 0 to 10 ms.

The node's stepping thread sleeps between its wake-ups (a chunk to step every 10 ms, Imu
samples every 2 ms). On some machines (this project's 2-core VM among them) code that has
slept runs several times slower when it wakes than when it runs back to back: caches, TLB
and branch predictors were given to something else, or the virtual CPU halted and its host
core slowed down. This script measures that, so the pacing's choice (``Outbox.REFILL``: step
five chunks back to back rather than one per wake-up) rests on a number.

Two kinds of work, each timed by the thread's CPU clock (``time.thread_time``) after a sleep
of each length, the sleep itself not counted:

* **python**: a small fixed unit of Python and NumPy (a loop of 200 additions, a sum and a
  product of a 100-element array), about what one packing step of the node does;
* **publish**: one ``sensor_msgs/Imu`` sent as serialized bytes by an rclpy publisher with no
  reader (``--no-ros`` skips it), in a DDS domain of its own.

Printed: the median CPU time per unit (us) after each sleep and its ratio to back to back.
Quote figures from a quiet machine.

Usage::

    .venv/bin/python bench/wake_cost.py [--repeats 1000] [--domain 97] [--no-ros]
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

import numpy as np

#: sleeps before each unit (s); 0 = back to back
SLEEPS = (0.0, 2e-4, 1e-3, 2.5e-3, 1e-2)


_ARRAY = np.zeros(100)


def python_unit():
    """The fixed unit of Python and NumPy work."""
    a = _ARRAY
    s = 0
    for i in range(200):
        s += i * i
    a.sum()
    a * 2.0
    return s


def per_unit(unit, sleep, repeats):
    """Median thread CPU time (s) of ``unit()`` run after ``sleep`` (s), ``repeats`` times."""
    unit()   # warm
    times = []
    for _ in range(repeats):
        if sleep:
            time.sleep(sleep)
        t0 = time.thread_time()
        unit()
        times.append(time.thread_time() - t0)
    return statistics.median(times)


def publisher_unit(domain):
    """A function sending one serialized Imu, and a function closing the node."""
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    import rclpy
    from rclpy.qos import qos_profile_sensor_data
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import Imu
    rclpy.init(domain_id=domain)
    node = rclpy.create_node('wake_cost')
    pub = node.create_publisher(Imu, 'wake_cost/imu', qos_profile_sensor_data)
    data = serialize_message(Imu())

    def close():
        node.destroy_node()
        rclpy.try_shutdown()
    return (lambda: pub.publish(data)), close


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--repeats', type=int, default=1000, help='units per sleep length')
    parser.add_argument('--domain', type=int, default=97, help='DDS domain of the publisher')
    parser.add_argument('--no-ros', action='store_true', help='the Python unit only')
    args = parser.parse_args(argv)
    units = {'python': python_unit}
    close = None
    if not args.no_ros:
        units['publish'], close = publisher_unit(args.domain)
    try:
        print(f'{"work":8s} ' + ' '.join(f'{f"after {s * 1e3:g} ms":>16s}' for s in SLEEPS))
        for name, unit in units.items():
            base = None
            cells = []
            for sleep in SLEEPS:
                us = per_unit(unit, sleep, args.repeats) * 1e6
                base = us if base is None else base
                cells.append(f'{us:7.1f} us {us / base:4.1f}x')
            print(f'{name:8s} ' + ' '.join(f'{c:>16s}' for c in cells), flush=True)
    finally:
        if close is not None:
            close()
    print('median thread CPU per unit after each sleep (the sleep not counted), and its '
          'ratio to back to back')
    return 0


if __name__ == '__main__':
    sys.exit(main())
