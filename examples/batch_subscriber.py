"""Read the full-rate accelerometer stream: one line per second of signal."""
import signal

import numpy as np
import rclpy
from rclpy.executors import ExternalShutdownException
from sensor_msgs.msg import PointCloud2

from impact_damper_sim.ros.rows import batch_rows, batch_start

TOPIC = 'accel/hpotp_casing_bottom/batch'     # the default scene's accelerometer, 2 kHz
second = {'start': None, 'rows': []}           # the batches of the current second


def on_batch(msg):
    start = batch_start(msg)                   # sim time of the batch's first sample (s)
    if second['start'] is None:
        second['start'] = start
    if start - second['start'] >= 1.0:
        rows = np.concatenate(second['rows'])  # fields t (s), ax ay az (m/s^2), wx wy wz
        print(f"{TOPIC}: {len(rows) / (start - second['start']):.0f} samples/s, "
              f"rms ay {np.sqrt(np.mean(rows['ay'] ** 2)):.3g} m/s^2", flush=True)
        second.update(start=start, rows=[])
    second['rows'].append(batch_rows(msg))


stopping = []   # Ctrl-C seen: rclpy shuts down, and spin ends (with an error or not)
signal.signal(signal.SIGINT, lambda *_: stopping.append(True))   # rclpy.init chains to it
rclpy.init()
node = rclpy.create_node('batch_subscriber')
node.create_subscription(PointCloud2, TOPIC, on_batch, 100)   # reliable, keep last 100
try:
    rclpy.spin(node)
except (KeyboardInterrupt, ExternalShutdownException):
    pass
except RuntimeError:   # Ctrl-C: rclpy may shut the context down under spin's wait
    if not stopping:
        raise
