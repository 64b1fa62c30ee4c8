"""Message definitions and type hashes as rosbag2 stores them, read from the installed ``.msg``.

rosbag2 (jazzy, ``rosbag2_cpp/message_definitions/local_message_definition_source.cpp``) stores
each type's schema as its ``.msg`` text followed by every dependency not written yet, depth
first, sorted within each level (a ``std::set`` of ``pkg/Type`` names). Each dependency is
joined as ``"\\n" + "=" * 80 + "\\nMSG: pkg/Type\\n" + text``. Dependencies are the field types
found by rosbag2's regular expression; a type without a package is in the package of the file
that names it. The type hash (``RIHS01_...``) is read from ``share/<pkg>/msg/<Type>.json``.

Files are found through the ament index (``AMENT_PREFIX_PATH``), as rosbag2 finds them.
No rclpy is needed.
"""
from __future__ import annotations

import functools
import json
import os
import re

#: rosbag2's field-type pattern (``MSG_FIELD_TYPE_REGEX``): a word at the start of a line,
#: optionally an array suffix, then whitespace.
_MSG_FIELD_TYPE = re.compile(r'(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+')
#: rosbag2's ``PACKAGE_TYPENAME_REGEX``: ``pkg/Type`` or ``pkg/msg/Type``.
_PACKAGE_TYPENAME = re.compile(r'^([a-zA-Z0-9_]+)/(?:msg/|srv/)?([a-zA-Z0-9_]+)$')
_PRIMITIVES = frozenset({
    'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16', 'int32',
    'uint32', 'int64', 'uint64', 'string'})
DELIMITER = '=' * 80


class DefinitionNotFoundError(LookupError):
    """A type's ``.msg`` file (or one of its dependencies') is not installed."""


class AmentIndexError(DefinitionNotFoundError, OSError):
    """The ament index cannot be searched: ``AMENT_PREFIX_PATH`` is unset, empty, or names no
    prefix holding the ROS message definitions.

    An ``OSError`` (an environment problem, as ament_index_python raises it) as well as a
    :class:`DefinitionNotFoundError`: a recorder's start refuses with it before creating its file.
    """


#: Message packages every ROS 2 installation has; a recorder checks it can read them first.
CORE_PACKAGES = ('builtin_interfaces', 'std_msgs')


def _prefix_with(package):
    """This Python's install prefix if ``share/<package>/msg`` is in it, else ``None``: the
    value ``AMENT_PREFIX_PATH`` most likely needs (a venv with the PyPI ROS 2 wheels)."""
    import sys
    if os.path.isdir(os.path.join(sys.prefix, 'share', package, 'msg')):
        return sys.prefix
    return None


def _index_hint(package):
    prefix = _prefix_with(package)
    if prefix:
        return f'export AMENT_PREFIX_PATH={prefix} (where {package} is installed)'
    return ('source a ROS 2 setup file, or export AMENT_PREFIX_PATH=<the prefix holding '
            f'share/{package}/msg>')


def split_type_name(type_name):
    """Split ``pkg/msg/Type`` (or ``pkg/Type``) into ``(pkg, Type)``.

    Parameters
    ----------
    type_name : str
        ROS type name, e.g. ``sensor_msgs/msg/Imu``.

    Returns
    -------
    tuple of str
        Package and type, e.g. ``('sensor_msgs', 'Imu')``.

    Raises
    ------
    ValueError
        If the name is not of either form.
    """
    match = _PACKAGE_TYPENAME.match(type_name)
    if not match:
        raise ValueError(f"type name {type_name!r} is not of the form 'pkg/msg/Type'")
    return match.group(1), match.group(2)


def _share_dir(package):
    if not os.environ.get('AMENT_PREFIX_PATH'):
        raise AmentIndexError(
            f'AMENT_PREFIX_PATH is not set (or empty), so the ROS message definitions '
            f'(share/{package}/msg) cannot be found; {_index_hint(package)}')
    from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
    try:
        return get_package_share_directory(package)
    except OSError as exc:   # ament_index_python: the variable is unset or empty
        raise AmentIndexError(f'{exc}; {_index_hint(package)}') from None
    except (PackageNotFoundError, LookupError, ValueError) as exc:
        raise DefinitionNotFoundError(
            f"package {package!r} not found in the ament index (AMENT_PREFIX_PATH="
            f"{os.environ.get('AMENT_PREFIX_PATH', '')!r}): {exc}") from None


def check_ament_index(packages=CORE_PACKAGES):
    """Raise :class:`AmentIndexError` unless the ament index has the message definitions of
    ``packages``: what a recorder checks before it creates its file.

    Parameters
    ----------
    packages : iterable of str, optional
        Message packages that must be found, with their ``msg`` directory.

    Raises
    ------
    AmentIndexError
        One line: what is missing and the ``AMENT_PREFIX_PATH`` to set.
    """
    for package in packages:
        try:
            share = _share_dir(package)
        except AmentIndexError:
            raise
        except DefinitionNotFoundError:
            share = None
        if share is None or not os.path.isdir(os.path.join(share, 'msg')):
            raise AmentIndexError(
                f"no message definitions of {package} under AMENT_PREFIX_PATH="
                f"{os.environ.get('AMENT_PREFIX_PATH', '')!r}; {_index_hint(package)}")


@functools.lru_cache(maxsize=None)
def msg_text(type_name):
    """Return the exact text of a type's installed ``.msg`` file.

    Parameters
    ----------
    type_name : str
        ``pkg/Type`` or ``pkg/msg/Type``.

    Returns
    -------
    str
        The file's text, byte for byte (no newline translation).
    """
    package, name = split_type_name(type_name)
    path = os.path.join(_share_dir(package), 'msg', name + '.msg')
    try:
        with open(path, 'rb') as f:
            return f.read().decode('utf-8')
    except OSError as exc:
        raise DefinitionNotFoundError(f'no .msg definition for {type_name}: {exc}') from None


def msg_dependencies(text, package):
    """Return the non-primitive field types a ``.msg`` text names, as rosbag2 parses them.

    Parameters
    ----------
    text : str
        ``.msg`` text.
    package : str
        Package of the file, for types named without one.

    Returns
    -------
    list of str
        ``pkg/Type`` names, sorted (rosbag2 keeps them in a ``std::set``).
    """
    deps = set()
    for match in _MSG_FIELD_TYPE.finditer(text):
        field_type = match.group(1)
        if field_type in _PRIMITIVES:
            continue
        deps.add(field_type if '/' in field_type else f'{package}/{field_type}')
    return sorted(deps)


@functools.lru_cache(maxsize=None)
def message_definition(type_name):
    """Return the schema text rosbag2 writes for a type: its ``.msg`` plus its dependencies.

    Parameters
    ----------
    type_name : str
        ``pkg/msg/Type``.

    Returns
    -------
    str
        Root text, then for each dependency not written yet (depth first, sorted within each
        level) a newline, 80 ``=``, a newline, ``MSG: pkg/Type``, a newline and its text.

    Raises
    ------
    DefinitionNotFoundError
        If the type or a dependency has no installed ``.msg``.
    """
    seen = set()

    def append(name, depth):
        if depth <= 0:   # rosbag2's recursion limit; only a cyclic definition reaches it
            raise DefinitionNotFoundError(f'definition of {type_name} is too deep or cyclic')
        text = msg_text(name)
        parts = [text]
        for dep in msg_dependencies(text, split_type_name(name)[0]):
            if dep not in seen:
                seen.add(dep)
                parts.append(f'\n{DELIMITER}\nMSG: {dep}\n')
                parts.append(append(dep, depth - 1))
        return ''.join(parts)

    return append(type_name, 50)


@functools.lru_cache(maxsize=None)
def type_hash(type_name):
    """Return the RIHS01 type hash of an installed type, or ``''`` if it has no ``.json``.

    Parameters
    ----------
    type_name : str
        ``pkg/msg/Type``.

    Returns
    -------
    str
        ``RIHS01_<64 hex digits>`` from ``share/<pkg>/msg/<Type>.json`` (the entry of
        ``type_hashes`` whose ``type_name`` is the type), or ``''`` (what rosbag2 stores when
        it does not know the hash).
    """
    package, name = split_type_name(type_name)
    try:
        path = os.path.join(_share_dir(package), 'msg', name + '.json')
        with open(path, 'rb') as f:
            description = json.load(f)
    except (DefinitionNotFoundError, OSError, ValueError):
        return ''
    full_name = f'{package}/msg/{name}'
    for entry in description.get('type_hashes', []):
        if entry.get('type_name') == full_name:
            return str(entry.get('hash_string', ''))
    return ''
