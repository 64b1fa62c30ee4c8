"""``vibration_node``: a scene's vibration, stepped paced to the wall clock, on ROS 2 topics.

A thin adapter over :class:`~impact_damper_sim.live.realtime.LiveSimulation`: it declares and
validates the parameters, feeds commands to the core, paces it with
:class:`~impact_damper_sim.live.realtime.Pacer` and publishes what it produces. The topics and
their encodings are in :mod:`impact_damper_sim.ros.interface` and docs/node.md.

This module holds the node's life cycle: parameters, commands, the stepping thread and
``main``. What a chunk puts on the wire and when is in :mod:`.node_publishing`, the
``/diagnostics`` report in :mod:`.node_diagnostics` and the MCAP recorder in
:mod:`.node_recording`; :class:`VibrationNode` takes them in as mixins.

Run it with ``ros2 run impact_damper_sim vibration_node`` (or the ``vibration_node`` console
script), e.g. ``--ros-args -p scene:=rbs -r __ns:=/rbs``.
"""
from __future__ import annotations

import collections
import math
import sys
import threading
import time

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Vector3Stamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, JointState, PointCloud2
from std_msgs.msg import Float64, String
from std_srvs.srv import SetBool

from rclpy.parameter import Parameter

from ..live.realtime import CommandError, LiveSimulation, Pacer
from ..live.schedule import Schedule
from ..live.streams import live_scene
from ..recording.node_messages import NodeMessages, fault_command_text, float64_cdr, string_cdr
from ..recording.node_topics import STRING
from ..scene.schema import SceneError
from . import interface as itf
from .node_diagnostics import DiagnosticsMixin, _Stats
from .node_publishing import PublishingMixin
from .node_recording import RecordingMixin
from .parameters import PARAMETERS, RCLPY_PARAMETERS, ParameterError, check, declare_all, \
    parameters_markdown
from .wire import BusyNotice, HandoffLock, NameClash, Outlet, freeze_start_up_heap, \
    guard_services, ignore_further_interrupts, settle_interrupt, shutdown_quietly, spin_guarded


class VibrationNode(PublishingMixin, DiagnosticsMixin, RecordingMixin, Node):
    """The live simulator node.

    Parameters
    ----------
    node_name : str
        Node name.
    clock : callable
        Wall clock for pacing (s); ``time.monotonic`` by default (tests may inject one).
    start_stepping : bool
        Start the stepping thread at once (default). Tests that drive :meth:`tick`
        themselves pass False; :meth:`start` starts it later.
    **kwargs
        Passed to ``rclpy.node.Node`` (``context``, ``namespace``, ``parameter_overrides``,
        ``cli_args``).

    Raises
    ------
    SceneError
        The scene or a start-up parameter is invalid (the message names it).
    """

    #: how early (wall s) an item may be published with the one due before it, at most
    EARLY = 1.2e-3
    #: ... and in per-sample Imu periods: 1.1 sends each Imu sample with the one before it,
    #: so one wake-up sends 2 samples per accelerometer (every 2 ms at 1 kHz): half the
    #: wake-ups of one sample each, and a keep-last-5 reader holds 2 such pairs
    EARLY_SAMPLES = 1.1
    #: Imu samples per accelerometer any wake-up may send (or 1 ms of them, if more); one
    #: that finds a backlog may send up to MAX_BURST, earned at CATCH_UP_RATE
    BURST = 2
    #: wall time (s) between the wake-ups that send a backlog (twice the sample rate or more)
    CATCH_UP = 5e-4
    #: a backlog leaves at up to this many times the Imu rate, counted over the wall time
    #: since the previous wake-up: on a busy core a wake-up takes 1-3 ms, not CATCH_UP, and a
    #: fixed BURST per wake-up then drained a 35 ms backlog in 0.6 s (measured)
    CATCH_UP_RATE = 4.0
    #: ... in groups of at most this many samples per accelerometer (keep-last-5 readers)
    MAX_BURST = 4
    #: longest single wait of the stepping thread (s): it re-reads the schedule at least this
    #: often, whatever the pacing asks
    MAX_WAIT = 0.5
    #: shortest interval (s) between two "accepted" lines of one command topic: every
    #: command a person sends is acknowledged (once a second hid the second of two
    #: ``ros2 topic pub --once`` in a row, issue 27); a flood is thinned to 10 lines a second
    COMMAND_LOG_PERIOD = 0.1
    #: the stepping thread is reported stalled (ERROR) after this long without a cycle (s)
    STALL = 2.0
    #: a diagnostics period is "behind" when its achieved real-time factor falls short of
    #: the requested one by more than this fraction (the goal is >= 0.98 in every 1 s)
    RTF_TOLERANCE = 0.02

    def __init__(self, node_name='vibration_node', *, clock=time.monotonic,
                 start_stepping=True, **kwargs):
        super().__init__(node_name, **kwargs)
        self._wall = clock
        # commands, parameter changes and diagnostics (executor thread) and stepping
        # (stepping thread) touch the simulation under this lock, one chunk at a time
        self._lock = HandoffLock()
        self._thread = None
        self._stop = threading.Event()
        # set by a parameter change and by stop(): a long wait (a tiny real_time_factor) must
        # not outlive the setting that caused it
        self._wake = threading.Event()
        self._heartbeat = None   # wall time (s) of the stepping thread's last cycle
        self._last_log = {}
        self._pending = collections.deque()   # (sim ns, outlet, message or bytes, wire)
        self._last_cycle = 0.0   # wall time (s) of the stepping thread's last wake-up
        p, unknown = declare_all(self)
        # declared by rclpy, not by us; any other name is refused (rclpy lets an undeclared
        # '' through: it tests its names with any(), and '' is false)
        self._rclpy_parameters = set(self._parameters) & set(RCLPY_PARAMETERS)
        for name in unknown:
            self.get_logger().warning(f'parameter {name!r} is not one of this node\'s; '
                                      f"ignored (known: {', '.join(PARAMETERS)})")
        rate_limit = p['speed_rate_limit'] or None
        busy = BusyNotice(self.get_logger().info, 'loading the scene and the compiled kernels '
                     '(a cold Numba cache compiles them once: 10-25 s on 2 cores, by machine, '
                     '40 s or more on a busy one; 1-3 s after that)')
        try:
            scene, target = live_scene(p['scene'], p['overrides'] or (),
                                       speed_rate_limit=rate_limit)
            self.live = LiveSimulation(
                scene, sample_rate=p['sample_rate'] or None, imu_rate=p['imu_rate'] or None,
                initial_target=target,
                max_speed=p['max_speed'] or None, max_unbalance=p['max_unbalance'],
                noise_std=p['noise_std'], seed=p['noise_seed'],
                dampers_enabled=p['dampers_enabled'], method=p['method'] or None)
            self.live.step(0)   # load the compiled kernels now, not in the first paced tick
        finally:
            loaded = busy.stop()
        if loaded > 5.0:
            self.get_logger().info(f'scene and kernels ready after {loaded:.0f} s (compiled '
                                   'kernels are cached: the next start is quick)')
        self._params = p
        self.recorder = None
        self.record_error = None
        self.scene = scene
        # the rate limit in force at start: speed_rate_limit 0 at run time restores it
        self._start_speed_rate = (self.live.profile.max_rate
                                  if hasattr(self.live.profile, 'command') else None)
        self.schedule = None
        if p['schedule']:
            try:
                self.schedule = Schedule.load(p['schedule'])
                self.schedule.check(self.live)
            except SceneError as exc:
                raise ParameterError(f"parameter 'schedule': {exc}") from None
        self._period = 1.0 / self.live.sample_rate
        self._make_interfaces(p)
        self.pacer = Pacer(p['real_time_factor'], self.live.t, max_lag=p['max_lag'],
                           clock=self._wall)
        self.stats = _Stats(self._wall(), time.process_time(), self.live.t, self.live.t)
        self.rejected = 0
        # since start (clipped: values, per accelerometer once one clips)
        self.stats_total = {'samples': 0, 'impacts': 0, 'clipped': 0}
        self._growth_rate = self.live.linear_growth_rate()
        self._failure_logged = False
        self.add_on_set_parameters_callback(self._on_set_parameters)
        if p['record']:
            error = self.start_recording(p['record'], p['record_overwrite'])
            if error:
                raise ParameterError(f"parameter 'record': {error}")
        self._publish_state()
        self._flush(math.inf)
        self.get_logger().info(
            f'scene {scene.name!r}: {scene.basis.n_modes} modes, '
            f'{len(scene.impactors)} impactors, integrator dt {self.live.dt:g} s, '
            f'{len(self.live.accelerometers)} accelerometers at {self.live.sample_rate:g} Hz '
            f'(per-sample Imu at {self.live.imu_rate:g} Hz), '
            f"real_time_factor {p['real_time_factor']:g}")
        guard_services(self, lambda text: self._log('warning', text, 1.0, 'service'))
        if start_stepping:
            self.start()

    # -- set-up ---------------------------------------------------------------------------
    def _make_interfaces(self, p):
        # the bytes of every topic come from the ROS-free packer that study record uses
        messages = self._messages = NodeMessages(
            self.live, self.scene, namespace=self.get_namespace(),
            node_name=self.get_fully_qualified_name(), publish_clock=p['publish_clock'],
            truth=p['publish_truth'])
        self._accel_pubs = [Outlet(self, Imu, itf.accel_topic(acc.name), itf.SENSOR_QOS)
                            for acc in self.live.accelerometers]   # per-sample, imu_rate
        self._batch_pubs = [Outlet(self, PointCloud2, itf.accel_batch_topic(acc.name),
                                   itf.BATCH_QOS)
                            for acc in self.live.accelerometers]   # full-rate batches
        self._truth_pubs = [Outlet(self, PointCloud2, itf.accel_truth_topic(acc.name),
                                   itf.BATCH_QOS)
                            for acc in self.live.accelerometers] if messages.truth else []
        self._impact_pub = Outlet(self, PointCloud2, itf.IMPACTS, itf.EVENT_QOS)
        self._state_pub = Outlet(self, JointState, itf.IMPACTOR_STATE, itf.LATCHED_QOS)
        self._speed_pub = Outlet(self, Vector3Stamped, itf.ROTOR_SPEED, itf.COMMAND_QOS)
        self._joint_pub = Outlet(self, JointState, itf.ROTOR_JOINT_STATES, itf.COMMAND_QOS)
        # the tachometer and keyphasor: scenes with a rotor only
        self._tach_pubs = [] if messages.tach is None else [
            Outlet(self, PointCloud2, itf.ROTOR_TACH, itf.BATCH_QOS),
            Outlet(self, PointCloud2, itf.ROTOR_KEYPHASOR, itf.EVENT_QOS)]
        self._clock_pub = (Outlet(self, Clock, itf.CLOCK, itf.CLOCK_QOS)
                           if p['publish_clock'] else None)
        self._outlet_of = {**dict(zip(messages.imu, self._accel_pubs)),
                           **dict(zip(messages.batch, self._batch_pubs)),
                           **dict(zip(messages.truth, self._truth_pubs)),
                           **dict(zip((messages.tach, messages.keyphasor), self._tach_pubs)),
                           messages.impacts: self._impact_pub, messages.state: self._state_pub,
                           messages.speed: self._speed_pub, messages.joint: self._joint_pub,
                           messages.clock: self._clock_pub}
        for stream, outlet in self._outlet_of.items():
            if outlet is not None and (messages.streams[stream].topic, messages.streams[
                    stream].type_name) != (outlet.topic, outlet.type_name):
                raise RuntimeError(f'stream {messages.streams[stream]} is not {outlet.topic}')
        self._diag_pub = Outlet(self, DiagnosticArray, itf.DIAGNOSTICS, itf.DIAGNOSTICS_QOS)
        self._command_subs = [
            self.create_subscription(Float64, itf.SPEED_COMMAND, self.on_speed_command,
                                     itf.COMMAND_QOS),
            self.create_subscription(Float64, itf.UNBALANCE_COMMAND, self.on_unbalance_command,
                                     itf.COMMAND_QOS)]
        # sensor faults on command (YAML or JSON text); in a log once one is received
        self._fault_sub = self.create_subscription(String, itf.FAULT_COMMAND,
                                                   self.on_fault_command, itf.COMMAND_QOS)
        self.create_service(SetBool, '~/record', self.on_record_request)
        self._tick_period = p['tick_period']
        # the graph is read with the diagnostics: often enough, and off the stepping thread
        self._name_clash = NameClash(self, lambda text: self._log('warning', text))
        self._diag_timer = self.create_timer(
            p['diagnostics_period'], lambda: (self._name_clash(), self.publish_diagnostics()))
        self._state_timer = self.create_timer(p['state_period'], self.publish_state)
        # samples per stepped chunk, and how far (wall s) stepping runs ahead of publishing
        self._chunk = max(1, int(round(p['tick_period'] * self.live.sample_rate)))
        self._lookahead = p['tick_period']
        self._t_published = self.live.t

    def _log(self, level, text, throttle=None, key=None):
        """Log ``text`` at ``level`` (info, warning, error), at most once per ``throttle`` s
        per ``key``; to stderr once the context is gone (there is no rosout then)."""
        if throttle:
            now = time.monotonic()
            key = (level, key)
            if now - self._last_log.get(key, -math.inf) < throttle:
                return
            self._last_log[key] = now
        if not self.context.ok():
            print(f'[{level.upper()}] [{self.get_name()}]: {text}', file=sys.stderr)
            return
        logger = self.get_logger()   # one call site per severity (rclpy requires it)
        if level == 'info':
            logger.info(text)
        elif level == 'warning':
            logger.warning(text)
        else:
            logger.error(text)

    # -- commands -------------------------------------------------------------------------
    def on_speed_command(self, msg):
        """Apply a ``rotor/speed_command`` (rad/s), or reject it with a throttled warning."""
        return self._command(self.live.command_speed, msg, 0)

    def on_unbalance_command(self, msg):
        """Apply a ``rotor/unbalance_command`` (X >= 0), or reject it with a warning."""
        return self._command(self.live.command_unbalance, msg, 1)

    def _command(self, apply, msg, which):
        """Apply a command (a received ``Float64``, or a schedule entry's value: recorded
        alike), or reject it with a throttled warning; True when applied."""
        value = getattr(msg, 'data', msg)
        try:
            with self._lock:
                if self.recorder is not None and isinstance(msg, (Float64, float)):
                    # every command received is recorded, the rejected ones too
                    self._record(self._command_subs[which].topic_name, 'std_msgs/msg/Float64',
                                 itf.COMMAND_QOS, float64_cdr(value))
                apply(value)
        except CommandError as exc:
            self.rejected += 1
            self._log('warning', f'rejected: {exc}', 1.0, 'command')
            return False
        except Exception as exc:   # no message may stop the node
            self.rejected += 1
            self._log('error', f'command {value!r} refused: {type(exc).__name__}: {exc}', 1.0,
                      'command')
            return False
        self.stats.commands += 1
        topic = (itf.SPEED_COMMAND, itf.UNBALANCE_COMMAND)[which]
        self._log('info', f'{topic} {value:g} accepted at sim time {self.live.t:.3f} s',
                  self.COMMAND_LOG_PERIOD, topic)
        return True

    def on_fault_command(self, msg):
        """Apply an ``accel/fault_command`` (a ``std_msgs/String``), or refuse it in one WARN
        line naming the key; True when applied."""
        return self._fault_command(msg.data)

    def _fault_command(self, text):
        """Apply a fault command (a received text, or a schedule entry's: recorded alike, as
        received) from the next stepped sample, or refuse it with a throttled warning; True
        when applied. Logged at INFO, never in /diagnostics (a real sensor does not report
        its own faults)."""
        topic = itf.FAULT_COMMAND
        try:
            with self._lock:
                if self.recorder is not None:   # every command received, refused ones too
                    self._record(self._fault_sub.topic_name, STRING, itf.COMMAND_QOS,
                                 string_cdr(text))
                action, names = self.live.fault_command(text, key=topic)
        except CommandError as exc:
            self.rejected += 1
            self._log('warning', f'rejected: {exc}', 1.0, topic)
            return False
        except Exception as exc:   # no message may stop the node
            self.rejected += 1
            self._log('error', f'{topic} {text!r} refused: {type(exc).__name__}: {exc}', 1.0,
                      topic)
            return False
        self.stats.commands += 1
        what = (f"fault {names[0]!r} added" if action == 'add' else
                f"cleared {', '.join(repr(n) for n in names) or 'nothing (none active)'}")
        self._log('info', f'{topic}: {what}, accepted at sim time {self.live.t:.3f} s',
                  self.COMMAND_LOG_PERIOD, topic)
        return True

    def _on_set_parameters(self, params):
        changes = {}
        for prm in params:
            name, value = prm.name, prm.value
            if name in self._rclpy_parameters:
                continue   # rclpy's own (use_sim_time): rclpy checks and applies it
            why = check(name, value)
            if why:
                return SetParametersResult(successful=False, reason=f'{name}: {why}')
            if PARAMETERS[name][3]:
                return SetParametersResult(successful=False,
                                           reason=f'{name} is read-only (set at start)')
            if name == 'dampers_enabled' and value and not self.scene.impactors:
                return SetParametersResult(successful=False, reason=(
                    f'scene {self.scene.name!r} has no impactors'))
            changes[name] = value
        # all valid: apply together
        try:
            with self._lock:
                self._apply(changes)
                if changes:   # in the log, as ros2 bag records a parameter change
                    self._record(itf.PARAMETER_EVENTS, 'rcl_interfaces/msg/ParameterEvent',
                                 itf.PARAMETER_EVENTS_QOS,
                                 self._messages.parameter_event(list(changes.items())))
        except (CommandError, ValueError) as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _apply(self, changes):
        if 'real_time_factor' in changes:
            self.pacer.reset(changes['real_time_factor'], self._published_t())
            self._wake.set()   # a wait computed for the old factor ends now
            # the achieved factor is measured against the new one from now on
            wall, st = self._wall(), self.stats
            self.stats = _Stats(wall, time.process_time(), self.live.t, self._delivered_t(wall),
                                steps0=self.live.steps, growing=st.growing,
                                last_peak=st.last_peak)
        if 'speed_rate_limit' in changes and self._start_speed_rate is not None:
            # without a commanded rotor it is kept and does nothing, as at start
            self.live.set_speed_rate(changes['speed_rate_limit'] or self._start_speed_rate)
        if 'noise_std' in changes or 'noise_seed' in changes:
            self.live.set_noise(changes.get('noise_std', self.live.noise_std),
                                changes.get('noise_seed'))
            self._messages.set_noise_variances(self.live.imu_noise_variances())
        if 'dampers_enabled' in changes:
            self.live.set_dampers_enabled(changes['dampers_enabled'])
            self._publish_state()

    @property
    def outlets(self):
        """list of _Outlet: Every publisher of the node (``topic``, ``type_name``, ``count``)."""
        return [*self._accel_pubs, *self._batch_pubs, *self._truth_pubs, self._impact_pub,
                self._state_pub, self._speed_pub, self._joint_pub, *self._tach_pubs,
                self._diag_pub] + (
                    [self._clock_pub] if self._clock_pub else [])

    # -- stepping -------------------------------------------------------------------------
    def start(self):
        """Start the stepping thread (idempotent).

        Stepping runs in its own thread, not in an executor callback: the executor then only
        wakes for commands, parameters and the slow timers, and a long chunk of physics
        never starves them (each chunk holds the lock for a few ms at most).
        """
        if self._thread is not None:
            return
        with self._lock:
            # the schedule and the first diagnostics period begin now, not when the node was
            # built: what ran in between (main's heap freeze, 0.15-0.3 s) is no deficit that
            # the first samples would have to catch up in a burst
            wall = self._wall()
            self.pacer.reset(self.pacer.real_time_factor, self._published_t())
            self.stats = _Stats(wall, time.process_time(), self.live.t, self._delivered_t(wall),
                                steps0=self.live.steps)
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name='vibration_stepping',
                                        daemon=True)
        self._thread.start()

    def stop(self):
        """Stop the stepping thread and wait for it (idempotent).

        What was already stepped (at most one chunk ahead of the clock) is published and
        recorded now, so the counters, the topics and the log agree.
        """
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join()
            self._thread = None
        if self.context.ok():
            self._flush(math.inf)

    def _run(self):
        """The stepping thread: compute one chunk ahead, publish each item at its time.

        Samples are published one by one when the wall clock reaches their sim time (through
        the pacer), not in bursts per chunk, so a keep-last-5 ``qos_profile_sensor_data``
        subscriber keeps up. Physics runs one chunk (``tick_period`` of sim time) ahead.
        """
        cycles = 0
        while not self._stop.is_set():
            self._heartbeat = self._wall()
            cycles += 1
            if cycles % 64 == 0 and not self.context.ok():   # a C call: not every cycle
                break
            try:
                delay = self._cycle()
            except Exception as exc:   # a bug must not kill the node silently
                if not self.context.ok():
                    break   # Ctrl-C shut the context down under a publish: not a failure
                with self._lock:
                    self.live.failure = f'{type(exc).__name__}: {exc}'
                delay = self._tick_period
            if not delay > 0:   # 0, or NaN from a degenerate schedule
                continue
            if delay > 0.05:
                if self._wake.wait(min(delay, self.MAX_WAIT)):
                    self._wake.clear()
            else:
                time.sleep(delay)   # cheaper than Event.wait at a few kHz

    def _cycle(self):
        """Publish what is due, step a chunk when the buffer runs short; return a wait (s)."""
        live = self.live
        now = self._wall()
        rtf = self.pacer.real_time_factor
        held = False
        if rtf > 0:
            # pairs of Imu samples (see EARLY_SAMPLES), far below a keep-last-5 reader's
            # depth; a backlog (the thread was descheduled) leaves in small groups, not in
            # one burst, at CATCH_UP_RATE x the stream's rate over the time since the last
            # wake-up. Counted in Imu samples, not in the full-rate batch's: at 20 kHz 1 ms
            # of the latter would be 20 Imu messages at once
            imu_period = 1.0 / self.live.imu_rate
            per_ms = max(self.BURST, math.ceil(1e-3 * rtf / imu_period - 1e-9))
            earned = self.CATCH_UP_RATE * rtf * (now - self._last_cycle) / imu_period
            # (+1e-9: 4 x 0.5 ms of a 2 kHz stream can round to 3.999...)
            held = self._flush(now + min(self.EARLY, self.EARLY_SAMPLES * imu_period / rtf),
                               max(per_ms, math.floor(min(earned, self.MAX_BURST) + 1e-9)))
            self._last_cycle = now
        else:
            self._flush(math.inf)
        if live.failure is not None:
            self._report_failure()
            return self._tick_period
        # lag of the stream, not of the last item out: at a tiny factor that stands still
        # between items (500 s at 1e-6) and every wake-up dropped a "deficit"
        target, lag = self.pacer.target(self._delivered_t(now))
        self.stats.lag = max(self.stats.lag, lag)
        if live.t < target + self._lookahead * self.pacer.real_time_factor - 1e-12 \
                or math.isinf(target):
            if live.t < target - self._chunk * self._period < math.inf:
                self.stats.overruns += 1   # a whole chunk behind schedule: late
            self._step(self._chunk)
            self._lock.hand_over()
            return self.CATCH_UP if held else 0.0   # a backlog waits, however late we are
        if held:
            return self.CATCH_UP
        if self._pending:
            return self.pacer.wall_at(self._pending[0][0] * 1e-9) - self._wall()
        return min(self._tick_period, self.pacer.wall_at(live.t) - self._wall())

    def _published_t(self):
        """Sim time up to which items have been published (s)."""
        return self._t_published

    def _delivered_t(self, wall):
        """Sim time (s) whose items are all out by wall time ``wall`` (s): the schedule's,
        up to the first item still queued (the queue is in time order: all before it are
        out) and the stepped time; never before the published time (an item may leave up
        to ``EARLY`` before its time). Never decreases between resets of the pacer, so the
        achieved factor is never negative. Call with the lock."""
        pending = self._pending
        first = pending[0][0] * 1e-9 if pending else math.inf
        return max(self._t_published, min(self.live.t, self.pacer.sim_at(wall), first))

    def destroy_node(self):
        """Stop stepping, finish any recording, then destroy the node."""
        self.stop()
        self.stop_recording()
        return super().destroy_node()

    def tick(self):
        """Step up to the paced sim time and publish it all now (tests drive this by hand).

        With ``real_time_factor`` 0 one chunk is stepped per call.
        """
        live = self.live
        if live.failure is not None:
            self._report_failure()
            return
        target, lag = self.pacer.target(live.t)
        self.stats.lag = max(self.stats.lag, lag)
        while True:
            n = (self._chunk if math.isinf(target)
                 else int(math.floor((target - live.t) / self._period + 1e-9)))
            if n <= 0 or not self._step(min(n, self._chunk)):
                break
            if math.isinf(target):
                break
        self._flush(math.inf)

    def _step(self, n):
        """Step ``n`` samples (fewer when a schedule entry falls inside them: it applies at
        its sample boundary) and queue what they produce; False once the simulation failed."""
        with self._lock:
            if self.schedule is not None and not self.schedule.done:
                self._play_schedule()
                ahead = self.schedule.samples_to_next(self.live.t, self.live.sample_rate)
                if ahead:
                    n = min(n, ahead)
            batch = self.live.step(n)
            if batch is None:
                self._report_failure()
                return False
            self._queue_batch(batch)
            self._queue_time()
        return True


    def _play_schedule(self):
        """Apply the schedule entries due now, each key as the live command or parameter
        change it stands for (recorded as such; a refused one is logged, as live)."""
        for entry in self.schedule.due(self.live.t, self.live.sample_rate):
            for key, kind, name, value in entry.commands:
                if key in ('fault', 'clear_fault'):   # as the text a live command sends
                    self._fault_command(fault_command_text(key, value))
                    continue
                if kind == 'topic':
                    apply = (self.live.command_speed if key == 'speed'
                             else self.live.command_unbalance)
                    self._command(apply, float(value), 0 if key == 'speed' else 1)
                    continue
                result = self.set_parameters([Parameter(name, value=value)])[0]
                if not result.successful:
                    self._log('warning', f'schedule entry at {entry.at:g} s: {name} refused: '
                                         f'{result.reason}')


def main(args=None):
    """Entry point: ``ros2 run impact_damper_sim vibration_node [--ros-args ...]``.

    Exit status 0 on Ctrl-C or shutdown, 2 (one line on stderr) when the scene or a start-up
    parameter is invalid.
    """
    import signal

    from rclpy.exceptions import ParameterException
    rclpy.init(args=args)
    # a closed terminal or an ended remote session (SIGHUP) ends the node as SIGTERM does,
    # finishing any recording, instead of killing it mid-file
    signal.signal(signal.SIGHUP, lambda *_: signal.raise_signal(signal.SIGTERM))
    node = None
    status = 0
    try:
        node = VibrationNode(start_stepping=False)
        freeze_start_up_heap()   # no 150 ms full collections of start-up objects while paced
        node.start()
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        spin_guarded(executor, lambda exc: node._log(
            'error', f'callback failed: {type(exc).__name__}: {exc}', 1.0, 'spin'))
    except (KeyboardInterrupt, ExternalShutdownException):
        ignore_further_interrupts()
        settle_interrupt()
    except (SceneError, ParameterException) as exc:
        print(f'vibration_node: {exc}', file=sys.stderr)
        status = 2
    finally:
        if node is not None:
            node.destroy_node()
        shutdown_quietly()
    return status


# PARAMETERS and parameters_markdown are re-exported: they were defined here before
__all__ = ['PARAMETERS', 'VibrationNode', 'main', 'parameters_markdown']


if __name__ == '__main__':
    sys.exit(main())
