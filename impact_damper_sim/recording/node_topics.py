"""The topics of ``vibration_node`` without ROS: names, message types and QoS as plain data.

One table for everything that writes the node's topics: the node itself
(:mod:`impact_damper_sim.ros.interface` builds its ``rclpy`` QoS profiles from these dicts)
and ``study record``, which writes the same log offline without rclpy. The encodings are
described in :mod:`impact_damper_sim.ros.interface` and docs/node.md.

QoS profiles are dicts in :func:`~.bag_metadata.qos_dict`'s form (rmw policy names, depth in
messages); keys left out take rclpy's ``QoSProfile()`` defaults, as a ``QoSProfile`` built
from the same keys does.
"""
from __future__ import annotations

#: the node's ``tick_period``: default and closed range (s of sim time per stepped chunk);
#: ``ros/parameters.py`` declares the parameter with these, ``study record`` writes with them
TICK_PERIOD = 0.01
TICK_PERIOD_RANGE = (0.001, 0.1)
#: the node's ``state_period``: default and range (s between ``impactor_state`` messages)
STATE_PERIOD = 1.0
STATE_PERIOD_RANGE = (0.01, 60.0)

ACCEL_PREFIX = 'accel/'
BATCH_SUFFIX = '/batch'
#: an accelerometer's ground truth (``accel/<name>`` + this): the model's acceleration before
#: the channel, in the batch layout; published when the node's ``publish_truth`` is on
TRUTH_SUFFIX = '/truth'
IMPACTS = 'impacts'
IMPACTOR_STATE = 'impactor_state'
ROTOR_SPEED = 'rotor/speed'
ROTOR_JOINT_STATES = 'rotor/joint_states'
#: the tachometer: the shaft angle at every full-rate sample (scenes with a rotor)
ROTOR_TACH = 'rotor/tach'
#: the once-per-revolution keyphasor events (scenes with a rotor)
ROTOR_KEYPHASOR = 'rotor/keyphasor'
SPEED_COMMAND = 'rotor/speed_command'
UNBALANCE_COMMAND = 'rotor/unbalance_command'
#: sensor fault commands (std_msgs/String: YAML or JSON text, ``live.fault_spec``): a fault
#: to add, ``{clear: <name>}`` or ``{clear: all}``; recorded as received, schedule faults too
FAULT_COMMAND = 'accel/fault_command'
CLOCK = '/clock'
DIAGNOSTICS = '/diagnostics'
#: where ROS 2 nodes announce parameter changes; the node's log records each accepted
#: change of a dynamic parameter here (live or from a schedule), as ``ros2 bag`` would
PARAMETER_EVENTS = '/parameter_events'

IMU = 'sensor_msgs/msg/Imu'
POINTCLOUD2 = 'sensor_msgs/msg/PointCloud2'
JOINT_STATE = 'sensor_msgs/msg/JointState'
VECTOR3_STAMPED = 'geometry_msgs/msg/Vector3Stamped'
FLOAT64 = 'std_msgs/msg/Float64'
STRING = 'std_msgs/msg/String'
CLOCK_TYPE = 'rosgraph_msgs/msg/Clock'
DIAGNOSTIC_ARRAY = 'diagnostic_msgs/msg/DiagnosticArray'
PARAMETER_EVENT = 'rcl_interfaces/msg/ParameterEvent'

#: ROS type names of each topic (``pkg/msg/Type``); ``accel/<sensor>`` under ACCEL_PREFIX.
TYPES = {
    ACCEL_PREFIX: IMU,
    BATCH_SUFFIX: POINTCLOUD2,
    TRUTH_SUFFIX: POINTCLOUD2,
    IMPACTS: POINTCLOUD2,
    IMPACTOR_STATE: JOINT_STATE,
    ROTOR_SPEED: VECTOR3_STAMPED,
    ROTOR_JOINT_STATES: JOINT_STATE,
    ROTOR_TACH: POINTCLOUD2,
    ROTOR_KEYPHASOR: POINTCLOUD2,
    SPEED_COMMAND: FLOAT64,
    UNBALANCE_COMMAND: FLOAT64,
    FAULT_COMMAND: STRING,
    CLOCK: CLOCK_TYPE,
    DIAGNOSTICS: DIAGNOSTIC_ARRAY,
    PARAMETER_EVENTS: PARAMETER_EVENT,
}

#: Accelerometer samples: best effort, volatile, keep last 100 (see ros.interface).
SENSOR_QOS = {'history': 'keep_last', 'depth': 100, 'reliability': 'best_effort',
              'durability': 'volatile'}
#: Batches (full-rate samples, ground truth, tachometer, impacts, keyphasor): reliable,
#: volatile, keep last 100.
BATCH_QOS = {'history': 'keep_last', 'depth': 100, 'reliability': 'reliable',
             'durability': 'volatile'}
#: Impact batches: every impact counts.
EVENT_QOS = BATCH_QOS
#: Impactor state: reliable and transient_local (latched), so late joiners get it.
LATCHED_QOS = {'history': 'keep_last', 'depth': 1, 'reliability': 'reliable',
               'durability': 'transient_local'}
#: Rotor speed and commands: reliable, volatile, small depth.
COMMAND_QOS = {'history': 'keep_last', 'depth': 10, 'reliability': 'reliable',
               'durability': 'volatile'}
#: /clock as Gazebo publishes it: reliable, keep last 1.
CLOCK_QOS = {'history': 'keep_last', 'depth': 1, 'reliability': 'reliable',
             'durability': 'volatile'}
#: /diagnostics: diagnostic_updater's default, keep last 10, reliable.
DIAGNOSTICS_QOS = COMMAND_QOS
#: /parameter_events: rclpy's ``qos_profile_parameter_events`` (keep last 1000, reliable).
PARAMETER_EVENTS_QOS = {'history': 'keep_last', 'depth': 1000, 'reliability': 'reliable',
                        'durability': 'volatile'}


#: MCAP chunk size of the node's logs (bytes, uncompressed), as rosbag2's MCAP storage: the
#: summary keeps one index per chunk in memory until the file closes
RECORD_CHUNK_SIZE = 768 * 1024


def accel_topic(sensor):
    """Return the relative topic name of an accelerometer's per-sample stream (str)."""
    return ACCEL_PREFIX + sensor


def accel_batch_topic(sensor):
    """Return the relative topic name of an accelerometer's full-rate batches (str)."""
    return ACCEL_PREFIX + sensor + BATCH_SUFFIX


def accel_truth_topic(sensor):
    """Return the relative topic name of an accelerometer's ground truth batches (str)."""
    return ACCEL_PREFIX + sensor + TRUTH_SUFFIX


def qualified(topic, namespace='/'):
    """The fully qualified name of ``topic`` in ``namespace`` (absolute names stay)."""
    if topic.startswith('/'):
        return topic
    return namespace.rstrip('/') + '/' + topic


__all__ = ['ACCEL_PREFIX', 'BATCH_QOS', 'BATCH_SUFFIX', 'CLOCK', 'CLOCK_QOS', 'CLOCK_TYPE',
           'COMMAND_QOS', 'DIAGNOSTICS', 'DIAGNOSTICS_QOS', 'DIAGNOSTIC_ARRAY', 'EVENT_QOS',
           'FAULT_COMMAND', 'FLOAT64', 'IMPACTS', 'IMPACTOR_STATE', 'IMU', 'JOINT_STATE',
           'LATCHED_QOS',
           'PARAMETER_EVENT', 'PARAMETER_EVENTS', 'PARAMETER_EVENTS_QOS', 'POINTCLOUD2',
           'RECORD_CHUNK_SIZE',
           'ROTOR_JOINT_STATES', 'ROTOR_KEYPHASOR', 'ROTOR_SPEED', 'ROTOR_TACH', 'SENSOR_QOS',
           'SPEED_COMMAND', 'STRING', 'TRUTH_SUFFIX', 'TYPES', 'UNBALANCE_COMMAND',
           'VECTOR3_STAMPED',
           'accel_batch_topic', 'accel_topic', 'accel_truth_topic', 'qualified']
