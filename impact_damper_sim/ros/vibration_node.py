"""``vibration_node``: a scene's vibration, stepped paced to the wall clock, on ROS 2 topics.

A thin adapter over the ROS-free core: :class:`~impact_damper_sim.live.realtime.
LiveSimulation` steps the scene and takes every command, and :class:`~impact_damper_sim.
live.pacing.Outbox` decides when to step and what to send at each wake-up. The node declares
and validates the parameters, turns topics, services and parameter changes into calls of the
core, runs the stepping thread and owns three helpers, each given what it needs:
:class:`~.node_publishing.Publishers` (the outlets, and what a chunk queues),
:class:`~.node_diagnostics.Diagnostics` (``/diagnostics`` and its counters) and
:class:`~.node_recording.Recording` (the MCAP recorder). The topics and their encodings are
in :mod:`impact_damper_sim.ros.interface` and docs/node.md.

Run it with ``ros2 run impact_damper_sim vibration_node`` (or the ``vibration_node`` console
script), e.g. ``--ros-args -p scene:=rbs -r __ns:=/rbs``.
"""
from __future__ import annotations

import math
import sys
import threading
import time

import rclpy
from rcl_interfaces.msg import SetParametersResult
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_msgs.msg import Float64, String
from std_srvs.srv import SetBool

from ..live.pacing import Outbox, Pacer
from ..live.realtime import CommandError, LiveSimulation
from ..live.schedule import Schedule
from ..live.streams import live_scene
from ..recording.message_cdr import fault_command_text, float64_cdr, string_cdr
from ..recording.node_messages import NodeMessages
from ..recording.node_topics import STRING
from ..scene.schema import SceneError
from . import interface as itf
from .handoff import HandoffLock
from .interface import named
from .node_diagnostics import Counters, Diagnostics
from .node_publishing import Publishers
from .node_recording import Recording
from .notices import BusyNotice, NameClash, ThrottledLog
from .parameters import PARAMETERS, RCLPY_PARAMETERS, ParameterError, check, declare_all
from .process import (
    SignalStop,
    freeze_start_up_heap,
    shutdown_quietly,
    spin_guarded,
    thread_stack,
)
from .service_guard import guard_services
from .stepping import CONTEXT_EVERY, wait_for


class VibrationNode(Node):
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

    #: longest single wait of the stepping thread (s): it re-reads the schedule at least this
    #: often, whatever the pacing asks
    MAX_WAIT = 0.5
    #: shortest interval (s) between two "accepted" lines of one command topic: every
    #: command a person sends is acknowledged (once a second hid the second of two
    #: ``ros2 topic pub --once`` in a row, issue 27); a flood is thinned to 10 lines a second
    COMMAND_LOG_PERIOD = 0.1

    def __init__(self, node_name='vibration_node', *, clock=time.monotonic,
                 start_stepping=True, **kwargs):
        super().__init__(node_name, **kwargs)
        self._wall = clock
        # commands, parameter changes and diagnostics (executor thread) and stepping
        # (stepping thread) touch the simulation under this lock, one chunk at a time
        self._lock = HandoffLock()
        self._thread = None
        self._shared = None   # the SharedStepping that steps this node, if any
        self._stop = threading.Event()
        # set by a parameter change and by stop(): a long wait (a tiny real_time_factor) must
        # not outlive the setting that caused it
        self._wake = threading.Event()
        self._heartbeat = None   # wall time (s) of the stepping thread's last cycle
        self._log = ThrottledLog(self)
        p, unknown = declare_all(self)
        # declared by rclpy, not by us; any other name is refused (rclpy lets an undeclared
        # '' through: it tests its names with any(), and '' is false)
        self._rclpy_parameters = set(self._parameters) & set(RCLPY_PARAMETERS)
        for name in unknown:
            self.get_logger().warning(f'parameter {name!r} is not one of this node\'s; '
                                      f"ignored (known: {', '.join(PARAMETERS)})")
        busy = BusyNotice(self.get_logger().info, 'loading the scene and the compiled kernels '
                     '(a cold Numba cache compiles them once: 10-25 s on 2 cores, by machine, '
                     '40 s or more on a busy one; 1-3 s after that)')
        try:
            scene, target = live_scene(p['scene'], p['overrides'] or (),
                                       speed_rate_limit=p['speed_rate_limit'] or None)
            self.live = LiveSimulation(
                scene, sample_rate=p['sample_rate'] or None, imu_rate=p['imu_rate'] or None,
                initial_target=target,
                max_speed=p['max_speed'] or None, max_unbalance=p['max_unbalance'],
                noise_std=p['noise_std'], seed=p['noise_seed'],
                dampers_enabled=p['dampers_enabled'], method=p['method'] or None)
            self.live.step(0)   # load the compiled kernels now, not in the first paced tick
        except SceneError as exc:   # the core names the quantity; the node the parameter
            errors = tuple(named(e) for e in exc.errors)
            if errors == exc.errors:
                raise
            raise ParameterError(errors, exc.source) from None
        finally:
            loaded = busy.stop()
        if loaded > 5.0:
            self.get_logger().info(f'scene and kernels ready after {loaded:.0f} s (compiled '
                                   'kernels are cached: the next start is quick)')
        self._params = p
        self.scene = scene
        self.schedule = None
        if p['schedule']:
            try:
                self.schedule = Schedule.load(p['schedule'])
                self.schedule.check(self.live)
            except SceneError as exc:
                raise ParameterError(f"parameter 'schedule': {exc}") from None
        self._period = 1.0 / self.live.sample_rate
        # samples per stepped chunk; stepping starts when less than a chunk's wall time is
        # stepped ahead of publishing (and refills Outbox.REFILL more)
        self._tick_period = p['tick_period']
        self._chunk = max(1, int(round(p['tick_period'] * self.live.sample_rate)))
        self.pacer = Pacer(p['real_time_factor'], self.live.t, max_lag=p['max_lag'],
                           clock=self._wall)
        self.outbox = Outbox(self.pacer, imu_rate=self.live.imu_rate,
                             lookahead=p['tick_period'], chunk=self._chunk * self._period,
                             t_sim=self.live.t, group=p['imu_group'])
        self._make_interfaces(p)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        if p['record']:
            error = self.start_recording(p['record'], p['record_overwrite'])
            if error:
                raise ParameterError(f"parameter 'record': {error}")
        self.publishing.publish_state_now()
        self._flush()
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
        self._messages = NodeMessages(
            self.live, self.scene, namespace=self.get_namespace(),
            node_name=self.get_fully_qualified_name(), publish_clock=p['publish_clock'],
            truth=p['publish_truth'])
        # the helpers log through _log late-bound (tests wrap it to read what is logged)
        log = lambda *args: self._log(*args)   # noqa: E731
        self.recording = Recording(
            self._lock, self.live, self._recorded_topics, self._run_metadata,
            opened=lambda: self.publishing.publish_state_now(), log=log)
        self.counters = Counters(self._wall(), self.live.t)
        self.publishing = Publishers(self, self._messages, self.outbox, self.counters,
                                     self.recording.record, publish_clock=p['publish_clock'])
        self.outbox.limited = frozenset(self.publishing.accel)
        # the graph is read with the diagnostics: often enough, and off the stepping thread
        clash = NameClash(self, lambda text: self._log('warning', text))
        self.diagnostics = Diagnostics(self, self.live, self.outbox, self._lock,
                                       self.publishing.diagnostics, self.recording,
                                       self._stepping, log, self._wall, self.counters,
                                       name_clash=clash, hardware_id=p['hardware_id'])
        self._command_subs = [
            self.create_subscription(Float64, itf.SPEED_COMMAND, self.on_speed_command,
                                     itf.COMMAND_QOS),
            self.create_subscription(Float64, itf.UNBALANCE_COMMAND, self.on_unbalance_command,
                                     itf.COMMAND_QOS)]
        # sensor faults on command (YAML or JSON text); in a log once one is received
        self._fault_sub = self.create_subscription(String, itf.FAULT_COMMAND,
                                                   self.on_fault_command, itf.COMMAND_QOS)
        self.create_service(SetBool, '~/record', self.on_record_request)
        self._diag_timer = self.create_timer(
            p['diagnostics_period'], lambda: (clash(), self.publish_diagnostics()))
        self._state_timer = self.create_timer(p['state_period'], self.publish_state)

    def _recorded_topics(self):
        """``(topic, type_name, qos)`` of every outlet and command subscription."""
        return ([(out.topic, out.type_name, out.qos) for out in self.publishing.all]
                + [(sub.topic_name, 'std_msgs/msg/Float64', itf.COMMAND_QOS)
                   for sub in self._command_subs])

    def _run_metadata(self):
        from ..recording.log_metadata import run_metadata
        return run_metadata(self.scene, self._params['overrides'], self._params,
                            self.get_fully_qualified_name(), live=self.live)

    # -- what the helpers keep, as the node's (tests and benches read them) ----------------
    @property
    def outlets(self):
        """list of Outlet: Every publisher of the node (``topic``, ``type_name``, ``count``)."""
        return self.publishing.all

    @property
    def stats(self):
        """_Stats: The counters of the diagnostics period under way."""
        return self.counters.stats

    @property
    def stats_total(self):
        """dict: Samples, impacts and clipped values since start."""
        return self.counters.stats_total

    @property
    def rejected(self):
        """int: Commands refused since start."""
        return self.counters.rejected

    @property
    def last_diagnostics(self):
        """dict: The values and level of the last ``/diagnostics`` report."""
        return self.diagnostics.last_diagnostics

    @property
    def recorder(self):
        """AsyncRecorder or None: The recording under way."""
        return self.recording.recorder

    @property
    def record_error(self):
        """str or None: The recording's disk error, in one line."""
        return self.recording.record_error

    def publish_diagnostics(self):
        """Publish ``/diagnostics`` (see :class:`~.node_diagnostics.Diagnostics`)."""
        self.diagnostics.publish()

    def publish_state(self):
        """Queue ``impactor_state`` (the periodic timer's callback)."""
        with self._lock:
            self.publishing.queue_state()

    def start_recording(self, path, overwrite=False):
        """Start recording every topic and command to ``path``; why not (str), or None."""
        return self.recording.start_recording(path, overwrite)

    def stop_recording(self):
        """Finish the record file; the recorder stopped, or None."""
        return self.recording.stop_recording()

    def on_record_request(self, request, response):
        """``~/record`` (std_srvs/SetBool): start (to the ``record`` parameter's path, or a
        new file) or stop recording."""
        return self.recording.on_request(request, response, self._params['record'],
                                         self._params['record_overwrite'])

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
                    self.recording.record(self._command_subs[which].topic_name,
                                          'std_msgs/msg/Float64', itf.COMMAND_QOS,
                                          float64_cdr(value))
                apply(value)
        except CommandError as exc:
            self.counters.rejected += 1
            self._log('warning', f'rejected: {named(exc)}', 1.0, 'command')
            return False
        except Exception as exc:   # no message may stop the node
            self.counters.rejected += 1
            self._log('error', f'command {value!r} refused: {type(exc).__name__}: {exc}', 1.0,
                      'command')
            return False
        self.counters.stats.commands += 1
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
                    self.recording.record(self._fault_sub.topic_name, STRING, itf.COMMAND_QOS,
                                 string_cdr(text))
                action, names = self.live.fault_command(text, key=topic)
        except CommandError as exc:
            self.counters.rejected += 1
            self._log('warning', f'rejected: {exc}', 1.0, topic)
            return False
        except Exception as exc:   # no message may stop the node
            self.counters.rejected += 1
            self._log('error', f'{topic} {text!r} refused: {type(exc).__name__}: {exc}', 1.0,
                      topic)
            return False
        self.counters.stats.commands += 1
        what = (f"fault {names[0]!r} added" if action == 'add' else
                f"cleared {', '.join(repr(n) for n in names) or 'nothing (none active)'}")
        self._log('info', f'{topic}: {what}, accepted at sim time {self.live.t:.3f} s',
                  self.COMMAND_LOG_PERIOD, topic)
        return True

    def _on_set_parameters(self, params):
        """rclpy's set-parameters callback: validate every change, then apply them all or
        none (as demo_nodes_py's set_parameters_callback). rclpy itself refuses read-only
        parameters before this is called."""
        changes, why = self._validate(params)
        if why:
            return SetParametersResult(successful=False, reason=why)
        try:
            self._apply(changes)
        except (CommandError, ValueError) as exc:
            return SetParametersResult(successful=False, reason=named(exc))
        return SetParametersResult(successful=True)

    def _validate(self, params):
        """The changes ``params`` ask for (dict) and why they are refused ('' when valid)."""
        changes = {}
        for prm in params:
            name, value = prm.name, prm.value
            if name in self._rclpy_parameters:
                continue   # rclpy's own (use_sim_time): rclpy checks and applies it
            why = check(name, value)
            if why:
                return {}, f'{name}: {why}'
            if name == 'dampers_enabled' and value and not self.scene.impactors:
                return {}, f'scene {self.scene.name!r} has no impactors'
            changes[name] = value
        return changes, ''

    def _apply(self, changes):
        """Apply validated changes together, and record them as ``ros2 bag`` would."""
        with self._lock:
            if 'real_time_factor' in changes:
                self.outbox.reset(changes['real_time_factor'])
                self._wake.set()   # a wait computed for the old factor ends now
                # the achieved factor is measured against the new one from now on
                self.diagnostics.restart_period()
            if 'speed_rate_limit' in changes and self.live.speed_commanded:
                # without a commanded rotor it is kept and does nothing, as at start
                self.live.set_speed_rate(changes['speed_rate_limit'])
            if 'noise_std' in changes or 'noise_seed' in changes:
                self.live.set_noise(changes.get('noise_std', self.live.noise_std),
                                    changes.get('noise_seed'))
                self._messages.set_noise_variances(self.live.imu_noise_variances())
            if 'dampers_enabled' in changes:
                self.live.set_dampers_enabled(changes['dampers_enabled'])
                self.publishing.publish_state_now()
            if changes:   # in the log, as ros2 bag records a parameter change
                self.recording.record(itf.PARAMETER_EVENTS, 'rcl_interfaces/msg/ParameterEvent',
                             itf.PARAMETER_EVENTS_QOS,
                             self._messages.parameter_event(list(changes.items())))

    # -- stepping -------------------------------------------------------------------------
    def start(self, stepping=None):
        """Start stepping (idempotent).

        Stepping runs in a thread, not in an executor callback: the executor then only
        wakes for commands, parameters and the slow timers, and a long chunk of physics
        never starves them (each chunk holds the lock for a few ms at most).

        Parameters
        ----------
        stepping : SharedStepping, optional
            A thread that steps this node with others of the process (``plant_host``), in
            turn; default a thread of its own. The node steps its refill phase's chunks
            now, and is stepped once the shared thread is started
            (:meth:`SharedStepping.start`).
        """
        if self._thread is not None:
            return
        with self._lock:
            # the schedule and the first diagnostics period begin now, not when the node was
            # built: what ran in between (main's heap freeze, 0.15-0.3 s) is no deficit that
            # the first samples would have to catch up in a burst
            self.outbox.reset(self.pacer.real_time_factor)
            self.diagnostics.restart_period(keep_trend=False)
        self._stop.clear()
        if stepping is not None:
            self._shared = stepping
            self._wake = stepping.wake   # a parameter change ends the shared wait
            self._thread = stepping.thread
            phase = stepping.add(self)
            with self._lock:   # its refills then come in their own turn (stepping.phase)
                for _ in range(phase):
                    if not self._step(self._chunk):
                        break
            return
        self._thread = threading.Thread(target=self._run, name='vibration_stepping',
                                        daemon=True)
        self._thread.start()

    def _stepping(self, wall):
        """Why the stepping thread is not stepping at wall time ``wall`` (s), or ''."""
        thread = self._thread
        if thread is None:
            return ''   # not started (tests drive tick() themselves) or stopped on purpose
        if not thread.is_alive():
            return 'stepping thread stopped: no samples are produced'
        stall = self.diagnostics.STALL
        if self._heartbeat is not None and wall - self._heartbeat > stall:
            return f'stepping thread stalled for {wall - self._heartbeat:.1f} s'
        return ''

    #: How long :meth:`stop` waits for the stepping thread (s): under the 5 s ``ros2 launch``
    #: gives a node between SIGINT and SIGTERM. A chunk takes milliseconds.
    STOP_WAIT = 3.0

    def stop(self):
        """Stop the stepping thread and wait for it, at most :attr:`STOP_WAIT` (idempotent).

        What was already stepped (up to 2 + ``Outbox.REFILL`` chunks ahead of the clock) is
        published and recorded now, so the counters, the topics and the log agree. A thread
        that does not stop in time is a bug: its stack is logged at ERROR and the node goes
        on shutting down (the thread is a daemon) rather than hang until ``ros2 launch``
        kills it. One stuck inside a chunk still holds the lock, which finishing a recording
        waits for; ``main``'s clean-up report then prints where every thread is.
        """
        self._stop.set()
        self._wake.set()
        thread = self._thread
        if thread is not None:
            if self._shared is not None:   # the thread goes on for the other machines
                left = self._shared.remove(self, self.STOP_WAIT)
            else:
                thread.join(self.STOP_WAIT)
                left = not thread.is_alive()
            if not left:   # a daemon: it does not hold the process up
                self._log('error', f'the stepping thread did not stop within '
                                   f'{self.STOP_WAIT:g} s; left behind, nothing flushed. '
                                   f'It was at:\n{thread_stack(thread)}')
                return
            self._thread = self._shared = None
        if self.context.ok():
            self._flush()

    def _run(self):
        """The stepping thread of a node on its own: compute chunks ahead, publish each item
        at its time.

        Samples are published one by one when the wall clock reaches their sim time (through
        the pacer), not in bursts per chunk, so a keep-last-5 ``qos_profile_sensor_data``
        subscriber keeps up. Physics runs one to 2 + ``Outbox.REFILL`` chunks
        (``tick_period`` of sim time each) ahead, refilled :attr:`Outbox.REFILL` + 1 at once.
        """
        cycles = 0
        while True:
            cycles += 1
            delay = self._turn(cycles % CONTEXT_EVERY == 0)
            if delay is None:
                break
            wait_for(delay, self._wake, self.MAX_WAIT)

    def _turn(self, check_context=False):
        """One turn of the stepping loop (:meth:`_cycle`): the wait it asks for (s), or
        None once this node is done (stopped, or its context shut down, when
        ``check_context``: a C call, not every turn). A failure inside the cycle is the
        simulation's, reported on ``/diagnostics``; it does not end the loop."""
        if self._stop.is_set() or (check_context and not self.context.ok()):
            return None
        self._heartbeat = self._wall()
        try:
            return self._cycle()
        except Exception as exc:   # a bug must not kill the node silently
            if not self.context.ok():
                return None   # Ctrl-C shut the context down under a publish: not a failure
            with self._lock:
                self.live.failure = f'{type(exc).__name__}: {exc}'
            return self._tick_period

    def _cycle(self):
        """Send what is due, step a chunk when the buffer runs short; return a wait (s).
        The rules are the outbox's (:class:`~impact_damper_sim.live.pacing.Outbox`)."""
        live, outbox = self.live, self.outbox
        now = self._wall()
        held = self._send_due(now)
        if live.failure is not None:
            self.diagnostics.report_failure()
            return self._tick_period
        plan = outbox.plan(now, live.t)
        stats = self.counters.stats
        stats.lag = max(stats.lag, plan.lag)
        if plan.step:
            if plan.late:
                stats.overruns += 1   # a whole chunk behind schedule: late
            # who reads what: asked once per refill (a reader that appears waits one refill)
            self.publishing.look_up_readers()
            shared = self._shared
            for k in range(plan.chunks):   # back to back: warm (Outbox.REFILL)
                if k and shared is not None:   # the other machines' sends do not wait
                    shared.send_others(self)   # for this whole refill
                if not self._step(self._chunk):
                    break
            self._lock.hand_over()
            return outbox.CATCH_UP if held else 0.0   # a backlog waits, however late we are
        return outbox.wait(held, self._wall(), live.t, self._tick_period)

    def _send_due(self, now):
        """Send what the pacing lets out at wall time ``now`` (s); True when due samples
        were held back (a backlog)."""
        with self._lock.stepper:
            return self.outbox.send_due(now, self.live.t, self.publishing.send)

    def _flush(self):
        """Send everything queued now."""
        with self._lock:
            self.outbox.flush(math.inf, self.live.t, self.publishing.send)

    def destroy_node(self):
        """Stop stepping, finish any recording, then destroy the node."""
        self.stop()
        self.recording.stop_recording()
        return super().destroy_node()

    def tick(self):
        """Step up to the paced sim time and publish it all now (tests drive this by hand).

        With ``real_time_factor`` 0 one chunk is stepped per call.
        """
        live = self.live
        if live.failure is not None:
            self.diagnostics.report_failure()
            return
        target, lag = self.pacer.target(live.t)
        self.counters.stats.lag = max(self.counters.stats.lag, lag)
        self.publishing.look_up_readers()
        while True:
            n = (self._chunk if math.isinf(target)
                 else int(math.floor((target - live.t) / self._period + 1e-9)))
            if n <= 0 or not self._step(min(n, self._chunk)):
                break
            if math.isinf(target):
                break
        self._flush()

    def _step(self, n):
        """Step ``n`` samples (fewer when a schedule entry falls inside them: it applies at
        its sample boundary) and queue what they produce; False once the simulation failed."""
        with self._lock.stepper:
            if self.schedule is not None and not self.schedule.done:
                self._play_schedule()
                ahead = self.schedule.samples_to_next(self.live.t, self.live.sample_rate)
                if ahead:
                    n = min(n, ahead)
            batch = self.live.step(n)
            if batch is None:
                self.diagnostics.report_failure()
                return False
            self.publishing.queue_batch(batch, self._period)
            self.publishing.queue_time()
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

    Exit status 0 on Ctrl-C, SIGTERM, SIGHUP or shutdown, 2 (one line on stderr) when the
    scene or a start-up parameter is invalid. The form of ros2/demos' Jazzy talker (rclpy 7
    has no ``with rclpy.init()``: it returns None), with signals that end the spin instead
    of raising in a callback (:class:`~.process.SignalStop`).
    """
    from rclpy.exceptions import ParameterException
    stop = SignalStop()   # before rclpy.init: rclpy's handlers chain to it
    rclpy.init(args=args)
    node = None
    try:
        node = VibrationNode(start_stepping=False)
        stop.begin_running()   # signals only noted from here: the node's threads start
        freeze_start_up_heap()   # no 150 ms full collections of start-up objects while paced
        node.start()
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        spin_guarded(executor, lambda exc: node._log(
            'error', f'callback failed: {type(exc).__name__}: {exc}', 1.0, 'spin'))
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (SceneError, ParameterException) as exc:
        print(f'vibration_node: {exc}', file=sys.stderr)
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


__all__ = ['VibrationNode', 'main']


if __name__ == '__main__':
    sys.exit(main())
