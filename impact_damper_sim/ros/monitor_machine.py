"""One machine the ``monitor`` follows: its subscriptions, its queued input, its statuses.

A machine is a namespace with a simulator (or a replay, or another driver) publishing the
node's topics in it. :class:`Machine` subscribes to them with the QoS of
:mod:`impact_damper_sim.ros.interface`, queues what arrives (a few microseconds a message,
under the monitor's queue lock), and later, in the monitor's report thread, decodes the
queued batches into its own :class:`~impact_damper_sim.live.monitoring.RollingVibrationStats`
(each machine has its own sim clock, so its own window) and words its ``/diagnostics``
statuses and its log line.

Which topic of a stream is read (layouts in :mod:`impact_damper_sim.recording.batches`):

* accelerometer ``<name>``: the full-rate ``accel/<name>/batch`` (sensor_msgs/PointCloud2,
  many samples a message) when it has a publisher, else the per-sample ``accel/<name>``
  (sensor_msgs/Imu, decimated by ``vibration_node``; an old log replayed, another driver);
* ``impacts``: sensor_msgs/PointCloud2 batches (one per stepped chunk, empty when nothing
  hit: a batch covers its interval, so impacts/s counts rows over the time the batches
  covered), else one geometry_msgs/WrenchStamped per impact (the old format).

One subscription a stream: the choice follows the publishers' types in the graph (both
published: the batch), checked when a stream is added and at every report; with no publisher
yet, the batch is subscribed. When a sensor changes topic, its history is dropped, so that a
window never mixes the decimated and the full-rate signal.

Names on ``/diagnostics`` (diagnostic_updater's form ``<node>: <task>``, with the monitor's
fully qualified name as ``diagnostic_updater.use_fqn`` gives it): ``<monitor>:
<machine namespace>/<sensor>`` and ``<monitor>: <machine namespace>/impacts``, e.g.
``/monitor: /pump3/hpotp_casing_bottom``; ``diagnostic_aggregator`` keys its items by name,
so two machines, or two monitors, never merge. hardware_id is the machine's: the one its
``vibration_node`` reports on ``/diagnostics`` (its ``hardware_id`` parameter, which a plant
sets), else, before that status arrives or for another publisher, ``<namespace>/<frame>``
(the frame alone at the root namespace); the frame is also the value ``frame_id``.
"""
from __future__ import annotations

import math
from array import array

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from geometry_msgs.msg import WrenchStamped
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.exceptions import InvalidNamespaceException
from rclpy.qos import qos_policy_name_from_kind
from rclpy.validate_namespace import validate_namespace
from sensor_msgs.msg import Imu, JointState, PointCloud2

from ..live.monitor_text import (
    FIRST_SAMPLE_GRACE_S,
    dampers_off,
    impact_values,
    impactor_stuck_flags,
    impacts_text,
    sensor_text,
    sensor_values,
    value_text,
    waiting_text,
)
from ..live.monitoring import RollingVibrationStats
from ..recording.batches import BATCH_SUFFIX, rows_of, sample_times_ns
from .interface import (
    ACCEL_PREFIX,
    BATCH_QOS,
    EVENT_QOS,
    IMPACTOR_STATE,
    IMPACTS,
    LATCHED_QOS,
    SENSOR_QOS,
    accel_topic,
)
from .monitor_cdr import read_cloud, rows_in
from .outlets import type_name

#: Samples (or impacts) queued on one per-sample stream, or in all batch messages of a
#: machine together (a batch counts at least 1, so empty ones are bounded too), before they
#: go to the report thread ahead of the report, so that memory stays bounded.
FLUSH_AT = 4096
#: A sensor is stale after this many windows without a valid sample.
STALE_WINDOWS = 2.0
#: The entry of the monitor's ``namespaces`` that means every machine in the graph.
EVERY_MACHINE = '*'
#: A ``vibration_node`` status on ``/diagnostics`` is named ``<its full name>`` + this.
SIMULATION_STATUS = ': simulation'
_NAMESPACE_FORM = ("an absolute '/pump1' or a relative 'pump1' ROS namespace (letters, digits "
                   "and '_', tokens separated by single '/', none starting with a digit, no "
                   "trailing '/'), or '*' for every machine in the graph")


class MonitorParameterError(ValueError):
    """A start-up parameter of the monitor is invalid (the message names it)."""


def resolve_namespaces(names, own):
    """The machines a ``namespaces`` parameter names, as absolute namespaces.

    Parameters
    ----------
    names : sequence of str
        The parameter's entries: absolute (``/pump1``) or relative (``pump1``, resolved
        against the monitor's namespace ``own``) namespaces, or ``'*'``.
    own : str
        The monitor's namespace (absolute).

    Returns
    -------
    namespaces : list of str
        Absolute namespaces, in order, without duplicates.
    every : bool
        ``'*'`` was given: follow every machine found in the graph too.

    Raises
    ------
    MonitorParameterError
        An entry is not a valid ROS namespace; the message names the parameter, the entry and
        the allowed form.
    """
    found, every = [], False
    for name in names:
        if name == EVERY_MACHINE:
            every = True
            continue
        full = name if name.startswith('/') else f'{own.rstrip("/")}/{name}'
        try:
            if not name:
                raise InvalidNamespaceException(name, 'namespace must not be empty', 0)
            validate_namespace(full)
        except InvalidNamespaceException as error:
            why = str(error).splitlines()[0].rstrip(':')
            raise MonitorParameterError(
                f'namespaces: {name!r} is not {_NAMESPACE_FORM} ({why})') from error
        found.append(full)
    return list(dict.fromkeys(found)), every


def accel_name(rest, types):
    """The accelerometer a topic names, from the part after ``accel/`` and its types, or None.

    ``<name>/batch`` of type PointCloud2 and ``<name>`` of type Imu name ``<name>``; any other
    topic under ``accel/`` (a ground truth ``<name>/truth``, a String) names none.
    """
    if not rest:
        return None
    stem = rest[:-len(BATCH_SUFFIX)]
    if rest.endswith(BATCH_SUFFIX) and stem and type_name(PointCloud2) in types:
        return stem
    return rest if type_name(Imu) in types else None


def machines_in(topics_and_types):
    """Namespaces in which an accelerometer topic (``accel/<name>/batch`` or ``accel/<name>``
    of its type) is in the graph, in order of first appearance (list of absolute str)."""
    marker = '/' + ACCEL_PREFIX
    found = []
    for topic, types in topics_and_types:
        at = topic.find(marker)
        if at >= 0 and accel_name(topic[at + len(marker):], types) is not None:
            found.append(topic[:at] or '/')
    return list(dict.fromkeys(found))


def machine_id(namespace, frame):
    """hardware_id of a machine whose node's own is not known: ``<namespace>/<frame>``
    (``'pump3/hpotp_casing_bottom'``; the frame alone at the root namespace)."""
    return '/'.join([*namespace.strip('/').split('/'), frame]).strip('/')


def plant_line(namespace, width, parts):
    """One machine's log line: its namespace padded to ``width``, then its parts.

    Parameters
    ----------
    namespace : str
        The machine's namespace (absolute).
    width : int
        Width of the namespace column (characters): the longest namespace followed.
    parts : list of str
        Each sensor's text and the impacts text, in order.
    """
    return f'{namespace:<{width}}  ' + '; '.join(parts)


def _stamp_s(stamp):
    """Return a builtin_interfaces/Time as float seconds."""
    return stamp.sec + 1e-9 * stamp.nanosec


def _stamps_s(ns):
    """Stamps (ns, int64 array) as float s, rounded exactly as :func:`_stamp_s` rounds them.

    A sample then has the same time (s) whether it came in an Imu or in a batch.
    """
    sec, nanosec = np.divmod(ns, 1_000_000_000)
    return sec + 1e-9 * nanosec


class _Batch:
    """Input a machine's callbacks queued since the last hand-over to the report thread."""

    def __init__(self, sensors=()):
        self.samples = {}      # sensor -> Imu rows (t, ax, ay, az) (s, m/s^2)
        self.clouds = {}       # sensor -> accel/<sensor>/batch CDR bytes, not read yet
        for name in sensors:
            self.add_sensor(name)
        self.cleared = set()   # sensors whose history goes before this batch is fed
        self.impacts = array('d')      # WrenchStamped stamps (s)
        self.impact_clouds = []        # impacts batch CDR bytes, not read yet
        self.queued = 0        # rows in the batch messages (at least 1 a message)
        self.states = []       # (stamp s, stuck flags, dampers off), None: rejected

    def add_sensor(self, name):
        self.samples.setdefault(name, array('d'))
        self.clouds.setdefault(name, [])


class _Stream:
    """An input that comes on one of several topics; the first one published is read.

    Parameters
    ----------
    options : list of tuple
        ``(topic, message class, callback, QoS)``, preferred first.
    """

    def __init__(self, options):
        self.options = options
        self.index = None          # the option subscribed, None before the first
        self.subscription = None

    @property
    def topic(self):
        """The topic read (str; relative in the monitor's own namespace)."""
        return self.options[self.index][0]


class Machine:
    """The subscriptions, queue, rolling statistics and statuses of one machine.

    Parameters
    ----------
    monitor : VibrationMonitor
        The node: it owns the queue lock (``_queue``) and the hand-over to its report thread.
    namespace : str
        The machine's namespace (absolute). The monitor's own namespace is read with
        relative topic names (remapping rules apply as to any node's relative names).
    sensors : sequence of str
        Accelerometers to watch; empty: discover them (:meth:`discover`).
    window : float
        Rolling window (s).

    Attributes
    ----------
    stats : RollingVibrationStats
        The core (owned by the report thread).
    last_report : VibrationReport or None
        Its latest report.
    message_counts : dict of str to int
        Messages received per stream (``accel``, ``impacts``, ``impactor_state``).
    node_hardware_id : str or None
        hardware_id of the machine's ``vibration_node`` status, once seen.
    """

    def __init__(self, monitor, namespace, sensors, window):
        self.monitor = monitor
        self.namespace = namespace
        self._relative = namespace == monitor.get_namespace()
        self.stats = RollingVibrationStats(window)
        self.last_report = None
        self.message_counts = {'accel': 0, 'impacts': 0, 'impactor_state': 0}
        self.node_hardware_id = None
        self.batch = _Batch()
        self.accel_streams = {}     # sensor -> _Stream
        self.frames = {}            # sensor -> frame_id of its latest message
        self._cloud_layouts = {}    # batch layouts read before (monitor_cdr.read_cloud)
        self.impact_frame = ''
        # owned by the report thread
        self._last_arrival = {}     # sensor -> node-clock time of its latest valid sample (s)
        self._watched_since = {}    # sensor -> node-clock time it was first reported (s)
        self._dampers_off = False
        self._last_impact_batch = None   # node-clock time an impacts batch last arrived (s)
        self._rejected_reported = {}
        self._rejected_states_reported = 0
        self.discover_sensors = not sensors
        for name in dict.fromkeys(sensors):   # ordered, without duplicates
            self.watch(name)
        self.impact_stream = _Stream([
            (self.topic(IMPACTS), PointCloud2, self._on_impact_batch, EVENT_QOS),
            (self.topic(IMPACTS), WrenchStamped, self._on_impact, EVENT_QOS)])
        self.settle(self.impact_stream)
        monitor.create_subscription(JointState, self.topic(IMPACTOR_STATE), self._on_state,
                                    LATCHED_QOS)

    def topic(self, relative):
        """The name to subscribe to for the machine's topic ``relative`` (str)."""
        return relative if self._relative else f'{self.namespace.rstrip("/")}/{relative}'

    @property
    def label(self):
        """The machine as status names and lines name it: its namespace, '' at the root."""
        return self.namespace.rstrip('/')

    # -- subscriptions (executor thread) -------------------------------------------------
    def watch(self, sensor):
        """Watch ``sensor``: subscribe to its batch topic, or to its Imu topic (see settle)."""
        topic = self.topic(accel_topic(sensor))
        stream = _Stream([
            (topic + BATCH_SUFFIX, PointCloud2,
             lambda msg, name=sensor: self._on_accel_batch(name, msg), BATCH_QOS),
            (topic, Imu, lambda msg, name=sensor: self._on_accel(name, msg), SENSOR_QOS)])
        try:
            self.settle(stream)
        except Exception as error:   # rclpy raises several kinds for a bad name
            raise MonitorParameterError(f'sensors: {sensor!r} does not make a valid topic '
                                        f'name {topic!r}: {error}') from error
        self.accel_streams[sensor] = stream
        with self.monitor._queue:
            self.batch.add_sensor(sensor)

    def settle(self, stream, sensor=None):
        """Subscribe ``stream`` to its first option that has a publisher of its type.

        With no publisher on any option, the current subscription stays (at first, the
        first option). A sensor that changes topic loses its history (``sensor``: its name).
        """
        node = self.monitor
        index = next((i for i, (topic, msg_type, _, _) in enumerate(stream.options)
                      if any(info.topic_type == type_name(msg_type)
                             for info in node.get_publishers_info_by_topic(topic))),
                     0 if stream.index is None else stream.index)
        if index == stream.index:
            return
        topic, msg_type, callback, qos = stream.options[index]
        if stream.subscription is not None:
            node.destroy_subscription(stream.subscription)
        # batches come as bytes, read later as arrays (monitor_cdr): no message objects
        stream.subscription = node.create_subscription(msg_type, topic, callback, qos,
                                                       raw=msg_type is PointCloud2,
                                                       event_callbacks=self._events(topic))
        if stream.index is not None and sensor is not None:
            with node._queue:
                self.batch.samples[sensor] = array('d')
                self.batch.clouds[sensor] = []
                self.batch.cleared.add(sensor)
        stream.index = index
        node.get_logger().info(f'watching {node.resolve_topic_name(topic)} '
                               f'({type_name(msg_type)})')

    def _events(self, topic):
        """Event handlers of a stream subscription: an incompatible-QoS warning, as rclpy's
        default, but not rclpy's incompatible-type one (a type is subscribed only when a
        publisher offers it, and another type on an accel/* topic is not a sensor). Each
        handler is one more entity in every wait of the executor: with ten machines the two
        defaults were 62 of its 97."""
        logger = self.monitor.get_logger()
        name = self.monitor.resolve_topic_name(topic)

        def incompatible(event):
            logger.warning(f'a publisher on {name} offers incompatible QoS (policy '
                           f'{qos_policy_name_from_kind(event.last_policy_kind)}): nothing '
                           'is received from it', throttle_duration_sec=10.0)
        return SubscriptionEventCallbacks(incompatible_qos=incompatible,
                                          use_default_callbacks=False)

    def settle_all(self):
        """Re-check which topic each stream reads (at every report)."""
        for sensor, stream in self.accel_streams.items():
            self.settle(stream, sensor)
        self.settle(self.impact_stream)

    def discover(self, topics_and_types):
        """Watch every accelerometer of the machine not yet watched.

        Parameters
        ----------
        topics_and_types : list of (str, list of str)
            The graph's topics, as ``Node.get_topic_names_and_types`` gives them.
        """
        prefix = self.monitor.resolve_topic_name(self.topic(ACCEL_PREFIX.rstrip('/'))) + '/'
        found = [accel_name(topic[len(prefix):], types) for topic, types in topics_and_types
                 if topic.startswith(prefix)]
        for sensor in dict.fromkeys(name for name in found if name is not None):
            if sensor not in self.accel_streams:
                self.watch(sensor)

    def _on_accel(self, sensor, msg):
        # hot path (thousands a second): queue only
        a = msg.linear_acceleration
        row = (_stamp_s(msg.header.stamp), a.x, a.y, a.z)
        monitor = self.monitor
        with monitor._queue:
            samples = self.batch.samples[sensor]
            samples.extend(row)
            if len(samples) >= 4 * FLUSH_AT:
                monitor._hand_over(report=False, machine=self)
        self.frames[sensor] = msg.header.frame_id
        self.message_counts['accel'] += 1

    def _on_accel_batch(self, sensor, data):
        # queue the bytes as they are: the report thread reads them
        with self.monitor._queue:
            self.batch.clouds[sensor].append(data)
            self._queue_rows(data)
        self.message_counts['accel'] += 1

    def _on_impact(self, msg):
        with self.monitor._queue:
            self.batch.impacts.append(_stamp_s(msg.header.stamp))
            if len(self.batch.impacts) >= FLUSH_AT:
                self.monitor._hand_over(report=False, machine=self)
        self.impact_frame = msg.header.frame_id.rpartition('/')[0]
        self.message_counts['impacts'] += 1

    def _on_impact_batch(self, data):
        with self.monitor._queue:
            self.batch.impact_clouds.append(data)
            self._queue_rows(data)
        self.message_counts['impacts'] += 1

    def _queue_rows(self, data):
        """Count a queued batch message; hand over when enough are (call with ``_queue``)."""
        self.batch.queued += max(1, rows_in(data))
        if self.batch.queued >= FLUSH_AT:
            self.monitor._hand_over(report=False, machine=self)

    def _on_state(self, msg):
        self.message_counts['impactor_state'] += 1
        try:
            _, stuck = impactor_stuck_flags(msg.name, msg.effort)
            state = (_stamp_s(msg.header.stamp), stuck, dampers_off(msg.effort))
        except ValueError as error:
            state = None
            self.monitor.get_logger().warning(
                f'{self.monitor.resolve_topic_name(self.topic(IMPACTOR_STATE))} rejected: '
                f'{error}', throttle_duration_sec=10.0)
        with self.monitor._queue:
            self.batch.states.append(state)

    def take_batch(self):
        """The queued input, replaced by an empty batch (call with the monitor's ``_queue``)."""
        batch, self.batch = self.batch, _Batch(self.batch.samples)
        return batch

    # -- the report thread ---------------------------------------------------------------
    def feed(self, batch, clock_s):
        """Decode ``batch`` into the core; ``clock_s``: node clock at its hand-over (s)."""
        stats = self.stats
        for sensor in batch.cleared:
            stats.clear_sensor(sensor)
        for sensor in batch.samples:
            stats.add_sensor(sensor)
            rows = self._accel_rows(sensor, batch)
            if rows is not None and stats.add_samples(sensor, rows[:, 0], rows[:, 1:]):
                self._last_arrival[sensor] = clock_s
        if batch.impacts:
            stats.add_impacts(np.frombuffer(batch.impacts, dtype=float))
        if batch.impact_clouds:
            self._last_impact_batch = clock_s
        for data in batch.impact_clouds:
            try:
                msg = read_cloud(data, self._cloud_layouts)
                self.impact_frame = msg.header.frame_id
                times = _stamps_s(sample_times_ns(msg))
            except ValueError as error:
                stats.reject_impacts(rows_in(data))
                self._warn(f'{self.topic(IMPACTS)}: batch rejected: {error}')
                continue
            # the batch covers its interval from its stamp on, empty or not
            stats.add_impacts(times, start=_stamp_s(msg.header.stamp))
        for state in batch.states:
            if state is None:
                stats.reject_state()
            else:
                stats.update_stuck(*state[:2])
                self._dampers_off = state[2]

    def _warn(self, text):
        self.monitor.get_logger().warning(text, throttle_duration_sec=10.0)

    def _accel_rows(self, sensor, batch):
        """Rows ``(t, ax, ay, az)`` (s, m/s^2) of ``sensor`` in ``batch``, or None if none.

        The batch messages are decoded here, each by its own fields, each as arrays (no
        Python per sample); a malformed one (a field missing, a bad datatype, short data)
        counts its rows as rejected samples.
        """
        parts = []
        if batch.samples[sensor]:
            parts.append(np.frombuffer(batch.samples[sensor], dtype=float).reshape(-1, 4))
        for data in batch.clouds[sensor]:
            try:
                msg = read_cloud(data, self._cloud_layouts)
                self.frames[sensor] = msg.header.frame_id
                cloud = rows_of(msg)
                parts.append(np.column_stack((_stamps_s(sample_times_ns(msg, cloud)),
                                              cloud['ax'], cloud['ay'], cloud['az'])))
            except ValueError as error:
                self.stats.reject_samples(sensor, rows_in(data))
                self._warn(f'{self.topic(accel_topic(sensor))}{BATCH_SUFFIX}: batch '
                           f'rejected: {error}')
        return np.concatenate(parts) if parts else None

    def statuses(self, clock_s, node_name):
        """Report: one status per sensor, then the impacts status (list of DiagnosticStatus).

        Parameters
        ----------
        clock_s : float
            Node clock now (s).
        node_name : str
            The monitor's fully qualified name, the first part of each status name.
        """
        report = self.stats.report()
        self.last_report = report
        found = [self._sensor_status(report, sensor, clock_s, node_name)
                 for sensor in report.sensors]
        found.append(self._impacts_status(report, clock_s, node_name))
        return found

    def hardware_id(self, frame):
        """The machine's hardware_id: its node's, else ``<namespace>/<frame>``."""
        if self.node_hardware_id:
            return self.node_hardware_id
        return machine_id(self.namespace, frame)

    def _status(self, name, problems, message, frame, values):
        keys = [KeyValue(key=key, value=value_text(v)) for key, v in values]
        keys.append(KeyValue(key='frame_id', value=frame))
        return DiagnosticStatus(
            level=DiagnosticStatus.WARN if problems else DiagnosticStatus.OK,
            name=name, message='; '.join(problems) or message,
            hardware_id=self.hardware_id(frame), values=keys)

    def _sensor_status(self, report, sensor, clock_s, node_name):
        stats = report.sensors[sensor]
        window = report.window
        stale_after = STALE_WINDOWS * window
        arrival = self._last_arrival.get(sensor)
        age = clock_s - arrival if arrival is not None else math.nan
        lag = (report.t - stats.last_sample_t if stats.last_sample_t is not None
               else math.nan)
        new_rejects = stats.rejected_samples - self._rejected_reported.get(sensor, 0)
        self._rejected_reported[sensor] = stats.rejected_samples
        problems = []
        waiting = None
        if arrival is None:
            # a start-up takes a while: INFO 'waiting ...' first, WARN after the grace period
            waited = clock_s - self._watched_since.setdefault(sensor, clock_s)
            warn, text = waiting_text(accel_topic(sensor), waited, FIRST_SAMPLE_GRACE_S)
            (problems.append if warn else lambda t: None)(text)
            waiting = None if warn else text
        elif age > stale_after:
            problems.append(f'stale: no sample for {age:.3g} s')
        elif lag > stale_after:
            problems.append(f'stale: newest sample {lag:.3g} s behind the other topics')
        if new_rejects:
            problems.append(f'{new_rejects} samples rejected (non-finite or out of range)')
        return self._status(f'{node_name}: {self.label}/{sensor}', problems, waiting or 'ok',
                            self.frames.get(sensor, ''),
                            sensor_values(stats, lag, age, window, report.t))

    def _impacts_status(self, report, clock_s, node_name):
        new_rejects = report.rejected_states - self._rejected_states_reported
        self._rejected_states_reported = report.rejected_states
        problems = []
        # impacts batches come every chunk, empty or not: their silence is a stopped machine
        # (one WrenchStamped per impact may be silent for long: no such rule)
        silent = clock_s - (self._last_impact_batch or clock_s)
        if self.impact_stream.index == 0 and silent > STALE_WINDOWS * report.window:
            problems.append(f'stale: no impacts batch for {silent:.3g} s')
        if math.isnan(report.stuck_fraction) and not self._dampers_off:
            problems.append(f'no {IMPACTOR_STATE} received')
        if new_rejects:
            problems.append(f'{new_rejects} {IMPACTOR_STATE} messages rejected')
        return self._status(f'{node_name}: {self.label}/impacts', problems, 'ok',
                            self.impact_frame, impact_values(report))

    def line_parts(self, statuses):
        """The machine's report in words: ``(ok, text)`` per sensor, then for impacts.

        Parameters
        ----------
        statuses : list of DiagnosticStatus
            What :meth:`statuses` returned for the latest report.
        """
        report = self.last_report
        parts = []
        for sensor, status in zip(report.sensors, statuses):
            ok = status.level == DiagnosticStatus.OK
            s = report.sensors[sensor]
            if s.samples == 0:
                parts.append((ok, f'{accel_topic(sensor)}: {status.message}'))
                continue
            line = sensor_text(accel_topic(sensor), s)
            parts.append((ok, line if ok else f'{line}: {status.message}'))
        line = impacts_text(report.impacts_per_s, report.stuck_fraction,
                            report.stuck_impactors, report.impactors, self._dampers_off)
        ok = statuses[-1].level == DiagnosticStatus.OK
        parts.append((ok, line if ok else f'{line}: {statuses[-1].message}'))
        return parts


__all__ = ['EVERY_MACHINE', 'FLUSH_AT', 'Machine', 'MonitorParameterError', 'STALE_WINDOWS',
           'accel_name', 'machine_id', 'machines_in', 'plant_line', 'resolve_namespaces']
