"""``vibration_node``: a scene's vibration, stepped paced to the wall clock, on ROS 2 topics.

A thin adapter over :class:`~impact_damper_sim.live.realtime.LiveSimulation`: it declares and
validates the parameters, feeds commands to the core, paces it with
:class:`~impact_damper_sim.live.realtime.Pacer` and publishes what it produces. The topics and
their encodings are in :mod:`impact_damper_sim.ros.interface` and docs/node.md.

Run it with ``ros2 run impact_damper_sim vibration_node`` (or the ``vibration_node`` console
script), e.g. ``--ros-args -p scene:=rbs -r __ns:=/rbs``.
"""
from __future__ import annotations

import collections
import math
import sys
import threading
import time

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Vector3Stamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, JointState, PointCloud2
from std_msgs.msg import Float64
from std_srvs.srv import SetBool

from ..live.realtime import CommandError, LiveSimulation, Pacer, live_scene
from ..recording.batches import (ACCEL_FIELDS, ACCEL_POINT_STEP, IMPACT_FIELDS,
                                 IMPACT_POINT_STEP, BatchEncoder)
from ..scene.schema import SceneError
from . import interface as itf
from .cdr import serialize
from .parameters import PARAMETERS, RCLPY_PARAMETERS, ParameterError, check, declare_all, \
    parameters_markdown
from .wire import ImuPacker, Outlet, freeze_start_up_heap, guard_services, \
    ignore_further_interrupts, settle_interrupt, shutdown_quietly, spin_guarded, stamp

_IMPACT = 0   # EVENT_KINDS index of an impact
RECORD_CHUNK_SIZE = 768 * 1024   # bytes, as rosbag2's MCAP storage
_stamp = stamp


class _HandoffLock:
    """A re-entrant lock that the stepping thread hands over when someone waits for it.

    Python locks are not fair: a thread that releases a lock and takes it again at once
    keeps winning, and stepping flat out (``real_time_factor`` 0) would starve commands and
    diagnostics. Waiters are counted; :meth:`hand_over`, called by the stepper between
    chunks, pauses 0.5 ms when anyone waits.
    """

    def __init__(self):
        self._lock = threading.RLock()
        self.waiting = 0

    def __enter__(self):
        self.waiting += 1
        self._lock.acquire()
        self.waiting -= 1
        return self

    def __exit__(self, *exc_info):
        self._lock.release()

    def acquire(self, timeout):
        """Take the lock, waiting at most ``timeout`` s; True when taken (release it)."""
        self.waiting += 1
        try:
            return self._lock.acquire(timeout=timeout)
        finally:
            self.waiting -= 1

    def release(self):
        """Release a lock taken with :meth:`acquire`."""
        self._lock.release()

    def hand_over(self):
        """Let a waiting thread take the lock (call with the lock released)."""
        if self.waiting > 0:
            time.sleep(0.0005)


class _Busy:
    """Logs, every ``period`` s until stopped, that a slow start-up step is still running."""

    def __init__(self, log, what, period=5.0):
        self._done = threading.Event()
        self._t0 = time.monotonic()

        def run():
            while not self._done.wait(period):
                log(f'still {what} ({time.monotonic() - self._t0:.0f} s)')

        self._thread = threading.Thread(target=run, name='startup_notice', daemon=True)
        self._thread.start()

    def stop(self):
        """Stop the notices; return the elapsed time (s)."""
        self._done.set()
        self._thread.join()
        return time.monotonic() - self._t0


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

    #: how early (wall s) an item may be published with the one due before it, at most
    EARLY = 1.2e-3
    #: ... and in per-sample Imu periods: 1.1 sends each Imu sample with the one before it,
    #: so one wake-up sends 2 samples per accelerometer (every 2 ms at 1 kHz): half the
    #: wake-ups of one sample each, and a keep-last-5 reader holds 2 such pairs
    EARLY_SAMPLES = 1.1
    #: most Imu samples per accelerometer one wake-up sends (or 1 ms of them, if more): a
    #: wake-up that comes late sends its backlog in such groups, not in one burst
    BURST = 2
    #: wall time (s) between the wake-ups that send a backlog (twice the sample rate or more)
    CATCH_UP = 5e-4
    #: longest single wait of the stepping thread (s): it re-reads the schedule at least this
    #: often, whatever the pacing asks
    MAX_WAIT = 0.5
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
        self._lock = _HandoffLock()
        self._thread = None
        self._stop = threading.Event()
        # set by a parameter change and by stop(): a long wait (a tiny real_time_factor) must
        # not outlive the setting that caused it
        self._wake = threading.Event()
        self._heartbeat = None   # wall time (s) of the stepping thread's last cycle
        self._last_log = {}
        self._pending = collections.deque()   # (sim ns, outlet, message or bytes, wire)
        p, unknown = declare_all(self)
        # declared by rclpy, not by us; any other name is refused (rclpy lets an undeclared
        # '' through: it tests its names with any(), and '' is false)
        self._rclpy_parameters = set(self._parameters) & set(RCLPY_PARAMETERS)
        for name in unknown:
            self.get_logger().warning(f'parameter {name!r} is not one of this node\'s; '
                                      f"ignored (known: {', '.join(PARAMETERS)})")
        rate_limit = p['speed_rate_limit'] or None
        busy = _Busy(self.get_logger().info, 'loading the scene and the compiled kernels '
                     '(a cold Numba cache compiles them once: 26 s on 2 quiet cores, 40 s or '
                     'more on a busy machine; 2 s after that)')
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
        self._period = 1.0 / self.live.sample_rate
        self._make_interfaces(p)
        self.pacer = Pacer(p['real_time_factor'], self.live.t, max_lag=p['max_lag'],
                           clock=self._wall)
        self.stats = _Stats(self._wall(), time.process_time(), self.live.t, self.live.t)
        self.rejected = 0
        self.stats_total = {'samples': 0, 'impacts': 0}   # since start, per accelerometer
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
        self._imu = []
        self._accel_pubs = []    # per-sample Imu, decimated to imu_rate
        self._batch_pubs = []    # full-rate batches
        self._batch_encoders = []
        for acc in self.live.accelerometers:
            self._accel_pubs.append(Outlet(self, Imu, itf.accel_topic(acc.name),
                                           itf.SENSOR_QOS))
            self._batch_pubs.append(Outlet(self, PointCloud2, itf.accel_batch_topic(acc.name),
                                           itf.BATCH_QOS))
            self._batch_encoders.append(BatchEncoder(acc.frame_id, ACCEL_FIELDS,
                                                     ACCEL_POINT_STEP))
            msg = Imu()
            msg.header.frame_id = acc.frame_id
            msg.orientation_covariance[0] = -1.0   # orientation not measured (REP-145)
            self._imu.append(msg)
        self._set_noise_covariance()
        self._impact_pub = Outlet(self, PointCloud2, itf.IMPACTS, itf.EVENT_QOS)
        self._state_pub = Outlet(self, JointState, itf.IMPACTOR_STATE, itf.LATCHED_QOS)
        self._speed_pub = Outlet(self, Vector3Stamped, itf.ROTOR_SPEED, itf.COMMAND_QOS)
        self._joint_pub = Outlet(self, JointState, itf.ROTOR_JOINT_STATES, itf.COMMAND_QOS)
        self._clock_pub = (Outlet(self, Clock, itf.CLOCK, itf.CLOCK_QOS)
                           if p['publish_clock'] else None)
        self._diag_pub = Outlet(self, DiagnosticArray, itf.DIAGNOSTICS, itf.DIAGNOSTICS_QOS)
        self._command_subs = [
            self.create_subscription(Float64, itf.SPEED_COMMAND, self.on_speed_command,
                                     itf.COMMAND_QOS),
            self.create_subscription(Float64, itf.UNBALANCE_COMMAND, self.on_unbalance_command,
                                     itf.COMMAND_QOS)]
        self.create_service(SetBool, '~/record', self.on_record_request)
        # per modal-model impactor (a zero-mass scene entry has none), matched by name
        spec_of = {spec['name']: spec for spec in self.scene.scene['impactors']}
        specs = [spec_of[imp.name] for imp in self.scene.impactors]
        dofs_of = [[spec['dof']] if spec['kind'] == 'sdof' else list(spec['plane'])
                   for spec in specs]
        axis_of = {'ux': 0, 'uy': 1, 'uz': 2}
        self._impactor_axes = [[axis_of[d] for d in dofs] for dofs in dofs_of]
        self._joint_names = [f"{spec['name']}/{d}" for spec, dofs in zip(specs, dofs_of)
                             for d in dofs]
        # the housings' frame; with housings at several nodes, the scene's (axes are global)
        housings = sorted({spec['node'] for spec in specs})
        impact_frame = (self._frame_of_node(housings[0]) if len(housings) == 1
                        else self.scene.name)
        self._impact_encoder = BatchEncoder(impact_frame, IMPACT_FIELDS, IMPACT_POINT_STEP)
        self._tick_period = p['tick_period']
        self._diag_timer = self.create_timer(p['diagnostics_period'], self.publish_diagnostics)
        self._state_timer = self.create_timer(p['state_period'], self.publish_state)
        # samples per stepped chunk, and how far (wall s) stepping runs ahead of publishing
        self._chunk = max(1, int(round(p['tick_period'] * self.live.sample_rate)))
        self._lookahead = p['tick_period']
        self._t_published = self.live.t
        # the start of the interval the next impact batch covers (ns)
        self._impacts_from = int(round(self.live.t * 1e9))

    def _frame_of_node(self, node):
        for acc in self.live.accelerometers:
            if acc.node == node:
                return acc.frame_id
        return f'{self.scene.name}_node{node}'

    def _set_noise_covariance(self):
        var = self.live.noise_std ** 2
        for msg in self._imu:
            msg.linear_acceleration_covariance = [var, 0.0, 0.0, 0.0, var, 0.0, 0.0, 0.0, var]
        self._packers = [self._make_packer(msg) for msg in self._imu]

    def _make_packer(self, msg):
        try:
            return ImuPacker(msg)
        except RuntimeError as exc:   # another CDR layout: serialize message by message
            self.get_logger().warning(f'{exc}; serializing message by message instead',
                                      once=True)
            return None

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
        value = getattr(msg, 'data', msg)
        try:
            with self._lock:
                if self.recorder is not None and isinstance(msg, Float64):
                    # every command received is recorded, the rejected ones too
                    self._record(self._command_subs[which].topic_name, 'std_msgs/msg/Float64',
                                 itf.COMMAND_QOS, serialize(msg))
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
        self._log('info', f'{topic} {value:g} accepted at sim time {self.live.t:.3f} s', 1.0,
                  topic)
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
        if 'noise_std' in changes or 'noise_seed' in changes:
            self.live.set_noise(changes.get('noise_std', self.live.noise_std),
                                changes.get('noise_seed'))
            self._set_noise_covariance()
        if 'dampers_enabled' in changes:
            self.live.set_dampers_enabled(changes['dampers_enabled'])
            self._publish_state()

    @property
    def outlets(self):
        """list of _Outlet: Every publisher of the node (``topic``, ``type_name``, ``count``)."""
        return [*self._accel_pubs, *self._batch_pubs, self._impact_pub, self._state_pub,
                self._speed_pub, self._joint_pub, self._diag_pub] + (
                    [self._clock_pub] if self._clock_pub else [])

    # -- recording ------------------------------------------------------------------------
    def start_recording(self, path, overwrite=False):
        """Start recording every published topic and received command to ``path``.

        Parameters
        ----------
        path : str
            MCAP file (rosbag2 layout).
        overwrite : bool
            Replace an existing file (otherwise refused).

        Returns
        -------
        str or None
            Why recording could not start, or None.
        """
        from ..recording import AsyncRecorder
        with self._lock:
            if self.recorder is not None:
                return f'already recording to {self.recorder.path}'
            try:
                # rosbag2's chunk size: the summary keeps one index per chunk in memory until
                # the file closes (64 KiB chunks grew RSS ~0.8 MB/min); a chunk is still
                # closed at least every flush period, which bounds what a crash loses
                rec = AsyncRecorder(path, overwrite=overwrite, on_error=self._on_disk_error,
                                    chunk_size=RECORD_CHUNK_SIZE,
                                    overwrite_option='record_overwrite:=true')
            except (OSError, ValueError) as exc:
                return str(exc)
            rec.add_metadata('impact_damper_sim', self._run_metadata())
            for out in self.outlets:
                rec.add_topic(out.topic, out.type_name, out.qos)
            for sub in self._command_subs:
                rec.add_topic(sub.topic_name, 'std_msgs/msg/Float64', itf.COMMAND_QOS)
            self.recorder = rec
            self.record_error = None
            self._publish_state()   # the latched state opens the log
        self.get_logger().info(f'recording to {path}')
        return None

    def stop_recording(self):
        """Finish the record file (summary and rosbag2 metadata); no-op when not recording."""
        with self._lock:
            rec, self.recorder = self.recorder, None
        if rec is not None:
            rec.close()
            self._log('info', f'recorded {rec.stats()["messages_written"]} messages to '
                              f'{rec.path}')
        return rec

    def on_record_request(self, request, response):
        """``~/record`` (std_srvs/SetBool): true starts recording to the ``record`` parameter's
        path (or a new timestamped file), false stops."""
        if request.data:
            if self._params['record']:
                path, overwrite = self._params['record'], self._params['record_overwrite']
            else:   # a new file each start: an automatic name never overwrites
                path, overwrite = _new_record_path(self.scene.name), False
            error = self.start_recording(path, overwrite)
            response.success = error is None
            response.message = error or str(path)
        else:
            rec = self.stop_recording()
            error = rec.error if rec is not None else None
            response.success = rec is not None and error is None
            response.message = ('not recording' if rec is None else
                                f'{rec.path}: recording stopped by a disk error: {error}'
                                if error is not None else str(rec.path))
        return response

    def _record(self, topic, type_name, qos, data, ns=None):
        rec = self.recorder
        if rec is not None:
            # the log runs on sim time, as a recorder with use_sim_time on our /clock would:
            # an item's own sim time (samples: their stamp), else now
            if ns is None:
                ns = int(round(self.live.t * 1e9))
            rec.write(topic, type_name, qos, data, ns, ns)

    def _on_disk_error(self, exc):
        self.record_error = str(exc)   # reported in /diagnostics; the simulation goes on

    def _run_metadata(self):
        import yaml

        import impact_damper_sim
        params = {k: v for k, v in self._params.items()}
        return {
            'software_version': impact_damper_sim.__version__,
            'scene': self.scene.name, 'scene_source': str(self.scene.source),
            'overrides': yaml.safe_dump(list(self._params['overrides'] or ()),
                                        default_flow_style=True).strip(),
            'resolved_scene_si': yaml.safe_dump(_plain(self.scene.scene), sort_keys=False),
            'node_parameters': yaml.safe_dump(params, sort_keys=True),
            'node_name': self.get_fully_qualified_name(),
            'time_base': 'sim time (log_time = publish_time = sim time of the publish call)',
        }

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
            # depth; a backlog (the thread was descheduled) is spread the same way instead of
            # leaving in one burst. Counted in Imu samples, not in the full-rate batch's: at
            # 20 kHz 1 ms of the latter would be 20 Imu messages at once
            imu_period = 1.0 / self.live.imu_rate
            held = self._flush(now + min(self.EARLY, self.EARLY_SAMPLES * imu_period / rtf),
                               max(self.BURST, math.ceil(1e-3 * rtf / imu_period - 1e-9)))
        else:
            self._flush(math.inf)
        if live.failure is not None:
            self._report_failure()
            return self._tick_period
        target, lag = self.pacer.target(self._published_t())
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
        """Sim time (s) whose items are all out by wall time ``wall`` (s): the published
        time, or, with no backlog, the stepped time up to the schedule (between two wake-ups
        the published time stands still while the schedule moves on). Call with the lock."""
        due = self.pacer.sim_at(wall)
        pending = self._pending
        if pending and pending[0][0] * 1e-9 <= due:
            return self._t_published   # a backlog: what consumers have got so far
        return max(self._t_published, min(self.live.t, due))

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
        """Step ``n`` samples and queue what they produce; False once the simulation failed."""
        with self._lock:
            batch = self.live.step(n)
            if batch is None:
                self._report_failure()
                return False
            self._queue_batch(batch)
            self._queue_time()
        return True

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
        """Queue a stepped chunk: per accelerometer one full-rate batch (sent at its last
        sample's time) and the decimated samples one by one (each sent when the filter has
        it, a filter delay after its stamp); the chunk's impacts as one batch."""
        # the per-sample work is one NumPy pass per accelerometer (ImuPacker), no Python
        # message objects; items are queued in the order of their send times
        delay_ns = int(round(self.live.imu_delay * 1e9))
        imu_ns = np.rint(batch.imu_t * 1e9).astype(np.int64)
        items = []
        for a, (pub, msg, packer) in enumerate(zip(self._accel_pubs, self._imu, self._packers)):
            lin = batch.imu_linear_acceleration[:, a, :]
            ang = batch.imu_angular_velocity[:, a, :]
            wire = pub.has_subscribers()
            if packer is not None:
                data = packer.pack(imu_ns, lin, ang)
            else:
                data = []
                for ns, la, av in zip(imu_ns.tolist(), lin.tolist(), ang.tolist()):
                    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(ns, 1_000_000_000)
                    (msg.linear_acceleration.x, msg.linear_acceleration.y,
                     msg.linear_acceleration.z) = la
                    msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z = av
                    data.append(serialize(msg))
            items += [(ns + delay_ns, a, pub, d, wire) for ns, d in zip(imu_ns.tolist(), data)]
        t_ns = np.rint(batch.t * 1e9).astype(np.int64)
        k = t_ns.size
        if k:
            for a, (pub, encoder) in enumerate(zip(self._batch_pubs, self._batch_encoders)):
                rows = np.empty(k, encoder.dtype)
                rows['t'] = (t_ns - t_ns[0]) * 1e-9
                for name, column in zip(('ax', 'ay', 'az'), batch.linear_acceleration[:, a].T):
                    rows[name] = column
                for name, column in zip(('wx', 'wy', 'wz'), batch.angular_velocity[:, a].T):
                    rows[name] = column
                items.append((int(t_ns[-1]), a, pub, encoder.encode(t_ns[0], rows),
                              pub.has_subscribers()))
        ev = batch.events
        impacts = ev[ev['kind'] == _IMPACT]
        end_ns = int(round(self.live.t * 1e9))
        if self.scene.impactors:
            items.append((end_ns, len(self._accel_pubs), self._impact_pub,
                          self._impact_batch(impacts), self._impact_pub.has_subscribers()))
        self._impacts_from = end_ns
        items.sort(key=lambda item: item[:2])   # by send time, then accelerometer
        self._pending.extend((ns, pub, data, wire) for ns, _, pub, data, wire in items)
        self.stats.samples += k
        self.stats_total['samples'] += k
        lin = batch.linear_acceleration
        peak = float(np.max(np.abs(lin))) if lin.size else 0.0   # a scene may have no sensor
        self.stats.peak = max(self.stats.peak, peak)
        self.stats.impacts += impacts.size
        self.stats_total['impacts'] += impacts.size
        stuck = sum(self.live._stuck)
        self.stats.stuck_time += stuck * k * self._period
        if batch.states_changed:
            self._queue_state()

    def _impact_batch(self, impacts):
        """The CDR bytes of the impact batch covering the chunk just stepped."""
        encoder = self._impact_encoder
        rows = np.zeros(impacts.size, encoder.dtype)
        if impacts.size:
            t_ns = np.rint(impacts['t'] * 1e9).astype(np.int64)
            rows['t'] = (t_ns - self._impacts_from) * 1e-9
            which = impacts['impactor'].astype(np.int64)
            rows['impactor'] = which
            impulse = np.zeros((impacts.size, 3))
            for j in np.unique(which).tolist():   # plane DOFs -> x, y, z of the frame
                hit = which == j
                for k, axis in enumerate(self._impactor_axes[j]):
                    impulse[hit, axis] = impacts['impulse'][hit] * impacts['normal'][hit, k]
            rows['jx'], rows['jy'], rows['jz'] = impulse.T
            rows['v_approach'] = np.abs(impacts['v_n'])
            rows['v_separation'] = np.abs(impacts['v_n_after'])
            rows['energy'] = impacts['loss']
            order = np.argsort(t_ns, kind='stable')
            rows = rows[order]
        return encoder.encode(self._impacts_from, rows)

    def _queue_time(self):
        # like the samples, a topic nobody subscribes to (volatile: no late joiner gets it)
        # is not put on the wire and costs the stepping thread no wake-up
        t = self.live.t
        ns = int(round(t * 1e9))
        if self._clock_pub is not None:
            self._pending.append((ns, self._clock_pub, Clock(clock=_stamp(t)),
                                  self._clock_pub.has_subscribers()))
        if self.live.has_rotor:
            speed, rate, x = self.live.rotor_state()
            msg = Vector3Stamped()
            msg.header.stamp = _stamp(t)
            msg.vector.x, msg.vector.y, msg.vector.z = speed, rate, x
            self._pending.append((ns, self._speed_pub, msg, self._speed_pub.has_subscribers()))
            joint = JointState(name=['rotor'])
            joint.header.stamp = msg.header.stamp
            joint.position = [float(self.live.profile.angle(np.asarray(t))) % (2.0 * math.pi)]
            joint.velocity = [speed]
            self._pending.append((ns, self._joint_pub, joint, self._joint_pub.has_subscribers()))

    def publish_state(self):
        """Queue ``impactor_state`` (the periodic timer's callback): it leaves with the
        samples of its sim time, not a chunk ahead of them."""
        with self._lock:
            self._queue_state()

    def _publish_state(self):
        self._state_pub.publish(self._state_message(), int(round(self.live.t * 1e9)))

    def _queue_state(self):
        self._pending.append((int(round(self.live.t * 1e9)), self._state_pub,
                              self._state_message(), True))

    def _state_message(self):
        msg = JointState()
        msg.header.stamp = _stamp(self.live.t)
        msg.name = list(self._joint_names)
        pos, vel, eff = [], [], []
        enabled = self.live.dampers_enabled
        for s in self.live.impactor_states():
            d = len(s['position'])
            pos += [float(x) for x in s['position']]
            vel += [float(x) for x in s['velocity']]
            eff += [(1.0 if s['stuck'] else 0.0) if enabled else -1.0] * d
        msg.position, msg.velocity, msg.effort = pos, vel, eff
        return msg

    # -- health ---------------------------------------------------------------------------
    def _report_failure(self):
        if not self._failure_logged:
            self._failure_logged = True
            self.get_logger().error(f'simulation stopped: {self.live.failure}; the node stays '
                                    'up (diagnostics report ERROR)')
            self.publish_diagnostics()

    def publish_diagnostics(self):
        """Publish ``/diagnostics``: pacing, CPU, impacts, stuck fraction, peak, health."""
        if not self._lock.acquire(self.STALL):   # the stepping thread is stuck in a chunk
            status = DiagnosticStatus(
                name=f'{self.get_name()}: simulation', hardware_id=self.scene.name,
                level=DiagnosticStatus.ERROR,
                message=f'stepping thread stalled: it has held the simulation for over '
                        f'{self.STALL:g} s')
            msg = DiagnosticArray(status=[status])
            msg.header.stamp = self.get_clock().now().to_msg()
            self._diag_pub.publish(msg)
            self.last_diagnostics = {'level': 2, 'message': status.message}
            self.get_logger().error(status.message, throttle_duration_sec=5.0)
            return
        try:
            self._publish_diagnostics()
        finally:
            self._lock.release()

    def _stalled(self, wall):
        """Why the stepping thread is not stepping (str), or '' while it is alive and cycling."""
        thread = self._thread
        if thread is None:
            return ''   # not started (tests drive tick() themselves) or stopped on purpose
        if not thread.is_alive():
            return 'stepping thread stopped: no samples are produced'
        if self._heartbeat is not None and wall - self._heartbeat > self.STALL:
            return f'stepping thread stalled for {wall - self._heartbeat:.1f} s'
        return ''

    def _publish_diagnostics(self):
        live, st = self.live, self.stats
        wall, cpu = self._wall(), time.process_time()
        d_wall = max(wall - st.wall, 1e-9)
        d_sim = live.t - st.sim
        # delivered, not stepped, sim time: stepping runs up to a chunk and a lookahead
        # ahead, which would put +-2 % of noise on a 1 s period
        delivered = self._delivered_t(wall)
        achieved = (delivered - st.delivered) / d_wall
        n_imp = len(self.scene.impactors)
        stuck_fraction = (st.stuck_time / (d_sim * n_imp)) if d_sim > 0 and n_imp else 0.0
        status = DiagnosticStatus(name=f'{self.get_name()}: simulation',
                                  hardware_id=self.scene.name)
        level, messages = DiagnosticStatus.OK, []
        rtf = self.pacer.real_time_factor
        stalled = self._stalled(wall)
        if live.failure is not None:
            level = DiagnosticStatus.ERROR
            messages.append(f'stopped: {live.failure}')
        elif stalled:
            level = DiagnosticStatus.ERROR
            messages.append(stalled)
        else:
            if rtf > 0 and achieved < rtf * (1.0 - self.RTF_TOLERANCE):
                level = DiagnosticStatus.WARN
                messages.append(f'behind real time: achieved {achieved:.3f} of {rtf:g} '
                                f'(tolerance {100 * self.RTF_TOLERANCE:g} %)')
                # our throttle: rclpy's inspects the caller's frame on every call (2-6 ms)
                self._log('warning', messages[-1], 5.0, 'behind')
            if self._growth_rate > 0:
                level = max(level, DiagnosticStatus.WARN)
                messages.append(f'linear model unstable: growth rate {self._growth_rate:.3g} '
                                '1/s without impactors')
            if self.recorder is not None and self.recorder.error is not None:
                self.record_error = self.record_error or str(self.recorder.error)
            if self.record_error:
                level = max(level, DiagnosticStatus.WARN)
                messages.append(f'recording stopped by a disk error: {self.record_error}')
            if st.growing >= 5:
                level = max(level, DiagnosticStatus.WARN)
                messages.append('response growing for 5 periods')
        status.level = level
        status.message = '; '.join(messages) or 'ok'
        speed, _, x = live.rotor_state()
        values = {
            'sim_time_s': live.t, 'real_time_factor_requested': rtf,
            'real_time_factor_achieved': achieved,
            'cpu_percent': 100.0 * (cpu - st.cpu) / d_wall,
            'step_rate_hz': (live.steps - st.steps0) / d_wall,
            'samples_per_s': st.samples / d_sim if d_sim > 0 else 0.0,
            'impacts_per_s': st.impacts / d_sim if d_sim > 0 else 0.0,
            'stuck_fraction': stuck_fraction, 'peak_acceleration_g': st.peak / itf.G0,
            'max_lag_s': st.lag, 'late_ticks': st.overruns,
            'schedule_deficits_dropped': self.pacer.deficits,
            'rejected_commands': self.rejected, 'dampers_enabled': live.dampers_enabled,
            'rotor_speed_rad_s': speed, 'unbalance_multiplier': x,
            'linear_growth_rate_1_s': self._growth_rate,
        }
        rec = self.recorder
        if rec is not None:
            if rec.error is not None and not self.record_error:
                self.record_error = str(rec.error)
            rs = rec.stats()
            values.update({'record_path': str(rec.path),
                           'record_messages_written': rs['messages_written'],
                           'record_messages_dropped': rs['messages_dropped'],
                           'record_queue_high_water': rs['queue_high_water']})
        values['record_error'] = self.record_error or ''

        status.values = [KeyValue(key=k, value=f'{v:.6g}' if isinstance(v, float) else str(v))
                         for k, v in values.items()]
        msg = DiagnosticArray(status=[status])
        msg.header.stamp = _stamp(live.t)
        self._diag_pub.publish(msg)
        self.last_diagnostics = values | {'level': int.from_bytes(level, 'little')
                                          if isinstance(level, bytes) else int(level),
                                          'message': status.message}
        # growth only counts at steady speed (a ramp through a critical also grows)
        growing = st.peak > 1.2 * st.last_peak > 0 and live.rotor_state()[1] == 0.0
        self.stats = _Stats(wall, cpu, live.t, delivered, steps0=live.steps,
                            growing=st.growing + 1 if growing else 0, last_peak=st.peak)


def _new_record_path(scene, directory='.'):
    """A record file name not used before: ``<scene>_<date>-<time>.mcap``, or with ``-2``,
    ``-3``, ... when that exists (the clock's second repeats across quick starts)."""
    import pathlib
    base = pathlib.Path(directory) / time.strftime(f'{scene}_%Y%m%d-%H%M%S')
    path, n = base.with_name(base.name + '.mcap'), 1
    while path.exists():
        n += 1
        path = base.with_name(f'{base.name}-{n}.mcap')
    return path


def _plain(value):
    """A scene value as plain YAML-safe data (tuples to lists, NumPy to Python)."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    return value


class _Stats:
    """Counters of one diagnostics period."""

    def __init__(self, wall, cpu, sim, delivered, steps0=0, growing=0, last_peak=0.0):
        self.wall, self.cpu, self.sim, self.steps0 = wall, cpu, sim, steps0
        self.delivered = delivered
        self.samples = self.impacts = self.commands = self.overruns = 0
        self.stuck_time = self.peak = self.lag = 0.0
        self.growing, self.last_peak = growing, last_peak


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
