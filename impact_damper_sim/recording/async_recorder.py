"""Record off the stepping path: a queue in front of :class:`.Rosbag2McapWriter`.

The caller's :meth:`AsyncRecorder.write` validates, appends a tuple to a deque and returns
(about a microsecond; no lock, no wake-up). A background thread wakes every ``wake_period``,
drains the deque into the writer, closes chunks older than ``flush_period`` and fsyncs at most
every ``fsync_period``. A full queue drops the message (counted) rather than block the caller.

Shutdown: :meth:`AsyncRecorder.close` stops accepting, lets the thread drain the queue and
finalize the file (``rosbag2`` record, summary, fsync), and waits. It is idempotent, may be
called from any thread and from a signal handler (it takes no lock the caller could hold), and
runs at interpreter exit for recorders never closed. SIGKILL loses the queue and the open
chunk (at most about ``flush_period + wake_period`` of data); ``study recover`` repairs the
rest.

The caller's contract is the writer's (see :class:`.Rosbag2McapWriter`): opening errors raise
here, in the caller, as one-line ``OSError`` exceptions (a second writer of the same file
included);
after :meth:`close`, :attr:`AsyncRecorder.error` is not None whenever the file is not a
finished log, and :attr:`AsyncRecorder.finished` and ``stats()['finished']`` say whether it
is.
"""
from __future__ import annotations

import atexit
import collections
import errno
import os
import threading
import weakref

from .bag_metadata import qos_list
from .definitions import AmentIndexError, check_ament_index, message_definition
from .log_file import log_error
from .rosbag2_mcap import Rosbag2McapWriter, check_times, check_topic, full_type_name

#: Queue capacity (messages); about 30 MB of ``sensor_msgs/Imu``.
DEFAULT_MAX_QUEUE = 100_000
#: Period (s) at which the writer thread wakes to drain the queue.
DEFAULT_WAKE_PERIOD = 0.05

_open_recorders = weakref.WeakSet()


@atexit.register
def _close_open_recorders():
    # atexit runs while daemon threads still run, so the writer thread can finish the file
    for recorder in list(_open_recorders):
        recorder.close()


class AsyncRecorder:
    """Queue messages from the stepping loop; write them to MCAP from a background thread.

    Parameters
    ----------
    path : str or os.PathLike
        Output file.
    max_queue : int, optional
        Queue capacity (messages); further messages are dropped and counted.
    wake_period : float, optional
        Writer-thread wake-up period (s).
    on_error : callable, optional
        Called once, from the writer thread, with the first disk error (``OSError``).
    **writer_options
        Passed to :class:`.Rosbag2McapWriter`: ``overwrite``, ``overwrite_option`` (what the
        caller's user sets for ``overwrite``, named in the ``FileExistsError``), ``chunk_size``
        (bytes), ``flush_period`` (s), ``fsync_period`` (s), ``compression``, ``custom_data``,
        ``ros_distro``.

    Raises
    ------
    FileExistsError
        If the file exists and ``overwrite`` is not true (raised here, in the caller).
    impact_damper_sim.recording.log_file.FileLockedError
        An ``OSError``: another writer is writing the file (overwrite or not).
    AmentIndexError
        An ``OSError``: the message definitions cannot be read (``AMENT_PREFIX_PATH`` unset or
        wrong), checked before the file is created, so nothing is written.
    OSError
        If the file cannot be created (one line: ``cannot create <path>: <reason>``).

    A refused start leaves no file behind: every check comes before the file is created.
    """

    def __init__(self, path, *, max_queue=DEFAULT_MAX_QUEUE, wake_period=DEFAULT_WAKE_PERIOD,
                 on_error=None, **writer_options):
        if not (isinstance(max_queue, int) and max_queue > 0) or not wake_period > 0:
            raise ValueError('max_queue must be a positive int and wake_period > 0 s')
        unknown = set(writer_options) - {'overwrite', 'overwrite_option', 'chunk_size',
                                         'flush_period', 'fsync_period', 'compression',
                                         'custom_data', 'ros_distro'}
        if unknown:
            raise TypeError(f'unknown AsyncRecorder options: {sorted(unknown)}')
        try:   # every topic's schema is read from the ament index: check it before the file
            check_ament_index()
        except AmentIndexError as exc:
            raise AmentIndexError(f'cannot record to {os.fspath(path)} (nothing written): '
                                  f'{exc}') from None
        self._writer = Rosbag2McapWriter(path, on_error=on_error, **writer_options)
        self.path = self._writer.path
        self._max_queue = max_queue
        self._wake_period = wake_period
        self._queue = collections.deque()   # append/popleft are atomic: no lock needed
        self._types = {}                    # topic -> type name, checked in the caller
        self._closing = False
        self._stop = threading.Event()
        self._drop_lock = threading.Lock()
        self._dropped = 0
        self._high_water = 0
        self._thread_error = None
        self._unfinished_at_close = None   # set when close() returns before the thread ends
        self._thread = threading.Thread(target=self._run, name=f'mcap-recorder:{self.path}',
                                        daemon=True)
        self._thread.start()
        _open_recorders.add(self)

    # ------------------------------------------------------------------ caller side
    def add_topic(self, topic, type_name, qos=None):
        """Register a topic now (its channel is written before its first message).

        Parameters
        ----------
        topic : str
            Fully qualified topic name.
        type_name : str
            ``pkg/msg/Type``.
        qos : rclpy.qos.QoSProfile, dict, list of them, or None
            Offered QoS (see :func:`.bag_metadata.qos_dict`).

        Raises
        ------
        ValueError, LookupError
            As :meth:`.Rosbag2McapWriter.add_topic` (checked here, in the caller).
        """
        self._check_topic(topic, type_name, qos)
        if not self._closing:
            self._queue.append(('topic', (topic, type_name, qos)))

    def add_metadata(self, name, data):
        """Queue a metadata record (written in order with the messages).

        Parameters
        ----------
        name : str
            Record name, e.g. ``impact_damper_sim``.
        data : dict of str to str
            Key-value pairs.
        """
        if name == 'rosbag2':
            raise ValueError("metadata name 'rosbag2' is reserved for the bag metadata at close")
        if not all(isinstance(k, str) and isinstance(v, str) for k, v in data.items()):
            raise TypeError('metadata keys and values must be str')
        if not self._closing:
            self._queue.append(('metadata', (name, dict(data))))

    def _check_topic(self, topic, type_name, qos):
        known = self._types.get(topic)
        if known is None:
            check_topic(topic)
            message_definition(full_type_name(type_name))   # raises if not installed; cached
            qos_list(qos)                                    # raises for a bad profile
            self._types[topic] = type_name
        elif known != type_name and full_type_name(known) != full_type_name(type_name):
            raise ValueError(f'topic {topic} was registered as {known}, not {type_name}')

    def write(self, topic, type_name, qos, data, log_time_ns, publish_time_ns):
        """Queue one serialized message; never blocks, never raises for a disk error.

        Parameters
        ----------
        topic : str
            Fully qualified topic name.
        type_name : str
            ``pkg/msg/Type``.
        qos : rclpy.qos.QoSProfile, dict, list or None
            Offered QoS; used when the topic is first seen.
        data : bytes
            CDR payload (``rclpy.serialization.serialize_message(msg)``), bytes.
        log_time_ns : int
            Receive time (ns since the epoch).
        publish_time_ns : int
            Send time (ns since the epoch).

        Returns
        -------
        bool
            True if queued; False if dropped (queue full, closing, or after a disk error).
        """
        if self._types.get(topic) != type_name:
            self._check_topic(topic, type_name, qos)
        check_times(log_time_ns, publish_time_ns)
        queue = self._queue
        n = len(queue)
        if (n >= self._max_queue or self._closing or self._writer.error is not None
                or self._thread_error is not None):
            with self._drop_lock:   # rare path; keeps the count exact across threads
                self._dropped += 1
            return False
        queue.append((topic, type_name, qos, data, log_time_ns, publish_time_ns))
        if n >= self._high_water:
            self._high_water = n + 1
        return True

    # ------------------------------------------------------------------ writer thread
    def _run(self):
        writer = self._writer
        queue = self._queue
        try:
            while True:
                stopping = self._stop.is_set()   # read before draining: nothing is left behind
                while queue:
                    item = queue.popleft()
                    if len(item) == 6:
                        writer.write(*item)
                    elif item[0] == 'topic':
                        writer.add_topic(*item[1])
                    else:
                        writer.add_metadata(*item[1])
                writer.poll()
                if stopping:
                    break
                self._stop.wait(self._wake_period)
        except BaseException as exc:   # a bug here must still leave a finished file
            self._thread_error = exc
        finally:
            writer.close()

    # ------------------------------------------------------------------ shutdown, status
    def close(self, timeout=None):
        """Stop accepting, drain the queue, finalize the file; idempotent and signal-safe.

        Parameters
        ----------
        timeout : float, optional
            Longest wait (s) for the writer thread; ``None`` waits until it is done.

        Returns
        -------
        dict
            :meth:`stats` after closing.
        """
        self._closing = True
        self._stop.set()
        _open_recorders.discard(self)
        if threading.current_thread() is not self._thread:
            self._thread.join(timeout)
            if self._thread.is_alive():   # error says so while it is true
                self._unfinished_at_close = log_error(
                    errno.ETIMEDOUT, f'{self.path} was still being finished by the writer '
                    f'thread when close() returned (timeout {timeout} s)', self.path)
        return self.stats()

    @property
    def closed(self):
        """bool: True once the file is finalized (the writer thread has ended)."""
        return self._writer.closed and not self._thread.is_alive()

    @property
    def finished(self):
        """bool: True once the file is a finished log (closed with its summary, no error)."""
        return self.closed and self._writer.finished and self._thread_error is None

    @property
    def error(self):
        """OSError or Exception or None: the first disk error (or the file lost while
        written), a writer-thread failure, or, after a :meth:`close` whose timeout expired
        and while the thread still finishes the file, an ``OSError`` (ETIMEDOUT) saying so.
        After close it is None only for a finished log."""
        if self._writer.error is not None:
            return self._writer.error
        if self._thread_error is not None:
            return self._thread_error
        if self._unfinished_at_close is not None and self._thread.is_alive():
            return self._unfinished_at_close
        return None

    def topic_counts(self):
        """Return messages written per topic (dict of str to int, messages)."""
        return self._writer.topic_counts()

    def stats(self):
        """Return the counters.

        Returns
        -------
        dict
            ``messages_written`` (in the file), ``messages_dropped`` (queue full, closing, or
            disk error), ``bytes_written`` (CDR payload bytes), ``file_bytes`` (bytes),
            ``queue_length`` and ``queue_high_water`` (messages), ``error`` (str or None),
            ``closed`` (bool), ``finished`` (bool, see :attr:`finished`).
        """
        stats = self._writer.stats()
        error = self.error
        stats.update(messages_dropped=self._dropped + self._writer.messages_dropped,
                     queue_length=len(self._queue), queue_high_water=self._high_water,
                     error=None if error is None else f'{type(error).__name__}: {error}',
                     closed=self.closed, finished=self.finished)
        return stats

    def __enter__(self):
        return self

    def __exit__(self, *exc_info):
        self.close()
