"""The publisher set of ``vibration_node``: its outlets, and what a stepped chunk queues.

:class:`Publishers` makes one :class:`~.outlets.Outlet` per published topic and turns what
:class:`~impact_damper_sim.live.realtime.LiveSimulation` steps into queued items of the
node's :class:`~impact_damper_sim.live.pacing.Outbox` (per-sample ``Imu``, full-rate and
impact batches, ``/clock``, rotor speed and joint state, ``impactor_state``), counting what
it holds. The bytes come from :class:`~impact_damper_sim.recording.node_messages.
NodeMessages`, ROS-free, which ``study record`` packs its offline logs with too; when each
item leaves is the outbox's rule, not this module's.
"""
from __future__ import annotations

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Vector3Stamped
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, JointState, PointCloud2

from ..recording.node_messages import published_samples
from . import interface as itf
from .outlets import Outlet

_IMPACT = 0   # EVENT_KINDS index of an impact


class Publishers:
    """Every publisher of the node, and the queueing of what it steps.

    Parameters
    ----------
    node : rclpy.node.Node
        Creates the publishers.
    messages : NodeMessages
        Packs each stream's bytes.
    outbox : Outbox
        Where queued items wait for their time.
    counters : Counters
        Its ``stats`` (this period) and ``stats_total`` count what is queued.
    record : callable
        ``record(topic, type_name, qos, data, ns)``: every published message's bytes.
    publish_clock : bool
        Publish ``/clock``.
    """

    def __init__(self, node, messages, outbox, counters, record, *, publish_clock):
        self.messages, self.outbox, self.counters = messages, outbox, counters
        live = messages.live
        self.live = live

        def outlet(msg_type, topic, qos):
            return Outlet(node, msg_type, topic, qos, record)
        self.accel = [outlet(Imu, itf.accel_topic(acc.name), itf.SENSOR_QOS)
                      for acc in live.accelerometers]   # per-sample, imu_rate
        self.batch = [outlet(PointCloud2, itf.accel_batch_topic(acc.name), itf.BATCH_QOS)
                      for acc in live.accelerometers]   # full-rate batches
        self.truth = [outlet(PointCloud2, itf.accel_truth_topic(acc.name), itf.BATCH_QOS)
                      for acc in live.accelerometers] if messages.truth else []
        self.impacts = outlet(PointCloud2, itf.IMPACTS, itf.EVENT_QOS)
        self.state = outlet(JointState, itf.IMPACTOR_STATE, itf.LATCHED_QOS)
        self.speed = outlet(Vector3Stamped, itf.ROTOR_SPEED, itf.COMMAND_QOS)
        self.joint = outlet(JointState, itf.ROTOR_JOINT_STATES, itf.COMMAND_QOS)
        # the tachometer and keyphasor: scenes with a rotor only
        self.tach = [] if messages.tach is None else [
            outlet(PointCloud2, itf.ROTOR_TACH, itf.BATCH_QOS),
            outlet(PointCloud2, itf.ROTOR_KEYPHASOR, itf.EVENT_QOS)]
        self.clock = outlet(Clock, itf.CLOCK, itf.CLOCK_QOS) if publish_clock else None
        self.diagnostics = outlet(DiagnosticArray, itf.DIAGNOSTICS, itf.DIAGNOSTICS_QOS)
        self.outlet_of = {**dict(zip(messages.imu, self.accel)),
                          **dict(zip(messages.batch, self.batch)),
                          **dict(zip(messages.truth, self.truth)),
                          **dict(zip((messages.tach, messages.keyphasor), self.tach)),
                          messages.impacts: self.impacts, messages.state: self.state,
                          messages.speed: self.speed, messages.joint: self.joint,
                          messages.clock: self.clock}
        for stream, out in self.outlet_of.items():
            if out is not None and (messages.streams[stream].topic, messages.streams[
                    stream].type_name) != (out.topic, out.type_name):
                raise RuntimeError(f'stream {messages.streams[stream]} is not {out.topic}')
        # per stream number, its outlet (a list: indexed per queued item)
        self._outlets = [self.outlet_of.get(stream) for stream in range(len(messages.streams))]
        self._every = self.all
        self.look_up_readers()

    @property
    def all(self):
        """list of Outlet: Every publisher (``topic``, ``type_name``, ``count``)."""
        return [*self.accel, *self.batch, *self.truth, self.impacts, self.state, self.speed,
                self.joint, *self.tach, self.diagnostics] + ([self.clock] if self.clock else [])

    def look_up_readers(self):
        """Ask every outlet whether anybody reads it (:meth:`Outlet.look_up`): once per
        refill of the outbox, before its chunks are stepped, not once per outlet and chunk.
        A reader that appears gets the chunks of the next refill (up to ``tick_period`` x
        (1 + ``Outbox.REFILL``) later: 50 ms); what is queued meanwhile leaves as for nobody
        (volatile topics: no late joiner gets it)."""
        for outlet in self._every:
            outlet.look_up()

    @staticmethod
    def send(ns, outlet, item, wire):
        """Publish one queued item (the outbox's ``send``)."""
        if item.__class__ is bytes:
            outlet.publish_raw(item, ns, wire)
        else:
            outlet.publish(item, ns, wire)

    def queue_batch(self, batch, period):
        """Queue a stepped chunk (``period``: output sample period, s): the messages
        :class:`~impact_damper_sim.recording.node_messages.NodeMessages` packs from it (the
        same bytes ``study record`` writes), each with its send time, and count what it
        holds. Whether anybody reads each topic is what :meth:`look_up_readers` found last."""
        outlets, put = self._outlets, self.outbox.put
        for ns, stream, data in self.messages.batch_items(batch):
            outlet = outlets[stream]
            put(ns, outlet, data, outlet.wire)
        stats, total = self.counters.stats, self.counters.stats_total
        # what was published: a sample a sensor fault lost is not counted (the counters
        # say nothing of faults, as a DAQ driver counting what it sends would not)
        # (count_nonzero, not all() or any(): a fraction of their cost on these small arrays)
        valid = batch.valid
        lin = batch.linear_acceleration
        if valid is None or np.count_nonzero(valid) == valid.size:
            published = int(batch.t.size)
        else:   # the peak of what was sent
            published = published_samples(batch)
            lin = lin[valid]
        stats.samples += published
        total['samples'] += published
        peak = float(np.abs(lin).max()) if lin.size else 0.0   # a scene may have no sensor
        stats.peak = max(stats.peak, peak)
        impacts = int(np.count_nonzero(batch.events['kind'] == _IMPACT))
        stats.impacts += impacts
        total['impacts'] += impacts
        if batch.clipped is not None and np.count_nonzero(batch.clipped):   # DAQ overrange
            stats.clipped = stats.clipped + batch.clipped
            total['clipped'] = total['clipped'] + batch.clipped
        stats.stuck_time += self.live.stuck_count() * batch.t.size * period
        if batch.states_changed:
            self.queue_state()

    def queue_time(self):
        """Queue ``/clock``, rotor speed and joint state for the stepped time."""
        # like the samples, a topic nobody subscribes to (volatile: no late joiner gets it)
        # is not put on the wire and costs the stepping thread no wake-up
        outlets, put = self._outlets, self.outbox.put
        for ns, stream, data in self.messages.time_items():
            outlet = outlets[stream]
            put(ns, outlet, data, outlet.wire)

    def publish_state_now(self):
        """Publish ``impactor_state`` at once (latched: start-up, a switch of the dampers)."""
        self.state.publish_raw(self.messages.state_message(), int(round(self.live.t * 1e9)))

    def queue_state(self):
        """Queue ``impactor_state``: it leaves with the samples of its sim time, not a chunk
        ahead of them."""
        self.outbox.put(int(round(self.live.t * 1e9)), self.state,
                        self.messages.state_message(), True)


__all__ = ['Publishers']
