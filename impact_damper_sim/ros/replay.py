"""``replay``: publish a recorded MCAP log with its original timing.

::

    replay FILE.mcap [--rate X] [--start-offset S] [--loop] [--topics T [T ...]]
                     [--remap OLD:=NEW [OLD:=NEW ...]] [--no-clock] [--clock-hz HZ]
                     [--delay S] [--ros-args ...]

Works on any MCAP with profile ``ros2`` whose message types are installed: logs written by
``vibration_node``'s recorder and by ``ros2 bag record``. Each message is published as the
raw CDR bytes it was recorded with (``Publisher.publish`` takes ``bytes`` in rclpy 7), so
replay costs no decoding. Messages go out in log_time order, each at

    wall deadline = (log_time - (log start + start offset)) / rate

after playback starts; a message that is late is published at once (never dropped), and the
achieved lateness is logged at the end. ``/clock`` (``rosgraph_msgs/Clock``, reliable, keep
last 1) carries the log time every ``1/--clock-hz`` s of wall time; a tick that is already late
is skipped rather than sent in a burst. With ``--loop`` the log plays again and again; a pass
starts one mean inter-message interval (of log time) after the previous one ended, and
``/clock`` jumps back to the log's start.

Each topic's publisher gets the QoS the recording publishers offered, read from the channel's
``offered_qos_profiles`` metadata (or, failing that, from the ``rosbag2`` metadata record):
reliability, durability, deadline, lifespan and liveliness as recorded; the recorded history
and depth when they are known, else keep last 10 (rosbag2 records offers from DDS discovery,
which carries no history). Unlike ``ros2 bag play`` a recorded keep-last depth is kept, so a
latched depth-1 topic gives a late joiner only the latest state, as the original did. A topic
without readable QoS, or whose publishers offered differing QoS, falls back to reliable,
volatile, keep last 10, with a warning. Policies are accepted as strings (bag metadata
version 9, Jazzy) or integers (older versions).

A file that is missing, empty, not MCAP, truncated, corrupt or not ROS 2, an unknown message
type or bad options give a one-line error on stderr and exit status 2.

The pacing (:class:`Schedule`, :class:`Player`) knows nothing of ROS; :class:`ReplayNode`
feeds it the log and publishers.
"""
from __future__ import annotations

import argparse
import collections
import importlib
import itertools
import math
import re
import statistics
import sys
import threading
import time
from dataclasses import dataclass, field

import rclpy
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import (DurabilityPolicy, HistoryPolicy, LivelinessPolicy, QoSProfile,
                       ReliabilityPolicy)

from ..studies.report import LogError, RosLog, type_name
from .interface import CLOCK, CLOCK_QOS
from .wire import freeze_start_up_heap, ignore_further_interrupts, settle_interrupt, \
    shutdown_quietly

EXIT_USAGE = 2
DEFAULT_CLOCK_HZ = 100.0
#: used when a topic's offered QoS is missing or mixed (rosbag2's default offer)
FALLBACK_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                          reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.VOLATILE)
#: lateness statistics are kept over this many recent messages (bounded memory with --loop)
LATENESS_WINDOW = 100_000


# --- pacing (no ROS) --------------------------------------------------------------------------

class Schedule:
    """Wall-clock deadlines of a log's messages.

    Parameters
    ----------
    start_ns : int
        log_time of the log's first message (ns).
    end_ns : int
        log_time of its last message (ns).
    count : int
        Number of messages in the log (sets the gap between loop passes).
    rate : float
        Playback speed factor (-); 2 plays twice as fast. Must be > 0.
    start_offset : float
        Log time skipped at the start (s), >= 0 and not past the end.
    loop : bool
        Play again and again.

    Raises
    ------
    ValueError
        A rate that is not a positive number, or an offset outside the log.
    """

    def __init__(self, start_ns, end_ns, count=2, rate=1.0, start_offset=0.0, loop=False):
        if not (isinstance(rate, (int, float)) and math.isfinite(rate) and rate > 0):
            raise ValueError(f'--rate must be a number > 0, got {rate}')
        span = int(end_ns) - int(start_ns)
        if span < 0:
            raise ValueError('the log ends before it starts')
        if not (math.isfinite(start_offset) and start_offset >= 0):
            raise ValueError(f'--start-offset must be >= 0 s, got {start_offset}')
        if start_offset * 1e9 > span:
            raise ValueError(f'--start-offset {start_offset:g} s is past the end of the log '
                             f'({span * 1e-9:g} s long)')
        self.rate = float(rate)
        self.loop = bool(loop)
        self.begin_ns = int(start_ns) + round(start_offset * 1e9)
        self.end_ns = int(end_ns)
        # a pass restarts one mean message interval after the last message (1 s for one)
        gap = span / (count - 1) if count > 1 and span > 0 else 1e9
        self.period_ns = (self.end_ns - self.begin_ns) + gap

    def selects(self, log_time_ns):
        """True if a message at ``log_time_ns`` (ns) is played (not before the offset)."""
        return log_time_ns >= self.begin_ns

    def deadline(self, log_time_ns, iteration=0):
        """Wall time (s after playback start) at which to publish a message.

        Parameters
        ----------
        log_time_ns : int
            The message's log_time (ns).
        iteration : int
            Loop pass, from 0.

        Returns
        -------
        float
        """
        return ((log_time_ns - self.begin_ns) + iteration * self.period_ns) / (self.rate * 1e9)

    def log_time_at(self, wall_s):
        """Log time (ns) that playback has reached ``wall_s`` s after its start: the /clock.

        Parameters
        ----------
        wall_s : float
            Wall time since playback start (s).

        Returns
        -------
        int
        """
        elapsed = wall_s * self.rate * 1e9
        if self.loop:
            elapsed = math.fmod(elapsed, self.period_ns)
        return self.begin_ns + int(min(elapsed, self.end_ns - self.begin_ns))

    def iterations(self):
        """Return the pass numbers: 0 only, or 0, 1, 2, ... with ``loop``."""
        return itertools.count() if self.loop else range(1)

    @property
    def pass_s(self):
        """float: wall duration of one pass, first to last message (s)."""
        return (self.end_ns - self.begin_ns) / (self.rate * 1e9)


def deadlines(log_times_ns, rate=1.0, start_offset=0.0, passes=1):
    """Wall deadlines of a list of log times, over a number of passes.

    Parameters
    ----------
    log_times_ns : sequence of int
        log_time of each message (ns), sorted, at least one.
    rate : float
        Playback speed factor (-).
    start_offset : float
        Log time skipped at the start (s).
    passes : int
        Number of passes (more than 1 loops).

    Returns
    -------
    list of tuple
        ``(pass, index, deadline_s)`` for every message played, in publishing order.
    """
    times = list(log_times_ns)
    if not times:
        raise ValueError('no log times')
    s = Schedule(times[0], times[-1], len(times), rate, start_offset, loop=passes > 1)
    return [(k, i, s.deadline(t, k)) for k in range(passes) for i, t in enumerate(times)
            if s.selects(t)]


@dataclass
class PlaybackStats:
    """What a playback achieved (wall times in s)."""

    messages: int = 0
    passes: int = 0
    clock_ticks: int = 0
    wall_s: float = 0.0
    median_lateness_s: float = math.nan
    max_lateness_s: float = math.nan
    stopped: bool = False


class _Stopped(Exception):
    pass


class Player:
    """Publish a schedule's messages at their deadlines, with /clock ticks in between.

    Parameters
    ----------
    schedule : Schedule
        Deadlines.
    source : callable
        ``source()`` returns an iterable of ``(key, log_time_ns, data)`` in log_time order;
        called once per pass.
    publish : callable
        ``publish(key, data)``.
    clock : callable, optional
        ``clock(log_time_ns)`` publishes the clock; None for no clock.
    clock_period : float
        Wall time between clock ticks (s).
    stop : threading.Event, optional
        Set to end playback early.
    now : callable
        Monotonic wall clock (s).
    """

    def __init__(self, schedule, source, publish, clock=None, clock_period=0.01, stop=None,
                 now=time.monotonic):
        if not clock_period > 0:
            raise ValueError(f'clock period must be > 0 s, got {clock_period}')
        self.schedule, self._source, self._publish = schedule, source, publish
        self._clock, self._period = clock, clock_period
        self._stop = stop if stop is not None else threading.Event()
        self._now = now

    def _wait(self, t):
        remaining = t - self._now()
        if remaining > 0 and self._stop.wait(remaining):
            raise _Stopped
        if self._stop.is_set():
            raise _Stopped

    def run(self):
        """Play to the end (or until stopped).

        Returns
        -------
        PlaybackStats
        """
        s, stats = self.schedule, PlaybackStats()
        late = collections.deque(maxlen=LATENESS_WINDOW)
        worst, tick, last_log = -math.inf, 0, None
        t0 = self._now()
        try:
            for iteration in s.iterations():
                for key, log_time, data in self._source():
                    if not s.selects(log_time):
                        continue
                    due = s.deadline(log_time, iteration)
                    while self._clock is not None and tick * self._period <= due:
                        self._wait(t0 + tick * self._period)
                        # behind by whole ticks: skip them rather than send a burst
                        behind = int((self._now() - t0) / self._period)
                        if behind > tick and behind * self._period <= due:
                            tick = behind
                        self._clock(s.log_time_at(tick * self._period))
                        tick += 1
                        stats.clock_ticks += 1
                    self._wait(t0 + due)
                    self._publish(key, data)
                    lateness = self._now() - t0 - due
                    late.append(lateness)
                    worst = max(worst, lateness)
                    stats.messages += 1
                    last_log = log_time
                stats.passes += 1
            if self._clock is not None and last_log is not None:
                self._clock(last_log)   # the clock ends where the log's content ends
                stats.clock_ticks += 1
        except _Stopped:
            stats.stopped = True
        stats.wall_s = self._now() - t0
        if late:
            stats.median_lateness_s = statistics.median(late)
            stats.max_lateness_s = worst
        return stats


# --- QoS and types ----------------------------------------------------------------------------

def _policy(enum, value, what):
    """An rclpy policy from an int (bag version <= 8) or a short key (version 9)."""
    if isinstance(value, bool):
        raise ValueError(f'{what}: {value!r}')
    if isinstance(value, int) or (isinstance(value, str) and value.strip().isdigit()):
        return enum(int(value))
    if isinstance(value, str):
        return enum(enum.get_from_short_key(value.strip().lower()))
    raise ValueError(f'{what}: {value!r}')


def _duration(node):
    """A recorded {sec, nsec} duration; None when unset (0) or infinite."""
    if node is None:
        return None
    sec, nsec = int(node.get('sec', 0)), int(node.get('nsec', 0))
    # >= 2^31 - 1 s: RMW_DURATION_INFINITE and the Foxy-era "infinite" encodings
    if sec >= 0x7FFFFFFF or (sec == 0 and nsec == 0):
        return None
    return Duration(seconds=sec, nanoseconds=nsec)


def _profile(d):
    if not isinstance(d, dict):
        raise ValueError(f'a QoS entry is not a mapping: {d!r}')
    reliability = _policy(ReliabilityPolicy, d.get('reliability'), 'reliability')
    durability = _policy(DurabilityPolicy, d.get('durability'), 'durability')
    for policy, allowed in ((reliability, (ReliabilityPolicy.RELIABLE,
                                           ReliabilityPolicy.BEST_EFFORT,
                                           ReliabilityPolicy.SYSTEM_DEFAULT)),
                            (durability, (DurabilityPolicy.TRANSIENT_LOCAL,
                                          DurabilityPolicy.VOLATILE,
                                          DurabilityPolicy.SYSTEM_DEFAULT))):
        if policy not in allowed:
            raise ValueError(f'offered {policy.name.lower()}')
    history = _policy(HistoryPolicy, d.get('history', 'unknown'), 'history')
    depth = int(d.get('depth') or 0)
    kwargs = {'reliability': reliability, 'durability': durability}
    if history == HistoryPolicy.KEEP_ALL:
        kwargs['history'] = HistoryPolicy.KEEP_ALL
    elif history == HistoryPolicy.KEEP_LAST and depth > 0:
        kwargs.update(history=HistoryPolicy.KEEP_LAST, depth=depth)
    else:   # unknown from DDS discovery: rosbag2's default history
        kwargs.update(history=HistoryPolicy.KEEP_LAST, depth=10)
    try:
        liveliness = _policy(LivelinessPolicy, d.get('liveliness', 'system_default'),
                             'liveliness')
    except (ValueError, KeyError):
        liveliness = LivelinessPolicy.SYSTEM_DEFAULT
    if liveliness in (LivelinessPolicy.AUTOMATIC, LivelinessPolicy.MANUAL_BY_TOPIC):
        kwargs['liveliness'] = liveliness
    for key in ('deadline', 'lifespan', 'liveliness_lease_duration'):
        value = _duration(d.get(key))
        if value is not None:
            kwargs[key] = value
    kwargs['avoid_ros_namespace_conventions'] = bool(
        d.get('avoid_ros_namespace_conventions', False))
    return QoSProfile(**kwargs)


def qos_from_offered(offered):
    """The QoS to publish a topic with, from its recorded ``offered_qos_profiles``.

    Parameters
    ----------
    offered : str or list or None
        The YAML text of the channel metadata (a list of QoS mappings), or the already
        parsed list (the ``rosbag2`` metadata record, version 9).

    Returns
    -------
    qos : rclpy.qos.QoSProfile
        The recorded profile, or :data:`FALLBACK_QOS`.
    problem : str or None
        Why the fallback was used.
    """
    import yaml
    if offered is None or (isinstance(offered, str) and not offered.strip()):
        return FALLBACK_QOS, 'no offered_qos_profiles recorded'
    try:
        data = yaml.safe_load(offered) if isinstance(offered, str) else offered
    except yaml.YAMLError:
        return FALLBACK_QOS, 'offered_qos_profiles is not valid YAML'
    if isinstance(data, dict):
        data = [data]
    if not isinstance(data, list) or not data:
        return FALLBACK_QOS, 'offered_qos_profiles is empty'
    try:
        profiles = [_profile(d) for d in data]
    except (ValueError, KeyError, TypeError, AttributeError) as exc:
        return FALLBACK_QOS, f'offered_qos_profiles not understood ({exc})'
    first = profiles[0]

    def key(p):   # the policies that decide compatibility (rosbag2 compares the same)
        return (p.reliability, p.durability, p.deadline, p.liveliness,
                p.liveliness_lease_duration)
    if any(key(p) != key(first) for p in profiles[1:]):
        return FALLBACK_QOS, f'{len(profiles)} publishers offered different QoS'
    return first, None


def _qos_text(q):
    depth = f' {q.depth}' if q.history == HistoryPolicy.KEEP_LAST else ''
    return (f'{q.reliability.name.lower()}, {q.durability.name.lower()}, '
            f'{q.history.name.lower()}{depth}')


_IDENT = re.compile(r'^[A-Za-z][A-Za-z0-9_]*$')


def message_class(rtype):
    """Import the Python class of an installed ROS message type.

    Parameters
    ----------
    rtype : str
        ``pkg/msg/Type`` (or ``pkg/Type``).

    Returns
    -------
    type

    Raises
    ------
    LogError
        Not a message type name, or not installed.
    """
    from rclpy.type_support import check_for_type_support
    parts = type_name(rtype).split('/')
    if len(parts) != 3 or parts[1] != 'msg' or not all(_IDENT.match(p) for p in parts):
        raise LogError(f'unsupported message type {rtype!r} (expected pkg/msg/Type)')
    pkg, _, name = parts
    try:
        module = importlib.import_module(f'{pkg}.msg')
        cls = getattr(module, name)
        check_for_type_support(cls)
    except Exception:   # ImportError, AttributeError, or type support that fails to load
        raise LogError(f'message type {rtype} is not installed here (source the workspace '
                       'that provides it, or leave its topic out with --topics)') from None
    return cls


def _installed_type_hash(rtype):
    """RIHS01 hash of the installed type (share/<pkg>/msg/<Type>.json), None if unknown."""
    import json
    try:
        from ament_index_python.packages import get_package_share_directory
        pkg, _, name = type_name(rtype).split('/')
        with open(f'{get_package_share_directory(pkg)}/msg/{name}.json') as fh:
            hashes = json.load(fh)['type_hashes']
        return next(h['hash_string'] for h in hashes if h['type_name'] == type_name(rtype))
    except Exception:   # no ament index, no JSON (pre-Iron type), unexpected layout
        return None


# --- plan -------------------------------------------------------------------------------------

def _absolute(topic):
    return topic if topic.startswith('/') else '/' + topic


def parse_remaps(remaps):
    """Read ``OLD:=NEW`` pairs.

    Parameters
    ----------
    remaps : iterable of str
        Remapping rules.

    Returns
    -------
    dict
        Absolute old topic name to the new name (as given; relative names resolve in the
        replay node's namespace).

    Raises
    ------
    ValueError
        A rule without ``:=``, with an empty side, or a topic remapped twice.
    """
    out = {}
    for rule in remaps:
        old, sep, new = rule.partition(':=')
        if not sep or not old.strip() or not new.strip():
            raise ValueError(f'--remap expects OLD:=NEW, got {rule!r}')
        key = _absolute(old.strip())
        if key in out:
            raise ValueError(f'--remap: {old} is remapped twice')
        out[key] = new.strip()
    return out


@dataclass
class Track:
    """One recorded channel and how it is replayed."""

    channel_id: int
    topic: str               #: as recorded
    out_topic: str           #: as published (after --remap)
    type: str                #: pkg/msg/Type
    msg_class: type
    qos: QoSProfile
    warnings: list = field(default_factory=list)


@dataclass
class Plan:
    """A checked log, the tracks to replay and their schedule."""

    log: RosLog
    tracks: list
    schedule: Schedule
    warnings: list = field(default_factory=list)


def _rosbag2_offers(metadata):
    """topic -> offered_qos_profiles from the ``rosbag2`` metadata record (if any)."""
    import yaml
    text = metadata.get('rosbag2', {}).get('serialized_metadata')
    if not text:
        return {}
    try:
        info = yaml.safe_load(text)['rosbag2_bagfile_information']
        return {_absolute(t['topic_metadata']['name']): t['topic_metadata'].get(
                    'offered_qos_profiles') for t in info.get('topics_with_message_count', [])}
    except Exception:   # a damaged record only costs the fallback
        return {}


def prepare(path, topics=(), remaps=(), rate=1.0, start_offset=0.0, loop=False):
    """Open and check a log and plan its replay (no ROS context needed).

    Parameters
    ----------
    path : str or os.PathLike
        The ``.mcap`` file.
    topics : iterable of str
        Topics to replay (as recorded; a missing leading slash is fine); default all.
    remaps : iterable of str
        ``OLD:=NEW`` rules.
    rate : float
        Playback speed factor (-), > 0.
    start_offset : float
        Log time skipped at the start (s).
    loop : bool
        Play again and again.

    Returns
    -------
    Plan

    Raises
    ------
    LogError
        The file cannot be replayed (unreadable, not ROS 2, no messages, type not installed).
    ValueError
        Bad options (rate, offset, a topic filter or remap that names no recorded topic).
    """
    log = RosLog(path)
    if log.message_count == 0:
        raise LogError(f'{log.path}: the log has no messages')
    by_topic = {}
    for cid, ch in sorted(log.channels.items()):
        by_topic.setdefault(_absolute(ch.topic), []).append(ch)
    wanted = {_absolute(t) for t in topics}
    remap = parse_remaps(remaps)
    for option, names in (('--topics', wanted), ('--remap', set(remap))):
        missing = sorted(names - set(by_topic))
        if missing:
            raise ValueError(f"{option}: not recorded in {log.path}: {', '.join(missing)} "
                             f"(recorded: {', '.join(sorted(by_topic))})")
    offers = _rosbag2_offers(log.metadata)
    tracks, warnings = [], []
    for topic, channels in sorted(by_topic.items()):
        if wanted and topic not in wanted:
            continue
        for ch in channels:
            if log.counts.get(ch.id, 1) == 0:
                continue
            if ch.message_encoding != 'cdr':
                warnings.append(f'{ch.topic}: message encoding {ch.message_encoding!r}, not '
                                'cdr; skipped')
                continue
            rtype = log.type_of(ch)
            cls = message_class(rtype)
            offered = ch.metadata.get('offered_qos_profiles', offers.get(topic))
            qos, problem = qos_from_offered(offered)
            track = Track(ch.id, ch.topic, remap.get(topic, ch.topic), rtype, cls, qos)
            if problem:
                track.warnings.append(f'{ch.topic}: {problem}; publishing {_qos_text(qos)}')
            recorded, installed = ch.metadata.get('topic_type_hash'), None
            if recorded:
                installed = _installed_type_hash(rtype)
            if recorded and installed and recorded != installed:
                track.warnings.append(f'{ch.topic}: recorded {rtype} definition differs from '
                                      'the installed one (type hash); subscribers may misread '
                                      'it')
            tracks.append(track)
    if not tracks:
        raise LogError(f'{log.path}: no replayable topic (all skipped)')
    schedule = Schedule(log.start_ns, log.end_ns, log.message_count, rate, start_offset, loop)
    return Plan(log, tracks, schedule, warnings)


# --- node -------------------------------------------------------------------------------------

class ReplayNode(Node):
    """Publishes a planned log: one publisher per recorded topic, plus ``/clock``.

    Parameters
    ----------
    plan : Plan
        From :func:`prepare`.
    clock : bool
        Publish ``/clock`` from the log time.
    clock_hz : float
        Clock ticks per second of wall time (Hz).
    node_name : str
        Node name.
    **kwargs
        Passed to ``rclpy.node.Node`` (e.g. ``context``, ``namespace``).
    """

    def __init__(self, plan, *, clock=True, clock_hz=DEFAULT_CLOCK_HZ, node_name='replay',
                 **kwargs):
        if not (math.isfinite(clock_hz) and clock_hz > 0):
            raise ValueError(f'--clock-hz must be > 0, got {clock_hz}')
        super().__init__(node_name, **kwargs)
        self.plan = plan
        self._clock_period = 1.0 / clock_hz
        self._stop = threading.Event()
        self.context.on_shutdown(self._stop.set)
        self._publishers_by_channel = {}
        for w in plan.warnings:
            self.get_logger().warning(w)
        for tr in plan.tracks:
            for w in tr.warnings:
                self.get_logger().warning(w)
            self._publishers_by_channel[tr.channel_id] = self.create_publisher(
                tr.msg_class, tr.out_topic, tr.qos)
        self._clock_pub = None
        if clock:
            from rosgraph_msgs.msg import Clock
            self._clock_msg = Clock()
            self._clock_pub = self.create_publisher(Clock, CLOCK, CLOCK_QOS)
        self._topics = sorted({tr.topic for tr in plan.tracks})
        self.stats = None

    def play(self):
        """Play the log in the calling thread (blocks; :meth:`stop` ends it early).

        Returns
        -------
        PlaybackStats
        """
        player = Player(self.plan.schedule, self._source, self._publish,
                        clock=self._publish_clock if self._clock_pub is not None else None,
                        clock_period=self._clock_period, stop=self._stop)
        self.stats = player.run()
        return self.stats

    def stop(self):
        """End :meth:`play` early (thread-safe)."""
        self._stop.set()

    def wait_for_acks(self, timeout_s=1.0):
        """Wait up to ``timeout_s`` (s) for reliable subscribers to acknowledge everything."""
        deadline = time.monotonic() + timeout_s
        for pub in self._publishers_by_channel.values():
            left = max(0.0, deadline - time.monotonic())
            pub.wait_for_all_acked(Duration(nanoseconds=int(left * 1e9)))

    def _source(self):
        for ch, msg in self.plan.log.messages(topics=self._topics):
            if ch.id in self._publishers_by_channel:
                data = msg.data
                yield ch.id, msg.log_time, data if isinstance(data, bytes) else bytes(data)

    def _publish(self, channel_id, data):
        self._publishers_by_channel[channel_id].publish(data)   # raw CDR: no decoding

    def _publish_clock(self, log_time_ns):
        sec, nanosec = divmod(int(log_time_ns), 1_000_000_000)
        self._clock_msg.clock.sec, self._clock_msg.clock.nanosec = sec, nanosec
        self._clock_pub.publish(self._clock_msg)


# --- command line -----------------------------------------------------------------------------

def _parser():
    p = argparse.ArgumentParser(
        prog='replay',
        description='Publish a recorded MCAP log (rosbag2 layout, profile ros2) with its '
                    'original timing, its recorded QoS and /clock from the log time.')
    p.add_argument('file', metavar='FILE', help='the .mcap file')
    p.add_argument('--rate', type=float, default=1.0,
                   help='playback speed factor (> 0, default 1; 2 is twice as fast)')
    p.add_argument('--start-offset', type=float, default=0.0, metavar='S',
                   help='skip this much log time at the start (s, default 0)')
    p.add_argument('--loop', action='store_true', help='play again and again')
    p.add_argument('--topics', nargs='+', action='extend', default=[], metavar='TOPIC',
                   help='replay only these topics (repeatable; default all)')
    p.add_argument('--remap', nargs='+', action='extend', default=[], metavar='OLD:=NEW',
                   help='publish topic OLD as NEW (repeatable)')
    p.add_argument('--no-clock', action='store_true', help='do not publish /clock')
    p.add_argument('--clock-hz', type=float, default=DEFAULT_CLOCK_HZ, metavar='HZ',
                   help=f'/clock ticks per wall second (Hz, default {DEFAULT_CLOCK_HZ:g})')
    p.add_argument('--delay', type=float, default=0.0, metavar='S',
                   help='wait this long before playing, e.g. for discovery (s, default 0)')
    return p


def _split_ros_args(argv):
    """Split ``argv`` into ours and the ``--ros-args ... [--]`` blocks.

    rcl would also take a bare ``OLD:=NEW`` outside ``--ros-args`` as a (deprecated) global
    remap rule, so the values of ``--remap`` must never reach it.
    """
    ours, ros_args, inside = [], [], False
    for arg in argv:
        if arg == '--ros-args':
            inside = True
            ros_args.append(arg)
        elif inside and arg == '--':
            inside = False
            ros_args.append(arg)
        else:
            (ros_args if inside else ours).append(arg)
    return ours, ros_args


def _error(message):
    print(f"replay: error: {' '.join(str(message).split())}", file=sys.stderr)


def main(args=None):
    """Run the ``replay`` executable.

    Parameters
    ----------
    args : list of str, optional
        Command-line arguments without the program name (ROS arguments after
        ``--ros-args`` included); default ``sys.argv[1:]``.

    Returns
    -------
    int
        Exit status: 0 when played (or interrupted), 2 for bad input or a bad file.
    """
    argv = list(sys.argv[1:] if args is None else args)
    ours, ros_args = _split_ros_args(argv)
    try:
        options = _parser().parse_args(ours)
    except SystemExit as exc:   # argparse printed the usage and the problem
        return exc.code if isinstance(exc.code, int) else EXIT_USAGE
    try:
        if not (math.isfinite(options.delay) and options.delay >= 0):
            raise ValueError(f'--delay must be >= 0 s, got {options.delay}')
        if not (math.isfinite(options.clock_hz) and options.clock_hz > 0):
            raise ValueError(f'--clock-hz must be > 0, got {options.clock_hz}')
        # check the file and the types before bringing up ROS
        plan = prepare(options.file, options.topics, options.remap, options.rate,
                       options.start_offset, options.loop)
    except (LogError, ValueError) as exc:
        _error(exc)
        return EXIT_USAGE
    rclpy.init(args=['replay'] + ros_args)
    node = executor = spinner = None
    status = 0
    try:
        node = ReplayNode(plan, clock=not options.no_clock, clock_hz=options.clock_hz)
        freeze_start_up_heap()   # paced playing: no full collections of start-up objects
        # spin in the background (graph and parameter services); play in this thread
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        spinner = threading.Thread(target=_spin_quietly, args=(executor,), daemon=True)
        spinner.start()
        if options.delay and node._stop.wait(options.delay):
            raise ExternalShutdownException()
        stats = node.play()
        if stats.stopped and not rclpy.ok():
            raise ExternalShutdownException()
        node.wait_for_acks(1.0)
        node.get_logger().info(
            f'replayed {stats.messages} messages ({stats.passes} pass(es)) in '
            f'{stats.wall_s:.3f} s; lateness median {stats.median_lateness_s * 1e3:.3f} ms, '
            f'max {stats.max_lateness_s * 1e3:.3f} ms')
    except (KeyboardInterrupt, ExternalShutdownException):
        ignore_further_interrupts()
        settle_interrupt()
    except LogError as exc:   # damage found while reading on
        _error(exc)
        status = EXIT_USAGE
    finally:
        if node is not None:
            node.stop()
        if executor is not None:
            executor.shutdown(timeout_sec=1.0)
        if node is not None:
            node.destroy_node()
        shutdown_quietly()
        if spinner is not None:
            spinner.join(timeout=1.0)
    return status


def _spin_quietly(executor):
    """Spin until shutdown; Ctrl-C shuts the context down under the spin, which is no error
    (nor is the wait set rclpy was making at that moment: "the given context is not valid")."""
    try:
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception:
        if executor.context.ok():
            raise


if __name__ == '__main__':
    sys.exit(main())
