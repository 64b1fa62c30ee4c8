"""The health report of ``vibration_node``: ``/diagnostics`` and the counters behind it.

:class:`Diagnostics` keeps the counters of each period (:class:`_Stats`) and since start,
and publishes one ``diagnostic_msgs/DiagnosticArray`` per period (pacing, CPU, impacts,
stuck fraction, peak, recording, and the ERROR and WARN levels of a failed simulation, a
stalled stepping thread, a response that keeps growing). It only reads what the node, its
stepping thread and its recorder did; each is given to it explicitly.
"""
from __future__ import annotations

import time

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

from . import interface as itf
from .outlets import stamp

_stamp = stamp


def default_hardware_id(namespace, scene):
    """The ``hardware_id`` of a node whose ``hardware_id`` parameter is empty: its namespace
    and scene, ``'pump3/hpotp'`` (``'hpotp'`` at the root namespace)."""
    return '/'.join([*namespace.strip('/').split('/'), scene]).lstrip('/')


class Diagnostics:
    """The node's health on ``/diagnostics``, and the counters behind it.

    Parameters
    ----------
    node : rclpy.node.Node
        Names the report (its name, fully qualified name and clock).
    live : LiveSimulation
        The simulation reported on.
    outbox : Outbox
        Its pacer and delivered time give the achieved real-time factor.
    lock : HandoffLock
        Held while the report reads the simulation.
    outlet : Outlet
        ``/diagnostics``.
    recording : Recording
        Its disk errors are reported.
    stepping : callable
        ``stepping(wall)``: why the stepping thread is not stepping ('' while it is).
    log : callable
        ``log(level, text, throttle, key)``.
    clock : callable
        Wall clock (s).
    counters : Counters
        What the publishers and commands counted.
    name_clash : NameClash, optional
        Another node with this node's name is reported while it is there (the node's timer
        looks before each report).
    hardware_id : str, optional
        The status's ``hardware_id`` (a plant's name for the machine); empty: the node's
        namespace and the scene (:func:`default_hardware_id`).

    The status is named ``<fully qualified node name>: simulation`` (e.g.
    ``/pump3/vibration_node: simulation``), so that nodes in several namespaces stay apart in
    an aggregator (``diagnostic_aggregator`` groups by name).
    """

    #: the stepping thread is reported stalled (ERROR) after this long without a cycle (s)
    STALL = 2.0
    #: a diagnostics period is "behind" when its achieved real-time factor falls short of
    #: the requested one by more than this fraction (the goal is >= 0.98 in every 1 s)
    RTF_TOLERANCE = 0.02

    def __init__(self, node, live, outbox, lock, outlet, recording, stepping, log, clock,
                 counters, name_clash=None, hardware_id=''):
        self.node, self.live, self.outbox, self._lock = node, live, outbox, lock
        self.outlet, self.recording, self.stepping = outlet, recording, stepping
        self._log, self.clock, self.name_clash = log, clock, name_clash
        self.counters = counters
        self.scene = live.scene
        self.status_name = f'{node.get_fully_qualified_name()}: simulation'
        self.hardware_id = hardware_id or default_hardware_id(node.get_namespace(),
                                                              self.scene.name)
        self.growth_rate = live.linear_growth_rate()
        self.last_diagnostics = None
        self._failure_logged = False

    @property
    def stats(self):
        """_Stats: The counters of the period under way."""
        return self.counters.stats

    @stats.setter
    def stats(self, value):
        self.counters.stats = value

    def restart_period(self, keep_trend=True):
        """Begin a new period now (a changed factor is measured against from now on)."""
        wall, st, live = self.clock(), self.stats, self.live
        self.stats = _Stats(wall, time.process_time(), live.t,
                            self.outbox.delivered_t(wall, live.t), steps0=live.steps,
                            growing=st.growing if keep_trend else 0,
                            last_peak=st.last_peak if keep_trend else 0.0)

    def report_failure(self):
        """Log the simulation's failure once at ERROR and report it."""
        if not self._failure_logged:
            self._failure_logged = True
            self.node.get_logger().error(f'simulation stopped: {self.live.failure}; the node '
                                         'stays up (diagnostics report ERROR)')
            self.publish()

    def publish(self):
        """Publish ``/diagnostics``: pacing, CPU, impacts, stuck fraction, peak, health."""
        if not self._lock.acquire(self.STALL):   # the stepping thread is stuck in a chunk
            status = DiagnosticStatus(
                name=self.status_name, hardware_id=self.hardware_id,
                level=DiagnosticStatus.ERROR,
                message=f'stepping thread stalled: it has held the simulation for over '
                        f'{self.STALL:g} s')
            msg = DiagnosticArray(status=[status])
            msg.header.stamp = self.node.get_clock().now().to_msg()
            self.outlet.publish(msg)
            self.last_diagnostics = {'level': 2, 'message': status.message}
            self._log('error', status.message, 5.0, 'stalled')
            return
        try:
            self._publish_diagnostics()
        finally:
            self._lock.release()

    def _publish_diagnostics(self):
        live, st = self.live, self.stats
        wall, cpu = self.clock(), time.process_time()
        d_wall = max(wall - st.wall, 1e-9)
        d_sim = live.t - st.sim
        # delivered, not stepped, sim time: stepping runs up to a chunk and a lookahead
        # ahead, which would put +-2 % of noise on a 1 s period
        delivered = self.outbox.delivered_t(wall, live.t)
        achieved = (delivered - st.delivered) / d_wall
        n_imp = len(self.scene.impactors)
        stuck_fraction = (st.stuck_time / (d_sim * n_imp)) if d_sim > 0 and n_imp else 0.0
        status = DiagnosticStatus(name=self.status_name, hardware_id=self.hardware_id)
        level, messages = DiagnosticStatus.OK, []
        rtf = self.outbox.pacer.real_time_factor
        stalled = self.stepping(wall)
        clipped = st.clipped + np.zeros(len(live.accelerometers), np.int64)   # per accelerometer
        if live.failure is not None:
            level = DiagnosticStatus.ERROR
            messages.append(f'stopped: {live.failure}')
        elif stalled:
            level = DiagnosticStatus.ERROR
            messages.append(stalled)
        else:
            if rtf > 0 and achieved < rtf * (1.0 - self.RTF_TOLERANCE):
                level = DiagnosticStatus.WARN
                messages.append(f'behind real time: achieved {achieved:.3g} of {rtf:g} '
                                f'(tolerance {100 * self.RTF_TOLERANCE:g} %)')
                # our throttle: rclpy's inspects the caller's frame on every call (2-6 ms)
                self._log('warning', messages[-1], 5.0, 'behind')
            if self.growth_rate > 0:
                level = max(level, DiagnosticStatus.WARN)
                messages.append(f'linear model unstable: growth rate {self.growth_rate:.3g} '
                                '1/s without impactors')
            record_error = self.recording.current_error()
            if record_error:
                level = max(level, DiagnosticStatus.WARN)
                messages.append(f'recording stopped by a disk error: {record_error}')
            if st.growing >= 5:
                level = max(level, DiagnosticStatus.WARN)
                messages.append('response growing for 5 periods')
            over = [f'{acc.name} {int(n)}' for acc, n in zip(live.accelerometers, clipped) if n]
            if over:   # a DAQ reports overrange: the signal beyond the range is lost
                level = max(level, DiagnosticStatus.WARN)
                messages.append(f"clipped by the sensor's range or ADC: {', '.join(over)} "
                                'values')
            clash = self.name_clash
            if clash is not None and clash.clashing:   # an aggregator sees two of us as one
                level = max(level, DiagnosticStatus.WARN)
                messages.append('another node has this fully qualified name '
                                f'({self.node.get_fully_qualified_name()}): /clock runs '
                                'backwards')
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
            'schedule_deficits_dropped': self.outbox.pacer.deficits,
            'rejected_commands': self.counters.rejected, 'dampers_enabled': live.dampers_enabled,
            'rotor_speed_rad_s': speed, 'unbalance_multiplier': x,
            'linear_growth_rate_1_s': self.growth_rate,
        }
        totals = self.counters.stats_total['clipped'] + np.zeros(len(live.accelerometers), np.int64)
        for acc, n, total in zip(live.accelerometers, clipped, totals):
            values[f'clipped_values_{acc.name}'] = int(n)            # in this period
            values[f'clipped_values_total_{acc.name}'] = int(total)  # since start
        rec = self.recording.recorder
        if rec is not None:
            rs = rec.stats()
            values.update({'record_path': str(rec.path),
                           'record_messages_written': rs['messages_written'],
                           'record_messages_dropped': rs['messages_dropped'],
                           'record_queue_high_water': rs['queue_high_water']})
        values['record_error'] = self.recording.current_error() or ''

        status.values = [KeyValue(key=k, value=f'{v:.6g}' if isinstance(v, float) else str(v))
                         for k, v in values.items()]
        msg = DiagnosticArray(status=[status])
        msg.header.stamp = _stamp(live.t)
        self.outlet.publish(msg)
        self.last_diagnostics = values | {'level': int.from_bytes(level, 'little')
                                          if isinstance(level, bytes) else int(level),
                                          'message': status.message}
        # growth only counts at steady speed (a ramp through a critical also grows)
        growing = st.peak > 1.2 * st.last_peak > 0 and live.rotor_state()[1] == 0.0
        self.stats = _Stats(wall, cpu, live.t, delivered, steps0=live.steps,
                            growing=st.growing + 1 if growing else 0, last_peak=st.peak)


class Counters:
    """What the node counted: this diagnostics period's :class:`_Stats`, totals since start
    and the commands refused.

    Parameters
    ----------
    wall : float
        Wall time now (s).
    t_sim : float
        Sim time now (s).
    """

    def __init__(self, wall, t_sim):
        self.stats = _Stats(wall, time.process_time(), t_sim, t_sim)
        # since start (clipped: values, per accelerometer once one clips)
        self.stats_total = {'samples': 0, 'impacts': 0, 'clipped': 0}
        self.rejected = 0


class _Stats:
    """Counters of one diagnostics period."""

    def __init__(self, wall, cpu, sim, delivered, steps0=0, growing=0, last_peak=0.0):
        self.wall, self.cpu, self.sim, self.steps0 = wall, cpu, sim, steps0
        self.clipped = 0   # values clipped: 0, or an array per accelerometer once one clips
        self.delivered = delivered
        self.samples = self.impacts = self.commands = self.overruns = 0
        self.stuck_time = self.peak = self.lag = 0.0
        self.growing, self.last_peak = growing, last_peak


__all__ = ['Counters', 'Diagnostics']
