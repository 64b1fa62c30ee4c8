"""A monitoring node: each second of signal, the RMS acceleration and the 1x amplitude."""
import signal
import sys

import numpy as np
import rclpy
from geometry_msgs.msg import Vector3Stamped
from rclpy.executors import ExternalShutdownException
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import Float64

from impact_damper_sim.ros import interface as itf
from impact_damper_sim.ros.rows import batch_rows, batch_start

G = 9.80665                                     # m/s^2 in one g
SENSOR = sys.argv[1] if len(sys.argv) > 1 else 'hpotp_casing_bottom'
accel, tach = {}, {}      # header stamp (ns) -> batch, until both batches of a chunk are in
window = {'start': None, 'ay': [], 'angle': [], 'speed': []}
applied = {'unbalance': 1.0}                    # the node's unbalance multiplier X


def stamp_ns(msg):
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


def on_accel(msg):
    accel[stamp_ns(msg)] = msg
    pair_up()


def on_tach(msg):
    tach[stamp_ns(msg)] = msg
    pair_up()


def pair_up():
    """The accelerometer's batch and the tachometer's of one chunk share their stamp."""
    for stamp in sorted(accel.keys() & tach.keys()):
        a, t = accel.pop(stamp), tach.pop(stamp)
        rows, turns = batch_rows(a), batch_rows(t)
        if len(rows) == len(turns):             # no sample dropped by a sensor fault
            add(batch_start(a), rows, turns)


def add(start, rows, turns):
    if window['start'] is None:
        window['start'] = start
    if start - window['start'] >= 1.0:
        report(start)
    window['ay'].append(rows['ay'])             # m/s^2, the casing's y axis
    window['angle'].append(turns['angle'])      # rad, the shaft angle at each sample
    window['speed'].append(turns['speed'])      # rad/s


def report(end):
    ay = np.concatenate(window['ay']) / G
    angle = np.concatenate(window['angle'])
    speed = window['speed'][-1][-1]
    rms = np.sqrt(np.mean(ay ** 2))
    one_x = 2.0 * abs(np.mean(ay * np.exp(-1j * angle)))   # the once-per-turn part
    print(f'sim {end:5.1f} s: {speed:6.1f} rad/s, rms {rms:.3f} g, 1x {one_x:.3f} g, '
          f'unbalance x{applied["unbalance"]:g}', flush=True)
    window.update(start=end, ay=[], angle=[], speed=[])


def on_speed(msg):
    applied['unbalance'] = msg.vector.z         # what the node applies, not what was asked


def on_unbalance_command(msg):
    print(f'{itf.UNBALANCE_COMMAND} {msg.data:g} seen: the 1x follows the unbalance',
          flush=True)


stopping = []   # Ctrl-C seen: rclpy shuts down, and spin ends (with an error or not)
signal.signal(signal.SIGINT, lambda *_: stopping.append(True))   # rclpy.init chains to it
rclpy.init()
node = rclpy.create_node('monitoring_node')
node.create_subscription(PointCloud2, itf.accel_batch_topic(SENSOR), on_accel, itf.BATCH_QOS)
node.create_subscription(PointCloud2, itf.ROTOR_TACH, on_tach, itf.BATCH_QOS)
node.create_subscription(Vector3Stamped, itf.ROTOR_SPEED, on_speed, 10)
node.create_subscription(Float64, itf.UNBALANCE_COMMAND, on_unbalance_command,
                         itf.COMMAND_QOS)
try:
    rclpy.spin(node)
except (KeyboardInterrupt, ExternalShutdownException):
    pass
except RuntimeError:   # Ctrl-C: rclpy may shut the context down under spin's wait
    if not stopping:
        raise
