"""The rclpy-free reader of recorded ROS 2 MCAP logs, shared by ``study report`` and ``replay``.

:class:`RosLog` checks that a file is a complete ROS 2 MCAP (a regular file with the MCAP magic
at both ends, profile ``ros2``, a summary or else every record readable, a log-time span under
a year) and turns every problem with it into a one-line :class:`LogError`; :func:`printable`
escapes what such a message quotes from a damaged file. Messages are read lazily with the
``mcap`` reader, without rclpy. Apart from :mod:`.report` because the ROS replay node
(:mod:`impact_damper_sim.ros.replay`) opens logs with it too and needs none of the report's
analysis.
"""
from __future__ import annotations

import contextlib
import os
import re
from stat import S_ISREG

MCAP_MAGIC = b'\x89MCAP0\r\n'


#: Longest log-time span a log may have (ns): a year. Anything longer is a corrupt or absurd
#: timestamp (one message at 2^63 - 1 ns made replay wait 292 years).
MAX_LOG_SPAN_NS = 365 * 86400 * 10**9


class LogError(Exception):
    """A log that cannot be used; the message is one line, meant for the user."""


_CONTROL = re.compile('[\x00-\x1f\x7f-\x9f\u2028\u2029]')


def printable(text):
    """Return ``text`` with every control character (and line separator) escaped as
    :func:`repr` does (``\\x00``, ``\\n``).

    Messages quote names and text from damaged files: escaped, they stay on one line and
    cannot garble a terminal.

    Parameters
    ----------
    text : str

    Returns
    -------
    str
    """
    return _CONTROL.sub(lambda m: repr(m.group())[1:-1], text)


@contextlib.contextmanager
def _reading(path, what='corrupt MCAP file'):
    """Turn any failure of the ``mcap`` library on ``path`` into a one-line LogError."""
    try:
        yield
    except LogError:
        raise
    except OSError as exc:
        raise LogError(f'{path}: cannot read: {exc.strerror or exc}') from None
    except Exception as exc:   # the mcap reader raises many kinds on bad bytes
        text = ' '.join(str(exc).split()) or type(exc).__name__
        raise LogError(printable(f'{path}: {what} ({type(exc).__name__}: {text})')) from None


def type_name(name):
    """Return a ROS type name as ``pkg/msg/Type`` (``pkg/Type`` is accepted too).

    Parameters
    ----------
    name : str
        Schema name from the log.

    Returns
    -------
    str
    """
    parts = name.split('/')
    return f'{parts[0]}/msg/{parts[1]}' if len(parts) == 2 else name


class RosLog:
    """A complete ROS 2 MCAP file: header, schemas, channels, statistics and metadata.

    Opening checks the file: it exists and is not empty, starts and ends with the MCAP magic
    (a file without the closing magic was cut off), has profile ``ros2``, and its summary (or,
    without one, every record) reads. Messages are read lazily by :meth:`messages`.

    Parameters
    ----------
    path : str or os.PathLike
        The ``.mcap`` file.

    Raises
    ------
    LogError
        Missing, empty, not MCAP, truncated, corrupt or not ROS 2; one line naming the file.

    Examples
    --------
    The node's log of 50 ms of the ``sdof`` scene, written offline by ``study record``
    (:func:`~impact_damper_sim.studies.record.record_log`): the accelerometer's decimated Imu
    stream; its full-rate batches, ``/clock`` and the impacts once per 10 ms tick; the
    impactor state at the start; no impact yet (the first comes at 0.208 s):

    >>> import os, tempfile
    >>> from impact_damper_sim.studies.record import record_log
    >>> folder = tempfile.TemporaryDirectory()
    >>> path = os.path.join(folder.name, 'sdof.mcap')
    >>> result = record_log('sdof', path, 0.05, progress=False)
    >>> result['samples'], result['impacts']
    (100, 0)
    >>> log = RosLog(path)
    >>> log.message_count, round(log.duration_s, 6)
    (40, 0.05)
    >>> for channel in sorted(log.channels.values(), key=lambda c: c.topic):
    ...     if log.counts.get(channel.id):
    ...         print(f'{channel.topic:27} {log.type_of(channel):30} {log.counts[channel.id]}')
    /accel/sdof_primary         sensor_msgs/msg/Imu            24
    /accel/sdof_primary/batch   sensor_msgs/msg/PointCloud2    5
    /clock                      rosgraph_msgs/msg/Clock        5
    /impactor_state             sensor_msgs/msg/JointState     1
    /impacts                    sensor_msgs/msg/PointCloud2    5
    >>> sorted(log.metadata)
    ['impact_damper_sim', 'impact_damper_sim_faults', 'rosbag2']
    >>> try:
    ...     RosLog(os.path.join(folder.name, 'missing.mcap'))
    ... except LogError as exc:
    ...     print(exc)
    /...missing.mcap: cannot read: No such file or directory
    >>> folder.cleanup()
    """

    def __init__(self, path):
        from mcap.reader import SeekingReader
        self.path = os.fspath(path)
        self._check_ends()
        with _reading(self.path), open(self.path, 'rb') as fh:
            reader = SeekingReader(fh, validate_crcs=True)
            header = reader.get_header()
            summary = reader.get_summary()
            self.profile, self.library = header.profile, header.library
            if self.profile != 'ros2':
                raise LogError(f'{self.path}: not a ROS 2 log: MCAP profile '
                               f"{self.profile!r}, expected 'ros2'")
            self._metadata = None
            if summary is not None and summary.statistics is not None:
                self.schemas, self.channels = dict(summary.schemas), dict(summary.channels)
                stats = summary.statistics
                self.message_count = stats.message_count
                self.counts = dict(stats.channel_message_counts)
                self.start_ns, self.end_ns = stats.message_start_time, stats.message_end_time
                if summary.metadata_indexes:
                    self._metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
                else:
                    self._metadata = {}
        if self._metadata is None:   # no summary (a streamed file): read every record once
            self._scan()
        if self.message_count == 0:
            self.start_ns = self.end_ns = 0
        if self.end_ns - self.start_ns > MAX_LOG_SPAN_NS:   # replay would wait that long
            raise LogError(f'{self.path}: messages span {(self.end_ns - self.start_ns) * 1e-9:.3g}'
                           f' s of log time, over {MAX_LOG_SPAN_NS * 1e-9:.3g} s (a year): a '
                           'corrupt or absurd timestamp')

    def _check_ends(self):
        try:
            st = os.stat(self.path)
            # a FIFO would block the open, a device (/dev/zero) never end a read
            if not S_ISREG(st.st_mode):
                from ..scene.loading import file_kind
                raise LogError(f'{self.path}: not an MCAP log ({file_kind(self.path)}, not a '
                               'regular file)')
            size = st.st_size
            with open(self.path, 'rb') as fh:
                head = fh.read(len(MCAP_MAGIC))
                fh.seek(max(0, size - len(MCAP_MAGIC)))
                tail = fh.read(len(MCAP_MAGIC))
        except OSError as exc:
            raise LogError(f'{self.path}: cannot read: {exc.strerror or exc}') from None
        if size == 0:
            raise LogError(f'{self.path}: empty file (0 bytes), not an MCAP log')
        if head != MCAP_MAGIC:
            if MCAP_MAGIC.startswith(head):
                raise LogError(f'{self.path}: truncated MCAP file ({size} bytes)')
            raise LogError(f'{self.path}: not an MCAP file (it does not start with the MCAP '
                           'magic bytes)')
        if tail != MCAP_MAGIC or size < 2 * len(MCAP_MAGIC):
            raise LogError(f'{self.path}: truncated MCAP file: it does not end with the MCAP '
                           'magic bytes (a recording cut off by a crash? `study recover '
                           f'{self.path} OUT.mcap` saves what it holds)')

    def _scan(self):
        from mcap.records import Channel, Message, Metadata, Schema
        from mcap.stream_reader import StreamReader
        self.schemas, self.channels, self.counts, self._metadata = {}, {}, {}, {}
        start = end = None
        with _reading(self.path), open(self.path, 'rb') as fh:
            for record in StreamReader(fh, validate_crcs=True).records:
                if isinstance(record, Schema):
                    self.schemas[record.id] = record
                elif isinstance(record, Channel):
                    self.channels[record.id] = record
                elif isinstance(record, Message):
                    if record.channel_id not in self.channels:
                        raise LogError(f'{self.path}: corrupt MCAP file (message on unknown '
                                       f'channel {record.channel_id})')
                    self.counts[record.channel_id] = self.counts.get(record.channel_id, 0) + 1
                    t = record.log_time
                    start = t if start is None else min(start, t)
                    end = t if end is None else max(end, t)
                elif isinstance(record, Metadata):
                    self._metadata[record.name] = dict(record.metadata)
        self.message_count = sum(self.counts.values())
        self.start_ns, self.end_ns = start or 0, end or 0

    @property
    def duration_s(self):
        """float: log_time span from the first to the last message (s)."""
        return (self.end_ns - self.start_ns) * 1e-9

    @property
    def metadata(self):
        """dict: metadata records, ``{name: {key: value}}`` (str values)."""
        return dict(self._metadata)

    def schema_of(self, channel):
        """Return the schema record of a channel (None if it has none)."""
        return self.schemas.get(channel.schema_id)

    def type_of(self, channel):
        """Return a channel's ROS type, ``pkg/msg/Type`` ('' if it has no schema)."""
        schema = self.schema_of(channel)
        return type_name(schema.name) if schema is not None else ''

    def messages(self, topics=None, log_time_order=True):
        """Yield ``(channel, message)`` pairs; ``message.log_time`` in ns since the epoch.

        Parameters
        ----------
        topics : iterable of str, optional
            Topic names as recorded; default all.
        log_time_order : bool
            Sorted by log_time (merging chunks) rather than in file order.

        Raises
        ------
        LogError
            A record that cannot be read (the messages before it have been yielded).
        """
        from mcap.reader import SeekingReader
        topics = None if topics is None else list(topics)
        with _reading(self.path), open(self.path, 'rb') as fh:
            reader = SeekingReader(fh, validate_crcs=True)
            for _, channel, message in reader.iter_messages(topics=topics,
                                                            log_time_order=log_time_order):
                yield channel, message


__all__ = ['LogError', 'RosLog', 'type_name']
