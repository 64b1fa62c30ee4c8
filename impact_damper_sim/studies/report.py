"""``study report``: what a vibration engineer looks at first in a recorded MCAP log.

::

    study report FILE.mcap [--json] [--plot PATH.png] [--csv PATH]

The log is an MCAP file in rosbag2's layout (profile ``ros2``, ``ros2msg`` schemas, ``cdr``
messages), from ``vibration_node``'s recorder or from ``ros2 bag record``. It is read with
the ``mcap`` reader and decoded with ``mcap_ros2.decoder.DecoderFactory``: no rclpy, no ROS
installation beyond the Python packages. The report gives

* per topic: type, message count and rate (count over the log's duration, by log_time) and
  mean frequency (intervals between the topic's own messages);
* per sensor (every ``accel/<name>/batch`` ``sensor_msgs/PointCloud2`` topic: the full-rate
  signal, many samples a message; and every ``sensor_msgs/Imu`` topic, one sample a message,
  except the decimated ``accel/<name>`` of a sensor whose batches are in the log): peak and
  RMS of the linear acceleration in g (G0 = 9.80665 m/s^2) per axis and of its magnitude,
  and a Welch spectrum with its dominant frequency; when the log has ``rotor/speed`` with a
  speed range, a waterfall (spectrum per slice of time against the rotor speed) as well;
* the impact rate over time: impact stamps counted in 1 s bins, from ``impacts`` batches
  (``sensor_msgs/PointCloud2``, one row per impact with its impactor's index, named through
  the ``impactor_state`` joint names ``<impactor>/<dof>`` in impactor order, else
  ``impactor<i>``) or, in older logs, one ``geometry_msgs/WrenchStamped`` per impact (the
  impactor the last component of its frame_id);
* the stuck fraction of each impactor: ``impactor_state`` effort flags, time-weighted (each
  state holds until the next message, the last one until the end of the log);
* the metadata records (``impact_damper_sim``: scene, overrides, software version;
  ``rosbag2``: the bag metadata).

Signal times are header stamps (sim time for ``vibration_node``; in a batch, ``header.stamp``
plus the row's ``t``), counted from the earliest stamp in the log (the start of an impact
batch's interval counts). Counts and rates use log_time (receive time), as rosbag2 does.
Batch layouts: :mod:`impact_damper_sim.recording.batches`.

:class:`RosLog` is the rclpy-free reader shared with ``replay``: it checks that a file is a
complete ROS 2 MCAP and turns every problem with it into a one-line :class:`LogError`.
"""
from __future__ import annotations

import contextlib
import io
import math
import os
import re
from stat import S_ISREG

import numpy as np

from ..recording.batches import BATCH_SUFFIX, POINTCLOUD2, rows_of, sample_times_ns

from ..scene.units import G0  # standard gravity (m/s^2), exact
MCAP_MAGIC = b'\x89MCAP0\r\n'
IMU = 'sensor_msgs/msg/Imu'
WRENCH_STAMPED = 'geometry_msgs/msg/WrenchStamped'
JOINT_STATE = 'sensor_msgs/msg/JointState'
VECTOR3_STAMPED = 'geometry_msgs/msg/Vector3Stamped'
# topic names of ros.interface (relative there; matched here under any namespace)
ACCEL_PREFIX = 'accel/'
IMPACTS = 'impacts'
IMPACTOR_STATE = 'impactor_state'
ROTOR_SPEED = 'rotor/speed'
#: a rotor speed range wider than this fraction of the top speed gives a waterfall
WATERFALL_MIN_SPAN = 0.1
#: slices per waterfall (fewer when the record is short)
WATERFALL_SLICES = 40
BIN_S = 1.0   # impact-rate bin width (s)


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


# --- reading ----------------------------------------------------------------------------------

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
                from ..scene.schema import file_kind
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


# --- analysis ---------------------------------------------------------------------------------

def _base(topic):
    return topic.strip('/')


def _ends_with(topic, name):
    """True if ``topic`` is ``name`` under any namespace."""
    base = _base(topic)
    return base == name or base.endswith('/' + name)


def _namespace(topic, name):
    """The namespace in front of ``name`` (``/ns/`` for ``/ns/accel/s1`` and ``accel/``)."""
    base = '/' + _base(topic)
    at = base.rfind('/' + name)
    return base[:at + 1] if at >= 0 else base[:base.rfind('/') + 1]


def _sensor_name(topic):
    base = _base(topic)
    at = base.rfind(ACCEL_PREFIX)
    return base[at + len(ACCEL_PREFIX):] if at >= 0 and base[at + len(ACCEL_PREFIX):] else base


def _batch_stem(topic):
    """The topic without ``/batch`` if it is ``[/ns]/accel/<name>/batch`` (str), else None."""
    base = '/' + _base(topic)
    if not base.endswith(BATCH_SUFFIX):
        return None
    stem = base[:-len(BATCH_SUFFIX)]
    at = stem.rfind('/' + ACCEL_PREFIX)
    return stem if at >= 0 and stem[at + 1 + len(ACCEL_PREFIX):] else None


def _stamp_ns(msg):
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


class _Series:
    """Collected samples of one topic (stamps in ns, values as lists until finished).

    A batch topic collects one array per message in ``t``, ``values`` (accelerations) or
    ``labels`` (impactor indices), joined by :meth:`join`; ``starts`` holds the header
    stamps of impact batches (ns), the starts of the intervals they cover.
    """

    def __init__(self):
        self.t, self.values, self.labels, self.starts, self.failed = [], [], [], [], 0

    def join(self, kind):
        """Turn a batch topic's per-message arrays into one array each."""
        if kind == 'batch':
            self.t = np.concatenate(self.t) if self.t else np.empty(0, np.int64)
            self.values = np.concatenate(self.values) if self.values else np.empty((0, 3))
        elif kind == 'impact_batch':
            self.t = np.concatenate(self.t) if self.t else np.empty(0, np.int64)
            self.labels = (np.concatenate(self.labels) if self.labels
                           else np.empty(0, np.int64))

    def stamps(self):
        """Every stamp of the topic (ns, int64 array), interval starts included."""
        return np.concatenate([np.asarray(self.t, dtype=np.int64).reshape(-1),
                               np.asarray(self.starts, dtype=np.int64)])


def analyze(path):
    """Read a log and compute the report.

    Parameters
    ----------
    path : str or os.PathLike
        The ``.mcap`` file.

    Returns
    -------
    report : dict
        The ``study report --json`` data: ``file``, ``profile``, ``library``,
        ``start_time_ns``/``end_time_ns`` (log_time), ``duration_s``, ``message_count``,
        ``time_origin_s``/``stamped_span_s`` (header stamps), ``topics``, ``sensors``
        (:func:`sensor_report`), ``rotor_speed``, ``impacts`` (:func:`impact_rate`),
        ``impactor_state`` (:func:`stuck_fractions`), ``metadata`` and ``warnings``.
        Accelerations in g, times in s, rates in 1/s, frequencies in Hz, speeds in rad/s
        and rpm.
    series : dict
        Arrays for the plot (spectra, waterfalls, impact-rate bins, stuck-state steps).

    Raises
    ------
    LogError
        The file cannot be read (see :class:`RosLog`).
    """
    from mcap_ros2.decoder import DecoderFactory
    log = RosLog(path)
    warnings = []
    factory = DecoderFactory()
    # which channels to decode, and how to read each message into a row
    wanted = {}
    for cid, ch in log.channels.items():
        kind = _kind(ch.topic, log.type_of(ch))
        if kind is not None:
            wanted[cid] = kind
    # a sensor with full-rate batches in the log is read from them, not from its decimated Imu
    batched = {_batch_stem(log.channels[cid].topic) for cid, kind in wanted.items()
               if kind == 'batch' and log.counts.get(cid, 0)}
    wanted = {cid: kind for cid, kind in wanted.items()
              if not (kind == 'imu' and '/' + _base(log.channels[cid].topic) in batched)}
    decoders, series = {}, {cid: _Series() for cid in wanted}
    counts, first, last = {}, {}, {}
    for ch, msg in log.messages(log_time_order=False):
        cid = ch.id
        counts[cid] = counts.get(cid, 0) + 1
        t = msg.log_time
        first[cid] = min(first.get(cid, t), t)
        last[cid] = max(last.get(cid, t), t)
        if cid not in wanted:
            continue
        if cid not in decoders:
            # mcap_ros2's vendored rosidl parser prints 'Error with: ...' before it raises
            with _reading(log.path, f'cannot decode schema of topic {ch.topic}'), \
                    contextlib.redirect_stderr(io.StringIO()), \
                    contextlib.redirect_stdout(io.StringIO()):
                decoders[cid] = factory.decoder_for(ch.message_encoding, log.schema_of(ch))
            if decoders[cid] is None:
                warnings.append(f'topic {ch.topic}: cannot decode (message encoding '
                                f'{ch.message_encoding!r}); not analyzed')
        if decoders[cid] is None:
            continue
        s = series[cid]
        try:
            _collect(wanted[cid], decoders[cid](msg.data), s)
        except Exception:   # a damaged payload: skip it, say how many
            s.failed += 1
    for cid, s in series.items():
        s.join(wanted[cid])
        if s.failed:
            warnings.append(f'topic {log.channels[cid].topic}: {s.failed} message(s) could not '
                            'be decoded and were skipped')
    for cid, n in counts.items():
        if log.counts.get(cid, n) != n:
            warnings.append(f'topic {log.channels[cid].topic}: {n} messages read, the summary '
                            f'says {log.counts[cid]}')
    return _assemble(log, wanted, series, counts, first, last, warnings)


def _kind(topic, rtype):
    if rtype == IMU:
        return 'imu'
    if rtype == POINTCLOUD2 and _batch_stem(topic) is not None:
        return 'batch'
    if rtype == POINTCLOUD2 and _ends_with(topic, IMPACTS):
        return 'impact_batch'
    if rtype == WRENCH_STAMPED and _ends_with(topic, IMPACTS):
        return 'impacts'
    if rtype == JOINT_STATE and _ends_with(topic, IMPACTOR_STATE):
        return 'state'
    if rtype == VECTOR3_STAMPED and _ends_with(topic, ROTOR_SPEED):
        return 'speed'
    return None


def _collect(kind, m, s):
    if kind == 'batch':
        rows = rows_of(m)
        values = np.column_stack((rows['ax'], rows['ay'], rows['az']))
        s.t.append(sample_times_ns(m, rows))
        s.values.append(values)
        return
    if kind == 'impact_batch':
        rows = rows_of(m)
        index = rows['impactor'].astype(np.int64)
        s.t.append(sample_times_ns(m, rows))
        s.labels.append(index)
        s.starts.append(_stamp_ns(m))
        return
    t = _stamp_ns(m)
    if kind == 'imu':
        a = m.linear_acceleration
        s.values.append((a.x, a.y, a.z))
    elif kind == 'impacts':
        s.labels.append(m.header.frame_id.rsplit('/', 1)[-1])
    elif kind == 'state':
        s.values.append(list(m.effort))
        s.labels.append(list(m.name))
    else:
        s.values.append(m.vector.x)
    s.t.append(t)


def _assemble(log, wanted, series, counts, first, last, warnings):
    duration = log.duration_s
    topics = []
    for cid, ch in sorted(log.channels.items(), key=lambda kv: kv[1].topic):
        n = counts.get(cid, 0)
        span = (last[cid] - first[cid]) * 1e-9 if n else 0.0
        topics.append({'topic': ch.topic, 'type': log.type_of(ch), 'count': n,
                       'rate_hz': n / duration if duration > 0 else None,
                       'frequency_hz': (n - 1) / span if n > 1 and span > 0 else None})
    stamps = [x for x in (series[cid].stamps() for cid in wanted) if x.size]
    origin = min(int(x.min()) for x in stamps) if stamps else 0
    end = max(int(x.max()) for x in stamps) if stamps else 0
    plot = {'origin_ns': origin, 'sensors': {}, 'impacts': {}, 'states': {}}
    report = {'file': log.path, 'profile': log.profile, 'library': log.library,
              'start_time_ns': log.start_ns, 'end_time_ns': log.end_ns, 'duration_s': duration,
              'message_count': sum(counts.values()), 'time_origin_s': origin * 1e-9,
              'stamped_span_s': (end - origin) * 1e-9, 'topics': topics, 'sensors': [],
              'rotor_speed': [], 'impacts': [], 'impactor_state': [],
              'metadata': log.metadata, 'warnings': warnings}
    speeds = {}
    for cid in sorted(c for c, k in wanted.items() if k == 'speed'):
        topic = log.channels[cid].topic
        t, w = _sorted(series[cid].t, series[cid].values)
        if t.size:
            speeds[topic] = (t, w)
            report['rotor_speed'].append({
                'topic': topic, 'samples': int(t.size), 'min_rad_s': float(w.min()),
                'max_rad_s': float(w.max()), 'min_rpm': float(w.min()) * 30 / math.pi,
                'max_rpm': float(w.max()) * 30 / math.pi})
    for cid in sorted((c for c, k in wanted.items() if k in ('imu', 'batch')),
                      key=lambda c: log.channels[c].topic):
        topic = log.channels[cid].topic
        t, acc = _sorted(series[cid].t, series[cid].values)
        if t.size == 0:
            continue
        speed = _speed_for(topic, speeds)
        entry, arrays = sensor_report(t, acc / G0, origin, speed)
        name = _sensor_name(_batch_stem(topic) if wanted[cid] == 'batch' else topic)
        report['sensors'].append({'topic': topic, 'sensor': name, **entry})
        plot['sensors'][topic] = arrays
        if entry['gaps']:
            warnings.append(f"topic {topic}: {entry['gaps']} gap(s) longer than 1.5 sample "
                            'periods (dropped samples?); the spectrum assumes even sampling')
        if any(entry['nonfinite_samples'].values()):
            warnings.append(f'topic {topic}: {nonfinite_text(entry)}; left out of peak and '
                            'RMS, replaced by the axis mean in the spectra')
    joints = {log.channels[cid].topic: _first_names(series[cid])
              for cid, kind in wanted.items() if kind == 'state' and series[cid].t}
    for cid in sorted(c for c, k in wanted.items() if k in ('impacts', 'impact_batch')):
        topic = log.channels[cid].topic
        labels = series[cid].labels
        if wanted[cid] == 'impact_batch':
            labels = _impactor_labels(labels, _impactor_order(topic, joints))
        entry, arrays = impact_rate(series[cid].t, labels, origin, end)
        report['impacts'].append({'topic': topic, **entry})
        plot['impacts'][topic] = arrays
    for cid in sorted(c for c, k in wanted.items() if k == 'state'):
        topic = log.channels[cid].topic
        s = series[cid]
        impactors, steps = stuck_fractions(s.t, s.labels, s.values, end)
        if s.t and not impactors:
            warnings.append(f'topic {topic}: no effort flags (JointState.effort is empty); '
                            'no stuck fraction')
        report['impactor_state'].append({'topic': topic, 'impactors': impactors})
        plot['states'][topic] = steps
    return report, plot


def _first_names(states):
    """The joint names of the earliest ``impactor_state`` message of a series (list)."""
    return states.labels[int(np.argmin(states.t))]


def _impactor_order(topic, joints):
    """Impactor names in impactor order for an ``impacts`` topic (list of str).

    From the ``impactor_state`` joint names ``<impactor>/<dof>`` in the same namespace, else
    of the only such topic; empty when none is known.
    """
    ns = _namespace(topic, IMPACTS)
    names = next((n for state, n in joints.items() if _namespace(state, IMPACTOR_STATE) == ns),
                 next(iter(joints.values())) if len(joints) == 1 else [])
    return list(dict.fromkeys(name.rsplit('/', 1)[0] for name in names))


def _impactor_labels(index, order):
    """Name of each impact's impactor: ``order[i]`` for index ``i``, else ``impactor<i>``."""
    top = int(index.max()) + 1 if index.size else 0
    table = np.array(list(order) + [f'impactor{i}' for i in range(len(order), top)],
                     dtype=object)
    return table[index]


def _sorted(t, values):
    t = np.asarray(t, dtype=np.int64)
    order = np.argsort(t, kind='stable')
    return t[order], np.asarray(values, dtype=float)[order]


def _speed_for(topic, speeds):
    """The rotor speed series in the sensor's namespace, else the only one, else None."""
    ns = _namespace(topic, ACCEL_PREFIX)
    for name, series in speeds.items():
        if _namespace(name, ROTOR_SPEED) == ns:
            return series
    return next(iter(speeds.values())) if len(speeds) == 1 else None


def sensor_report(t_ns, a_g, origin_ns=0, speed=None):
    """Peak, RMS, spectrum and (over a speed range) waterfall of one accelerometer.

    Parameters
    ----------
    t_ns : numpy.ndarray of int, shape (n,)
        Sample stamps (ns), sorted.
    a_g : numpy.ndarray, shape (n, 3)
        Linear acceleration along x, y, z (g).
    origin_ns : int
        Time origin of the slice times (ns).
    speed : tuple of numpy.ndarray, optional
        Rotor speed stamps (ns, sorted) and speeds (rad/s); a waterfall is computed when the
        speed spans more than ``WATERFALL_MIN_SPAN`` of its largest magnitude.

    Returns
    -------
    entry : dict
        ``samples``, ``sample_rate_hz``, ``gaps``, ``duration_s``, ``peak_g`` and ``rms_g``
        (``x``, ``y``, ``z``, ``magnitude``; g), ``spectrum`` (``method``,
        ``segment_samples``, ``resolution_hz``, ``dominant_hz`` per axis and ``total``; None
        with fewer than 16 samples) and ``waterfall`` (None, or ``slices``,
        ``segment_samples``, ``resolution_hz``, and per slice ``time_s``, ``speed_rad_s``,
        ``speed_rpm``, ``dominant_hz``, ``amplitude_g``).
    arrays : dict
        Spectrum (``freq_hz``, ``psd_g2_hz`` shape (3, m)) and waterfall arrays for the plot.
    """
    n = t_ns.size
    axes = ('x', 'y', 'z')
    a_g = np.asarray(a_g, dtype=float)
    bad = ~np.isfinite(a_g)
    nonfinite = {k: int(bad[:, i].sum()) for i, k in enumerate(axes)}
    if bad.any():
        # NaN or inf samples: left out of peak and RMS (None for an axis without a finite
        # one), the magnitude over the finite components, and the spectra with each such
        # sample replaced by its axis' finite mean (no power added)
        finite_mean = [float(np.mean(a_g[~bad[:, i], i])) if (~bad[:, i]).any() else 0.0
                       for i in range(3)]
        a_g = np.where(bad, np.asarray(finite_mean)[None, :], a_g)
    mag_rows = ~bad.all(axis=1)
    mag = np.sqrt(np.sum(np.where(bad, 0.0, a_g) ** 2, axis=1))[mag_rows]

    def stat(values, ok, fn):
        return float(fn(values[ok])) if ok.any() else None

    peak = {k: stat(np.abs(a_g[:, i]), ~bad[:, i], np.max) for i, k in enumerate(axes)}
    peak['magnitude'] = float(mag.max()) if mag.size else None
    rms = {k: stat(a_g[:, i] ** 2, ~bad[:, i], lambda v: np.sqrt(np.mean(v)))
           for i, k in enumerate(axes)}
    rms['magnitude'] = float(np.sqrt(np.mean(mag ** 2))) if mag.size else None
    dt = np.diff(t_ns) * 1e-9
    step = float(np.median(dt)) if n > 1 else 0.0
    fs = 1.0 / step if step > 0 else None
    entry = {'samples': int(n), 'sample_rate_hz': fs,
             'gaps': int(np.sum(dt > 1.5 * step)) if step > 0 else 0,
             'duration_s': (int(t_ns[-1]) - int(t_ns[0])) * 1e-9, 'peak_g': peak, 'rms_g': rms,
             'nonfinite_samples': nonfinite, 'spectrum': None, 'waterfall': None}
    arrays = {}
    if fs is None or n < 16:
        return entry, arrays
    seg = _segment(n)
    freq, psd = welch(a_g, fs, seg)
    total = psd.sum(axis=0)
    dom = {k: float(freq[1 + np.argmax(psd[i, 1:])]) for i, k in enumerate(axes)}
    dom['total'] = float(freq[1 + np.argmax(total[1:])])
    entry['spectrum'] = {'method': 'welch, hann, 50% overlap', 'segment_samples': int(seg),
                         'resolution_hz': float(fs / seg), 'dominant_hz': dom}
    arrays.update(freq_hz=freq, psd_g2_hz=psd)
    if speed is not None:
        entry['waterfall'], more = _waterfall(t_ns, a_g, fs, speed, origin_ns)
        arrays.update(more)
    return entry, arrays


def nonfinite_text(entry):
    """``'non-finite samples (NaN or inf): x 10 of 2000, ...'`` of a sensor entry."""
    bad = entry['nonfinite_samples']
    return ('non-finite samples (NaN or inf): '
            + ', '.join(f"{axis} {count} of {entry['samples']}"
                        for axis, count in bad.items() if count))


def welch(x, fs, nperseg):
    """One-sided Welch PSD: periodic Hann window, 50 % overlap, mean removed per segment.

    NumPy only (SciPy's import costs seconds on the command's start-up path); the same
    estimate as ``scipy.signal.welch(x, fs, 'hann', nperseg, axis=0)``.

    Parameters
    ----------
    x : numpy.ndarray, shape (n, k)
        Evenly sampled signals in columns (any unit U).
    fs : float
        Sample rate (Hz).
    nperseg : int
        Segment length (samples), <= n.

    Returns
    -------
    freq : numpy.ndarray, shape (m,)
        Frequencies (Hz), m = nperseg // 2 + 1.
    psd : numpy.ndarray, shape (k, m)
        Power spectral density (U^2/Hz).
    """
    window = 0.5 - 0.5 * np.cos(2 * np.pi * np.arange(nperseg) / nperseg)
    starts = range(0, x.shape[0] - nperseg + 1, nperseg - nperseg // 2)
    psd = 0.0
    for k, start in enumerate(starts, 1):
        seg = x[start:start + nperseg]
        spec = np.fft.rfft((seg - seg.mean(axis=0)) * window[:, None], axis=0)
        psd = psd + np.abs(spec) ** 2
    psd = psd / (k * fs * np.sum(window ** 2))
    psd[1:-1 if nperseg % 2 == 0 else None] *= 2   # one-sided: fold negative frequencies
    return np.fft.rfftfreq(nperseg, 1.0 / fs), psd.T


def _segment(n):
    """Welch segment length: about a quarter of the record as a power of two, >= 256."""
    return int(min(n, max(256, 2 ** int(math.floor(math.log2(max(n / 4, 1)))))))


def _waterfall(t_ns, a_g, fs, speed, origin_ns):
    st, w = speed
    top = float(np.max(np.abs(w))) if w.size else 0.0
    if w.size < 2 or top <= 0 or float(w.max() - w.min()) <= WATERFALL_MIN_SPAN * top:
        return None, {}
    # up to WATERFALL_SLICES slices, but not shorter than 256 samples while 4 slices fit
    seg = max(min(256, t_ns.size // 4), t_ns.size // WATERFALL_SLICES, 16)
    n_slices = t_ns.size // seg
    if n_slices < 2:
        return None, {}
    window = np.hanning(seg)
    freq = np.fft.rfftfreq(seg, 1.0 / fs)
    rows, times, speeds = [], [], []
    for k in range(n_slices):
        part = slice(k * seg, (k + 1) * seg)
        x = a_g[part] - a_g[part].mean(axis=0)
        spec = np.fft.rfft(x * window[:, None], axis=0)
        # single-sided amplitude (g) of a sine, Hann-corrected; axes summed in power
        rows.append(np.sqrt(np.sum(np.abs(spec) ** 2, axis=1)) * 2 / window.sum())
        ts = t_ns[part]
        times.append((float(ts.mean()) - origin_ns) * 1e-9)
        speeds.append(float(np.mean(np.interp(ts.astype(float), st.astype(float), w))))
    amp = np.array(rows)
    dom = freq[1 + np.argmax(amp[:, 1:], axis=1)]
    entry = {'slices': n_slices, 'segment_samples': int(seg), 'resolution_hz': fs / seg,
             'time_s': times, 'speed_rad_s': speeds,
             'speed_rpm': [s * 30 / math.pi for s in speeds],
             'dominant_hz': [float(f) for f in dom],
             'amplitude_g': [float(a) for a in amp[:, 1:].max(axis=1)]}
    return entry, {'waterfall_freq_hz': freq, 'waterfall_amp_g': amp,
                   'waterfall_speed_rad_s': np.array(speeds)}


def impact_rate(t_ns, impactors, origin_ns, end_ns):
    """Impacts per second in bins of ``BIN_S`` from the time origin.

    Parameters
    ----------
    t_ns : sequence of int
        Impact stamps (ns).
    impactors : sequence of str
        Impactor name of each impact (the last component of a WrenchStamped's
        ``frame_id``, or named from a batch row's impactor index).
    origin_ns, end_ns : int
        Start and end of the log's stamped time (ns); the last bin ends at ``end_ns``.

    Returns
    -------
    entry : dict
        ``count``, ``mean_rate_hz`` (count over the stamped span), ``peak_rate_hz`` (the
        largest full bin), ``bin_s``, ``bins`` (``start_s`` from the origin, ``width_s``,
        ``count``, ``rate_hz``) and ``per_impactor`` counts.
    arrays : dict
        ``start_s``, ``width_s``, ``rate_hz`` for the plot.
    """
    t = np.asarray(t_ns, dtype=np.int64)
    span = max(0, int(end_ns) - int(origin_ns)) * 1e-9
    n_bins = max(1, math.ceil(span / BIN_S))
    width = np.full(n_bins, BIN_S)
    width[-1] = span - (n_bins - 1) * BIN_S
    index = np.minimum(((t - origin_ns) * 1e-9 // BIN_S).astype(int), n_bins - 1)
    count = np.bincount(np.maximum(index, 0), minlength=n_bins)
    with np.errstate(divide='ignore', invalid='ignore'):
        rate = np.where(width > 0, count / np.where(width > 0, width, 1.0), np.nan)
    full = width >= BIN_S - 1e-12
    peak = rate[full].max() if full.any() else (np.nanmax(rate) if np.isfinite(rate).any()
                                                  else None)
    per = {}
    for name in impactors:
        per[name] = per.get(name, 0) + 1
    starts = np.arange(n_bins) * BIN_S
    entry = {'count': int(t.size), 'mean_rate_hz': t.size / span if span > 0 else None,
             'peak_rate_hz': None if peak is None else float(peak), 'bin_s': BIN_S,
             'bins': [{'start_s': float(s), 'width_s': float(w), 'count': int(c),
                       'rate_hz': float(r) if np.isfinite(r) else None}
                      for s, w, c, r in zip(starts, width, count, rate)],
             'per_impactor': dict(sorted(per.items()))}
    return entry, {'start_s': starts, 'width_s': width, 'rate_hz': rate}


def stuck_fractions(t_ns, names, efforts, end_ns):
    """Time-weighted stuck fraction of each impactor from ``JointState`` effort flags.

    Parameters
    ----------
    t_ns : list of int
        Message stamps (ns).
    names : list of list of str
        Joint names per message, ``<impactor>/<dof>``.
    efforts : list of list of float
        Effort per joint: 1.0 while stuck, 0.0 while free.
    end_ns : int
        End of the log's stamped time (ns); the last state holds until then.

    Returns
    -------
    impactors : dict
        Per impactor: ``stuck_fraction`` (stuck time over observed time), ``stuck_s``,
        ``observed_s`` (from its first state to the end) and ``stick_events`` (free to stuck
        transitions, a first state that is stuck included).
    steps : dict
        Per impactor ``(t_ns, stuck)`` arrays for the plot.
    """
    order = sorted(range(len(t_ns)), key=lambda i: t_ns[i])
    states = {}
    for i in order:
        flags = {}
        for name, effort in zip(names[i], efforts[i]):
            imp = name.rsplit('/', 1)[0]
            flags[imp] = flags.get(imp, False) or effort >= 0.5
        for imp, stuck in flags.items():
            states.setdefault(imp, ([], []))
            states[imp][0].append(int(t_ns[i]))
            states[imp][1].append(stuck)
    out, steps = {}, {}
    for imp, (t, stuck) in sorted(states.items()):
        t = np.asarray(t, dtype=np.int64)
        stuck = np.asarray(stuck, dtype=bool)
        stop = max(int(end_ns), int(t[-1]))
        held = np.diff(np.append(t, stop)) * 1e-9
        observed = (stop - int(t[0])) * 1e-9
        stuck_s = float(held[stuck].sum())
        entries = int(stuck[0]) + int(np.sum(stuck[1:] & ~stuck[:-1]))
        out[imp] = {'stuck_fraction': stuck_s / observed if observed > 0 else None,
                    'stuck_s': stuck_s, 'observed_s': observed, 'stick_events': entries}
        steps[imp] = (np.append(t, stop), np.append(stuck, stuck[-1]))
    return out, steps


# --- output -----------------------------------------------------------------------------------

def csv_rows(report):
    """Flatten a report into ``(section, name, quantity, value, unit)`` rows.

    Parameters
    ----------
    report : dict
        Output of :func:`analyze`.

    Returns
    -------
    list of tuple
    """
    rows = [('log', report['file'], 'duration', report['duration_s'], 's'),
            ('log', report['file'], 'messages', report['message_count'], '')]
    for t in report['topics']:
        rows += [('topic', t['topic'], 'type', t['type'], ''),
                 ('topic', t['topic'], 'count', t['count'], ''),
                 ('topic', t['topic'], 'rate', t['rate_hz'], '1/s'),
                 ('topic', t['topic'], 'frequency', t['frequency_hz'], 'Hz')]
    for s in report['sensors']:
        for stat in ('peak_g', 'rms_g'):
            for axis, v in s[stat].items():
                rows.append(('sensor', s['topic'], f"{stat[:-2]}_{axis}", v, 'g'))
        rows.append(('sensor', s['topic'], 'sample_rate', s['sample_rate_hz'], 'Hz'))
        if s['spectrum']:
            for axis, f in s['spectrum']['dominant_hz'].items():
                rows.append(('sensor', s['topic'], f'dominant_{axis}', f, 'Hz'))
    for imp in report['impacts']:
        rows += [('impacts', imp['topic'], 'count', imp['count'], ''),
                 ('impacts', imp['topic'], 'mean_rate', imp['mean_rate_hz'], '1/s')]
        rows += [('impact_rate', imp['topic'], f"bin_{b['start_s']:g}", b['rate_hz'], '1/s')
                 for b in imp['bins']]
    for st in report['impactor_state']:
        rows += [('stuck_fraction', f"{st['topic']}:{name}", 'stuck_fraction',
                  v['stuck_fraction'], '') for name, v in st['impactors'].items()]
    return rows


def write_csv(report, path):
    """Write :func:`csv_rows` to ``path`` with a header line."""
    import csv
    with open(path, 'w', newline='') as fh:
        writer = csv.writer(fh)
        writer.writerow(['section', 'name', 'quantity', 'value', 'unit'])
        writer.writerows(['' if v is None else v for v in row] for row in csv_rows(report))


def plot(report, series, path):
    """Spectra or waterfalls per sensor, the impact rate and the stuck state (PNG, Agg).

    Parameters
    ----------
    report, series : dict
        Output of :func:`analyze`.
    path : str or os.PathLike
        PNG file.
    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    sensors = [s for s in report['sensors'] if s['topic'] in series['sensors']
               and series['sensors'][s['topic']]]
    panels = len(sensors) + bool(report['impacts']) + bool(report['impactor_state'])
    fig, axes = plt.subplots(max(panels, 1), 1, figsize=(8, 2.8 * max(panels, 1) + 0.4),
                             squeeze=False)
    axes = list(axes[:, 0])
    for s in sensors:
        ax, arrays = axes.pop(0), series['sensors'][s['topic']]
        if s['waterfall']:
            freq, amp = arrays['waterfall_freq_hz'], arrays['waterfall_amp_g']
            rpm = arrays['waterfall_speed_rad_s'] * 30 / math.pi
            order = np.argsort(rpm, kind='stable')
            db = 20 * np.log10(amp[order] + 1e-12)
            top = float(np.nanmax(db)) if db.size else 0.0
            # 80 dB of range: below it, near-silent slices (standstill) would take the scale
            mesh = ax.pcolormesh(freq, rpm[order], db, shading='nearest', cmap='viridis',
                                 vmin=top - 80.0, vmax=top)
            ax.plot(rpm[order] / 60, rpm[order], 'w--', lw=0.8, label='1x')
            fig.colorbar(mesh, ax=ax, label='amplitude (dB re 1 g)')
            ax.set_xlim(freq[0], freq[-1])
            ax.set_ylabel('rotor speed (rpm)')
            ax.set_title(f"waterfall {s['topic']}")
            ax.legend(fontsize=8, loc='upper left')
        else:
            psd = arrays['psd_g2_hz'][:, 1:]
            top = float(psd.max()) if psd.size else 0.0
            floor = top * 1e-10   # 100 dB below the largest: where plotting stops
            quiet = []
            for i, axis in enumerate('xyz'):
                if not psd[i].max() > floor:   # an axis that does not move: named, not drawn
                    quiet.append(axis)
                    continue
                ax.semilogy(arrays['freq_hz'][1:], np.maximum(psd[i], floor), label=axis)
            if top > 0:
                ax.set_ylim(floor, top * 3)
            if quiet:
                ax.text(0.99, 0.02, f"{', '.join(quiet)}: no signal (not drawn)",
                        ha='right', va='bottom', fontsize=8, transform=ax.transAxes)
            ax.axvline(s['spectrum']['dominant_hz']['total'], color='k', ls=':',
                       label=f"{s['spectrum']['dominant_hz']['total']:.4g} Hz")
            ax.set_ylabel('PSD (g$^2$/Hz)')
            peak, rms = s['peak_g']['magnitude'], s['rms_g']['magnitude']
            ax.set_title(f"spectrum {s['topic']} (peak "
                         + ('n/a' if peak is None else f'{peak:.3g} g') + ', RMS '
                         + ('n/a' if rms is None else f'{rms:.3g} g') + ')')
            ax.legend(fontsize=8)
        ax.set_xlabel('frequency (Hz)')
        ax.grid(True, alpha=0.3)
    if report['impacts']:
        ax = axes.pop(0)
        for imp in report['impacts']:
            a = series['impacts'][imp['topic']]
            starts, widths = np.asarray(a['start_s']), np.asarray(a['width_s'])
            rate = np.nan_to_num(np.asarray(a['rate_hz'], dtype=float))
            full = widths >= BIN_S - 1e-9
            if full.any():
                edges = np.append(starts[full], starts[full][-1] + BIN_S)
                line = ax.stairs(rate[full], edges, label=imp['topic'], lw=1.5,
                                 baseline=None)
                color = line.get_edgecolor()
            else:
                color = None
            # a short last bin is a noisy rate estimate: drawn faint, its width as it is
            for s0, w, r in zip(starts[~full], widths[~full], rate[~full]):
                if w > 0:
                    ax.stairs([r], [s0, s0 + w], color=color, alpha=0.5, ls=':',
                              baseline=None,
                              label=f'{imp["topic"]} last {w:.2g} s (partial bin)')
        ax.set_xlabel('time (s)')
        ax.set_ylabel('impacts/s')
        ax.set_ylim(bottom=0)
        ax.set_title(f'impact rate ({BIN_S:g} s bins)')
        ax.legend(fontsize=8)
        ax.grid(True, alpha=0.3)
    if report['impactor_state']:
        ax, level = axes.pop(0), 0
        origin = series['origin_ns']
        ticks, names = [], []
        lanes = [(st, name, ts) for st in report['impactor_state']
                 for name, ts in series['states'][st['topic']].items()]
        colors = plt.get_cmap('tab20' if len(lanes) > 10 else 'tab10')
        for k, (st, name, (t, stuck)) in enumerate(lanes):
            frac = st['impactors'][name]['stuck_fraction']
            color = colors(k % colors.N)
            ax.step((t - origin) * 1e-9, stuck * 0.6 + level, where='post', color=color,
                    gid=f'lane:{name}')
            # each lane labelled on the axis itself, in its colour, at its free (low) level,
            # drawn as a dotted baseline: no label floating away from a flat trace
            ax.axhline(level, color=color, lw=0.6, ls=':', gid=f'lane:{name}')
            ticks.append(level)
            names.append(f'{name} ({100 * frac:.3g} % stuck)' if frac is not None else name)
            level += 1
        ax.set_xlabel('time (s)')
        ax.set_yticks(ticks, names, fontsize=8)
        for label, k in zip(ax.get_yticklabels(), range(len(lanes))):
            label.set_color(colors(k % colors.N))
        ax.set_ylim(-0.3, max(level - 0.2, 0.9))
        ax.set_title('stuck state (a lane per impactor: low = free, high = stuck)')
    for ax in axes:   # a log with nothing to plot
        ax.text(0.5, 0.5, 'no sensor, impact or impactor-state topics', ha='center',
                transform=ax.transAxes)
        ax.set_axis_off()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def run_report(args):
    """Run ``study report``: print the report, write the optional CSV and plot.

    Parameters
    ----------
    args : argparse.Namespace
        ``file``, ``json``, ``plot`` and ``csv``.

    Returns
    -------
    int
        0 on success, 2 for a file that cannot be read or output that cannot be written.
    """
    import sys
    from .output import EXIT_USAGE
    from .output import print_error as _error
    from .output import print_json as _print_json
    try:
        report, series = analyze(args.file)
    except LogError as exc:
        _error(printable(str(exc)))
        return EXIT_USAGE
    try:
        if args.csv:
            write_csv(report, args.csv)
        if args.plot:
            plot(report, series, args.plot)
    except OSError as exc:
        _error(f'cannot write output: {exc}')
        return EXIT_USAGE
    if args.json:
        _print_json(report)
    else:
        print_report(report)
    for w in report['warnings']:
        print(f'study: warning: {printable(w)}', file=sys.stderr)
    return 0


def _short(value, width=70):
    text = ' '.join(str(value).split())
    return text if len(text) <= width else text[:width - 3] + '...'


def print_report(r):
    """Print a report as text (the ``study report`` default output)."""
    from .output import fmt as _g
    from .output import table as _table
    print(f"log {r['file']} (profile {r['profile']}, written by {r['library'] or 'unknown'})")
    print(f"{r['message_count']} messages over {_g(r['duration_s'])} s of log time")
    for name, record in r['metadata'].items():
        print(f'\nmetadata {name}:')
        for key, value in record.items():
            print(f'  {key}: {_short(value)}')
    print()
    print(_table(['topic', 'type', 'count', 'rate (msg/s)', 'frequency (Hz)'],
                 [(t['topic'], t['type'], t['count'], _g(t['rate_hz']), _g(t['frequency_hz']))
                  for t in r['topics']]))
    if r['sensors']:
        print(f"\naccelerations in g (G0 = {G0} m/s^2); times from the first stamp")
        rows = []
        for s in r['sensors']:
            dom = s['spectrum']['dominant_hz']['total'] if s['spectrum'] else None
            rows.append([s['sensor'], s['samples'], _g(s['sample_rate_hz'])]
                        + [_g(s['peak_g'][k], 4) for k in ('x', 'y', 'z', 'magnitude')]
                        + [_g(s['rms_g'][k], 4) for k in ('x', 'y', 'z', 'magnitude')]
                        + [_g(dom, 5)])
        print(_table(['sensor', 'samples', 'fs (Hz)', 'peak x', 'peak y', 'peak z', 'peak |a|',
                      'rms x', 'rms y', 'rms z', 'rms |a|', 'dominant (Hz)'], rows))
        for s in r['sensors']:
            if any(s['nonfinite_samples'].values()):
                print(f"{s['topic']}: {nonfinite_text(s)} (left out of peak and RMS; 'n/a' "
                      'for an axis without a finite sample)')
        for s in r['sensors']:
            w = s['waterfall']
            if w:
                print(f"waterfall {s['sensor']}: {w['slices']} slices of {w['segment_samples']}"
                      f" samples ({_g(w['resolution_hz'], 3)} Hz), "
                      f"{_g(min(w['speed_rpm']), 5)} to {_g(max(w['speed_rpm']), 5)} rpm")
    for sp in r['rotor_speed']:
        print(f"\nrotor speed {sp['topic']}: {_g(sp['min_rpm'], 5)} to {_g(sp['max_rpm'], 5)} "
              f"rpm ({sp['samples']} samples)")
    for imp in r['impacts']:
        per = ', '.join(f'{k} {v}' for k, v in imp['per_impactor'].items())
        print(f"\nimpacts {imp['topic']}: {imp['count']}, mean {_g(imp['mean_rate_hz'])}/s, "
              f"peak {_g(imp['peak_rate_hz'])}/s" + (f' ({per})' if per else ''))
        full = [b for b in imp['bins'] if b['width_s'] >= imp['bin_s'] - 1e-9]
        part = [b for b in imp['bins'] if b['width_s'] < imp['bin_s'] - 1e-9]
        print(f"  impacts/s per full {_g(imp['bin_s'])} s bin: "
              + (' '.join(_g(b['rate_hz'], 4) for b in full[:60]) or 'none')
              + (' ...' if len(full) > 60 else ''))
        for b in part:   # a short last bin is not comparable: its count, not a rate
            print(f"  last {_g(b['width_s'], 3)} s (partial bin): {b['count']} impact(s)")
    for st in r['impactor_state']:
        print(f"\nstuck fraction ({st['topic']}, time-weighted):")
        print(_table(['impactor', 'stuck fraction', 'stuck (s)', 'observed (s)', 'stick events'],
                     [(name, _g(v['stuck_fraction'], 4), _g(v['stuck_s'], 4),
                       _g(v['observed_s'], 4), v['stick_events'])
                      for name, v in st['impactors'].items()]))


__all__ = ['G0', 'LogError', 'RosLog', 'analyze', 'csv_rows', 'impact_rate', 'plot',
           'print_report', 'run_report', 'sensor_report', 'stuck_fractions', 'type_name',
           'write_csv']
