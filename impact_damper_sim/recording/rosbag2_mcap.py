"""Write MCAP files the way rosbag2 (jazzy, ``rosbag2_storage_mcap``) writes them, crash-safe.

Layout, as ``ros2 bag record -s mcap`` writes it (sources in :mod:`.definitions` and
:mod:`.bag_metadata`):

* header profile ``ros2``;
* one schema per type, named ``pkg/msg/Type``, encoding ``ros2msg``, data the ``.msg`` text
  with its dependencies (:func:`.definitions.message_definition`);
* one channel per topic (fully qualified name), message encoding ``cdr``, metadata
  ``offered_qos_profiles`` (YAML list of the publishers' QoS) and ``topic_type_hash``
  (RIHS01);
* messages with ``log_time`` = receive time and ``publish_time`` = send time (ns since the
  epoch), ``sequence`` 0;
* at close, a metadata record ``rosbag2`` whose key ``serialized_metadata`` holds the bag
  metadata YAML (version 9), then the summary section.

Not like rosbag2: chunks are small (64 KiB, rosbag2: 768 KiB) and carry a CRC, every closed
chunk goes to the OS at once (no user-space buffer), and the open chunk is closed at least
every ``flush_period`` (0.5 s) and the file fsync'd at most every ``fsync_period`` (1 s). A
SIGKILL therefore loses at most the open chunk, at most about 0.5 s of data (a power loss: at
most about 1.5 s); ``study recover`` (:func:`.recovery.recover`) turns such a file into a
finished one. Each schema and channel record is also written outside the chunks, to the file
at once, when its topic is registered (the open chunk is closed first; the chunk after keeps
mcap's own copy): a crash file has no summary repeating them, and one corrupt chunk would
otherwise take every definition with it and leave no message attributable. rosbag2 readers
(``ros2 bag``, rosbags, mcap's readers) ignore the differences.

One writer per file: the file is locked (``flock``, see :mod:`.log_file`) from before it is
truncated until it is closed, and a second writer is refused naming the holder.

Disk errors (``OSError`` on a write, flush, fsync) never raise out of :meth:`write`,
:meth:`add_metadata`, :meth:`poll` or :meth:`close`: the writer stores the first one in
:attr:`Rosbag2McapWriter.error`, calls ``on_error`` once, stops writing and counts later
messages as dropped. What reached the file before the error stays there (recoverable).
Programming errors (a relative topic name, an unknown type, a type change on a topic, negative
times) raise ``ValueError`` / ``LookupError``.

The CDR payload comes from the caller (``rclpy.serialization.serialize_message(msg)``), so
this module does not import rclpy (only :mod:`impact_damper_sim.ros` may).
"""
from __future__ import annotations

import os
import time
from importlib.metadata import PackageNotFoundError, version

from mcap.data_stream import RecordBuilder
from mcap.records import Channel as ChannelRecord
from mcap.records import Schema as SchemaRecord
from mcap.writer import CompressionType, Writer

from .. import __version__
from .bag_metadata import DEFAULT_ROS_DISTRO, bag_metadata, dump_yaml, qos_list
from .definitions import message_definition, split_type_name, type_hash
from .log_file import close_log, open_log, vanished

#: Chunk size (bytes, uncompressed): a chunk is closed once it holds more than this.
DEFAULT_CHUNK_SIZE = 64 * 1024
#: Longest time (s, wall) a message may wait in the open chunk before it is written to the OS.
DEFAULT_FLUSH_PERIOD = 0.5
#: Shortest time (s, wall) between two fsyncs; ``None`` never fsyncs before close.
DEFAULT_FSYNC_PERIOD = 1.0
_U64 = 2**64
_COMPRESSION = {'none': CompressionType.NONE, 'lz4': CompressionType.LZ4,
                'zstd': CompressionType.ZSTD}


def _library():
    try:
        mcap_version = version('mcap')
    except PackageNotFoundError:   # pragma: no cover - mcap is installed with its metadata
        mcap_version = 'unknown'
    return f'impact_damper_sim/{__version__} mcap-python/{mcap_version} (rosbag2 mcap layout)'


def full_type_name(type_name):
    """Return ``pkg/msg/Type`` for ``pkg/Type`` or ``pkg/msg/Type``.

    Parameters
    ----------
    type_name : str
        ROS type name.

    Returns
    -------
    str
    """
    package, name = split_type_name(type_name)
    return f'{package}/msg/{name}'


def check_topic(topic):
    """Raise ``ValueError`` unless ``topic`` is a fully qualified ROS name (as rosbag2 records).

    Parameters
    ----------
    topic : str
        Topic name, e.g. ``/accel/s1`` (``publisher.topic_name`` gives it).
    """
    if not isinstance(topic, str) or not topic.startswith('/') or len(topic) < 2:
        raise ValueError(f'topic {topic!r} is not a fully qualified name (e.g. '
                         f"'/accel/s1'; rclpy's publisher.topic_name gives it)")


def check_times(log_time_ns, publish_time_ns):
    """Raise ``ValueError`` unless both times are integers in [0, 2**64) ns.

    Parameters
    ----------
    log_time_ns, publish_time_ns : int
        Receive and send time (ns since the epoch).
    """
    if not (0 <= log_time_ns < _U64 and 0 <= publish_time_ns < _U64) \
            or not (isinstance(log_time_ns, int) and isinstance(publish_time_ns, int)):
        raise ValueError(f'message times must be integers in [0, 2**64) ns, got log_time '
                         f'{log_time_ns!r} and publish_time {publish_time_ns!r}')


class _RawFile:
    """Unbuffered output: each write goes to the OS at once, so a closed chunk survives a kill.

    mcap's Writer writes a whole record group per call (a chunk, its message indexes), so
    this costs a few system calls per chunk.
    """

    def __init__(self, fd):
        self.fd = fd
        self.position = 0   # bytes written (mcap asks for tell())

    def write(self, data):
        view = memoryview(data)
        while view:
            written = os.write(self.fd, view)
            view = view[written:]
            self.position += written
        return len(data)

    def tell(self):
        return self.position

    def flush(self):
        pass


class _Channel:
    __slots__ = ('id', 'topic', 'type', 'encoding', 'qos', 'hash', 'count')

    def __init__(self, channel_id, topic, type_name, encoding, qos, hash_string):
        self.id = channel_id
        self.topic = topic
        self.type = type_name
        self.encoding = encoding
        self.qos = qos
        self.hash = hash_string
        self.count = 0


class Rosbag2McapWriter:
    """Write one MCAP file in rosbag2's layout; small chunks, time-based flushing.

    Not thread-safe and not re-entrant: call it from one thread, and not from a signal
    handler that may interrupt it (:class:`.AsyncRecorder` is safe for both).

    Contract for callers (the node, ``study record``, ``study dataset``, ``study recover``):

    * Opening raises, and its ``str()`` is one line naming the file and the reason, with no
      ``[Errno N]`` prefix: ``FileExistsError`` (``<path> exists; not overwriting it (set
      <overwrite_option> to replace it)``); :class:`.log_file.FileLockedError`, an
      ``OSError`` (``<path> is being written by process 1234 (<command line>); not writing
      it``), whether ``overwrite`` is set or not, the other writer's file untouched; any
      other ``OSError`` as ``cannot create <path>: <reason>`` (``FileNotFoundError`` for a
      missing directory, ``PermissionError``, ``IsADirectoryError``, ``OSError`` with errno
      EROFS for a read-only file system, ...).
    * Nothing raises for a disk error after that: the first one is stored in :attr:`error`
      and passed to ``on_error`` once, from the thread that hit it.
    * After :meth:`close`, :attr:`error` is not None whenever the file is not a finished,
      readable log: a write, fsync or close error (``ENOSPC`` on a full disk, ``EIO``, ...),
      or the file deleted (alone or with its directory) or moved while being written
      (``ENOENT``, ``<path> was deleted while being written ...``, checked at every fsync
      and at close; ``<path> was moved while being written (the file is now ...)``, checked
      at close: a moved file still takes the data). :attr:`finished` is True exactly when the
      file is closed with its summary and no error; ``stats()['finished']`` says the same.

    Parameters
    ----------
    path : str or os.PathLike
        Output file (rosbag2 names it ``<bag>_0.mcap``; any name works).
    overwrite : bool, optional
        Replace an existing file. Without it an existing file raises ``FileExistsError``.
    overwrite_option : str, optional
        How the caller's user asks for ``overwrite``, named in that error's message (``set
        {overwrite_option} to replace it``): default ``overwrite=True``; a node passes its
        parameter (``record_overwrite:=true``), a command line its option.
    chunk_size : int, optional
        Chunk size (bytes, uncompressed) at which a chunk is closed.
    flush_period : float, optional
        Longest wait (s) of a message in the open chunk, checked on each :meth:`write` and
        :meth:`poll`.
    fsync_period : float or None, optional
        Shortest interval (s) between fsyncs after a flush; ``None``: fsync only at close.
    compression : {'none', 'lz4', 'zstd'}, optional
        Chunk compression (rosbag2's default is none).
    custom_data : dict of str, optional
        rosbag2's ``custom_data`` in the ``rosbag2`` record.
    ros_distro : str, optional
        ``ros_distro`` in the ``rosbag2`` record; default ``$ROS_DISTRO`` or ``jazzy``.
    on_error : callable, optional
        Called once with the first ``OSError`` (from the thread that hit it).
    clock : callable, optional
        Monotonic clock (s) for the flush and fsync periods; default ``time.monotonic``.

    Raises
    ------
    FileExistsError
        If ``path`` exists and ``overwrite`` is false (and no writer holds it).
    impact_damper_sim.recording.log_file.FileLockedError
        An ``OSError``: another writer, in this process or another, is writing ``path``.
    OSError
        If the file cannot be created (one-line text, see above).

    Attributes
    ----------
    error : OSError or None
        The first disk error, or the file lost while written; once set, nothing more is
        written.
    messages_written : int
        Messages accepted into the file (messages).
    messages_dropped : int
        Messages refused because of an earlier error or after close (messages).
    bytes_written : int
        CDR payload bytes accepted (bytes).
    """

    def __init__(self, path, *, overwrite=False, chunk_size=DEFAULT_CHUNK_SIZE,
                 flush_period=DEFAULT_FLUSH_PERIOD, fsync_period=DEFAULT_FSYNC_PERIOD,
                 compression='none', custom_data=None, ros_distro=None, on_error=None,
                 clock=time.monotonic, overwrite_option='overwrite=True'):
        if compression not in _COMPRESSION:
            raise ValueError(f'compression {compression!r} is not one of {list(_COMPRESSION)}')
        if not (isinstance(chunk_size, int) and chunk_size > 0):
            raise ValueError(f'chunk_size must be a positive int (bytes), got {chunk_size!r}')
        if not flush_period > 0 or (fsync_period is not None and not fsync_period >= 0):
            raise ValueError('flush_period must be > 0 s and fsync_period >= 0 s or None')
        self.path = os.fspath(path)
        self.custom_data = dict(custom_data or {})
        self.ros_distro = ros_distro or os.environ.get('ROS_DISTRO') or DEFAULT_ROS_DISTRO
        self.flush_period = flush_period
        self.fsync_period = fsync_period
        self.error = None
        self.messages_written = 0
        self.messages_dropped = 0
        self.bytes_written = 0
        self._on_error = on_error
        self._clock = clock
        self._channels = {}    # topic -> _Channel
        self._schemas = {}     # (name, encoding, data) -> schema id
        self._start_ns = None  # earliest and latest log time (ns)
        self._end_ns = None
        self._closed = False
        self._finished = False
        self._fd = open_log(self.path, overwrite, overwrite_option)
        self._stat = os.fstat(self._fd)   # to tell at fsync and close if the file vanished
        self._absolute = os.path.abspath(self.path)
        self._file = _RawFile(self._fd)
        self._mcap = Writer(self._file, chunk_size=chunk_size,
                            compression=_COMPRESSION[compression], enable_crcs=True)
        now = clock()
        self._last_flush = now
        self._last_fsync = now
        try:
            self._mcap.start(profile='ros2', library=_library())
        except OSError as exc:
            self._fail(exc)

    # ------------------------------------------------------------------ registration
    def add_topic(self, topic, type_name, qos=None):
        """Register a topic (a channel) before its first message; repeated calls are no-ops.

        Parameters
        ----------
        topic : str
            Fully qualified topic name, e.g. ``/accel/s1``.
        type_name : str
            ROS type, ``pkg/msg/Type`` (``pkg/Type`` is accepted).
        qos : rclpy.qos.QoSProfile, dict, list of them, or None
            The offered QoS (one per publisher; see :func:`.bag_metadata.qos_dict`).

        Returns
        -------
        bool
            False if a disk error stopped the writer.

        Raises
        ------
        ValueError
            For a relative topic name, a malformed type name, a bad QoS, or a topic already
            registered with another type.
        LookupError
            If the type's ``.msg`` is not installed.
        """
        return self._channel(topic, type_name, qos) is not None

    def _channel(self, topic, type_name, qos):
        channel = self._channels.get(topic)
        if channel is not None:
            if channel.type != type_name and channel.type != full_type_name(type_name):
                raise ValueError(f'topic {topic} was registered as {channel.type}, '
                                 f'not {type_name}')
            return channel
        check_topic(topic)
        name = full_type_name(type_name)
        definition = message_definition(name).encode('utf-8')
        return self._register(topic, name, 'ros2msg', definition, 'cdr', qos_list(qos),
                              type_hash(name))

    def _register(self, topic, schema_name, schema_encoding, schema_data, message_encoding,
                  qos, hash_string, metadata=None):
        """Register a schema (deduplicated) and a channel; return the channel or None."""
        if self.error is not None or self._closed:
            return None
        if metadata is None:
            metadata = {'offered_qos_profiles': dump_yaml(qos), 'topic_type_hash': hash_string}
        try:
            # close the open chunk first: mcap keeps its own copy of the records below for
            # the next chunk, which then comes after the copy written here (a reader that
            # loses either one to damage still finds the other)
            self._mcap.flush()
            schema_id = 0
            if schema_name:
                key = (schema_name, schema_encoding, schema_data)
                schema_id = self._schemas.get(key)
                if schema_id is None:
                    schema_id = self._mcap.register_schema(schema_name, schema_encoding,
                                                           schema_data)
                    self._schemas[key] = schema_id
                    self._write_record(SchemaRecord(id=schema_id, name=schema_name,
                                                    encoding=schema_encoding,
                                                    data=schema_data))
            channel_id = self._mcap.register_channel(topic, message_encoding, schema_id,
                                                     metadata)
            self._write_record(ChannelRecord(id=channel_id, topic=topic,
                                             message_encoding=message_encoding,
                                             schema_id=schema_id, metadata=metadata))
        except OSError as exc:
            self._fail(exc)
            return None
        channel = _Channel(channel_id, topic, schema_name, message_encoding, qos, hash_string)
        self._channels[topic] = channel
        return channel

    def _write_record(self, record):
        """Write a record to the file now, outside any chunk (it survives a corrupt chunk).

        mcap's Writer has written out everything but its open chunk between two calls, and
        it asks the file for its offsets, so a record written here keeps its indexes right
        (its data-section CRC is off: ``enable_data_crcs`` is false).
        """
        builder = RecordBuilder()
        record.write(builder)
        self._file.write(builder.end())

    # ------------------------------------------------------------------ writing
    def write(self, topic, type_name, qos, data, log_time_ns, publish_time_ns):
        """Write one serialized message; never raises for a disk error.

        Parameters
        ----------
        topic : str
            Fully qualified topic name; registered on first use.
        type_name : str
            ROS type, ``pkg/msg/Type``.
        qos : rclpy.qos.QoSProfile, dict, list or None
            Offered QoS; used only when the topic is registered.
        data : bytes
            CDR payload (``rclpy.serialization.serialize_message(msg)``), bytes.
        log_time_ns : int
            Receive time (ns since the epoch): when the recorder got the message.
        publish_time_ns : int
            Send time (ns since the epoch): when the publisher sent it.

        Returns
        -------
        bool
            True if accepted, False if dropped (after a disk error or close).
        """
        if self.error is not None or self._closed:
            self.messages_dropped += 1
            return False
        channel = self._channels.get(topic)
        if channel is None or channel.type != type_name:
            channel = self._channel(topic, type_name, qos)
            if channel is None:
                self.messages_dropped += 1
                return False
        check_times(log_time_ns, publish_time_ns)
        return self._add_message(channel, data, log_time_ns, publish_time_ns)

    def _add_message(self, channel, data, log_time_ns, publish_time_ns, sequence=0):
        try:
            self._mcap.add_message(channel.id, log_time_ns, data, publish_time_ns, sequence)
        except OSError as exc:   # the chunk filled up and could not be written
            self._fail(exc)
            self.messages_dropped += 1
            return False
        channel.count += 1
        self.messages_written += 1
        self.bytes_written += len(data)
        if self._start_ns is None:
            self._start_ns = self._end_ns = log_time_ns
        elif log_time_ns > self._end_ns:
            self._end_ns = log_time_ns
        elif log_time_ns < self._start_ns:
            self._start_ns = log_time_ns
        now = self._clock()
        if now - self._last_flush >= self.flush_period:
            self._flush(now)
        return True

    def add_metadata(self, name, data):
        """Write a metadata record now (before the open chunk; it survives a crash).

        Parameters
        ----------
        name : str
            Record name, e.g. ``impact_damper_sim``. ``rosbag2`` is reserved (written at close).
        data : dict of str to str
            Key-value pairs, e.g. ``{'scene': <resolved scene YAML>, 'version': '0.1.0'}``.

        Returns
        -------
        bool
            False if a disk error stopped the writer.
        """
        if name == 'rosbag2':
            raise ValueError("metadata name 'rosbag2' is reserved for the bag metadata at close")
        if not all(isinstance(k, str) and isinstance(v, str) for k, v in data.items()):
            raise TypeError('metadata keys and values must be str')
        if self.error is not None or self._closed:
            return False
        try:
            self._mcap.add_metadata(name, dict(data))
        except OSError as exc:
            self._fail(exc)
            return False
        return True

    def poll(self, now=None):
        """Close and write the open chunk if it is older than ``flush_period``.

        Call it from a timer when messages may stop for a while (:class:`.AsyncRecorder`
        does); :meth:`write` does it by itself.

        Parameters
        ----------
        now : float, optional
            Current time of ``clock`` (s).
        """
        if self.error is None and not self._closed:
            now = self._clock() if now is None else now
            if now - self._last_flush >= self.flush_period:
                self._flush(now)

    def flush(self, fsync=False):
        """Close and write the open chunk now; optionally fsync.

        Parameters
        ----------
        fsync : bool, optional
            Also fsync the file (slow: milliseconds).
        """
        if self.error is None and not self._closed:
            self._flush(self._clock(), force_fsync=fsync)

    def _flush(self, now, force_fsync=False):
        self._last_flush = now
        try:
            self._mcap.flush()   # closes the chunk (if it holds messages) and writes it
            if force_fsync or (self.fsync_period is not None
                               and now - self._last_fsync >= self.fsync_period):
                self._last_fsync = now
                os.fsync(self._fd)
                # writes to a deleted file succeed: look for it, so on_error says so now
                lost = vanished(self._fd, self.path, self._stat, check_moved=False)
                if lost is not None:
                    self._fail(lost)
        except OSError as exc:
            self._fail(exc)

    def _fail(self, exc):
        if self.error is not None:
            return
        self.error = exc
        if self._on_error is not None:
            try:
                self._on_error(exc)
            except Exception:   # a failing error callback must not stop the caller either
                pass

    # ------------------------------------------------------------------ closing
    def bag_metadata(self):
        """Return the rosbag2 bag metadata (version 9) of what was written so far.

        Returns
        -------
        dict
            See :func:`.bag_metadata.bag_metadata`.
        """
        topics = [{'name': c.topic, 'type': c.type, 'serialization_format': c.encoding,
                   'offered_qos_profiles': c.qos, 'type_description_hash': c.hash,
                   'message_count': c.count} for c in self._channels.values()]
        return bag_metadata(topics, self._start_ns, self._end_ns, os.path.basename(self.path),
                            self.ros_distro, self.custom_data)

    def close(self):
        """Write the ``rosbag2`` record and the summary, fsync and close; idempotent.

        After a disk error the file is closed as it is (no summary); ``study recover`` makes
        a finished copy. Afterwards :attr:`finished` tells whether the file is a finished
        log, and :attr:`error` why not.
        """
        if self._closed:
            return
        self._closed = True
        if self.error is None:
            try:
                self._mcap.add_metadata('rosbag2', {
                    'serialized_metadata': dump_yaml(self.bag_metadata())})
                self._mcap.finish()
                os.fsync(self._fd)
            except OSError as exc:
                self._fail(exc)
        lost = vanished(self._fd, self.path, self._stat, self._absolute)
        if lost is not None:
            self._fail(lost)
        try:
            close_log(self._fd)
        except OSError as exc:
            self._fail(exc)
        self._finished = self.error is None

    @property
    def closed(self):
        """bool: True once :meth:`close` has run."""
        return self._closed

    @property
    def finished(self):
        """bool: True once :meth:`close` has written the summary and closed the file with
        no error: a finished, readable log at :attr:`path`."""
        return self._finished

    @property
    def file_bytes(self):
        """int: bytes written to the file so far (bytes)."""
        return self._file.position

    def topic_counts(self):
        """Return the number of messages written per topic.

        Returns
        -------
        dict of str to int
            Topic name to message count (messages), in registration order.
        """
        return {c.topic: c.count for c in self._channels.values()}

    def stats(self):
        """Return the counters.

        Returns
        -------
        dict
            ``messages_written``, ``messages_dropped`` (messages), ``bytes_written`` (CDR
            payload bytes), ``file_bytes`` (bytes in the file), ``error`` (str or None),
            ``closed`` (bool), ``finished`` (bool, see :attr:`finished`).
        """
        return {'messages_written': self.messages_written,
                'messages_dropped': self.messages_dropped,
                'bytes_written': self.bytes_written, 'file_bytes': self.file_bytes,
                'error': None if self.error is None else str(self.error),
                'closed': self._closed, 'finished': self._finished}

    def __enter__(self):
        return self

    def __exit__(self, *exc_info):
        self.close()
