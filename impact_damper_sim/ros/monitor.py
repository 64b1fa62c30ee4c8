"""``monitor``: rolling vibration statistics of a running ``vibration_node``, on /diagnostics.

A thin adapter over :class:`impact_damper_sim.live.monitoring.RollingVibrationStats`: it
subscribes to each accelerometer, to ``impacts`` and to ``impactor_state``
(sensor_msgs/JointState, latched) with the QoS of :mod:`impact_damper_sim.ros.interface`,
feeds their header stamps (sim time) and values to the core, and every ``report_period``
logs one line per sensor and publishes a diagnostic_msgs/DiagnosticArray on ``/diagnostics``.
Topic names are relative, so ``ros2 run impact_damper_sim monitor --ros-args -r
__ns:=/hpotp`` watches the simulator running in ``/hpotp``.

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
window never mixes the decimated and the full-rate signal. Discovery (``sensors`` unset)
finds the names of both kinds of ``accel/*`` topic.

Threads: the subscription callbacks only queue what they receive (a few microseconds a
message: batches are decoded later). A report thread owns the core: it decodes and feeds it
the queued input, and computes and publishes the reports, so that a long window (at 60 s
and 20 kHz, an FFT of 1.2 million points a sensor) does not stall the executor while the
best-effort queues fill.

Diagnostics: one status per sensor and one for impacts, their keys (units in the names) and
levels in docs/node.md ("The monitor"); the values come from
:mod:`impact_damper_sim.live.monitor_text`.
"""
from __future__ import annotations

import math
import threading
from array import array

import numpy as np
import rclpy
import rclpy.executors
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import WrenchStamped
from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter
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
    DIAGNOSTICS,
    DIAGNOSTICS_QOS,
    EVENT_QOS,
    IMPACTOR_STATE,
    IMPACTS,
    LATCHED_QOS,
    SENSOR_QOS,
    accel_topic,
)
from .outlets import type_name
from .parameters import serve_unset_parameters
from .process import (
    freeze_start_up_heap,
    ignore_further_interrupts,
    settle_interrupt,
    shutdown_quietly,
    spin_guarded,
)
from .service_guard import guard_services

#: Samples (or impacts) queued on one per-sample stream, or in all batch messages together
#: (a batch counts at least 1, so empty ones are bounded too), before they go to the report
#: thread ahead of the report, so that memory stays bounded for long report periods.
FLUSH_AT = 4096
#: A sensor is stale after this many windows without a valid sample.
STALE_WINDOWS = 2.0


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
    """Input the callbacks queued since the last hand-over to the report thread."""

    def __init__(self, sensors=()):
        self.samples = {}      # sensor -> Imu rows (t, ax, ay, az) (s, m/s^2)
        self.clouds = {}       # sensor -> accel/<sensor>/batch messages, not decoded yet
        for name in sensors:
            self.add_sensor(name)
        self.cleared = set()   # sensors whose history goes before this batch is fed
        self.impacts = array('d')      # WrenchStamped stamps (s)
        self.impact_clouds = []        # impacts batch messages, not decoded yet
        self.queued = 0        # rows in the batch messages (at least 1 a message)
        self.states = []       # (stamp s, stuck flags), or None for a rejected message
        self.clock_s = math.nan    # node clock at the hand-over (s)
        self.report = False

    def add_sensor(self, name):
        self.samples.setdefault(name, array('d'))
        self.clouds.setdefault(name, [])


class _Stream:
    """An input that comes on one of several topics; the first one published is read.

    Parameters
    ----------
    options : list of tuple
        ``(topic, message class, callback, QoS)``, preferred first; ``topic`` relative.
    """

    def __init__(self, options):
        self.options = options
        self.index = None          # the option subscribed, None before the first
        self.subscription = None

    @property
    def topic(self):
        """The relative topic read (str)."""
        return self.options[self.index][0]


class VibrationMonitor(Node):
    """Node that reports rolling vibration statistics of the ``accel/*`` topics.

    Parameters
    ----------
    node_name : str
        Node name (default ``monitor``).
    **kwargs
        Passed to :class:`rclpy.node.Node` (``context``, ``namespace``,
        ``parameter_overrides``, ...).

    Attributes
    ----------
    last_report : VibrationReport or None
        The latest report of the core (None before the first).
    message_counts : dict of str to int
        Messages received per stream (``accel``: Imu and batch messages, ``impacts``:
        WrenchStamped and batch messages, ``impactor_state``).
    """

    def __init__(self, node_name='monitor', **kwargs):
        super().__init__(node_name, **kwargs)
        sensors = self.declare_parameter(
            'sensors', Parameter.Type.STRING_ARRAY, ParameterDescriptor(
                description='accelerometers to watch, on topics accel/<name>/batch '
                            '(PointCloud2), or accel/<name> (Imu) when only that is '
                            'published (relative to the namespace); unset or empty: '
                            'discover the accel/* topics of the namespace at start and '
                            'every report period',
                read_only=True)).value or []
        window = self.declare_parameter('window', 2.0, ParameterDescriptor(
            description='rolling window of the statistics (s, in header-stamp time)',
            floating_point_range=[FloatingPointRange(from_value=0.1, to_value=60.0)]
        )).value
        period = self.declare_parameter('report_period', 1.0, ParameterDescriptor(
            description='period of the logged lines and /diagnostics reports (s, node clock)',
            floating_point_range=[FloatingPointRange(from_value=0.05, to_value=3600.0)],
            read_only=True)).value
        self.declare_parameter('log_reports', True, ParameterDescriptor(
            description='log one INFO line per sensor and one for impacts every report'))
        self.add_post_set_parameters_callback(self._on_parameters_set)
        serve_unset_parameters(self)   # GetParameters naming an unset 'sensors' answers all

        self.last_report = None
        self.message_counts = {'accel': 0, 'impacts': 0, 'impactor_state': 0}
        # owned by the report thread (or a caller of report()), under _core_lock
        self._core_lock = threading.Lock()
        self._stats = RollingVibrationStats(window)
        self._window = window
        self._last_arrival = {}     # sensor -> node-clock time of its latest valid sample (s)
        self._watched_since = {}    # sensor -> node-clock time it was first reported (s)
        self._dampers_off = False   # the latest impactor_state says the dampers are off
        self._rejected_reported = {}
        self._rejected_states_reported = 0
        # shared with the callbacks, under _queue (callbacks never wait on the core)
        self._queue = threading.Condition()
        self._batch = _Batch()
        self._jobs = []
        self._stopping = False
        self._frames = {}           # sensor -> frame_id of its latest message
        self._impact_frame = ''
        self._accel_streams = {}    # sensor -> _Stream
        self._discover_sensors = not sensors
        for name in dict.fromkeys(sensors):   # ordered, without duplicates
            self._watch(name)
        self._impact_stream = _Stream([
            (IMPACTS, PointCloud2, self._on_impact_batch, EVENT_QOS),
            (IMPACTS, WrenchStamped, self._on_impact, EVENT_QOS)])
        self._settle(self._impact_stream)
        self.create_subscription(JointState, IMPACTOR_STATE, self._on_state, LATCHED_QOS)
        self._diagnostics = self.create_publisher(DiagnosticArray, DIAGNOSTICS,
                                                  DIAGNOSTICS_QOS)
        if self._discover_sensors:
            self.discover()
        self._worker = threading.Thread(target=self._work, name=f'{node_name}-report',
                                        daemon=True)
        self._worker.start()
        self._timer = self.create_timer(period, self._on_timer)
        # no request may stop the node (a SetParameters with an unknown type raises in rclpy)
        guard_services(self, lambda text: self.get_logger().warning(
            text, throttle_duration_sec=1.0))

    @property
    def sensors(self):
        """Names of the watched sensors (tuple of str)."""
        return tuple(self._accel_streams)

    @property
    def topics(self):
        """The relative topic read per sensor, and ``impacts`` (dict of str to str)."""
        read = {sensor: stream.topic for sensor, stream in self._accel_streams.items()}
        read[IMPACTS] = self._impact_stream.topic
        return read

    def destroy_node(self):
        """Stop the report thread, then destroy the node."""
        with self._queue:
            self._stopping = True
            self._queue.notify()
        self._worker.join(timeout=5.0)
        return super().destroy_node()

    # -- subscriptions -----------------------------------------------------------------
    def _watch(self, sensor):
        """Watch ``sensor``: subscribe to its batch topic, or to its Imu topic (see _settle)."""
        topic = accel_topic(sensor)
        stream = _Stream([
            (topic + BATCH_SUFFIX, PointCloud2,
             lambda msg, name=sensor: self._on_accel_batch(name, msg), BATCH_QOS),
            (topic, Imu, lambda msg, name=sensor: self._on_accel(name, msg), SENSOR_QOS)])
        try:
            self._settle(stream)
        except Exception as error:   # rclpy raises several kinds for a bad name
            raise ValueError(f'sensor {sensor!r} does not make a valid topic name '
                             f'{topic!r}: {error}') from error
        self._accel_streams[sensor] = stream
        with self._queue:
            self._batch.add_sensor(sensor)

    def _settle(self, stream, sensor=None):
        """Subscribe ``stream`` to its first option that has a publisher of its type.

        With no publisher on any option, the current subscription stays (at first, the
        first option). A sensor that changes topic loses its history (``sensor``: its name).
        """
        index = next((i for i, (topic, msg_type, _, _) in enumerate(stream.options)
                      if any(info.topic_type == type_name(msg_type)
                             for info in self.get_publishers_info_by_topic(topic))),
                     0 if stream.index is None else stream.index)
        if index == stream.index:
            return
        topic, msg_type, callback, qos = stream.options[index]
        if stream.subscription is not None:
            self.destroy_subscription(stream.subscription)
        stream.subscription = self.create_subscription(msg_type, topic, callback, qos)
        if stream.index is not None and sensor is not None:
            with self._queue:
                self._batch.samples[sensor] = array('d')
                self._batch.clouds[sensor] = []
                self._batch.cleared.add(sensor)
        stream.index = index
        self.get_logger().info(f'watching {self.resolve_topic_name(topic)} '
                               f'({type_name(msg_type)})')

    def discover(self):
        """Watch every accelerometer of the namespace not yet watched.

        A sensor is named by an ``accel/<name>/batch`` PointCloud2 topic or an
        ``accel/<name>`` Imu topic; :meth:`_settle` picks which of the two is read.
        """
        prefix = self.resolve_topic_name(ACCEL_PREFIX.rstrip('/')) + '/'
        found = []
        for topic, types in self.get_topic_names_and_types():
            name = topic[len(prefix):]
            if not (topic.startswith(prefix) and name):
                continue
            stem = name[:-len(BATCH_SUFFIX)]
            if name.endswith(BATCH_SUFFIX) and stem and type_name(PointCloud2) in types:
                found.append(stem)
            if type_name(Imu) in types:
                found.append(name)
        for sensor in dict.fromkeys(found):
            if sensor not in self._accel_streams:
                self._watch(sensor)

    def _on_accel(self, sensor, msg):
        # hot path (thousands a second): queue only
        a = msg.linear_acceleration
        row = (_stamp_s(msg.header.stamp), a.x, a.y, a.z)
        with self._queue:
            samples = self._batch.samples[sensor]
            samples.extend(row)
            if len(samples) >= 4 * FLUSH_AT:
                self._hand_over(report=False)
        self._frames[sensor] = msg.header.frame_id
        self.message_counts['accel'] += 1

    def _on_accel_batch(self, sensor, msg):
        # queue the message as it is: the report thread decodes it
        with self._queue:
            self._batch.clouds[sensor].append(msg)
            self._queue_rows(msg)
        self._frames[sensor] = msg.header.frame_id
        self.message_counts['accel'] += 1

    def _on_impact(self, msg):
        with self._queue:
            self._batch.impacts.append(_stamp_s(msg.header.stamp))
            if len(self._batch.impacts) >= FLUSH_AT:
                self._hand_over(report=False)
        self._impact_frame = msg.header.frame_id.rpartition('/')[0]
        self.message_counts['impacts'] += 1

    def _on_impact_batch(self, msg):
        with self._queue:
            self._batch.impact_clouds.append(msg)
            self._queue_rows(msg)
        self._impact_frame = msg.header.frame_id
        self.message_counts['impacts'] += 1

    def _queue_rows(self, msg):
        """Count a queued batch message; hand over when enough are (call with ``_queue``)."""
        self._batch.queued += max(1, msg.height * msg.width)
        if self._batch.queued >= FLUSH_AT:
            self._hand_over(report=False)

    def _on_state(self, msg):
        self.message_counts['impactor_state'] += 1
        try:
            _, stuck = impactor_stuck_flags(msg.name, msg.effort)
            state = (_stamp_s(msg.header.stamp), stuck, dampers_off(msg.effort))
        except ValueError as error:
            state = None
            self.get_logger().warning(f'{IMPACTOR_STATE} rejected: {error}',
                                      throttle_duration_sec=10.0)
        with self._queue:
            self._batch.states.append(state)

    def _on_parameters_set(self, parameters):
        for parameter in parameters:
            if parameter.name == 'window':
                self._window = parameter.value     # the report thread applies it

    def _on_timer(self):
        if self._discover_sensors:
            self.discover()
        for sensor, stream in self._accel_streams.items():
            self._settle(stream, sensor)
        self._settle(self._impact_stream)
        with self._queue:
            self._hand_over(report=True)

    # -- the report thread -------------------------------------------------------------
    def _hand_over(self, report):
        """Queue the current batch for the report thread (call with ``_queue`` held)."""
        batch = self._batch
        batch.clock_s = self.get_clock().now().nanoseconds * 1e-9
        batch.report = report
        self._batch = _Batch(batch.samples)
        self._jobs.append(batch)
        self._queue.notify()

    def _take_jobs(self):
        with self._queue:
            jobs, self._jobs = self._jobs, []
        return jobs

    def _work(self):
        while True:
            with self._queue:
                self._queue.wait_for(lambda: self._jobs or self._stopping)
                if self._stopping:
                    return
            # take the jobs under the core lock, so that batches are fed in their order
            with self._core_lock:
                try:
                    self._process(self._take_jobs())
                except Exception as error:   # keep monitoring whatever one batch did
                    if not self.context.ok():
                        return   # Ctrl-C shut the context down under a publish: no failure
                    self.get_logger().error(f'report failed: {error!r}',
                                            throttle_duration_sec=10.0)

    def report(self):
        """Feed the queued input to the core, then log and publish a report, in this thread.

        The timer does the same in the report thread every ``report_period``.

        Returns
        -------
        DiagnosticArray
            The array published on ``/diagnostics``.
        """
        with self._core_lock:
            with self._queue:
                self._hand_over(report=True)
            return self._process(self._take_jobs())

    def _process(self, jobs):
        """Feed batches to the core; publish a report if one of them asks for it."""
        if self._window != self._stats.window:
            self._stats.window = self._window
        report_due = False
        for job in jobs:
            for sensor in job.cleared:
                self._stats.clear_sensor(sensor)
            for sensor in job.samples:
                self._stats.add_sensor(sensor)
                rows = self._accel_rows(sensor, job)
                if rows is not None and self._stats.add_samples(sensor, rows[:, 0],
                                                                rows[:, 1:]):
                    self._last_arrival[sensor] = job.clock_s
            if job.impacts:
                self._stats.add_impacts(np.frombuffer(job.impacts, dtype=float))
            for msg in job.impact_clouds:
                try:
                    times = _stamps_s(sample_times_ns(msg))
                except ValueError as error:
                    self._stats.reject_impacts(msg.height * msg.width)
                    self.get_logger().warning(f'{IMPACTS}: batch rejected: {error}',
                                              throttle_duration_sec=10.0)
                    continue
                # the batch covers its interval from its stamp on, empty or not
                self._stats.add_impacts(times, start=_stamp_s(msg.header.stamp))
            for state in job.states:
                if state is None:
                    self._stats.reject_state()
                else:
                    self._stats.update_stuck(*state[:2])
                    self._dampers_off = state[2]
            report_due |= job.report
        if not report_due:
            return None
        clock_now = self.get_clock().now()
        clock_s = clock_now.nanoseconds * 1e-9
        report = self._stats.report()
        self.last_report = report
        array_msg = DiagnosticArray()
        array_msg.header.stamp = clock_now.to_msg()
        array_msg.status = [self._sensor_status(report, sensor, clock_s)
                            for sensor in report.sensors]
        array_msg.status.append(self._impacts_status(report))
        self._diagnostics.publish(array_msg)
        if self.get_parameter('log_reports').value:
            self._log(report, array_msg)
        return array_msg

    def _accel_rows(self, sensor, job):
        """Rows ``(t, ax, ay, az)`` (s, m/s^2) of ``sensor`` in ``job``, or None if none.

        The batch messages are decoded here, each by its own fields; a malformed one (a
        field missing, a bad datatype, short data) counts its rows as rejected samples.
        """
        parts = []
        if job.samples[sensor]:
            parts.append(np.frombuffer(job.samples[sensor], dtype=float).reshape(-1, 4))
        for msg in job.clouds[sensor]:
            try:
                cloud = rows_of(msg)
                parts.append(np.column_stack((_stamps_s(sample_times_ns(msg, cloud)),
                                              cloud['ax'], cloud['ay'], cloud['az'])))
            except ValueError as error:
                self._stats.reject_samples(sensor, msg.height * msg.width)
                self.get_logger().warning(
                    f'{accel_topic(sensor)}{BATCH_SUFFIX}: batch rejected: {error}',
                    throttle_duration_sec=10.0)
        return np.concatenate(parts) if parts else None

    def _status_name(self, item):
        return f'{self.get_name()}: {self.get_namespace().rstrip("/")}/{item}'

    def _sensor_status(self, report, sensor, clock_s):
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
        values = sensor_values(stats, lag, age, window, report.t)
        return DiagnosticStatus(
            level=DiagnosticStatus.WARN if problems else DiagnosticStatus.OK,
            name=self._status_name(sensor), message='; '.join(problems) or waiting or 'ok',
            hardware_id=self._frames.get(sensor, ''),
            values=[KeyValue(key=key, value=value_text(v)) for key, v in values])

    def _impacts_status(self, report):
        new_rejects = report.rejected_states - self._rejected_states_reported
        self._rejected_states_reported = report.rejected_states
        problems = []
        if math.isnan(report.stuck_fraction) and not self._dampers_off:
            problems.append(f'no {IMPACTOR_STATE} received')
        if new_rejects:
            problems.append(f'{new_rejects} {IMPACTOR_STATE} messages rejected')
        values = impact_values(report)
        return DiagnosticStatus(
            level=DiagnosticStatus.WARN if problems else DiagnosticStatus.OK,
            name=self._status_name('impacts'), message='; '.join(problems) or 'ok',
            hardware_id=self._impact_frame,
            values=[KeyValue(key=key, value=value_text(v)) for key, v in values])

    def _log(self, report, array):
        logger = self.get_logger()
        for sensor, status in zip(report.sensors, array.status):
            s = report.sensors[sensor]
            if s.samples == 0:
                (logger.info if status.level == DiagnosticStatus.OK else logger.warning)(
                    f'{accel_topic(sensor)}: {status.message}')
                continue
            line = sensor_text(accel_topic(sensor), s)
            if status.level == DiagnosticStatus.OK:
                logger.info(line)
            else:
                logger.warning(f'{line}: {status.message}')
        line = impacts_text(report.impacts_per_s, report.stuck_fraction,
                            report.stuck_impactors, report.impactors, self._dampers_off)
        if array.status[-1].level == DiagnosticStatus.OK:
            logger.info(line)
        else:
            logger.warning(f'{line}: {array.status[-1].message}')


def main(args=None):
    """Run the ``monitor`` node until Ctrl-C or an external shutdown."""
    rclpy.init(args=args)
    node = None
    try:
        node = VibrationMonitor()
        freeze_start_up_heap()   # its windows run every report: no walks of start-up objects
        executor = rclpy.executors.SingleThreadedExecutor()
        executor.add_node(node)
        spin_guarded(executor, lambda exc: node.get_logger().error(
            f'callback failed: {type(exc).__name__}: {exc}', throttle_duration_sec=1.0))
    except (KeyboardInterrupt, ExternalShutdownException):
        ignore_further_interrupts()
        settle_interrupt()
    finally:
        if node is not None:
            node.destroy_node()
        shutdown_quietly()


if __name__ == '__main__':
    main()
