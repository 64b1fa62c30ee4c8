"""``study record``: the node's log of a scripted run, written offline as fast as the engine goes.

::

    study record SCENE --duration S --out F.mcap [--schedule F.yaml] [--seed N]
                 [--noise-std A] [--tick-period T] [--truth] [--fault YAML ...]
                 [--set KEY=VALUE ...] [--overwrite] [--progress] [--json]

:func:`record_log` steps :class:`~impact_damper_sim.live.realtime.LiveSimulation` with no
wall clock and writes what ``vibration_node`` would publish and record with the same
parameters: the same topics, message types, CDR bytes (packed by the same
:class:`~impact_damper_sim.recording.node_messages.NodeMessages`), QoS metadata and rosbag2
layout (:class:`~impact_damper_sim.recording.Rosbag2McapWriter`), log time = sim time. A
schedule (:mod:`impact_damper_sim.live.schedule`) is applied at the same sample boundaries
as the node applies it, and each applied key is logged as the live command
(``std_msgs/Float64`` on ``rotor/speed_command`` or ``rotor/unbalance_command``) or
parameter change (``rcl_interfaces/ParameterEvent`` on ``/parameter_events``) it stands for;
a ``fault`` or ``clear_fault`` entry as the ``std_msgs/String`` on ``accel/fault_command``
the node would receive (the same text, read by the same parser). Faults given to
:func:`record_log` itself (``--fault``, a data set's ``faults``) apply from the start and are
logged as such commands at sim time 0. The log closes with the run's sensor faults and what
they did (metadata ``impact_damper_sim_faults``), as the node's does.
With ``truth`` the log also holds each accelerometer's ground truth (the node's
``publish_truth``), and its metadata the run's labels (the channels' presets and stages,
the unbalance multiplier, Kcc, the dampers, the seed) as the node's log does.

What the node writes and this does not: ``/diagnostics`` (a report of the wall-clock run:
real-time factor, CPU, lag; there is none here). ``impactor_state`` is written on every
change and every ``state_period`` of sim time (the node's timer runs on the wall clock,
which at real time is the same).

Deterministic: the same scene, overrides, schedule, seed, tick period and software version
give the same messages, byte for byte, in the same order; only the bag's creation time in
the ``rosbag2`` metadata record differs. Nothing here imports ROS.
"""
from __future__ import annotations

import math
import os
import sys
import time

import numpy as np

# the node's defaults that shape the log (its parameter table reads the same ones)
from ..recording.node_topics import STATE_PERIOD, TICK_PERIOD
from ..scene.units import G0
from .log_errors import LogWriteError, check_definitions, open_error, write_failure
from .tick_period import check_tick_period

NODE_NAME = '/vibration_node'


class RecordResult(dict):
    """What :func:`record_log` wrote and saw (a dict; keys documented there)."""


def record_log(scene, out, duration, *, schedule=None, overrides=(), seed=0, noise_std=0.0,
               overwrite=False, progress=None, sample_rate=None, imu_rate=None,
               tick_period=TICK_PERIOD, state_period=STATE_PERIOD, overwrite_option='--overwrite',
               stream=None, truth=False, faults=None):
    """Step a scene for ``duration`` of sim time and write the node's log of it to ``out``.

    Parameters
    ----------
    scene : str or os.PathLike
        Scene name or file.
    out : str or os.PathLike
        MCAP file to write (rosbag2 layout).
    duration : float
        Sim time to record (s), > 0.
    schedule : str or os.PathLike or Schedule, optional
        Command schedule (YAML file or a loaded one).
    overrides : sequence of str
        ``key=value`` scene overrides (units allowed).
    seed : int
        Noise seed (the node's ``noise_seed``, dimensionless).
    noise_std : float
        Accelerometer noise at start (m/s^2; the node's ``noise_std``).
    overwrite : bool
        Replace an existing ``out``.
    progress : bool, optional
        A progress line on ``stream`` (percent, sim time, x real time); default when it is
        a terminal.
    sample_rate, imu_rate : float, optional
        The node's ``sample_rate`` and ``imu_rate`` (Hz); default from the scene.
    tick_period, state_period : float
        The node's ``tick_period`` (s of sim time per stepped chunk, in
        :data:`TICK_PERIOD_RANGE`: the full-rate batch, impact batch, ``/clock`` and rotor
        messages come once per chunk; the per-sample Imu messages keep their number and
        times) and
        ``state_period`` (s of sim time).
    overwrite_option : str
        How the caller asks for ``overwrite`` (named when the file exists).
    stream : file, optional
        Where progress goes; default ``sys.stderr``.
    truth : bool
        Also write each accelerometer's ground truth ``accel/<name>/truth`` (the node's
        ``publish_truth``).
    faults : sequence of (dict or str or FaultSpec), optional
        Sensor faults from the start (:mod:`impact_damper_sim.live.fault_spec`: mappings
        with units, or YAML/JSON text as ``accel/fault_command`` takes it); a fault without
        ``onset`` starts at 0. Each is logged as the fault command it stands for at sim
        time 0.

    Returns
    -------
    RecordResult
        ``path``, ``sim_time_s`` (reached), ``wall_s``, ``real_time_factor`` (sim s per wall
        s), ``messages``, ``bytes``, ``channel_preset`` (the accelerometers' channel preset;
        ``name=preset`` pairs joined by ``;`` when they differ), ``samples`` (full-rate, per
        accelerometer),
        ``impacts``, ``impacts_per_s``, ``stuck_fraction`` (time-weighted mean over the
        impactors, dimensionless; None without impactors), ``peak_g`` and ``rms_g`` (of the
        acceleration components over every accelerometer, g; ``samples``, ``peak_g`` and
        ``rms_g`` count the published samples: not those a sensor fault lost),
        ``commands`` (schedule keys applied), ``fault_labels`` (every sensor fault of the run
        with its actual window, ``FaultInjector.labels()``), ``diverged`` (bool),
        ``failure`` (why the simulation stopped, or None), ``finished`` (True: the log is
        closed with its summary) and ``write_error`` (None).

    Raises
    ------
    SceneError
        A bad scene, override or schedule (each problem named), a schedule the scene
        cannot take, a bad fault in ``faults`` (a ``FaultError``, one line naming its key),
        or a ``tick_period`` out of :data:`TICK_PERIOD_RANGE`.
    FileExistsError
        ``out`` exists and ``overwrite`` is false.
    SceneError
        Also: the ROS message definitions are not found (``AMENT_PREFIX_PATH``), checked
        before ``out`` is created.
    LogOpenError
        ``out`` cannot be created (an ``OSError``; nothing written): one line naming it.
    LogWriteError
        A disk error while writing (ENOSPC, EIO, ...) or the file lost: the run stops at
        the error, the file is closed as it is (recoverable with ``study recover`` when
        data reached it), and the error's one line says what is on disk; its ``result``
        holds the run up to there (``finished`` False, ``write_error`` the line).
    """
    from ..live.realtime import CommandError, LiveSimulation
    from ..live.schedule import Schedule
    from ..live.streams import live_scene
    from ..recording import Rosbag2McapWriter
    from ..recording.log_metadata import FAULTS_METADATA, fault_metadata, run_metadata
    from ..recording.message_cdr import fault_command_text, float64_cdr, string_cdr
    from ..recording.node_messages import NodeMessages
    from ..recording.node_topics import FAULT_COMMAND, FLOAT64, RECORD_CHUNK_SIZE
    from ..scene.schema import SceneError
    duration = float(duration)
    if not (math.isfinite(duration) and duration > 0):
        raise SceneError(f'--duration: must be a finite time > 0 s, got {duration:g}')
    tick_period = check_tick_period(tick_period)
    scene_model, target = live_scene(scene, overrides)
    live = LiveSimulation(scene_model, sample_rate=sample_rate, imu_rate=imu_rate,
                          initial_target=target, noise_std=noise_std, seed=seed)
    if schedule is not None and not isinstance(schedule, Schedule):
        schedule = Schedule.load(schedule)
    if schedule is not None:
        schedule.check(live)
    start_faults = _start_faults(live, faults)
    messages = NodeMessages(live, scene_model, node_name=NODE_NAME, truth=bool(truth))
    streams = messages.streams
    parameters = {'scene': str(scene), 'overrides': list(overrides) or None,
                  'sample_rate': live.sample_rate, 'imu_rate': live.imu_rate,
                  'noise_std': float(noise_std), 'noise_seed': int(seed),
                  'publish_truth': bool(truth),
                  'tick_period': float(tick_period), 'state_period': float(state_period),
                  'schedule': schedule.source if schedule is not None else '',
                  'real_time_factor': 0.0, 'recorded_by': 'study record',
                  'duration': duration}
    if start_faults:
        parameters['faults'] = start_faults
    check_definitions(out)
    try:
        writer = Rosbag2McapWriter(out, overwrite=overwrite, chunk_size=RECORD_CHUNK_SIZE,
                                   flush_period=math.inf, fsync_period=None,
                                   overwrite_option=overwrite_option)
    except FileExistsError:
        raise
    except OSError as exc:   # missing or read-only directory, a directory, another writer
        raise open_error(exc, out) from None
    wall0 = time.perf_counter()
    bar = _Progress(duration, stream, progress)
    reached = _Reached(writer)
    summary = _Summary(live, scene_model)
    applied = 0
    try:
        metadata = run_metadata(scene_model, overrides, parameters, NODE_NAME, live=live)
        if schedule is not None:
            metadata['schedule'] = schedule.text
        writer.add_metadata('impact_damper_sim', metadata)
        # the channels the node opens its log with: every publisher, then the commands
        for i, s in enumerate(streams):
            if i not in (messages.parameter_events, messages.fault_command):
                writer.add_topic(s.topic, s.type_name, s.qos)
        reached.bytes = writer.file_bytes   # the opening records hold no message

        def write(stream_index, data, ns=None):
            s = streams[stream_index]
            ns = int(round(live.t * 1e9)) if ns is None else ns
            writer.write(s.topic, s.type_name, s.qos, data, ns, ns)
            reached.note()

        def parameter(name, value):
            if name == 'speed_rate_limit':
                live.set_speed_rate(value)   # 0: the rate at start
            elif name == 'dampers_enabled':
                live.set_dampers_enabled(value)
                write(messages.state, messages.state_message())
            else:   # noise_std, noise_seed
                live.set_noise(value if name == 'noise_std' else live.noise_std,
                               value if name == 'noise_seed' else None)
                messages.set_noise_variances(live.imu_noise_variances())
            write(messages.parameter_events, messages.parameter_event([(name, value)]))

        write(messages.state, messages.state_message())   # the latched state opens the log
        for text in start_faults:   # applied before the log opened, logged as received
            write(messages.fault_command, string_cdr(text))
        chunk = max(1, int(round(tick_period * live.sample_rate)))
        total = int(round(duration * live.sample_rate))
        done = 0
        next_state = state_period
        while done < total and writer.error is None:   # a disk error ends the run
            n = min(chunk, total - done)
            if schedule is not None and not schedule.done:
                for entry in schedule.due(live.t, live.sample_rate):
                    for key, kind, name, value in entry.commands:
                        try:
                            if key in ('fault', 'clear_fault'):   # the node's text
                                text = fault_command_text(key, value)
                                write(messages.fault_command, string_cdr(text))
                                live.fault_command(text, key=FAULT_COMMAND)
                            elif kind == 'topic':   # recorded as received, then applied
                                s = streams[messages.speed_command if key == 'speed'
                                            else messages.unbalance_command]
                                writer.write(s.topic, FLOAT64, s.qos, float64_cdr(value),
                                             *[int(round(live.t * 1e9))] * 2)
                                reached.note()
                                (live.command_speed if key == 'speed'
                                 else live.command_unbalance)(value)
                            else:
                                parameter(name, value)
                            applied += 1
                        except CommandError as exc:   # as the node: logged, the run goes on
                            print(f'study record: schedule entry at {entry.at:g} s: {exc}',
                                  file=sys.stderr)
                ahead = schedule.samples_to_next(live.t, live.sample_rate)
                if ahead:
                    n = min(n, ahead)
            batch = live.step(n)
            if batch is None:
                break
            done += n
            for ns, stream_index, data in messages.batch_items(batch):
                write(stream_index, data, ns)
            for ns, stream_index, data in messages.time_items():
                write(stream_index, data, ns)
            summary.add(batch)
            if batch.states_changed or live.t >= next_state - 0.5 / live.sample_rate:
                write(messages.state, messages.state_message())
                while next_state <= live.t + 0.5 / live.sample_rate:
                    next_state += state_period
            bar.show(live.t)
    finally:
        if writer.error is None:   # the faults came after the log opened: at its close
            writer.add_metadata(FAULTS_METADATA, fault_metadata(live))
        writer.close()
        bar.end()
    wall = time.perf_counter() - wall0
    stats = writer.stats()
    # finished: closed with its summary, no error, and still there (a file deleted while
    # written takes every write without an error)
    finished = (writer.error is None and getattr(writer, 'finished', True)
                and os.path.exists(out))
    result = RecordResult(
        path=str(out), sim_time_s=live.t, wall_s=wall,
        real_time_factor=live.t / wall if wall > 0 else math.inf,
        messages=stats['messages_written'], bytes=stats['file_bytes'],
        commands=applied, diverged=live.failure is not None, failure=live.failure,
        fault_labels=live.faults.labels(),
        finished=bool(finished), write_error=None, channel_preset=channel_preset(live),
        **summary.result(live.t))
    if not finished:
        line, reason, recoverable = write_failure(out, writer.error, stats,
                                                  complete=reached.messages)
        result['write_error'] = line
        raise LogWriteError(line, os.fspath(out), reason, result, recoverable)
    return result


def _start_faults(live, faults):
    """Add the faults of a run's start to ``live`` (before its log opens: a bad one leaves no
    file) and return the ``accel/fault_command`` text each stands for (list of str).

    Raises
    ------
    FaultError
        One line naming the fault's key (``faults[1].accelerometer``: the accelerometers
        there are), its range, a name given twice, or a clear command among them.
    """
    from ..live.fault_spec import FaultError, FaultSpec, parse_command, parse_fault
    from ..live.realtime import CommandError
    from ..recording.message_cdr import fault_command_text
    names = [acc.name for acc in live.accelerometers]
    texts = []
    for i, raw in enumerate(faults or ()):
        key = f'faults[{i}]'
        if isinstance(raw, FaultSpec):
            spec = raw
            spec.check(names, key)
        elif isinstance(raw, str):   # a command's text
            command = parse_command(raw, names, key=key)
            if command.action != 'add':
                raise FaultError(f"key '{key}': a fault to add, not a clear command")
            spec = command.spec
        else:
            spec = parse_fault(raw, names, key=key)
        try:
            live.add_fault(spec, key=key)
        except CommandError as exc:
            raise FaultError(str(exc)) from None
        texts.append(fault_command_text('fault', spec.as_dict()))
    return texts


def channel_preset(live):
    """The channel preset of a run's accelerometers (str): the one name when they share it,
    else ``name=preset`` per accelerometer joined by ``;`` ('' without accelerometers)."""
    presets = {acc.name: channel.spec['preset'] or 'ideal'
               for acc, channel in zip(live.accelerometers, live.channels)}
    if len(set(presets.values())) <= 1:
        return next(iter(presets.values()), '')
    return ';'.join(f'{name}={preset}' for name, preset in presets.items())


class _Reached:
    """Messages known to be in complete chunks on disk: all of them each time the file grew
    after a message without an error (a chunk, with every message written so far, reached
    the file; the opening records, written before the first message, do not count)."""

    def __init__(self, writer):
        self.writer = writer
        self.messages = 0
        self.bytes = writer.file_bytes

    def note(self):
        writer = self.writer
        if writer.file_bytes != self.bytes and writer.error is None:
            self.messages, self.bytes = writer.messages_written, writer.file_bytes


class _Summary:
    """Labels of a run, gathered while it steps: impacts, stuck time, peak and RMS."""

    def __init__(self, live, scene_model):
        self.live = live
        self.n_impactors = len(scene_model.impactors)
        self.impacts = 0
        self.stuck_time = 0.0
        self.samples = 0
        self.peak = 0.0
        self.square_sum = 0.0
        self.values = 0

    def add(self, batch):
        from ..recording.node_messages import published_samples
        k = batch.t.size
        ev = batch.events
        self.impacts += int(np.count_nonzero(ev['kind'] == 0))
        self.stuck_time += sum(self.live._stuck) * k / self.live.sample_rate
        lin = batch.linear_acceleration
        if batch.valid is not None and not batch.valid.all():   # what was published
            lin = lin[batch.valid]
        if lin.size:
            self.peak = max(self.peak, float(np.max(np.abs(lin))))
            self.square_sum += float(np.sum(lin * lin))
            self.values += lin.size
        self.samples += published_samples(batch)

    def result(self, t):
        t = max(t, 1e-300)
        return {'samples': self.samples, 'impacts': self.impacts,
                'impacts_per_s': self.impacts / t,
                'stuck_fraction': (self.stuck_time / (t * self.n_impactors)
                                   if self.n_impactors else None),
                'peak_g': self.peak / G0,
                'rms_g': math.sqrt(self.square_sum / self.values) / G0 if self.values else 0.0}


class _Progress:
    """``record  42%  sim 4.20 s of 10 s  23.5 x real time`` on one line, redrawn."""

    def __init__(self, duration, stream, enabled):
        self.duration = duration
        self.stream = sys.stderr if stream is None else stream
        if enabled is None:
            enabled = bool(getattr(self.stream, 'isatty', lambda: False)())
        self.enabled = enabled
        self.start = time.perf_counter()
        self.last = -math.inf
        self.drawn = False
        self.t = 0.0

    def show(self, t, force=False):
        self.t = t
        now = time.perf_counter()
        if not self.enabled or (now - self.last < 0.2 and not force):
            return
        self.last = now
        wall = now - self.start
        factor = f'{t / wall:6.1f} x real time' if wall > 0 else ''
        self.stream.write(f'\rrecord {100 * t / self.duration:5.1f} %  sim {t:.2f} s of '
                          f'{self.duration:g} s  {factor} ')
        self.stream.flush()
        self.drawn = True

    def end(self):
        if self.enabled and self.drawn:
            self.show(self.t, force=True)
            self.stream.write('\n')
            self.stream.flush()


__all__ = ['RecordResult', 'channel_preset', 'record_log']
