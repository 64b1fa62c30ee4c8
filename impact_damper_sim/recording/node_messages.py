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
import operator
from typing import NamedTuple

import numpy as np

from ..integrate.events import IMPACT, empty_events
from ..integrate.kernels.impact_rows import impact_rows
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
    Vector3StampedEncoder,
    clock_cdr,
    parameter_event_cdr,
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
            self._speed_encoder = Vector3StampedEncoder(rotor_frame_id(scene.name))
            self._joint_encoder = JointStateEncoder(['rotor'], rotor_frame_id(scene.name),
                                                    effort=False)
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
        # per normal component, each impactor's impulse column in an impact row: 2 + its
        # frame axis (jx jy jz), 5 (v_approach, written after) where a one-directional
        # impactor has no second one
        table = np.full((2, max(1, len(dofs_of))), 5, np.int64)
        for j, axes in enumerate(self.impactor_axes):
            table[:len(axes), j] = [2 + axis for axis in axes]
        self._impulse_columns = table
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
        if scene.impactors:   # the kernel loaded (or compiled) now, not in a paced chunk:
            for m in (1, 2):   # for both layouts (NumPy calls a field view of one event contiguous)
                self._impact_batch(empty_events(m))

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
        n_acc = len(self.imu)
        items = []
        if batch.imu_t.size:
            delay_ns = int(round(live.imu_delay * 1e9))
            imu_ns = np.rint(batch.imu_t * 1e9).astype(np.int64)
            send_ns = (imu_ns + delay_ns).tolist()
            lin, ang = batch.imu_linear_acceleration, batch.imu_angular_velocity
            for a, keep in enumerate(_present_each(batch.imu_valid, n_acc)):
                imu_encoder, stream = self._imu_encoders[a], self.imu[a]
                if keep is None:
                    data = imu_encoder.pack(imu_ns, lin[:, a], ang[:, a])
                    items += [(ns, a, stream, d) for ns, d in zip(send_ns, data)]
                else:   # the samples a fault lost are not sent
                    data = imu_encoder.pack(imu_ns[keep], lin[keep, a], ang[keep, a])
                    sent = (imu_ns[keep] + delay_ns).tolist()
                    items += [(ns, a, stream, d) for ns, d in zip(sent, data)]
        t_ns = np.rint(batch.t * 1e9).astype(np.int64)
        k = t_ns.size
        if k:
            first, last = int(t_ns[0]), int(t_ns[-1])
            t_rel = (t_ns - t_ns[0]) * 1e-9   # each row's t (s) after the stamp
        if k and n_acc:
            # every accelerometer's rows at once: t, ax ay az, wx wy wz (seven float64, no
            # gaps, so every byte is written)
            rows = np.empty((n_acc, k, 7))
            rows[:, :, 0] = t_rel
            rows[:, :, 1:4] = batch.linear_acceleration.transpose(1, 0, 2)
            rows[:, :, 4:7] = batch.angular_velocity.transpose(1, 0, 2)
            for a, keep in enumerate(_present_each(batch.valid, n_acc)):
                encoder = self._batch_encoders[a]
                mine = rows[a] if keep is None else rows[a, keep]
                items.append((last, a, self.batch[a],
                              encoder.encode_data(first, len(mine), mine.tobytes())))
            if self.truth:   # the same rows with the model's acceleration
                rows[:, :, 1:4] = batch.truth.transpose(1, 0, 2)
                for a, encoder in enumerate(self._batch_encoders):
                    items.append((last, a, self.truth[a],
                                  encoder.encode_data(first, k, rows[a].tobytes())))
        end_ns = int(round(live.t * 1e9))
        if self.scene.impactors:
            items.append((end_ns, n_acc, self.impacts, self._impact_batch(batch.events)))
        if self.tach is not None:
            # the tachometer (angle and speed at every full-rate sample) and the keyphasor
            # (the turns completed in the interval the impact batch covers), after it
            if k:
                tach = np.empty((k, 3))   # t, angle, speed: no gaps
                tach[:, 0] = t_rel
                tach[:, 1] = batch.shaft_angle
                tach[:, 2] = batch.shaft_speed
                items.append((end_ns, n_acc, self.tach,
                              self._tach_encoder.encode_data(first, k, tach.tobytes())))
            items.append((end_ns, n_acc, self.keyphasor, self._keyphasor_batch(batch.keyphasor)))
        self.impacts_from = end_ns
        items.sort(key=_SEND_ORDER)   # by send time, then accelerometer (stable)
        return [(ns, stream, data) for ns, _, stream, data in items]

    def _keyphasor_batch(self, events):
        """The CDR bytes of the keyphasor batch: the turns completed in the chunk just
        stepped (the interval the impact batch covers too)."""
        encoder = self._keyphasor_encoder
        n = events.size
        if not n:
            return encoder.encode_data(self.impacts_from, 0, b'')
        # a row is t (float64), revolution (uint32 and 4 zero bytes), speed (float64)
        rows = np.zeros((n, 3), '<f8')
        # the exact crossing time, relative to the interval's start (ns) in float64 (s)
        rows[:, 0] = np.maximum(events['t'] - self.impacts_from * 1e-9, 0.0)
        rows.view('<u4')[:, 2] = events['revolution']
        rows[:, 2] = events['speed']
        return encoder.encode_data(self.impacts_from, n, rows.tobytes())

    def _impact_batch(self, events):
        """The CDR bytes of the impact batch covering the chunk just stepped: the impacts
        among its ``events``, in time order (one compiled call,
        :func:`~impact_damper_sim.integrate.kernels.impact_rows.impact_rows`)."""
        m = events.size
        # a row is t, impactor (uint32 and 4 zero bytes), jx jy jz, v_approach,
        # v_separation, energy: eight 8-byte slots, zeros where nothing is written
        rows = np.zeros((m, 8), '<f8')
        n = impact_rows(events['t'], events['kind'], events['impactor'], events['impulse'],
                        events['normal'], events['v_n'], events['v_n_after'], events['loss'],
                        IMPACT, self.impacts_from, self._impulse_columns,
                        np.empty(m, np.int64), rows, rows.view('<u4'))
        return self._impact_encoder.encode_data(self.impacts_from, n, rows[:n].tobytes())

    def time_items(self):
        """``/clock``, ``rotor/speed`` and ``rotor/joint_states`` now: list of (ns, stream,
        bytes) (only ``/clock`` without a rotor)."""
        live = self.live
        t = live.t
        ns = int(round(t * 1e9))
        items = []
        if self.clock is not None:
            items.append((ns, self.clock, clock_cdr(ns)))
        if live.has_rotor:
            speed, rate, x = live.rotor_state()
            items.append((ns, self.speed, self._speed_encoder.pack(ns, speed, rate, x)))
            angle = float(live.profile.angle(t)) % (2.0 * math.pi)
            items.append((ns, self.joint, self._joint_encoder.pack(ns, (angle,), (speed,))))
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


def _present_each(valid, n_acc):
    """Per accelerometer, the mask of its samples that are there (ndarray of bool), or None
    when every one is (or no mask is given): the fast path, the bytes of a run without
    faults."""
    # count_nonzero: a fraction of the cost of all()'s reduction on these small masks
    if valid is None or np.count_nonzero(valid) == valid.size:
        return [None] * n_acc
    return [None if np.count_nonzero(keep) == keep.size else keep for keep in valid.T]


_SEND_ORDER = operator.itemgetter(0, 1)


def published_samples(batch):
    """Full-rate sample times of a stepped chunk published on at least one accelerometer's
    batch (dimensionless): the chunk's samples less those every accelerometer lost to a
    sensor fault (all of them without a mask or an accelerometer)."""
    valid = batch.valid
    if valid is None or valid.shape[1] == 0 or valid.all():
        return int(batch.t.size)
    return int(np.count_nonzero(valid.any(axis=1)))


__all__ = ['NodeMessages', 'Stream', 'published_samples', 'rotor_frame_id']
