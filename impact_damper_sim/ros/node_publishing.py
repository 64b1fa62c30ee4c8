"""The publishing helpers of ``vibration_node``: what a stepped chunk puts on the wire, and when.

:class:`PublishingMixin` queues what the chunks :class:`~impact_damper_sim.live.realtime.
LiveSimulation` steps produce (per-sample ``Imu``, full-rate and impact batches, ``/clock``,
rotor speed and joint state, ``impactor_state``) and sends each at its sim time through the
pacer. The bytes themselves come from :class:`~impact_damper_sim.recording.node_messages.
NodeMessages`, ROS-free, which ``study record`` packs its offline logs with too; this module
decides when they leave. It is separate from :mod:`.vibration_node` because it is the node's
message layer, not its life cycle: the node declares parameters, handles commands and runs
the stepping thread. A mixin of :class:`~impact_damper_sim.ros.vibration_node.VibrationNode`
only: it keeps no state of its own and works on the node's (``live``, ``pacer``, ``stats``,
``_lock``, ``_pending``, ``_messages`` and the outlets that ``_make_interfaces`` makes).
"""
from __future__ import annotations

import numpy as np

from ..recording.node_messages import published_samples

_IMPACT = 0   # EVENT_KINDS index of an impact


class PublishingMixin:
    """Queue what :class:`~impact_damper_sim.ros.vibration_node.VibrationNode` steps and
    publish it at its time (a mixin of that node; no state of its own)."""

    # -- publishing -----------------------------------------------------------------------
    def _flush(self, now, burst=None):
        """Publish every queued item due by wall time ``now`` (through the pacer).

        An item nobody receives (no subscriber when it was queued: it is only counted and
        recorded, with its own stamp as log time) does not wait for its time, so a topic
        nobody reads costs no wake-ups; items still leave in time order.

        Parameters
        ----------
        now : float
            Wall time (s); ``math.inf`` publishes everything queued.
        burst : int, optional
            Most samples sent per accelerometer (None: no limit).

        Returns
        -------
        bool
            True when due samples were held back by ``burst`` (a backlog to send next).
        """
        pending = self._pending
        if not pending:
            # nothing queued (a scene without outputs): all that was stepped is out, up to
            # the schedule, or pacing would wait forever for an item
            self._t_published = max(self._t_published,
                                    min(self.live.t, self.pacer.sim_at(now)))
            return False
        with self._lock:
            horizon = self.pacer.sim_at(now) * 1e9   # ns (a float; inf for now = inf)
            left = dict.fromkeys(self._accel_pubs, burst) if burst else None
            while pending:
                ns, outlet, item, wire = pending[0]
                if wire:
                    if ns > horizon:
                        break
                    if left is not None and outlet in left:
                        if not left[outlet]:
                            return True
                        left[outlet] -= 1
                pending.popleft()
                if isinstance(item, bytes):
                    outlet.publish_raw(item, ns, wire)
                else:
                    outlet.publish(item, ns, wire)
                self._t_published = min(ns, horizon) * 1e-9
        return False

    def _queue_batch(self, batch):
        """Queue a stepped chunk: the messages :class:`~impact_damper_sim.recording.
        node_messages.NodeMessages` packs from it (the same bytes ``study record`` writes),
        each with its send time, and count what it holds."""
        outlet_of = self._outlet_of
        wire_of = {}   # one has_subscribers() per outlet and chunk
        for ns, stream, data in self._messages.batch_items(batch):
            outlet = outlet_of[stream]
            wire = wire_of.get(stream)
            if wire is None:
                wire = wire_of[stream] = outlet.has_subscribers()
            self._pending.append((ns, outlet, data, wire))
        k = batch.t.size
        # what was published: a sample a sensor fault lost is not counted (the counters
        # say nothing of faults, as a DAQ driver counting what it sends would not)
        published = published_samples(batch)
        self.stats.samples += published
        self.stats_total['samples'] += published
        lin = batch.linear_acceleration
        if batch.valid is not None and not batch.valid.all():   # the peak of what was sent
            lin = lin[batch.valid]
        peak = float(np.max(np.abs(lin))) if lin.size else 0.0   # a scene may have no sensor
        self.stats.peak = max(self.stats.peak, peak)
        ev = batch.events
        impacts = int(np.count_nonzero(ev['kind'] == _IMPACT))
        self.stats.impacts += impacts
        self.stats_total['impacts'] += impacts
        if batch.clipped is not None and batch.clipped.any():   # the DAQ's overrange count
            self.stats.clipped = self.stats.clipped + batch.clipped
            self.stats_total['clipped'] = self.stats_total['clipped'] + batch.clipped
        stuck = sum(self.live._stuck)
        self.stats.stuck_time += stuck * k * self._period
        if batch.states_changed:
            self._queue_state()

    def _queue_time(self):
        # like the samples, a topic nobody subscribes to (volatile: no late joiner gets it)
        # is not put on the wire and costs the stepping thread no wake-up
        for ns, stream, data in self._messages.time_items():
            outlet = self._outlet_of[stream]
            self._pending.append((ns, outlet, data, outlet.has_subscribers()))

    def publish_state(self):
        """Queue ``impactor_state`` (the periodic timer's callback): it leaves with the
        samples of its sim time, not a chunk ahead of them."""
        with self._lock:
            self._queue_state()

    def _publish_state(self):
        self._state_pub.publish_raw(self._messages.state_message(),
                                    int(round(self.live.t * 1e9)))

    def _queue_state(self):
        self._pending.append((int(round(self.live.t * 1e9)), self._state_pub,
                              self._messages.state_message(), True))
