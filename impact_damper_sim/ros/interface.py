"""The ROS interface of ``vibration_node``: topic names, message types, QoS and encodings.

One place for the contract that the node, ``monitor``, the recorder and ``replay`` share.
Topic names without a leading slash are relative (the node can be namespaced); ``/clock`` and
``/diagnostics`` are absolute, as ROS tools expect. Everything is SI (REP-103).

Encodings in ``common_interfaces`` types (no custom message package):

``accel/<sensor>`` -- ``sensor_msgs/Imu``, one message per output sample
    ``header.stamp`` sample time (sim time); ``header.frame_id`` the sensor's frame.
    ``linear_acceleration`` (m/s^2): the acceleration of the sensor's node along the frame's
    x, y, z (the global axes), as an AC-coupled vibration accelerometer reads it (no static
    1 g), averaged over each integrator step and passed through the scene's anti-alias
    low-pass, plus the configured noise. ``angular_velocity`` (rad/s): the node's rotational
    DOF rates. Orientation is not measured: ``orientation_covariance[0] = -1`` (REP-145).
    ``linear_acceleration_covariance`` is diagonal with the noise variance (all zeros when
    noise is off: unknown); ``angular_velocity_covariance`` is all zeros (unknown).

``impacts`` -- ``geometry_msgs/WrenchStamped``, one message per impact
    ``header.stamp`` the impact time (located inside the step, sim time);
    ``header.frame_id`` ``<housing frame>/<impactor name>``, so the impactor id is the last
    path component. ``wrench.force`` (N s): the impulse on the impactor, ``J n``, where ``n``
    is the unit contact normal in the frame (its direction is the normal, its length the
    impulse). ``wrench.torque.x`` (m/s): normal relative velocity of approach before the
    impact (> 0); ``torque.y`` (m/s): normal relative velocity of separation after it;
    ``torque.z`` (J): the kinetic energy the impact dissipated.

``impactor_state`` -- ``sensor_msgs/JointState``, on change and every ``state_period``
    ``name``: ``<impactor>/y`` and ``<impactor>/z`` for planar impactors (the plane's two
    axes, named by their DOFs), ``<impactor>/<dof>`` for one-directional ones.
    ``position`` (m): the impactor's position relative to its housing centre;
    ``velocity`` (m/s): its velocity relative to the housing; ``effort``: 1.0 while the
    impactor is stuck (rides its housing), 0.0 while free.

``rotor/joint_states`` -- ``sensor_msgs/JointState``, every stepped chunk
    The rotor as the continuous joint it is, read by any ROS tool without this page:
    ``name`` ``['rotor']``; ``position`` (rad) the shaft angle, wrapped to [0, 2 pi);
    ``velocity`` (rad/s) the applied speed; ``effort`` empty (not modelled).

``rotor/speed`` -- ``geometry_msgs/Vector3Stamped``, every stepped chunk
    ``vector.x`` (rad/s) applied rotor speed; ``vector.y`` (rad/s^2) applied speed rate;
    ``vector.z`` (dimensionless) applied unbalance multiplier X. Kept beside
    ``rotor/joint_states`` because it carries what JointState cannot (the commanded rate and
    the unbalance multiplier, which the rate limit and ``rotor/unbalance_command`` change), in
    one stamped message that ``study report`` reads for its waterfall and that existing logs
    hold.

Why ``impacts`` is a ``WrenchStamped``: no common_interfaces type describes an impact, and a
custom message package would not show up in every tool. The wrench's force is the impulse
vector (its direction is the contact normal, as a force's is), so RViz and PlotJuggler draw
it meaningfully; the torque slots carry the scalars of the impact law.

``rotor/speed_command``, ``rotor/unbalance_command`` -- ``std_msgs/Float64`` subscriptions
    Target speed (rad/s, applied under the scene's rate limit) and multiplier X (>= 0).
"""
from __future__ import annotations

from rclpy.qos import (DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy)

ACCEL_PREFIX = 'accel/'
IMPACTS = 'impacts'
IMPACTOR_STATE = 'impactor_state'
ROTOR_SPEED = 'rotor/speed'
ROTOR_JOINT_STATES = 'rotor/joint_states'
SPEED_COMMAND = 'rotor/speed_command'
UNBALANCE_COMMAND = 'rotor/unbalance_command'
CLOCK = '/clock'
DIAGNOSTICS = '/diagnostics'

#: ROS type names of each topic (``pkg/msg/Type``); ``accel/<sensor>`` under ACCEL_PREFIX.
TYPES = {
    ACCEL_PREFIX: 'sensor_msgs/msg/Imu',
    IMPACTS: 'geometry_msgs/msg/WrenchStamped',
    IMPACTOR_STATE: 'sensor_msgs/msg/JointState',
    ROTOR_SPEED: 'geometry_msgs/msg/Vector3Stamped',
    ROTOR_JOINT_STATES: 'sensor_msgs/msg/JointState',
    SPEED_COMMAND: 'std_msgs/msg/Float64',
    UNBALANCE_COMMAND: 'std_msgs/msg/Float64',
    CLOCK: 'rosgraph_msgs/msg/Clock',
    DIAGNOSTICS: 'diagnostic_msgs/msg/DiagnosticArray',
}

#: Accelerometer samples: best effort and volatile like ``qos_profile_sensor_data``; samples
#: are published one by one at their own time, and the depth leaves a slow reader's
#: executor 50 ms (at 2 kHz) before the writer overwrites.
SENSOR_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                        reliability=ReliabilityPolicy.BEST_EFFORT,
                        durability=DurabilityPolicy.VOLATILE)
#: Impact events: reliable (every impact counts), volatile.
EVENT_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000,
                       reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.VOLATILE)
#: Impactor state: reliable and transient_local (latched), so late joiners get it.
LATCHED_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: Rotor speed and commands: reliable, volatile, small depth.
COMMAND_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.VOLATILE)
#: /clock as Gazebo publishes it: reliable, keep last 1 (use_sim_time subscribers take
#: best effort, which a reliable publisher feeds).
CLOCK_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                       reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.VOLATILE)
#: /diagnostics: reliable, volatile, keep last 10 (diagnostic_updater publishes with the
#: default QoS, keep last 10, reliable).
DIAGNOSTICS_QOS = COMMAND_QOS

G0 = 9.80665   # standard gravity (m/s^2), for reports in g


def accel_topic(sensor):
    """Return the relative topic name of a sensor's accelerometer stream (str)."""
    return ACCEL_PREFIX + sensor


__all__ = ['ACCEL_PREFIX', 'CLOCK', 'CLOCK_QOS', 'COMMAND_QOS', 'DIAGNOSTICS',
           'DIAGNOSTICS_QOS', 'EVENT_QOS', 'G0', 'IMPACTS', 'IMPACTOR_STATE', 'LATCHED_QOS',
           'ROTOR_JOINT_STATES', 'ROTOR_SPEED', 'SENSOR_QOS', 'SPEED_COMMAND', 'TYPES',
           'UNBALANCE_COMMAND', 'accel_topic']
