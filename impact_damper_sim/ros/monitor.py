"""``monitor``: rolling vibration statistics of running ``vibration_node``\\ s, on /diagnostics.

A thin adapter over :class:`impact_damper_sim.live.monitoring.RollingVibrationStats`, one
core per machine it follows. A machine is a namespace (:class:`.monitor_machine.Machine`):
the monitor subscribes to its accelerometers, ``impacts`` and ``impactor_state``, feeds
their header stamps (sim time, each machine its own) and values to the machine's core, and
every ``report_period`` logs and publishes a diagnostic_msgs/DiagnosticArray on
``/diagnostics`` with the statuses of every machine.

Which machines (parameter ``namespaces``, read-only):

* unset: the monitor's own namespace, read with relative topic names, so ``ros2 run
  impact_damper_sim monitor --ros-args -r __ns:=/hpotp`` watches the simulator in ``/hpotp``
  and logs one line per sensor and one for impacts;
* a list of absolute or relative ROS namespaces (``['pump1', 'pump2']``; relative ones
  resolve against the monitor's namespace), and ``'*'`` for every namespace in which an
  accelerometer topic appears (checked at start and at every report): one line per machine
  per report, namespace first, padded so that the figures line up. A machine that stops
  publishing stays listed, its sensors WARN ``stale``; one that comes back is read again.

An invalid entry is refused at start with one line naming ``namespaces`` and the allowed
form (``main`` exits 2). Each machine's ``hardware_id`` is taken from its ``vibration_node``'s
own status on ``/diagnostics`` (see :mod:`.monitor_machine`).

Threads: the subscription callbacks only queue what they receive (a few microseconds a
message: batches are decoded later, as arrays). A report thread owns the cores: it decodes
and feeds them the queued input, and computes and publishes the reports, so that a long
window (at 60 s and 20 kHz, an FFT of 1.2 million points a sensor) does not stall the
executor while the best-effort queues fill.

Diagnostics: per machine one status per sensor and one for impacts, their keys (units in the
names) and levels in docs/node.md ("The monitor"); the values come from
:mod:`impact_damper_sim.live.monitor_text`.
"""
from __future__ import annotations

import sys
import threading

import rclpy
import rclpy.executors
from diagnostic_msgs.msg import DiagnosticArray
from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter

from .interface import DIAGNOSTICS, DIAGNOSTICS_QOS, IMPACTS
from .monitor_machine import (
    FLUSH_AT,
    SIMULATION_STATUS,
    STALE_WINDOWS,
    Machine,
    MonitorParameterError,
    machines_in,
    plant_line,
    resolve_namespaces,
)
from .parameters import serve_unset_parameters
from .process import (
    SignalStop,
    freeze_start_up_heap,
    shutdown_quietly,
    spin_guarded,
)
from .service_guard import guard_services


class _Job:
    """Batches handed to the report thread: ``[(machine, batch)]``, the node clock at the
    hand-over (s), and, for a report, the machines to report (else None)."""

    __slots__ = ('batches', 'clock_s', 'report')

    def __init__(self, batches, clock_s, report):
        self.batches, self.clock_s, self.report = batches, clock_s, report


class VibrationMonitor(Node):
    """Node that reports rolling vibration statistics of one or more machines.

    Parameters
    ----------
    node_name : str
        Node name (default ``monitor``).
    **kwargs
        Passed to :class:`rclpy.node.Node` (``context``, ``namespace``,
        ``parameter_overrides``, ...).

    Raises
    ------
    MonitorParameterError
        ``namespaces`` or ``sensors`` has an entry that is not a valid name.

    Attributes
    ----------
    machines : dict of str to Machine
        The machines followed, by namespace, in order (listed first, then discovered).
    """

    def __init__(self, node_name='monitor', **kwargs):
        super().__init__(node_name, **kwargs)
        names = self.declare_parameter(
            'namespaces', Parameter.Type.STRING_ARRAY, ParameterDescriptor(
                description="machines to follow: absolute ('/pump1') or relative ('pump1', "
                            "resolved against the monitor's namespace) ROS namespaces, and "
                            "'*' for every namespace with an accelerometer topic (checked "
                            'every report period); unset: the own namespace, with one log '
                            'line per sensor instead of one per machine',
                read_only=True)).value or []
        sensors = self.declare_parameter(
            'sensors', Parameter.Type.STRING_ARRAY, ParameterDescriptor(
                description='accelerometers to watch in each machine, on topics '
                            'accel/<name>/batch (PointCloud2), or accel/<name> (Imu) when '
                            'only that is published; unset or empty: discover the accel/* '
                            'topics of each machine at start and every report period',
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
            description='log the report lines every report period: one per machine when '
                        'namespaces is set, else one per sensor and one for impacts'))
        self.add_post_set_parameters_callback(self._on_parameters_set)
        serve_unset_parameters(self)   # GetParameters naming an unset parameter answers all

        # owned by the report thread (or a caller of report()), under _core_lock
        self._core_lock = threading.Lock()
        self._window = window
        # shared with the callbacks, under _queue (callbacks never wait on the cores)
        self._queue = threading.Condition()
        self._jobs = []
        self._stopping = False
        self._machines = {}         # namespace -> Machine (changed under _queue)
        self._sensors = list(sensors)
        self._plant = bool(names)   # log one line per machine
        try:
            namespaces, self._discover_machines = resolve_namespaces(names,
                                                                     self.get_namespace())
            for namespace in namespaces or ([] if self._discover_machines
                                            else [self.get_namespace()]):
                self._add_machine(namespace)
        except MonitorParameterError:
            Node.destroy_node(self)   # and with it any subscription made
            raise
        self._diagnostics = self.create_publisher(DiagnosticArray, DIAGNOSTICS,
                                                  DIAGNOSTICS_QOS)
        # each machine's own hardware_id, from its vibration_node's status
        self.create_subscription(DiagnosticArray, DIAGNOSTICS, self._on_diagnostics,
                                 DIAGNOSTICS_QOS)
        self.discover()
        self._worker = threading.Thread(target=self._work, name=f'{node_name}-report',
                                        daemon=True)
        self._worker.start()
        self._timer = self.create_timer(period, self._on_timer)
        # no request may stop the node (a SetParameters with an unknown type raises in rclpy)
        guard_services(self, lambda text: self.get_logger().warning(
            text, throttle_duration_sec=1.0))

    # -- what is followed --------------------------------------------------------------
    @property
    def machines(self):
        """The machines followed, by namespace (dict of str to Machine, a copy)."""
        return dict(self._machines)

    def _first(self):
        return next(iter(self._machines.values()), None)

    @property
    def sensors(self):
        """Names of the sensors watched in the first machine (tuple of str)."""
        machine = self._first()
        return tuple(machine.accel_streams) if machine else ()

    @property
    def topics(self):
        """The topic read per sensor, and ``impacts``, in the first machine (dict of str to
        str; relative in the monitor's own namespace)."""
        machine = self._first()
        if machine is None:
            return {}
        read = {sensor: stream.topic for sensor, stream in machine.accel_streams.items()}
        read[IMPACTS] = machine.impact_stream.topic
        return read

    @property
    def message_counts(self):
        """Messages received per stream, over all machines (dict of str to int): ``accel``
        (Imu and batch messages), ``impacts`` (WrenchStamped and batch messages),
        ``impactor_state``."""
        total = {'accel': 0, 'impacts': 0, 'impactor_state': 0}
        for machine in list(self._machines.values()):
            for key, count in machine.message_counts.items():
                total[key] += count
        return total

    @property
    def last_report(self):
        """The latest report of the first machine's core (VibrationReport or None)."""
        machine = self._first()
        return machine.last_report if machine else None

    def destroy_node(self):
        """Stop the report thread, then destroy the node."""
        with self._queue:
            self._stopping = True
            self._queue.notify()
        self._worker.join(timeout=5.0)
        return super().destroy_node()

    def _add_machine(self, namespace):
        machine = Machine(self, namespace, self._sensors, self._window)
        with self._queue:
            self._machines[namespace] = machine
        if self._plant:
            self.get_logger().info(f'following the machine in {namespace}')

    def discover(self):
        """Follow new machines (with ``'*'`` in ``namespaces``), and watch every accelerometer
        of each machine not yet watched (``sensors`` unset).

        A machine is a namespace with an ``accel/<name>/batch`` PointCloud2 topic or an
        ``accel/<name>`` Imu topic in the graph; the machine picks which of the two it reads.
        """
        looking = [m for m in self._machines.values() if m.discover_sensors]
        if not (looking or self._discover_machines):
            return
        topics = self.get_topic_names_and_types()
        if self._discover_machines:
            for namespace in sorted(set(machines_in(topics)) - set(self._machines)):
                self._add_machine(namespace)
                if self._machines[namespace].discover_sensors:
                    looking.append(self._machines[namespace])
        for machine in looking:
            machine.discover(topics)

    def _on_diagnostics(self, msg):
        # a vibration_node's status is '<its full name>: simulation'; its namespace is the
        # machine's (statuses of others, this monitor's included, are skipped)
        for status in msg.status:
            if status.name.endswith(SIMULATION_STATUS):
                node = status.name[:-len(SIMULATION_STATUS)]
                machine = self._machines.get(node.rpartition('/')[0] or '/')
                if machine is not None:
                    machine.node_hardware_id = status.hardware_id

    def _on_parameters_set(self, parameters):
        for parameter in parameters:
            if parameter.name == 'window':
                self._window = parameter.value     # the report thread applies it

    def _on_timer(self):
        self.discover()
        for machine in list(self._machines.values()):
            machine.settle_all()
        with self._queue:
            self._hand_over(report=True)

    # -- the report thread -------------------------------------------------------------
    def _hand_over(self, report, machine=None):
        """Queue the machines' batches (all, or ``machine``'s) for the report thread (call
        with ``_queue`` held); ``report``: the report thread then reports every machine."""
        machines = tuple(self._machines.values())
        batches = [(m, m.take_batch()) for m in (machines if machine is None else (machine,))]
        clock_s = self.get_clock().now().nanoseconds * 1e-9
        self._jobs.append(_Job(batches, clock_s, machines if report else None))
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
        """Feed the queued input to the cores, then log and publish a report, in this thread.

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
        """Feed batches to the cores; publish a report if one of them asks for it."""
        window = self._window
        due = None
        for job in jobs:
            for machine, batch in job.batches:
                if machine.stats.window != window:
                    machine.stats.window = window
                machine.feed(batch, job.clock_s)
            if job.report is not None:
                due = job.report
        if due is None:
            return None
        clock_now = self.get_clock().now()
        clock_s = clock_now.nanoseconds * 1e-9
        name = self.get_fully_qualified_name()
        array_msg = DiagnosticArray()
        array_msg.header.stamp = clock_now.to_msg()
        reported = []
        for machine in due:
            if machine.stats.window != window:
                machine.stats.window = window
            statuses = machine.statuses(clock_s, name)
            reported.append((machine, statuses))
            array_msg.status.extend(statuses)
        self._diagnostics.publish(array_msg)
        if self.get_parameter('log_reports').value:
            self._log(reported)
        return array_msg

    def _log(self, reported):
        """Log the report: one line per sensor and for impacts, or one per machine."""
        logger = self.get_logger()
        if not self._plant:
            for machine, statuses in reported:
                for ok, text in machine.line_parts(statuses):
                    _say(logger, ok, text)
            return
        if not reported:
            logger.info('no machine found yet (no accel/* topic in the graph)')
            return
        width = max(len(machine.namespace) for machine, _ in reported)
        for machine, statuses in reported:
            parts = machine.line_parts(statuses)
            line = plant_line(machine.namespace, width, [text for _, text in parts])
            _say(logger, all(ok for ok, _ in parts), line)


def _say(logger, ok, text):
    # one call site per severity: rclpy refuses a site whose severity changes
    if ok:
        logger.info(text)
    else:
        logger.warning(text)


def main(args=None):
    """Run the ``monitor`` node until Ctrl-C or an external shutdown.

    Exit status 0 on Ctrl-C, SIGTERM, SIGHUP or shutdown, 2 (one line on stderr) when a
    start-up parameter is invalid.
    """
    stop = SignalStop()   # before rclpy.init: rclpy's handlers chain to it
    rclpy.init(args=args)
    node = None
    try:
        node = VibrationMonitor()
        stop.begin_running()   # signals only noted from here: its threads start
        freeze_start_up_heap()   # its windows run every report: no walks of start-up objects
        executor = rclpy.executors.SingleThreadedExecutor()
        executor.add_node(node)
        spin_guarded(executor, lambda exc: node.get_logger().error(
            f'callback failed: {type(exc).__name__}: {exc}', throttle_duration_sec=1.0))
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (MonitorParameterError, ParameterException) as exc:
        print(f'monitor: {exc}', file=sys.stderr)
        return 2
    except Exception:
        if not stop.received:
            raise
        # the signal's shutdown under start-up ("context is invalid"): a stop, not a failure
    finally:
        stop.begin_clean_up()
        if node is not None:
            node.destroy_node()
        shutdown_quietly()
    return 0


__all__ = ['FLUSH_AT', 'STALE_WINDOWS', 'MonitorParameterError', 'VibrationMonitor', 'main']


if __name__ == '__main__':
    sys.exit(main())
