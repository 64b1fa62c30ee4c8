"""The recorder of ``vibration_node``: every published topic and received command to MCAP.

:class:`RecordingMixin` starts and stops an
:class:`~impact_damper_sim.recording.AsyncRecorder` (from the ``record`` parameter at start,
or the ``~/record`` service), writes each item with its sim time as log time and opens the
file with the run's metadata (software version, the resolved scene in SI, the node's
parameters); it closes it with the run's sensor faults (``impact_damper_sim_faults``: each
fault's kind, values, seed and actual window). It is separate from :mod:`.vibration_node`
because recording is an optional side channel of publishing: the node runs the same without
it. The node owns one :class:`Recording` and gives it what it needs: its lock, the
simulation, the outlets and command topics to declare, the run's metadata and a log.

A disk error (a full disk, an I/O error, the file or its directory removed) is logged once
at ERROR when it happens (from the writer thread) and the node goes on; stopping never says
"recorded N messages" of a file that is not a finished log: it says what is on disk and how
to recover it, and ``~/record false`` answers failure with that line.
"""
from __future__ import annotations

import os
import time

from ..recording.node_topics import RECORD_CHUNK_SIZE


class Recording:
    """Records what the node publishes and receives, on request.

    Parameters
    ----------
    lock : HandoffLock
        The node's lock: a recorder starts and stops between chunks.
    live : LiveSimulation
        The simulation (its time is the log time; its faults close the log).
    topics : callable
        ``topics()``: ``(topic, type_name, qos)`` of every outlet and command subscription,
        declared when a recording starts.
    metadata : callable
        ``metadata()``: the run's metadata (dict) that opens a log.
    opened : callable
        Called (under the lock) once a recording is open: the latched state opens the log.
    log : callable
        ``log(level, text)``.
    """

    def __init__(self, lock, live, topics, metadata, opened, log):
        self._lock, self.live, self._topics = lock, live, topics
        self._metadata, self._opened, self._log = metadata, opened, log
        self.recorder = None
        #: the disk error of this (or the last) recording, in one line (str or None)
        self.record_error = None
        #: the one line of the last recording that did not end as a finished log (or None)
        self.record_failure = None
        self._record_error_logged = False   # this recording's disk error is logged at ERROR

    def current_error(self):
        """The recording's disk error (str), or None: the writer's, once it has one."""
        if self.recorder is not None and self.recorder.error is not None:
            self.record_error = self.record_error or str(self.recorder.error)
        return self.record_error

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
                error = self.recorder.error
                return (f'already recording to {self.recorder.path}' if error is None else
                        f'already recording to {self.recorder.path}, stopped by a disk error '
                        f'({error}); ~/record false ends it')
            made = []   # the recorder, for the error callback (it may come before it exists)
            self.record_error = self.record_failure = None
            self._record_error_logged = False

            def on_error(exc):
                self._on_disk_error(exc, path, made[0] if made else None)
            try:
                # rosbag2's chunk size: the summary keeps one index per chunk in memory until
                # the file closes (64 KiB chunks grew RSS ~0.8 MB/min); a chunk is still
                # closed at least every flush period, which bounds what a crash loses
                rec = AsyncRecorder(path, overwrite=overwrite, on_error=on_error,
                                    chunk_size=RECORD_CHUNK_SIZE,
                                    overwrite_option='record_overwrite:=true')
            except (OSError, ValueError) as exc:
                return str(exc)
            made.append(rec)
            rec.add_metadata('impact_damper_sim', self._metadata())
            for topic, type_name, qos in self._topics():
                rec.add_topic(topic, type_name, qos)
            self.recorder = rec
            self._opened()   # the latched state opens the log
        self._log('info', f'recording to {path}')
        return None

    def stop_recording(self):
        """Finish the record file (summary and rosbag2 metadata); no-op when not recording.

        A file that is not a finished log (a disk error, the file or its directory removed)
        is never reported as recorded: one WARN line (ERROR if the error was not logged when
        it happened) says what is on disk and how to recover it, and :attr:`record_failure`
        keeps that line for ``~/record false``.

        Returns
        -------
        AsyncRecorder or None
            The recorder that was stopped.
        """
        from ..recording.log_metadata import FAULTS_METADATA, fault_metadata
        from ..studies.log_errors import write_failure
        with self._lock:
            rec, self.recorder = self.recorder, None
            if rec is not None:   # the sensor faults came after the log opened: at close
                rec.add_metadata(FAULTS_METADATA, fault_metadata(self.live))
        if rec is None:
            return None
        stats = rec.close()
        error = rec.error
        # a finished log: closed with its summary, no error, still there (an older writer
        # took the writes to a deleted file without an error)
        finished = (error is None and getattr(rec, 'finished', True)
                    and os.path.exists(rec.path))
        if finished:
            self.record_failure = None
            self._log('info', f'recorded {stats["messages_written"]} messages to {rec.path}')
            return rec
        line, _, _ = write_failure(rec.path, error, stats)
        self.record_failure = line
        self.record_error = self.record_error or line
        self._log('warning' if self._record_error_logged else 'error',
                  f'recording ended unfinished: {line}')
        self._record_error_logged = True
        return rec

    def on_request(self, request, response, path, overwrite):
        """``~/record`` (std_srvs/SetBool): true starts recording to ``path`` (the ``record``
        parameter's; '': a new timestamped file), false stops (failure, with what is on disk,
        when the file is not a finished log)."""
        if request.data:
            if not path:   # a new file each start: an automatic name never overwrites
                path, overwrite = _new_record_path(self.live.scene.name), False
            error = self.start_recording(path, overwrite)
            response.success = error is None
            response.message = error or str(path)
        else:
            rec = self.stop_recording()
            response.success = rec is not None and self.record_failure is None
            response.message = ('not recording' if rec is None else
                                f'recording stopped by a disk error: {self.record_failure}'
                                if self.record_failure else str(rec.path))
        return response

    def record(self, topic, type_name, qos, data, ns=None):
        """Write one message (bytes) to the recording, if any; ``ns``: log time (ns), the
        sim time now by default."""
        rec = self.recorder
        if rec is not None:
            # the log runs on sim time, as a recorder with use_sim_time on our /clock would:
            # an item's own sim time (samples: their stamp), else now
            if ns is None:
                ns = int(round(self.live.t * 1e9))
            rec.write(topic, type_name, qos, data, ns, ns)

    def _on_disk_error(self, exc, path=None, rec=None):
        """The recorder's first disk error (called once per recording, from its writer
        thread, or from the caller's while the file is opened): logged at ERROR now, reported
        in /diagnostics; the simulation goes on."""
        from ..studies.log_errors import error_reason
        self.record_error = str(exc)
        path = path if path is not None else getattr(rec, 'path', '?')
        if not os.path.exists(path):
            what = ('the file no longer exists (deleted, or its directory removed, while it '
                    'was written): what was recorded is lost')
        else:
            n = rec.stats()['messages_written'] if rec is not None else 0
            what = (f'{error_reason(exc)}; {n:,} messages were written before the error and '
                    'nothing is recorded from now on')
            if os.path.isfile(path):   # not /dev/full, a FIFO: there is a file to read back
                what += ('; the file stays unfinished (no summary): after ~/record false (or '
                         f'shutdown), `study recover {path} OUT.mcap` keeps what reached the '
                         'disk')
        self._record_error_logged = True
        self._log('error', f'recording to {path} failed: {what}; the simulation goes on')


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


__all__ = ['Recording']
