"""rosbag2's QoS and bag-metadata YAML (metadata version 9), without rclpy.

Sources (ros2/rosbag2, jazzy): ``rosbag2_storage/src/rosbag2_storage/qos.cpp`` (a QoS profile
is a map of history, depth, reliability, durability, deadline, lifespan, liveliness,
liveliness_lease_duration and avoid_ros_namespace_conventions; version 9 writes the policies
as rmw's strings, durations as ``{sec, nsec}``), ``rosbag2_storage/include/rosbag2_storage/
yaml.hpp`` (the bag metadata fields) and ``rosbag2_storage_mcap/src/mcap_storage.cpp`` (the
channel's ``offered_qos_profiles`` is the YAML text of the profile list; the ``rosbag2``
metadata record holds the metadata YAML with the profiles as a YAML sequence).

The YAML is emitted in yaml-cpp's block style (what ``YAML::Dump`` writes: two-space indents,
indented sequences, no trailing newline), and checked to load back to the same data.
"""
from __future__ import annotations

import json
import re

import yaml

#: rmw's policy strings (``rmw/qos_string_conversions.c``), indexed by the rmw enum value;
#: ``None`` where rmw has no string (rosbag2 writes ``unknown`` there).
_HISTORY = ('system_default', 'keep_last', 'keep_all', None)
_RELIABILITY = ('system_default', 'reliable', 'best_effort', None, 'best_available')
_DURABILITY = ('system_default', 'transient_local', 'volatile', None, 'best_available')
_LIVELINESS = ('system_default', 'automatic', None, 'manual_by_topic', None, 'best_available')
_NS = 1_000_000_000
#: rclpy's ``QoSProfile()`` defaults (``rmw_qos_profile_default``), for keys a dict leaves out.
_DEFAULTS = {'history': 'keep_last', 'depth': 10, 'reliability': 'reliable',
             'durability': 'volatile', 'deadline': 0, 'lifespan': 0,
             'liveliness': 'system_default', 'liveliness_lease_duration': 0,
             'avoid_ros_namespace_conventions': False}
QOS_KEYS = tuple(_DEFAULTS)
#: what rosbag2 stores when it is given no ROS_DISTRO; this package targets Jazzy.
DEFAULT_ROS_DISTRO = 'jazzy'
#: rosbag2's ``starting_time`` of a bag without messages (``std::chrono::nanoseconds::max()``).
NO_MESSAGES_START_NS = 2**63 - 1


def _policy(value, names, key):
    """Return rmw's string for a policy given as an enum, an int or a string."""
    if isinstance(value, str):
        text = value.lower()
        if text in names or text == 'unknown':
            return text
        raise ValueError(f'QoS {key}: {value!r} is not one of {[n for n in names if n]}')
    number = int(getattr(value, 'value', value))   # rclpy enums are IntEnums with .value
    if 0 <= number < len(names):
        return names[number] or 'unknown'
    return 'unknown'


def _duration(value, key):
    """Return ``{'sec': s, 'nsec': ns}`` for a duration given in ns, as rclpy Duration or dict."""
    if isinstance(value, dict):
        if set(value) != {'sec', 'nsec'}:
            raise ValueError(f"QoS {key}: a dict duration needs exactly 'sec' and 'nsec'")
        return {'sec': int(value['sec']), 'nsec': int(value['nsec'])}
    ns = int(getattr(value, 'nanoseconds', value))
    if ns < 0:
        raise ValueError(f'QoS {key}: negative duration {ns} ns')
    # rmw's RMW_DURATION_INFINITE is {9223372036, 854775807}, the same split of 2**63 - 1 ns
    return {'sec': ns // _NS, 'nsec': ns % _NS}


def qos_dict(profile):
    """Return one QoS profile in rosbag2's version-9 form.

    Parameters
    ----------
    profile : rclpy.qos.QoSProfile or dict
        An rclpy profile (read by attribute; no rclpy import here), or a dict with any of
        :data:`QOS_KEYS`: policies as rmw strings (``'best_effort'``), ints or enums; ``depth``
        an int (messages); durations as ints (ns), ``{'sec', 'nsec'}`` dicts or rclpy
        Durations. Missing keys take rclpy's ``QoSProfile()`` defaults; unknown keys raise.

    Returns
    -------
    dict
        Keys in rosbag2's order: history, depth, reliability, durability, deadline, lifespan,
        liveliness, liveliness_lease_duration, avoid_ros_namespace_conventions.
    """
    if isinstance(profile, dict):
        unknown = set(profile) - set(QOS_KEYS)
        if unknown:
            raise ValueError(f'unknown QoS keys {sorted(unknown)}; allowed: {list(QOS_KEYS)}')
        get = {**_DEFAULTS, **profile}.__getitem__
    else:
        def get(key):
            return getattr(profile, key)
    return {
        'history': _policy(get('history'), _HISTORY, 'history'),
        'depth': int(get('depth')),
        'reliability': _policy(get('reliability'), _RELIABILITY, 'reliability'),
        'durability': _policy(get('durability'), _DURABILITY, 'durability'),
        'deadline': _duration(get('deadline'), 'deadline'),
        'lifespan': _duration(get('lifespan'), 'lifespan'),
        'liveliness': _policy(get('liveliness'), _LIVELINESS, 'liveliness'),
        'liveliness_lease_duration': _duration(get('liveliness_lease_duration'),
                                               'liveliness_lease_duration'),
        'avoid_ros_namespace_conventions': bool(get('avoid_ros_namespace_conventions')),
    }


def qos_list(qos):
    """Return the offered profiles of a topic as a list of :func:`qos_dict` dicts.

    Parameters
    ----------
    qos : QoSProfile, dict, list of them, or None
        One profile, or one per publisher (rosbag2 stores every publisher's offer). ``None``
        means unknown and gives ``[]``.

    Returns
    -------
    list of dict
    """
    if qos is None:
        return []
    if isinstance(qos, (list, tuple)):
        return [qos_dict(p) for p in qos]
    return [qos_dict(qos)]


_PLAIN = re.compile(r'^[A-Za-z_/][A-Za-z0-9_/.\-]*$')
_YAML11_WORDS = frozenset({'y', 'n', 'yes', 'no', 'true', 'false', 'on', 'off', 'null', '~'})


def _scalar(value):
    if value is None:
        return '~'
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return repr(value)
    text = str(value)
    if _PLAIN.match(text) and text.lower() not in _YAML11_WORDS:
        return text
    return json.dumps(text)   # a JSON string is a valid YAML double-quoted scalar


def _emit(value, indent, lines):
    pad = ' ' * indent
    if isinstance(value, dict):
        for key, item in value.items():
            if isinstance(item, (dict, list)) and item:
                lines.append(f'{pad}{_scalar(key)}:')
                _emit(item, indent + 2, lines)
            else:
                lines.append(f'{pad}{_scalar(key)}: {_block_scalar(item)}')
    else:
        for item in value:
            if isinstance(item, (dict, list)) and item:
                start = len(lines)
                _emit(item, indent + 2, lines)
                lines[start] = f'{pad}- ' + lines[start][indent + 2:]
            else:
                lines.append(f'{pad}- {_block_scalar(item)}')


def _block_scalar(value):
    if isinstance(value, dict):
        return '{}'
    if isinstance(value, list):
        return '[]'
    return _scalar(value)


def dump_yaml(data):
    """Return YAML text for dicts, lists and scalars, in yaml-cpp's ``YAML::Dump`` layout.

    Parameters
    ----------
    data : dict or list
        Nested dicts (insertion order kept), lists, str, int, bool and None.

    Returns
    -------
    str
        Block-style YAML without a trailing newline; ``yaml.safe_load`` of it equals ``data``
        (if the compact emitter ever got that wrong, PyYAML's output is returned instead).
    """
    if isinstance(data, (dict, list)) and not data:
        text = _block_scalar(data)
    else:
        lines = []
        _emit(data, 0, lines)
        text = '\n'.join(lines)
    if yaml.safe_load(text) != data:   # never observed; a guard for unusual strings
        text = yaml.safe_dump(data, sort_keys=False, default_flow_style=False).rstrip('\n')
    return text


def bag_metadata(topics, start_ns, end_ns, relative_path, ros_distro=DEFAULT_ROS_DISTRO,
                 custom_data=None):
    """Return rosbag2's bag metadata (version 9) for one MCAP file, as a dict.

    Parameters
    ----------
    topics : list of dict
        One per channel, in channel order: ``name``, ``type`` (``pkg/msg/Type``),
        ``serialization_format`` (``cdr``), ``offered_qos_profiles`` (list of
        :func:`qos_dict`), ``type_description_hash`` (str) and ``message_count`` (messages).
    start_ns, end_ns : int or None
        Earliest and latest message log time (ns since the epoch); ``None`` without messages.
    relative_path : str
        File name of the bag file (rosbag2 stores it without directories).
    ros_distro : str, optional
        ROS distribution name.
    custom_data : dict of str, optional
        rosbag2's ``custom_data`` (``ros2 bag record --custom-data``).

    Returns
    -------
    dict
        Keys as rosbag2's ``convert<BagMetadata>::encode``: version, storage_identifier,
        duration {nanoseconds}, starting_time {nanoseconds_since_epoch}, message_count,
        topics_with_message_count, compression_format, compression_mode, relative_file_paths,
        files, custom_data, ros_distro. Times in ns.
    """
    total = sum(t['message_count'] for t in topics)
    if start_ns is None:
        start_ns = end_ns = NO_MESSAGES_START_NS
    duration = {'nanoseconds': end_ns - start_ns}
    starting_time = {'nanoseconds_since_epoch': start_ns}
    return {
        'version': 9,
        'storage_identifier': 'mcap',
        'duration': duration,
        'starting_time': starting_time,
        'message_count': total,
        'topics_with_message_count': [
            {'topic_metadata': {
                'name': t['name'], 'type': t['type'],
                'serialization_format': t['serialization_format'],
                'offered_qos_profiles': t['offered_qos_profiles'],
                'type_description_hash': t['type_description_hash']},
             'message_count': t['message_count']}
            for t in topics],
        'compression_format': '',
        'compression_mode': '',
        'relative_file_paths': [relative_path],
        'files': [{'path': relative_path, 'starting_time': dict(starting_time),
                   'duration': dict(duration), 'message_count': total}],
        # yaml-cpp writes an empty map node as null
        'custom_data': dict(custom_data) if custom_data else None,
        'ros_distro': ros_distro,
    }
