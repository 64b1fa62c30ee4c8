"""The streams of ``vibration_node`` and the CDR bytes a stepped simulation puts on them.

:class:`NodeMessages` turns what :class:`~impact_damper_sim.live.realtime.LiveSimulation`
steps into serialized messages, each with its sim time (ns) and the stream it belongs to:
per-sample ``sensor_msgs/Imu``, full-rate, ground-truth, tachometer, keyphasor and impact
batches (``sensor_msgs/PointCloud2``, :mod:`.batches`), ``/clock``, ``rotor/speed``,
``rotor/joint_states`` and ``impactor_state``; and the streams of the records of commands
(``std_msgs/Float64``) and accepted parameter changes (``rcl_interfaces/ParameterEvent``).
``vibration_node`` publishes these bytes and records them; ``study record`` writes them to
a log at the speed of the engine. The packing therefore exists once, and the two logs carry
equal bytes for equal simulations. The single messages' CDR is :mod:`.message_cdr`, the
log's metadata records :mod:`.log_metadata`.

The live simulation and scene are read by attribute (duck-typed): nothing here imports rclpy
or :mod:`..live`.
"""
from __future__ import annotations

import math
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
)
from .message_cdr import (
    ImuEncoder,
    JointStateEncoder,
    clock_cdr,
    joint_state_cdr,
    parameter_event_cdr,
    vector3_stamped_cdr,
)


def rotor_frame_id(scene_name):
    """The rotor's frame name (``'<scene>_rotor'``): ``rotor/speed`` and ``rotor/joint_states``."""
    return f'{scene_name}_rotor'


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
        self._state_encoder = JointStateEncoder(self.joint_names, impact_frame)
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
        position, velocity, stuck = live.impactor_state_arrays()
        effort = np.where(stuck, 1.0, 0.0) if live.dampers_enabled else np.full(stuck.size, -1.0)
        return self._state_encoder.pack(int(round(live.t * 1e9)), position, velocity, effort)

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


__all__ = ['NodeMessages', 'Stream', 'published_samples', 'rotor_frame_id']
