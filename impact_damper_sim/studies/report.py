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
  and a Welch spectrum with its dominant frequency; when the log has ``rotor/speed``, a
  waterfall as well (a spectrum per slice of time), against the rotor speed when the speed
  sweeps through most of the log, else against time;
* the impact rate over time: impact stamps counted in 1 s bins, from ``impacts`` batches
  (``sensor_msgs/PointCloud2``, one row per impact with its impactor's index, named through
  the ``impactor_state`` joint names ``<impactor>/<dof>`` in impactor order, else
  ``impactor<i>``) or, in older logs, one ``geometry_msgs/WrenchStamped`` per impact (the
  impactor the last component of its frame_id);
* the stuck fraction of each impactor: ``impactor_state`` effort flags, time-weighted (each
  state holds until the next message, the last one until the end of the log);
* the commands (``rotor/speed_command``, ``rotor/unbalance_command``,
  ``accel/fault_command``, ``/parameter_events``) at their times, marked on the plots' time
  axes;
* the metadata records (``impact_damper_sim``: scene, overrides, software version;
  ``rosbag2``: the bag metadata).

Signal times are header stamps (sim time for ``vibration_node``; in a batch, ``header.stamp``
plus the row's ``t``), counted from the earliest stamp in the log (the start of an impact
batch's interval counts). Counts and rates use log_time (receive time), as rosbag2 does.
Batch layouts: :mod:`impact_damper_sim.recording.batches`.

The log is opened with :class:`.log_reader.RosLog` (the reader ``replay`` shares). This module
sorts the log's messages into arrays per topic, assembles the report (:func:`analyze`) and
runs the command (:func:`run_report`); the estimates from those arrays (peak, RMS, spectrum,
waterfall, impact rate, stuck fraction) are in :mod:`.report_signals`, and the text, CSV and
plot the command writes in :mod:`.report_output`.
"""
from __future__ import annotations

import contextlib
import io
import math

import numpy as np

from ..recording.batches import rows_of, sample_times_ns
from ..recording.node_topics import BATCH_SUFFIX, POINTCLOUD2
from ..scene.units import G0  # standard gravity (m/s^2), exact
from .log_reader import LogError, RosLog, _reading, printable
from .report_output import plot, print_report, write_csv
from .report_signals import impact_rate, nonfinite_text, sensor_report, stuck_fractions

IMU = 'sensor_msgs/msg/Imu'
WRENCH_STAMPED = 'geometry_msgs/msg/WrenchStamped'
JOINT_STATE = 'sensor_msgs/msg/JointState'
VECTOR3_STAMPED = 'geometry_msgs/msg/Vector3Stamped'
FLOAT64 = 'std_msgs/msg/Float64'
STRING = 'std_msgs/msg/String'
PARAMETER_EVENT = 'rcl_interfaces/msg/ParameterEvent'
# topic names of ros.interface (relative there; matched here under any namespace)
ACCEL_PREFIX = 'accel/'
IMPACTS = 'impacts'
IMPACTOR_STATE = 'impactor_state'
ROTOR_SPEED = 'rotor/speed'
#: command topics (kind, topic name, message type) marked on the time axes of the report
COMMANDS = (('speed', 'rotor/speed_command', FLOAT64),
            ('unbalance', 'rotor/unbalance_command', FLOAT64),
            ('fault', 'accel/fault_command', STRING),
            ('parameter', 'parameter_events', PARAMETER_EVENT))


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
        # (log_time, header stamp) per message (ns): maps a command's log_time to a stamp
        self.clock = []

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
        ``impactor_state`` (:func:`stuck_fractions`), ``commands``, ``metadata`` and
        ``warnings``.
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
            decoded = decoders[cid](msg.data)
            if wanted[cid].startswith('command:'):   # no header: its log_time tells when
                s.t.append(t)
                s.values.append(_command_value(wanted[cid], decoded))
            else:
                _collect(wanted[cid], decoded, s)
                s.clock.append((t, _stamp_ns(decoded)))
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
    for kind, name, ctype in COMMANDS:
        if rtype == ctype and _ends_with(topic, name):
            return f'command:{kind}'
    return None


def _command_value(kind, m):
    """What a command message says, as text (``'1200 rad/s'``, ``'x3'``, the fault text)."""
    if kind == 'command:speed':
        return f'speed {m.data:.6g} rad/s ({m.data * 30 / math.pi:.5g} rpm)'
    if kind == 'command:unbalance':
        return f'unbalance x{m.data:.6g}'
    if kind == 'command:fault':
        return f"fault {' '.join(str(m.data).split())}"
    changed = []
    for p in m.changed_parameters:
        v = p.value
        value = {1: v.bool_value, 2: v.integer_value, 3: v.double_value,
                 4: v.string_value}.get(v.type, '?')
        changed.append(f'{p.name}={str(value).lower() if v.type == 1 else value}')
    return 'set ' + ', '.join(changed) if changed else None


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
    stamps = [x for x in (series[cid].stamps() for cid in wanted
                          if not wanted[cid].startswith('command:')) if x.size]
    origin = min(int(x.min()) for x in stamps) if stamps else 0
    end = max(int(x.max()) for x in stamps) if stamps else 0
    plot = {'origin_ns': origin, 'sensors': {}, 'impacts': {}, 'states': {}}
    report = {'file': log.path, 'profile': log.profile, 'library': log.library,
              'start_time_ns': log.start_ns, 'end_time_ns': log.end_ns, 'duration_s': duration,
              'message_count': sum(counts.values()), 'time_origin_s': origin * 1e-9,
              'stamped_span_s': (end - origin) * 1e-9, 'topics': topics, 'sensors': [],
              'rotor_speed': [], 'impacts': [], 'impactor_state': [],
              'commands': _commands(log, wanted, series, origin),
              'metadata': log.metadata, 'warnings': warnings}
    plot['commands'] = report['commands']
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


def _commands(log, wanted, series, origin):
    """The commands in the log in time order: ``time_s`` (stamp time from the origin), the
    ``topic`` and ``what`` (text).

    A command has no header; its log_time is turned into stamp time with the offset between
    log_time and header stamp of the stamped message received last before it (the first one
    for a command before every stamped message): equal for ``study record`` and the node's
    recorder (log_time = sim time), and right for ``ros2 bag record`` (receive time).
    """
    clock = sorted(pair for cid in wanted for pair in series[cid].clock)
    logs = np.array([c[0] for c in clock], dtype=np.int64)
    offsets = np.array([c[1] - c[0] for c in clock], dtype=np.int64)
    out = []
    for cid in sorted(c for c, k in wanted.items() if k.startswith('command:')):
        topic = log.channels[cid].topic
        for t, what in zip(series[cid].t, series[cid].values):
            if what is None:
                continue
            at = max(int(np.searchsorted(logs, t, side='right')) - 1, 0)
            stamp = t + (int(offsets[at]) if offsets.size else 0)
            out.append({'time_s': (stamp - origin) * 1e-9, 'topic': topic, 'what': what})
    return sorted(out, key=lambda c: c['time_s'])


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

    from .._exit_status import EXIT_USAGE
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


__all__ = ['G0', 'analyze', 'run_report']
