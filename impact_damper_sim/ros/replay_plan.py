"""What ``replay`` plays: a log opened and checked, its topics' QoS and types, the remaps.

:func:`prepare` opens an MCAP log (:class:`~impact_damper_sim.studies.log_reader.RosLog`), checks
that it can be replayed and returns a :class:`Plan`: one :class:`Track` per recorded channel
with its output topic (after ``--remap``), its installed message class and the QoS its
recording publishers offered (:func:`qos_from_offered`, or :data:`FALLBACK_QOS` with a
warning), and the :class:`~impact_damper_sim.live.playback.Schedule` of the playback. It is
kept apart from the node (:mod:`.replay`) because it needs no ROS context: the command line
checks the file and the options with it before ``rclpy.init``, and tests plan logs without
starting a node.
"""
from __future__ import annotations

import importlib
import re
from dataclasses import dataclass, field

from rclpy.duration import Duration
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    LivelinessPolicy,
    QoSProfile,
    ReliabilityPolicy,
)

from ..live.playback import Schedule
from ..studies.log_reader import LogError, RosLog, type_name

#: used when a topic's offered QoS is missing or mixed (rosbag2's default offer)
FALLBACK_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                          reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.VOLATILE)


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


def describe(plan):
    """What a replay is about to play, as the lines ``replay`` prints at start.

    Parameters
    ----------
    plan : Plan
        Output of :func:`prepare`.

    Returns
    -------
    list of str
        ``'replay: playing <file>: <n> messages on <k> topics, <d> s of log time, at rate
        <x> (real_time_factor <x>)'`` (with the offset and ``looping`` when given), then one
        line per topic: its name, type and message count (``-> <topic>`` when remapped).
    """
    log, sched = plan.log, plan.schedule
    counts = {tr.channel_id: log.counts.get(tr.channel_id) for tr in plan.tracks}
    total = sum(c for c in counts.values() if c is not None)
    span = max(sched.end_ns - sched.begin_ns, 0) * 1e-9
    extra = (f', from {(sched.begin_ns - log.start_ns) * 1e-9:.6g} s on'
             if sched.begin_ns != log.start_ns else '') + (', looping' if sched.loop else '')
    lines = [f'replay: playing {log.path}: {total} messages on {len(plan.tracks)} topic(s), '
             f'{span:.6g} s of log time, at rate {sched.rate:g} (real_time_factor '
             f'{sched.rate:g}: {span / sched.rate:.6g} s of wall time a pass){extra}']
    width = max(len(tr.topic) for tr in plan.tracks)
    for tr in plan.tracks:
        n = counts[tr.channel_id]
        remap = f' -> {tr.out_topic}' if tr.out_topic != tr.topic else ''
        lines.append(f"  {tr.topic:{width}}  {tr.type}  {'?' if n is None else n}{remap}")
    return lines


def finished_line(stats):
    """The line ``replay`` prints at the end: messages, passes, wall time and lateness.

    Parameters
    ----------
    stats : PlaybackStats
        What :meth:`Player.run` returns (``messages``, ``passes``, ``wall_s`` in s,
        ``median_lateness_s`` and ``max_lateness_s`` in s).
    """
    return (f'replay: played {stats.messages} messages ({stats.passes} pass(es)) in '
            f'{stats.wall_s:.3f} s of wall time; lateness median '
            f'{stats.median_lateness_s * 1e3:.3f} ms, max {stats.max_lateness_s * 1e3:.3f} ms')


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
    for _, ch in sorted(log.channels.items()):
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
