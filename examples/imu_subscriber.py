"""Read the per-sample Imu stream: one line per second of signal."""
import math
import signal

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu

TOPIC = 'accel/hpotp_casing_bottom'            # the default scene's accelerometer, 1 kHz Imu
second = {'start': None, 'n': 0, 'sum_sq': 0.0}


def on_imu(msg):
    t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9   # the sample's sim time (s)
    if second['start'] is None:
        second['start'] = t
    if t - second['start'] >= 1.0:
        print(f"{TOPIC}: {second['n'] / (t - second['start']):.0f} samples/s, "
              f"rms ay {math.sqrt(second['sum_sq'] / second['n']):.3g} m/s^2", flush=True)
        second.update(start=t, n=0, sum_sq=0.0)
    second['n'] += 1
    second['sum_sq'] += msg.linear_acceleration.y ** 2   # m/s^2


stopping = []   # Ctrl-C seen: rclpy shuts down, and spin ends (with an error or not)
signal.signal(signal.SIGINT, lambda *_: stopping.append(True))   # rclpy.init chains to it
rclpy.init()
node = rclpy.create_node('imu_subscriber')
# best effort, as the node offers it (a reliable reader, the default, matches nothing);
# 100 deep, 0.1 s at 1 kHz: a busy reader then loses no sample (qos_profile_sensor_data: 5)
qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.BEST_EFFORT)
node.create_subscription(Imu, TOPIC, on_imu, qos)
try:
    rclpy.spin(node)
except (KeyboardInterrupt, ExternalShutdownException):
    pass
except RuntimeError:   # Ctrl-C: rclpy may shut the context down under spin's wait
    if not stopping:
        raise
