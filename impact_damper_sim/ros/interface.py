"""The ROS interface of ``vibration_node``: topic names, message types, QoS and encodings.

One place for the contract that the node, ``monitor``, the recorder and ``replay`` share.
Topic names without a leading slash are relative (the node can be namespaced); ``/clock`` and
``/diagnostics`` are absolute, as ROS tools expect. Everything is SI (REP-103).

Encodings in ``common_interfaces`` types (no custom message package):

One stream per accelerometer location (a triaxial accelerometer at one node of the
structure), in two forms, as drivers of high-rate sensors publish:

``accel/<accelerometer>/batch`` -- ``sensor_msgs/PointCloud2``, the full-rate signal
    One message per stepped chunk (``tick_period``, 10 ms): ``header.stamp`` the first
    sample's time, ``header.frame_id`` the accelerometer frame, one row per sample with
    fields ``t`` (s, the sample's time minus ``header.stamp``), ``ax ay az`` (m/s^2) and
    ``wx wy wz`` (rad/s), all float64 (layout: :mod:`impact_damper_sim.recording.batches`);
    a sample a sensor fault dropped has no row, and no Imu message below.
    At 20 kHz that is 100 messages a second of 200 samples, which a Python client reads with
    ``np.frombuffer`` (``batches.rows_of``). Always recorded.

``accel/<accelerometer>`` -- ``sensor_msgs/Imu``, one message per sample of the live rate
    ``imu_rate`` (at most 1 kHz by default): the full-rate signal decimated through a
    linear-phase anti-alias FIR (flat to 0.4 x ``imu_rate``, 80 dB from 0.5 x ``imu_rate``
    on). ``header.stamp`` is the time the sample stands for; it is sent when the filter has
    it, a filter delay later (about 26 ms at 1 kHz, whatever the full rate; none when
    ``imu_rate`` equals ``sample_rate``). ``header.frame_id`` the accelerometer frame.

In both, the acceleration is that of the accelerometer's node along the frame's x, y, z (the
global axes), as an AC-coupled vibration accelerometer reads it (no static 1 g), averaged
over each integrator step and passed through the scene's anti-alias low-pass, plus the
configured noise; the angular velocity is the node's rotational DOF rates. In the Imu,
orientation is not measured: ``orientation_covariance[0] = -1`` (REP-145);
``linear_acceleration_covariance`` is diagonal with the noise variance (all zeros when
noise is off: unknown); ``angular_velocity_covariance`` is all zeros (unknown).

``accel/<accelerometer>/truth`` -- ``sensor_msgs/PointCloud2``, only with ``publish_truth``
    The ground truth of the batch beside it, in its layout, frame and times: ``ax ay az`` the
    model's acceleration (m/s^2, along the model's axes at the node) through the anti-alias
    low-pass and no other stage of the channel (no mounting, resonance, high-pass, noise,
    bias, range or ADC); ``wx wy wz`` as in the batch. With the ideal channel (and no noise)
    it equals the batch. Off by default: a test stand has no such signal.

``rotor/tach`` -- ``sensor_msgs/PointCloud2``, one batch per stepped chunk (rotor scenes)
    The tachometer at the full rate, one row per accelerometer sample time: ``t`` (s, minus
    ``header.stamp``, the first sample's time), ``angle`` (rad) the shaft angle ``phi(t)``
    the unbalance force uses, unwrapped (0 at sim time 0, never decreasing: order tracking
    resamples on it as it is), ``speed`` (rad/s); all float64; ``header.frame_id`` the
    rotor's frame, ``<scene>_rotor``.

``rotor/keyphasor`` -- ``sensor_msgs/PointCloud2``, one batch per stepped chunk (rotor scenes)
    The once-per-revolution reference: one row per time ``phi`` reached ``2 pi k``: ``t``
    (s, minus ``header.stamp``, the start of the interval the batch covers, as for
    ``impacts``), ``revolution`` (uint32, k, 1 first), ``speed`` (rad/s, float64);
    ``header.frame_id`` ``<scene>_rotor``. The unbalance of phase ``p`` points at
    ``phi + p``: at a keyphasor time it is at ``p``.

``impacts`` -- ``sensor_msgs/PointCloud2``, one batch per stepped chunk
    ``header.stamp`` the start of the interval the batch covers (an empty batch says nothing
    hit in it); ``header.frame_id`` the housing's frame. One row per impact: ``t`` (s, the
    impact time, located inside the step, minus ``header.stamp``), ``impactor`` (uint32,
    index of the impactor in ``impactor_state`` order), ``jx jy jz`` (N s, the impulse on
    the impactor: its direction is the contact normal, its length the impulse),
    ``v_approach`` (m/s, normal approach speed before, > 0), ``v_separation`` (m/s, normal
    separation speed after) and ``energy`` (J, the kinetic energy dissipated). Batched because
    impacts come by thousands a second (14,700 at the HPOTP ramp's peak).

``impactor_state`` -- ``sensor_msgs/JointState``, on change and every ``state_period``
    ``name``: ``<impactor>/y`` and ``<impactor>/z`` for planar impactors (the plane's two
    axes, named by their DOFs), ``<impactor>/<dof>`` for one-directional ones.
    ``position`` (m): the impactor's position relative to its housing centre;
    ``velocity`` (m/s): its velocity relative to the housing; ``effort``: 1.0 while the
    impactor is stuck (rides its housing), 0.0 while free, -1.0 on every entry while the
    dampers are off (``dampers_enabled`` false). ``header.frame_id`` the housing's frame.

``rotor/joint_states`` -- ``sensor_msgs/JointState``, every stepped chunk
    The rotor as the continuous joint it is, read by any ROS tool without this page
    (``header.frame_id`` ``<scene>_rotor``):
    ``name`` ``['rotor']``; ``position`` (rad) the shaft angle, wrapped to [0, 2 pi);
    ``velocity`` (rad/s) the applied speed; ``effort`` empty (not modelled).

``rotor/speed`` -- ``geometry_msgs/Vector3Stamped``, every stepped chunk
    ``vector.x`` (rad/s) applied rotor speed; ``vector.y`` (rad/s^2) applied speed rate;
    ``vector.z`` (dimensionless) applied unbalance multiplier X. Kept beside
    ``rotor/joint_states`` because it carries what JointState cannot (the commanded rate and
    the unbalance multiplier, which the rate limit and ``rotor/unbalance_command`` change), in
    one stamped message that ``study report`` reads for its waterfall and that existing logs
    hold.

Why PointCloud2 for batches: no common_interfaces type carries a batch of stamped samples,
a custom message package would not show up in every tool, and LiDAR drivers set the
precedent of a per-point time field ``t`` in a PointCloud2 (bench/stream_formats.py
measures the options).

``rotor/speed_command``, ``rotor/unbalance_command`` -- ``std_msgs/Float64`` subscriptions
    Target speed (rad/s, applied under the scene's rate limit) and multiplier X (>= 0).

``accel/fault_command`` -- ``std_msgs/String`` subscription
    A sensor fault on command (:mod:`impact_damper_sim.live.fault_spec`), YAML or JSON text:
    ``{kind: gain, accelerometer: hpotp_casing_bottom, gain: 20, duration: 0.5 s}`` adds one
    from the next stepped chunk (or its ``onset``), ``{clear: <name>}`` or ``{clear: all}``
    ends it (them). Recorded as received; the schedule's ``fault`` and ``clear_fault`` keys
    are recorded here too. A fault shows in the data (missing samples are missing, a gain
    clips) and in the log's labels, never in ``/diagnostics``.
"""
from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from ..recording import node_topics as _topics
from ..recording.bag_metadata import qos_dict as _qos_dict
from ..recording.node_topics import (  # noqa: F401
    ACCEL_PREFIX,
    BATCH_SUFFIX,
    CLOCK,
    DIAGNOSTICS,
    FAULT_COMMAND,
    IMPACTOR_STATE,
    IMPACTS,
    PARAMETER_EVENTS,
    ROTOR_JOINT_STATES,
    ROTOR_KEYPHASOR,
    ROTOR_SPEED,
    ROTOR_TACH,
    SPEED_COMMAND,
    TRUTH_SUFFIX,
    TYPES,
    UNBALANCE_COMMAND,
    accel_batch_topic,
    accel_topic,
    accel_truth_topic,
)
from ..scene.units import G0  # standard gravity (m/s^2), for reports in g


def _profile(policies):
    """An rclpy ``QoSProfile`` from a ROS-free profile of :mod:`..recording.node_topics`."""
    full = _qos_dict(policies)
    return QoSProfile(history=HistoryPolicy.get_from_short_key(full['history']),
                      depth=full['depth'],
                      reliability=ReliabilityPolicy.get_from_short_key(full['reliability']),
                      durability=DurabilityPolicy.get_from_short_key(full['durability']))


#: The profiles are made from the ROS-free table that ``study record`` writes too, so a log
#: of the node and an offline log carry the same QoS metadata.
#: Accelerometer samples: best effort and volatile like ``qos_profile_sensor_data``; samples
#: are published by their own time (in groups of ``imu_group``), and the depth leaves a
#: slow reader's executor 50 ms (at 2 kHz) before the writer overwrites.
SENSOR_QOS = _profile(_topics.SENSOR_QOS)
#: Batches (full-rate samples, impacts): reliable, volatile, keep last 100 (1 s of 10 ms
#: batches). A reliable writer also feeds best-effort readers; with keep-last it never
#: blocks on a slow one.
BATCH_QOS = _profile(_topics.BATCH_QOS)
#: Impact batches: every impact counts.
EVENT_QOS = BATCH_QOS
#: Impactor state: reliable and transient_local (latched), so late joiners get it.
LATCHED_QOS = _profile(_topics.LATCHED_QOS)
#: Rotor speed and commands: reliable, volatile, small depth.
COMMAND_QOS = _profile(_topics.COMMAND_QOS)
#: /clock as Gazebo publishes it: reliable, keep last 1 (use_sim_time subscribers take
#: best effort, which a reliable publisher feeds).
CLOCK_QOS = _profile(_topics.CLOCK_QOS)
#: /diagnostics: reliable, volatile, keep last 10 (diagnostic_updater publishes with the
#: default QoS, keep last 10, reliable).
DIAGNOSTICS_QOS = COMMAND_QOS
#: /parameter_events as rclpy publishes it (the log records accepted parameter changes).
PARAMETER_EVENTS_QOS = _profile(_topics.PARAMETER_EVENTS_QOS)

#: what the ROS-free core calls a quantity in its messages (``'<quantity>: ...'``) -> how a
#: user of the node sets it: the topic or the parameter
QUANTITY_NAMES = {'speed': SPEED_COMMAND, 'unbalance multiplier': UNBALANCE_COMMAND,
                  'sample rate': "parameter 'sample_rate'",
                  'imu rate': "parameter 'imu_rate'",
                  'speed rate limit': "parameter 'speed_rate_limit'",
                  'noise std': "parameter 'noise_std'",
                  'real-time factor': "parameter 'real_time_factor'"}


def named(text):
    """A core message (``'<quantity>: ...'``, e.g. a ``CommandError``) with the quantity
    named as the node's user sets it (``"parameter 'sample_rate': ..."``,
    ``'rotor/speed_command: ...'``); any other text as it is."""
    quantity, sep, rest = str(text).partition(': ')
    return f'{QUANTITY_NAMES[quantity]}: {rest}' if sep and quantity in QUANTITY_NAMES \
        else str(text)


__all__ = ['ACCEL_PREFIX', 'BATCH_QOS', 'BATCH_SUFFIX', 'CLOCK', 'CLOCK_QOS', 'COMMAND_QOS',
           'DIAGNOSTICS',
           'DIAGNOSTICS_QOS', 'EVENT_QOS', 'FAULT_COMMAND', 'G0', 'IMPACTS', 'IMPACTOR_STATE',
           'LATCHED_QOS',
           'PARAMETER_EVENTS', 'PARAMETER_EVENTS_QOS',
           'ROTOR_JOINT_STATES', 'ROTOR_KEYPHASOR', 'ROTOR_SPEED', 'ROTOR_TACH', 'SENSOR_QOS',
           'SPEED_COMMAND', 'TRUTH_SUFFIX', 'TYPES', 'UNBALANCE_COMMAND', 'accel_batch_topic',
           'QUANTITY_NAMES', 'accel_topic', 'accel_truth_topic', 'named']
