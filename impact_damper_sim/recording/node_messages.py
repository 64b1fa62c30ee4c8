"""The messages of ``vibration_node`` as CDR bytes, without ROS: one packer for node and log.

:class:`NodeMessages` turns what :class:`~impact_damper_sim.live.realtime.LiveSimulation`
steps into serialized messages, each with its sim time (ns) and the stream it belongs to:
per-sample ``sensor_msgs/Imu`` (one NumPy pass per chunk), full-rate, ground-truth, tachometer,
keyphasor and impact batches (``sensor_msgs/PointCloud2``, :mod:`.batches`), ``/clock``,
``rotor/speed``, ``rotor/joint_states`` and ``impactor_state``; and the records of commands
(``std_msgs/Float64``) and accepted parameter changes (``rcl_interfaces/ParameterEvent``).
``vibration_node`` publishes these bytes and records them; ``study record`` writes them to
a log at the speed of the engine. The packing therefore exists once, and the two logs carry
equal bytes for equal simulations.

The CDR written here is canonical little-endian XCDR1 as rosbags writes it (alignment counted
after the 4-byte encapsulation header, pads zero, nothing after the last field), so equal
messages are equal bytes; ``test/test_node_messages.py`` checks every encoder against rclpy's
message classes and :func:`impact_damper_sim.ros.cdr.serialize`. The live simulation and
scene are read by attribute (duck-typed): nothing here imports rclpy or :mod:`..live`.
"""
from __future__ import annotations

import math
import struct
from typing import NamedTuple

import numpy as np

from ..integrate.events import IMPACT
from . import node_topics as nt
from .batches import (
    ACCEL_FIELDS,
    ACCEL_POINT_STEP,
    IMPACT_FIELDS,
    IMPACT_POINT_STEP,
    KEYPHASOR_FIELDS,
    KEYPHASOR_POINT_STEP,
    TACH_FIELDS,
    TACH_POINT_STEP,
    BatchEncoder,
    CdrWriter,
)

_HEADER = b'\x00\x01\x00\x00'   # CDR encapsulation: little-endian
#: rcl_interfaces/ParameterType values
PARAMETER_BOOL, PARAMETER_INTEGER, PARAMETER_DOUBLE, PARAMETER_STRING = 1, 2, 3, 4


def clock_cdr(ns):
    """``rosgraph_msgs/Clock`` bytes for sim time ``ns`` (ns, >= 0)."""
    w = CdrWriter()
    w.stamp(ns)
    return w.bytes()


def float64_cdr(value):
    """``std_msgs/Float64`` bytes of ``value`` (in the unit of the topic)."""
    return _HEADER + struct.pack('<d', float(value))


def string_cdr(text):
    """``std_msgs/String`` bytes of ``text`` (UTF-8)."""
    w = CdrWriter()
    w.string(str(text))
    return w.bytes()


def fault_command_text(key, value):
    """The ``accel/fault_command`` text a schedule's fault key stands for (YAML flow, SI).

    Parameters
    ----------
    key : str
        ``'fault'`` or ``'clear_fault'``.
    value : dict or str
        A fault's plain SI mapping (``FaultSpec.as_dict``; keys without a value are left
        out), or the name of the fault to clear (``'all'``: every one).

    Returns
    -------
    str
        ``{kind: gain, accelerometer: hpotp_casing_bottom, duration: 0.5, axes: xyz, gain:
        20.0}`` or ``{clear: all}``: what a live command would send, read back to the same
        fault by ``parse_command``.
    """
    import yaml
    data = ({'clear': str(value)} if key == 'clear_fault' else
            {k: plain(v) for k, v in value.items() if v is not None})
    return yaml.safe_dump(data, default_flow_style=True, sort_keys=False, width=1 << 16).strip()


def vector3_stamped_cdr(ns, frame_id, vector):
    """``geometry_msgs/Vector3Stamped`` bytes.

    Parameters
    ----------
    ns : int
        ``header.stamp`` (ns, >= 0).
    frame_id : str
        ``header.frame_id``.
    vector : sequence of 3 float
        x, y, z (in the unit the topic states).
    """
    w = CdrWriter()
    w.stamp(ns)
    w.string(frame_id)
    w.put('3d', *(float(v) for v in vector))
    return w.bytes()


def rotor_frame_id(scene_name):
    """The rotor's frame name (``'<scene>_rotor'``): ``rotor/speed`` and ``rotor/joint_states``."""
    return f'{scene_name}_rotor'


def joint_state_cdr(ns, names, position=(), velocity=(), effort=(), frame_id=''):
    """``sensor_msgs/JointState`` bytes.

    Parameters
    ----------
    ns : int
        ``header.stamp`` (ns, >= 0).
    names : sequence of str
        Joint names.
    position, velocity, effort : sequence of float
        Per joint (m or rad, m/s or rad/s, N or N m); empty when not given.
    frame_id : str
        ``header.frame_id``.
    """
    w = CdrWriter()
    w.stamp(ns)
    w.string(frame_id)
    w.strings(list(names))
    w.doubles(position)
    w.doubles(velocity)
    w.doubles(effort)
    return w.bytes()


def parameter_value_type(value):
    """The ``rcl_interfaces/ParameterType`` of a bool, int, float or str value."""
    if isinstance(value, bool):
        return PARAMETER_BOOL
    if isinstance(value, (int, np.integer)):
        return PARAMETER_INTEGER
    if isinstance(value, (float, np.floating)):
        return PARAMETER_DOUBLE
    if isinstance(value, str):
        return PARAMETER_STRING
    raise TypeError(f'parameter value {value!r}: only bool, int, float and str are recorded')


def parameter_event_cdr(ns, node, changed):
    """``rcl_interfaces/ParameterEvent`` bytes: parameters of ``node`` changed at ``ns``.

    Parameters
    ----------
    ns : int
        ``stamp`` (ns, >= 0).
    node : str
        Fully qualified node name (``/vibration_node``).
    changed : sequence of (str, bool or int or float or str)
        ``changed_parameters``: name and new value, in order.
    """
    w = CdrWriter()
    w.stamp(ns)
    w.string(node)
    w.put('I', 0)                       # new_parameters
    w.put('I', len(changed))            # changed_parameters
    for name, value in changed:
        kind = parameter_value_type(value)
        w.string(name)
        w.put('B', kind)
        w.put('?', kind == PARAMETER_BOOL and bool(value))
        w.put('q', int(value) if kind == PARAMETER_INTEGER else 0)
        w.put('d', float(value) if kind == PARAMETER_DOUBLE else 0.0)
        w.string(value if kind == PARAMETER_STRING else '')
        for _ in range(5):              # the five array values: empty
            w.put('I', 0)
    w.put('I', 0)                       # deleted_parameters
    return w.bytes()


class ImuEncoder:
    """Writes chunks of ``sensor_msgs/Imu`` that differ only in stamp and readings.

    Every other field is fixed: the frame, orientation unknown (``orientation_covariance[0]
    = -1``, REP-145; the quaternion rclpy's default, w = 1), ``angular_velocity_covariance``
    zero (unknown) and ``linear_acceleration_covariance`` diagonal with the noise variance.

    Parameters
    ----------
    frame_id : str
        ``header.frame_id``.
    noise_variance : float
        Diagonal of ``linear_acceleration_covariance`` ((m/s^2)^2; 0 = unknown).
    """

    def __init__(self, frame_id, noise_variance=0.0):
        var = float(noise_variance)
        w = CdrWriter()
        w.stamp(0)
        w.string(frame_id)
        w.put('4d', 0.0, 0.0, 0.0, 1.0)                 # orientation (not measured)
        w.put('9d', -1.0, *[0.0] * 8)                   # orientation_covariance
        angular_at = w.size
        w.put('3d', 0.0, 0.0, 0.0)                      # angular_velocity
        w.put('9d', *[0.0] * 9)                         # angular_velocity_covariance
        linear_at = w.size
        w.put('3d', 0.0, 0.0, 0.0)                      # linear_acceleration
        w.put('9d', var, 0.0, 0.0, 0.0, var, 0.0, 0.0, 0.0, var)
        raw = w.bytes()
        head = len(_HEADER)
        self.size = len(raw)
        self.dtype = np.dtype({'names': ['sec', 'nsec', 'lin', 'ang'],
                               'formats': ['<i4', '<u4', ('<f8', 3), ('<f8', 3)],
                               'offsets': [head, head + 4, head + linear_at, head + angular_at],
                               'itemsize': self.size})
        self._template = np.frombuffer(raw, np.uint8).copy()

    def pack(self, t_ns, linear_acceleration, angular_velocity):
        """Serialized messages (list of bytes), one per row.

        Parameters
        ----------
        t_ns : ndarray of int, shape (k,)
            Stamps (ns, >= 0).
        linear_acceleration : ndarray, shape (k, 3)
            Readings (m/s^2).
        angular_velocity : ndarray, shape (k, 3)
            Readings (rad/s).
        """
        k = len(t_ns)
        buf = np.empty(k, self.dtype)
        buf.view(np.uint8).reshape(k, self.size)[:] = self._template
        buf['sec'], buf['nsec'] = np.divmod(np.asarray(t_ns, np.int64), 1_000_000_000)
        buf['lin'] = linear_acceleration
        buf['ang'] = angular_velocity
        raw = buf.tobytes()
        n = self.size
        return [raw[i:i + n] for i in range(0, k * n, n)]


class Stream(NamedTuple):
    """One topic the node writes: fully qualified name, ROS type and QoS (a dict)."""

    topic: str
    type_name: str
    qos: dict


class NodeMessages:
    """The node's topics and the bytes a stepped simulation puts on them.

    Parameters
    ----------
    live : LiveSimulation
        The simulation (read: ``accelerometers``, ``imu_delay``, ``imu_noise_variances()``, ``t``,
        ``has_rotor``, ``rotor_state()``, ``profile``, ``impactor_states()``,
        ``dampers_enabled``).
    scene : SceneModel
        Its scene (``name``, ``impactors``, ``scene['impactors']``).
    namespace : str
        Namespace of the relative topic names (``/`` or ``/rig``).
    node_name : str
        Fully qualified node name, for ``/parameter_events``.
    publish_clock : bool
        Whether ``/clock`` is one of the streams.
    truth : bool
        Whether each accelerometer's ground truth ``accel/<name>/truth`` is one of the
        streams (the node's ``publish_truth``, ``study record --truth``).

    Attributes
    ----------
    streams : list of Stream
        Every topic, indexed by the stream numbers below and in the items.
    imu, batch, truth : list of int
        Per accelerometer, the stream of its ``accel/<name>``, ``accel/<name>/batch`` and
        ``accel/<name>/truth`` (``truth`` empty when off).
    impacts, state, speed, joint, tach, keyphasor, clock, speed_command, unbalance_command,
    parameter_events, fault_command
        Stream numbers (``clock`` None without ``/clock``; ``tach`` and ``keyphasor`` None
        without a rotor). ``parameter_events`` and ``fault_command`` are in a log only
        once something is written to them.
    """

    def __init__(self, live, scene, *, namespace='/', node_name='/vibration_node',
                 publish_clock=True, truth=False):
        self.live = live
        self.scene = scene
        self.node_name = node_name
        self.streams = []

        def add(topic, qos, type_name=None):
            if type_name is None:
                type_name = nt.TYPES[nt.ACCEL_PREFIX if topic.startswith(nt.ACCEL_PREFIX)
                                     and not topic.endswith(nt.BATCH_SUFFIX) else
                                     nt.BATCH_SUFFIX if topic.endswith(nt.BATCH_SUFFIX)
                                     else topic]
            self.streams.append(Stream(nt.qualified(topic, namespace), type_name, qos))
            return len(self.streams) - 1

        self.imu, self.batch, self.truth = [], [], []
        self._batch_encoders = []
        for acc in live.accelerometers:
            self.imu.append(add(nt.accel_topic(acc.name), nt.SENSOR_QOS))
            self.batch.append(add(nt.accel_batch_topic(acc.name), nt.BATCH_QOS))
            if truth:   # the same layout and frame as the batch: one encoder for both
                self.truth.append(add(nt.accel_truth_topic(acc.name), nt.BATCH_QOS,
                                      nt.TYPES[nt.TRUTH_SUFFIX]))
            self._batch_encoders.append(BatchEncoder(acc.frame_id, ACCEL_FIELDS,
                                                     ACCEL_POINT_STEP))
        self.impacts = add(nt.IMPACTS, nt.EVENT_QOS)
        self.state = add(nt.IMPACTOR_STATE, nt.LATCHED_QOS)
        self.speed = add(nt.ROTOR_SPEED, nt.COMMAND_QOS)
        self.joint = add(nt.ROTOR_JOINT_STATES, nt.COMMAND_QOS)
        self.tach = self.keyphasor = None
        if live.has_rotor:
            self.tach = add(nt.ROTOR_TACH, nt.BATCH_QOS)
            self.keyphasor = add(nt.ROTOR_KEYPHASOR, nt.EVENT_QOS)
            # angles about the rotor axis: the rotor's frame
            self._tach_encoder = BatchEncoder(rotor_frame_id(scene.name), TACH_FIELDS,
                                              TACH_POINT_STEP)
            self._keyphasor_encoder = BatchEncoder(rotor_frame_id(scene.name),
                                                   KEYPHASOR_FIELDS, KEYPHASOR_POINT_STEP)
        self.clock = add(nt.CLOCK, nt.CLOCK_QOS) if publish_clock else None
        self.speed_command = add(nt.SPEED_COMMAND, nt.COMMAND_QOS)
        self.unbalance_command = add(nt.UNBALANCE_COMMAND, nt.COMMAND_QOS)
        self.parameter_events = add(nt.PARAMETER_EVENTS, nt.PARAMETER_EVENTS_QOS)
        self.fault_command = add(nt.FAULT_COMMAND, nt.COMMAND_QOS, nt.STRING)
        self.set_noise_variances(live.imu_noise_variances())
        # per modal-model impactor (a zero-mass scene entry has none), matched by name
        spec_of = {spec['name']: spec for spec in scene.scene['impactors']}
        specs = [spec_of[imp.name] for imp in scene.impactors]
        dofs_of = [[spec['dof']] if spec['kind'] == 'sdof' else list(spec['plane'])
                   for spec in specs]
        axis_of = {'ux': 0, 'uy': 1, 'uz': 2}
        self.impactor_axes = [[axis_of[d] for d in dofs] for dofs in dofs_of]
        # per impactor, the frame axis of each normal component; 3 (a dropped column) where
        # a one-directional impactor has no second one
        self._axis_table = np.full((max(1, len(dofs_of)), 2), 3, np.int64)
        for j, axes in enumerate(self.impactor_axes):
            self._axis_table[j, :len(axes)] = axes
        self.joint_names = [f"{spec['name']}/{d}" for spec, dofs in zip(specs, dofs_of)
                            for d in dofs]
        # the housings' frame; with housings at several nodes, the scene's (axes are global)
        housings = sorted({spec['node'] for spec in specs})
        impact_frame = (self._frame_of_node(housings[0]) if len(housings) == 1
                        else scene.name)
        self._impact_encoder = BatchEncoder(impact_frame, IMPACT_FIELDS, IMPACT_POINT_STEP)
        #: ``header.frame_id`` of ``impactor_state``: positions are relative to the housing
        self.impactor_frame = impact_frame
        #: ``header.frame_id`` of ``rotor/speed`` and ``rotor/joint_states``: the rotor's
        #: frame, named after the scene as the accelerometer frames are (``hpotp_rotor``)
        self.rotor_frame = rotor_frame_id(scene.name)
        # the start of the interval the next impact batch covers (ns)
        self.impacts_from = int(round(live.t * 1e9))

    def _frame_of_node(self, node):
        for acc in self.live.accelerometers:
            if acc.node == node:
                return acc.frame_id
        return f'{self.scene.name}_node{node}'

    def set_noise_variances(self, variances):
        """Write each accelerometer's noise variance ((m/s^2)^2, one per accelerometer, as
        :meth:`LiveSimulation.imu_noise_variances` gives them) into its Imu covariance from
        now on."""
        self._imu_encoders = [ImuEncoder(acc.frame_id, variance)
                              for acc, variance in zip(self.live.accelerometers, variances)]

    # -- what a chunk produces -------------------------------------------------------------
    def batch_items(self, batch):
        """The messages of a stepped chunk, in the order of their send times.

        Per accelerometer one full-rate batch (sent at its last sample's time), its ground
        truth batch when on (sent with it), and the decimated samples one by one (each sent
        when the filter has it, a filter delay after its stamp); the chunk's impacts, then
        with a rotor its tachometer and keyphasor batches, each as one batch (sent at the
        chunk's end).

        A sample a sensor fault lost (``batch.valid``, ``batch.imu_valid`` False) is missing:
        its row is left out of the accelerometer's batch (the rows keep their own times
        ``t`` after ``header.stamp``, which stays the chunk's first sample time, so a reader
        sees the gap; a chunk with every sample lost is an empty batch) and its Imu message
        is not sent. The ground truth keeps every row. With every sample there the bytes
        are those of a run without faults.

        Parameters
        ----------
        batch : Batch
            What ``live.step`` returned (the simulation is at the chunk's end).

        Returns
        -------
        list of (int, int, bytes)
            Send time (sim ns), stream, CDR bytes; sorted by send time, then accelerometer.
        """
        live = self.live
        delay_ns = int(round(live.imu_delay * 1e9))
        imu_ns = np.rint(batch.imu_t * 1e9).astype(np.int64)
        items = []
        for a, encoder in enumerate(self._imu_encoders):
            keep = _present(batch.imu_valid, a)
            if keep is None:
                data = encoder.pack(imu_ns, batch.imu_linear_acceleration[:, a, :],
                                    batch.imu_angular_velocity[:, a, :])
                sent = imu_ns
            else:   # the samples a fault lost are not sent
                sent = imu_ns[keep]
                data = encoder.pack(sent, batch.imu_linear_acceleration[keep, a, :],
                                    batch.imu_angular_velocity[keep, a, :])
            stream = self.imu[a]
            items += [(ns + delay_ns, a, stream, d) for ns, d in zip(sent.tolist(), data)]
        t_ns = np.rint(batch.t * 1e9).astype(np.int64)
        if t_ns.size:
            for a, encoder in enumerate(self._batch_encoders):
                rows = np.empty(t_ns.size, encoder.dtype)
                rows['t'] = (t_ns - t_ns[0]) * 1e-9
                for name, column in zip(('ax', 'ay', 'az'), batch.linear_acceleration[:, a].T):
                    rows[name] = column
                for name, column in zip(('wx', 'wy', 'wz'), batch.angular_velocity[:, a].T):
                    rows[name] = column
                keep = _present(batch.valid, a)
                items.append((int(t_ns[-1]), a, self.batch[a], encoder.encode(
                    t_ns[0], rows if keep is None else rows[keep])))
                if self.truth:   # the same rows with the model's acceleration
                    for name, column in zip(('ax', 'ay', 'az'), batch.truth[:, a].T):
                        rows[name] = column
                    items.append((int(t_ns[-1]), a, self.truth[a],
                                  encoder.encode(t_ns[0], rows)))
        end_ns = int(round(live.t * 1e9))
        if self.scene.impactors:
            ev = batch.events
            items.append((end_ns, len(self.imu), self.impacts,
                          self._impact_batch(ev[ev['kind'] == IMPACT])))
        if self.tach is not None:
            items += self._tach_items(batch, t_ns, end_ns)
        self.impacts_from = end_ns
        items.sort(key=lambda item: item[:2])   # by send time, then accelerometer
        return [(ns, stream, data) for ns, _, stream, data in items]

    def _tach_items(self, batch, t_ns, end_ns):
        """The tachometer batch (the angle and speed at every full-rate sample) and the
        keyphasor batch (the turns completed in the chunk's interval, which the impact batch
        covers too) of a stepped chunk, both sent at its end: list of items."""
        items = []
        order = len(self.imu)   # after the impacts at the same time
        if t_ns.size:
            rows = np.empty(t_ns.size, self._tach_encoder.dtype)
            rows['t'] = (t_ns - t_ns[0]) * 1e-9
            rows['angle'], rows['speed'] = batch.shaft_angle, batch.shaft_speed
            items.append((end_ns, order, self.tach, self._tach_encoder.encode(t_ns[0], rows)))
        events = batch.keyphasor
        rows = np.empty(events.size, self._keyphasor_encoder.dtype)
        # the exact crossing time, relative to the interval's start (ns) in float64 (s)
        rows['t'] = np.maximum(events['t'] - self.impacts_from * 1e-9, 0.0)
        rows['revolution'] = events['revolution']
        rows['speed'] = events['speed']
        items.append((end_ns, order, self.keyphasor,
                      self._keyphasor_encoder.encode(self.impacts_from, rows)))
        return items

    def _impact_batch(self, impacts):
        """The CDR bytes of the impact batch covering the chunk just stepped."""
        encoder = self._impact_encoder
        rows = np.zeros(impacts.size, encoder.dtype)
        if impacts.size:
            t_ns = np.rint(impacts['t'] * 1e9).astype(np.int64)
            rows['t'] = (t_ns - self.impacts_from) * 1e-9
            which = impacts['impactor'].astype(np.int64)
            rows['impactor'] = which
            # plane DOFs -> x, y, z of the frame, in one scatter per DOF of the plane
            impulse = np.zeros((impacts.size, 4))   # column 3 takes a DOF a plane lacks
            axes = self._axis_table[which]
            index = np.arange(impacts.size)
            for k in range(axes.shape[1]):
                impulse[index, axes[:, k]] = impacts['impulse'] * impacts['normal'][:, k]
            rows['jx'], rows['jy'], rows['jz'] = impulse[:, :3].T
            rows['v_approach'] = np.abs(impacts['v_n'])
            rows['v_separation'] = np.abs(impacts['v_n_after'])
            rows['energy'] = impacts['loss']
            order = np.argsort(t_ns, kind='stable')
            rows = rows[order]
        return encoder.encode(self.impacts_from, rows)

    def time_items(self):
        """``/clock``, ``rotor/speed`` and ``rotor/joint_states`` now: list of (ns, stream,
        bytes) (only ``/clock`` without a rotor)."""
        live = self.live
        ns = int(round(live.t * 1e9))
        items = []
        if self.clock is not None:
            items.append((ns, self.clock, clock_cdr(ns)))
        if live.has_rotor:
            speed, rate, x = live.rotor_state()
            items.append((ns, self.speed, vector3_stamped_cdr(ns, self.rotor_frame,
                                                              (speed, rate, x))))
            angle = float(live.profile.angle(np.asarray(live.t))) % (2.0 * math.pi)
            items.append((ns, self.joint, joint_state_cdr(ns, ['rotor'], [angle], [speed],
                                                          frame_id=self.rotor_frame)))
        return items

    def state_message(self):
        """``impactor_state`` now (bytes): positions (m), velocities (m/s), stuck flags
        (effort 1 stuck, 0 free, -1 dampers off)."""
        live = self.live
        pos, vel, eff = [], [], []
        enabled = live.dampers_enabled
        for s in live.impactor_states():
            d = len(s['position'])
            pos += [float(x) for x in s['position']]
            vel += [float(x) for x in s['velocity']]
            eff += [(1.0 if s['stuck'] else 0.0) if enabled else -1.0] * d
        return joint_state_cdr(int(round(live.t * 1e9)), self.joint_names, pos, vel, eff,
                               frame_id=self.impactor_frame)

    def parameter_event(self, changed):
        """``/parameter_events`` bytes for parameters of this node changed now.

        Parameters
        ----------
        changed : sequence of (str, value)
            Name and new value of each parameter.
        """
        return parameter_event_cdr(int(round(self.live.t * 1e9)), self.node_name, changed)


def _present(valid, a):
    """The mask of accelerometer ``a``'s samples that are there (ndarray of bool), or None
    when every one is (or no mask is given): the fast path, the bytes of a run without
    faults."""
    if valid is None:
        return None
    keep = valid[:, a]
    return None if keep.all() else keep


def published_samples(batch):
    """Full-rate sample times of a stepped chunk published on at least one accelerometer's
    batch (dimensionless): the chunk's samples less those every accelerometer lost to a
    sensor fault (all of them without a mask or an accelerometer)."""
    valid = batch.valid
    if valid is None or valid.shape[1] == 0 or valid.all():
        return int(batch.t.size)
    return int(np.count_nonzero(valid.any(axis=1)))


def run_labels(live, scene_model):
    """What a detector is scored against, as plain data: the run's labels at sim time now.

    Parameters
    ----------
    live : LiveSimulation
        The simulation (read: ``t``, ``noise_seed``, ``noise_std``, ``dampers_enabled``,
        ``unbalance``, ``profile``, ``accelerometers``, ``channels``).
    scene_model : SceneModel
        Its scene (``scene['structure']``: the cross-couplings).

    Returns
    -------
    dict
        ``sim_time_s`` (when these values hold: the log's start; a later change is in the
        log as the command or parameter change it was), ``seed`` (the noise seed, which
        seeds every random stage of the channels), ``noise_std`` (m/s^2),
        ``dampers_enabled``, ``unbalance_multiplier`` (X, None without unbalance),
        ``rotor_speed_rad_s`` (None without a rotor), ``kcc_n_per_m`` (the scene's
        cross-coupled stiffness, summed over its cross-couplings; 0 without) with
        ``cross_couplings`` (each: node, kcc N/m, dofs), ``accelerometers``: per
        accelerometer its node, frame and ``channel`` (the preset and every stage's values,
        :meth:`~impact_damper_sim.live.channel.SensorChannel.labels`), and ``faults``: the
        sensor faults added so far (``FaultInjector.labels``: kind, values, seed, window);
        those added later, and what every fault did, are in :func:`fault_metadata`, written
        when the log closes. Every value SI.
    """
    structure = scene_model.scene.get('structure') or {}
    couplings = [{'node': c['node'], 'kcc': c['kcc'], 'dofs': list(c['dofs'])}
                 for c in structure.get('cross_couplings') or ()]
    return plain({
        'sim_time_s': float(live.t),
        'seed': int(live.noise_seed),
        'noise_std': float(live.noise_std),
        'dampers_enabled': bool(live.dampers_enabled),
        'unbalance_multiplier': (None if live.unbalance is None
                                 else float(live.unbalance.multiplier)),
        'rotor_speed_rad_s': (None if live.profile is None
                              else float(live.profile.speed(np.asarray(live.t)))),
        'kcc_n_per_m': float(sum(c['kcc'] for c in couplings)),
        'cross_couplings': couplings,
        'accelerometers': {acc.name: {'node': acc.node, 'frame_id': acc.frame_id,
                                      'channel': channel.labels()}
                           for acc, channel in zip(live.accelerometers, live.channels)},
        'faults': live.faults.labels(),
    })


#: name of the metadata record with the run's sensor faults, written when a log closes
FAULTS_METADATA = 'impact_damper_sim_faults'


def fault_metadata(live):
    """The :data:`FAULTS_METADATA` record: every sensor fault of the run and what it did.

    Written when the log closes (``study record`` at its end, the node when recording
    stops): faults come on command after the log opened, so the opening ``labels`` cannot
    hold them. The node's ``/diagnostics`` never mention faults (a real sensor does not
    report its own); this record does.

    Parameters
    ----------
    live : LiveSimulation
        The simulation (read: ``t``, ``faults``).

    Returns
    -------
    dict of str to str
        ``sim_time_s`` (how far the run went) and ``faults``: YAML of
        ``FaultInjector.labels()``, one entry per fault in the order added: ``name``,
        ``kind``, ``accelerometer``, ``axes``, ``stage``, ``seed``, ``parameters`` (SI),
        ``requested`` onset and duration, the actual window ``onset_s`` < t <= ``end_s``
        (None: until the end of the run), ``cleared_at_s``, ``samples`` in the window,
        and ``events`` (spike times, open periods).
    """
    import yaml
    return {'sim_time_s': repr(float(live.t)),
            'faults': yaml.safe_dump(plain(live.faults.labels()), sort_keys=False)}


def run_metadata(scene_model, overrides, parameters, node_name, live=None):
    """The ``impact_damper_sim`` metadata record that opens the node's logs (str to str).

    Parameters
    ----------
    scene_model : SceneModel
        The scene run (``name``, ``source``, ``scene``: its resolved SI tree).
    overrides : sequence of str
        The ``key=value`` scene overrides.
    parameters : dict
        The node's parameters (or ``study record``'s equivalents), as YAML-safe values.
    node_name : str
        Fully qualified node name.
    live : LiveSimulation, optional
        The simulation about to be logged: its :func:`run_labels` are the ``labels`` entry.

    Returns
    -------
    dict of str to str
        Software version, scene, overrides, the resolved scene in SI, the parameters, the
        node name, the time base and (with ``live``) ``labels`` (YAML); nothing that changes
        from run to run.
    """
    import yaml

    import impact_damper_sim
    labels = {} if live is None else {
        'labels': yaml.safe_dump(run_labels(live, scene_model), sort_keys=False)}
    return {
        'software_version': impact_damper_sim.__version__,
        'scene': scene_model.name, 'scene_source': str(scene_model.source),
        'overrides': yaml.safe_dump(list(overrides or ()), default_flow_style=True).strip(),
        'resolved_scene_si': yaml.safe_dump(plain(scene_model.scene), sort_keys=False),
        'node_parameters': yaml.safe_dump(plain(dict(parameters)), sort_keys=True),
        'node_name': node_name,
        'time_base': 'sim time (log_time = publish_time = sim time of the publish call)',
        **labels,
    }


def plain(value):
    """A value as plain YAML-safe data (tuples to lists, NumPy to Python)."""
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return plain(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    return value


__all__ = ['FAULTS_METADATA', 'ImuEncoder', 'NodeMessages', 'PARAMETER_BOOL',
           'PARAMETER_DOUBLE', 'PARAMETER_INTEGER', 'PARAMETER_STRING', 'Stream', 'clock_cdr',
           'fault_command_text', 'fault_metadata', 'float64_cdr', 'joint_state_cdr',
           'parameter_event_cdr', 'parameter_value_type', 'plain', 'published_samples',
           'rotor_frame_id', 'run_labels', 'run_metadata', 'string_cdr',
           'vector3_stamped_cdr']
