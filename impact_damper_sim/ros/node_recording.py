"""The recorder of ``vibration_node``: every published topic and received command to MCAP.

:class:`RecordingMixin` starts and stops an
:class:`~impact_damper_sim.recording.AsyncRecorder` (from the ``record`` parameter at start,
or the ``~/record`` service), writes each item with its sim time as log time and opens the
file with the run's metadata (software version, the resolved scene in SI, the node's
parameters). It is separate from :mod:`.vibration_node` because recording is an optional
side channel of publishing: the node runs the same without it. A mixin of
:class:`~impact_damper_sim.ros.vibration_node.VibrationNode` only: it keeps ``recorder`` and
``record_error`` on the node and uses its lock, outlets and command subscriptions.
"""
from __future__ import annotations

import time

from ..recording.node_topics import RECORD_CHUNK_SIZE
from . import interface as itf


class RecordingMixin:
    """Record what :class:`~impact_damper_sim.ros.vibration_node.VibrationNode` publishes and
    receives (a mixin of that node)."""

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
        from ..recording.node_messages import run_metadata
        return run_metadata(self.scene, self._params['overrides'], self._params,
                            self.get_fully_qualified_name())


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
