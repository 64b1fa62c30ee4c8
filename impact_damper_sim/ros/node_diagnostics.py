"""The health report of ``vibration_node``: ``/diagnostics`` and the counters behind it.

:class:`DiagnosticsMixin` publishes one ``diagnostic_msgs/DiagnosticArray`` per period
(pacing, CPU, impacts, stuck fraction, peak, recording, and the ERROR and WARN levels of a
failed simulation, a stalled stepping thread, a response that keeps growing) from the
counters of :class:`_Stats`. It is separate from :mod:`.vibration_node` because it only
reads what the node and the stepping thread did; the node's life cycle does not depend on
it. A mixin of :class:`~impact_damper_sim.ros.vibration_node.VibrationNode` only: it keeps no
state of its own beyond ``stats`` and ``last_diagnostics`` on the node, and uses the node's
``STALL`` and ``RTF_TOLERANCE``.
"""
from __future__ import annotations

import time

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

from . import interface as itf
from .wire import stamp

_stamp = stamp


class DiagnosticsMixin:
    """Report the health of :class:`~impact_damper_sim.ros.vibration_node.VibrationNode` on
    ``/diagnostics`` (a mixin of that node)."""

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
            over = [f'{acc.name} {int(n)}' for acc, n in zip(live.accelerometers, clipped) if n]
            if over:   # a DAQ reports overrange: the signal beyond the range is lost
                level = max(level, DiagnosticStatus.WARN)
                messages.append(f"clipped by the sensor's range or ADC: {', '.join(over)} "
                                'values')
            clash = getattr(self, '_name_clash', None)
            if clash is not None and clash.clashing:   # an aggregator sees two of us as one
                level = max(level, DiagnosticStatus.WARN)
                messages.append('another node has this fully qualified name '
                                f'({self.get_fully_qualified_name()}): /clock runs backwards')
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
        totals = self.stats_total['clipped'] + np.zeros(len(live.accelerometers), np.int64)
        for acc, n, total in zip(live.accelerometers, clipped, totals):
            values[f'clipped_values_{acc.name}'] = int(n)            # in this period
            values[f'clipped_values_total_{acc.name}'] = int(total)  # since start
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


class _Stats:
    """Counters of one diagnostics period."""

    def __init__(self, wall, cpu, sim, delivered, steps0=0, growing=0, last_peak=0.0):
        self.wall, self.cpu, self.sim, self.steps0 = wall, cpu, sim, steps0
        self.clipped = 0   # values clipped: 0, or an array per accelerometer once one clips
        self.delivered = delivered
        self.samples = self.impacts = self.commands = self.overruns = 0
        self.stuck_time = self.peak = self.lag = 0.0
        self.growing, self.last_peak = growing, last_peak
