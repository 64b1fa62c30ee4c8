"""From a scene file or YAML text to a raw scene, and in one call to a validated one.

Reading is strict and bounded: :func:`load_yaml` refuses what is not a regular UTF-8 file under
:data:`MAX_SCENE_BYTES`, documents over the count budgets (:data:`MAX_SCENE_NODES` values,
:data:`MAX_SCENE_DEPTH` levels, :data:`~impact_damper_sim.scene.model_budget.MAX_IMPACTORS`
impactors: counted on the YAML event stream, before the document is composed), duplicate keys,
tagged values it cannot convert and alias bombs, each with its line. :func:`apply_overrides`
edits the raw mapping with ``key=value`` strings read by the same YAML loader, and
:func:`load_scene` chains both with :func:`~.schema.validate`. This is the text-and-file
side of the scene schema, separate from the fields in :mod:`.schema` and :mod:`.containers`,
which see only Python values.
"""
from __future__ import annotations

import copy
import os
import re
import reprlib
import stat
import unicodedata
from collections.abc import Iterable, Iterator, Mapping
from typing import Any

import yaml

from .model_budget import MAX_IMPACTORS
from .schema import Field, SceneError, _describe, _got, _join, validate

try:   # libyaml's parser: the pre-scan reads a 1 MB file's events in 0.1 s, not 2.5 s
    from yaml.cyaml import CParser as _CParser
except ImportError:   # PyYAML built without libyaml: the pure-Python parser, as slow
    _CParser = None

__all__ = ['MAX_SCENE_BYTES', 'MAX_SCENE_DEPTH', 'MAX_SCENE_NODES', 'MAX_SCENE_VALUES',
           'load_yaml', 'file_kind', 'apply_overrides', 'load_scene']


# --- YAML loading ----------------------------------------------------------------------------

#: What a typed tag's value must look like, for the message when its constructor cannot
#: convert it (``dof: !!int uy``)
_TAG_EXPECTS: dict[str | None, str] = {
    'int': 'an integer', 'float': 'a number', 'bool': 'true or false',
    'timestamp': 'a date or time, e.g. 2024-01-31 or 2024-01-31T12:00:00Z',
    'null': 'null or ~', 'binary': 'base64 text'}


class _StrictLoader(yaml.SafeLoader):
    """SafeLoader that rejects duplicate keys, reads ``1e-3`` as a float (YAML 1.2) and
    reports a tagged value it cannot convert as a YAML error, with its line and column."""

    def construct_object(self, node: yaml.Node, deep: bool = False) -> Any:
        try:
            return super().construct_object(node, deep=deep)
        except yaml.YAMLError:
            raise
        except (ValueError, KeyError, AttributeError, TypeError, OverflowError):
            # PyYAML's own int/float/bool/timestamp constructors raise these on a value
            # they cannot read ('!!int uy'): no mark, a traceback for the user
            tag = node.tag
            short = tag.rsplit(':', 1)[-1] if tag.startswith('tag:yaml.org,2002:') else None
            value = node.value if isinstance(node, yaml.ScalarNode) else f'a {node.id}'
            expects = _TAG_EXPECTS.get(short, 'a value of that type')
            raise yaml.constructor.ConstructorError(
                None, None, f'cannot read {reprlib.repr(value)} as '
                f'{"!!" + short if short else tag} ({expects})', node.start_mark) from None

    def construct_mapping(self, node: yaml.Node, deep: bool = False) -> dict[Any, Any]:
        if isinstance(node, yaml.MappingNode):
            seen: dict[object, yaml.Node] = {}
            for key_node, _ in node.value:
                if key_node.tag == 'tag:yaml.org,2002:merge':
                    continue   # '<<' merges may legitimately be overridden
                key = self.construct_object(key_node, deep=True)
                try:
                    first = seen.setdefault(key, key_node)
                except TypeError:
                    continue   # unhashable key: SafeLoader reports it below
                if first is not key_node:
                    raise yaml.constructor.ConstructorError(
                        None, None, f'found duplicate key {key!r} (first defined on line '
                        f'{first.start_mark.line + 1})', key_node.start_mark)
        return super().construct_mapping(node, deep=deep)


# YAML 1.1 (PyYAML) reads '1e-3' as a string and only '1.0e-3' as a float.
_StrictLoader.add_implicit_resolver(
    'tag:yaml.org,2002:float',
    re.compile(r'^[-+]?[0-9][0-9_]*(?:\.[0-9_]*)?[eE][-+]?[0-9]+$'),
    list('-+0123456789'))


#: Budgets of a scene document, checked before anything is built from it: the file's size
#: (bytes), the nesting depth, and the number of values once every alias is expanded (an
#: alias bomb of 457 bytes expands to billions). The shipped scenes are under 20 KB, depth 6,
#: 2,000 values.
MAX_SCENE_BYTES = 1 << 20
MAX_SCENE_DEPTH = 32
MAX_SCENE_VALUES = 1_000_000
#: Values written in a file (keys, scalars, lists, mappings, aliases unexpanded), counted on
#: the event stream before the document is composed: PyYAML composes and constructs about
#: 10,000 values a second (10,000 impactors, 160,000 events: 15.6 s on a loaded machine).
#: 1,000 impactors with every key written and every unit a mapping are about 50,000; the
#: shipped scenes 70 to 1,030.
MAX_SCENE_NODES = 100_000


def _check_budget(root: yaml.Node, source: str) -> None:
    """Refuse a composed YAML node graph deeper than :data:`MAX_SCENE_DEPTH`, with more than
    :data:`MAX_SCENE_VALUES` values when its aliases are expanded, or with a recursive alias.

    Each node is visited once (sizes and depths memoised by node), so a bomb costs its
    size in text, not its expansion.
    """
    sizes: dict[int, int] = {}
    depths: dict[int, int] = {}
    active: set[int] = set()
    stack = [(root, False)]
    while stack:
        node, done = stack.pop()
        key = id(node)
        children: list[yaml.Node] = []
        if isinstance(node, yaml.MappingNode):
            children = [n for pair in node.value for n in pair]
        elif isinstance(node, yaml.SequenceNode):
            children = list(node.value)
        if done:
            active.discard(key)
            sizes[key] = 1 + sum(sizes[id(c)] for c in children)
            depths[key] = 1 + max((depths[id(c)] for c in children), default=0)
            mark = node.start_mark
            if depths[key] > MAX_SCENE_DEPTH:
                raise SceneError(f'{source}:{mark.line + 1}: values nested deeper than '
                                 f'{MAX_SCENE_DEPTH} levels; a scene is a few levels deep')
            if sizes[key] > MAX_SCENE_VALUES:
                raise SceneError(f'{source}:{mark.line + 1}: more than {MAX_SCENE_VALUES:,} '
                                 'values once its aliases are expanded (an alias bomb?)')
            continue
        if key in sizes:
            continue
        if key in active:
            raise SceneError(f'{source}:{node.start_mark.line + 1}: a recursive alias (a '
                             'value that contains itself)')
        active.add(key)
        stack.append((node, True))
        stack.extend((c, False) for c in children if id(c) not in sizes)


def _events(text: str, libyaml: bool = True) -> Iterator[yaml.Event]:
    """The YAML events of ``text``: from libyaml when PyYAML has it and ``libyaml``, else
    from the pure-Python parser (the composer's)."""
    parser = _CParser(text) if libyaml and _CParser is not None else yaml.SafeLoader(text)
    try:
        while parser.check_event():
            yield parser.get_event()
    finally:
        parser.dispose()


def _prescan(text: str, source: str, kind: str) -> None:
    """Refuse a document over :data:`MAX_SCENE_NODES` values, :data:`MAX_SCENE_DEPTH` levels
    or (a scene) :data:`~impact_damper_sim.scene.model_budget.MAX_IMPACTORS` items in its
    top-level ``impactors`` list, reading its events only as far as the first excess.

    Composing is what costs (about 0.1 ms a value in Python); an event costs 1 us with
    libyaml. Aliases are not expanded here: :func:`_check_budget` bounds them after.

    Raises
    ------
    SceneError
        Over a budget: one line with the line number, the limit and the allowed range.
    yaml.YAMLError
        A syntax error, as the composer's parser reports it.
    """
    if _CParser is not None:
        try:
            return _count_events(_events(text), source, kind)
        except yaml.YAMLError:
            pass   # read again by the composer's parser: its error is the one reported,
            # and it may accept what libyaml refuses
    return _count_events(_events(text, libyaml=False), source, kind)


def _count_events(events: Iterable[yaml.Event], source: str, kind: str) -> None:
    # one frame per open collection: [is a mapping, next child is a key, last key,
    # items counted (the scene's impactors only, else None)]
    stack: list[list[Any]] = []
    nodes = 0
    for event in events:
        if isinstance(event, yaml.CollectionEndEvent):
            stack.pop()
            continue
        if not isinstance(event, yaml.NodeEvent):
            continue   # stream and document start and end
        nodes += 1
        line = event.start_mark.line + 1 if event.start_mark else 0
        if nodes > MAX_SCENE_NODES:
            raise SceneError(f'{source}:{line}: over the limit of {MAX_SCENE_NODES:,} values '
                             f'in a {kind} (allowed 1 to {MAX_SCENE_NODES:,} keys, items and '
                             'values; the shipped scenes have at most 1,100): refused before '
                             'reading the rest')
        if len(stack) >= MAX_SCENE_DEPTH:
            raise SceneError(f'{source}:{line}: values nested deeper than {MAX_SCENE_DEPTH} '
                             'levels; a scene is a few levels deep')
        key = None   # the key this node is the value of, in a mapping
        if stack:
            parent = stack[-1]
            if parent[0]:
                if parent[1]:
                    parent[2] = event.value if isinstance(event, yaml.ScalarEvent) else None
                else:
                    key = parent[2]
                parent[1] = not parent[1]
            elif parent[3] is not None:
                parent[3] += 1
                if parent[3] > MAX_IMPACTORS:
                    raise SceneError(
                        f"{source}:{line}: scene key 'impactors': over the limit of "
                        f'{MAX_IMPACTORS:,} impactors (allowed 0 to {MAX_IMPACTORS:,}; '
                        f'impactor {MAX_IMPACTORS + 1:,} is on this line): each costs time '
                        'every step and memory in every stuck configuration; use fewer '
                        'impactors')
        if isinstance(event, yaml.CollectionStartEvent):
            counted = (kind == 'scene' and len(stack) == 1 and key == 'impactors'
                       and isinstance(event, yaml.SequenceStartEvent))
            stack.append([isinstance(event, yaml.MappingStartEvent), True, None,
                          0 if counted else None])


def _is_path(path_or_text: str | os.PathLike[str]) -> bool:
    # A one-line string naming a .yaml file is a path; anything else is YAML text.
    return isinstance(path_or_text, os.PathLike) or (
        isinstance(path_or_text, str) and '\n' not in path_or_text
        and path_or_text.strip().endswith(('.yaml', '.yml')))


def file_kind(path: str | os.PathLike[str] | int) -> str | None:
    """What a path (or open file descriptor) is when it is not a regular file, else None.

    Parameters
    ----------
    path : str, os.PathLike or int
        A path (symbolic links followed) or a file descriptor.

    Returns
    -------
    str or None
        ``'a directory'``, ``'a FIFO'``, ``'a character device'``, ``'a block
        device'``, ``'a socket'`` or ``'not a regular file'``; None for a regular file.

    Raises
    ------
    OSError
        The path does not exist or cannot be examined.
    """
    mode = os.fstat(path).st_mode if isinstance(path, int) else os.stat(path).st_mode
    if stat.S_ISREG(mode):
        return None
    for test, kind in ((stat.S_ISDIR, 'a directory'), (stat.S_ISFIFO, 'a FIFO'),
                       (stat.S_ISCHR, 'a character device'), (stat.S_ISBLK, 'a block device'),
                       (stat.S_ISSOCK, 'a socket')):
        if test(mode):
            return kind
    return 'not a regular file'


def _reader_problem(text: str, exc: yaml.reader.ReaderError) -> str:
    """One line for PyYAML's ReaderError on ``text``: the character (as U+XXXX: a raw
    control character would garble the terminal) and where it is."""
    char = exc.character
    code = char if isinstance(char, int) else ord(char) if isinstance(char, str) else char[0]
    pos = exc.position
    if not (0 <= pos < len(text) and text[pos] == chr(code)):
        pos = max(text.find(chr(code)), 0)
    # YAML allows no other character before this one, so splitlines() breaks lines as YAML
    lines = text[:pos].splitlines(keepends=True)
    if not lines or lines[-1][-1] in '\r\n\x85\u2028\u2029':
        line, column = len(lines) + 1, 1
    else:
        line, column = len(lines), len(lines[-1]) + 1
    if unicodedata.category(chr(code)) == 'Cc':
        what, why = 'control character', 'YAML allows none but tab and line breaks'
    else:
        what, why = 'character', 'YAML does not allow it'
    return f'{what} U+{code:04X} at line {line}, column {column} ({why})'


def load_yaml(path_or_text: str | os.PathLike[str], *, source: str | None = None,
              kind: str = 'scene') -> Mapping[str, Any]:
    """Read a scene file or YAML text into a raw mapping (no validation).

    Parameters
    ----------
    path_or_text : str or os.PathLike
        A path (``pathlib.Path``, or a one-line string ending in ``.yaml``/``.yml``) or the
        YAML text itself.
    source : str, optional
        Name used in messages (default: the path, or ``'<text>'``).
    kind : str, optional
        What the file holds, for messages (``'scene'``; a command schedule says
        ``'schedule'``).

    Returns
    -------
    dict
        The top-level mapping.

    Raises
    ------
    SceneError
        For a missing file, one that is not a regular file, over :data:`MAX_SCENE_BYTES` or
        not UTF-8 text, over the count budgets (:func:`_prescan`, before composing), a YAML
        syntax error (with line and column), a duplicate key, values nested or aliased over
        the budgets (:func:`_check_budget`), or a top level that is not a mapping.
    """
    if _is_path(path_or_text):
        path = os.fspath(path_or_text)
        source = source or path
        try:
            file = file_kind(path)   # before opening: opening a FIFO blocks
            if file:
                raise SceneError(f'{source}: not a {kind} file ({file}, not a regular file)')
            with open(path, 'rb') as stream:
                file = file_kind(stream.fileno())   # replaced in between
                if file:
                    raise SceneError(f'{source}: not a {kind} file ({file}, not a regular file)')
                raw = stream.read(MAX_SCENE_BYTES + 1)   # never more, whatever the file
        except OSError as exc:
            raise SceneError(f'{source}: cannot read {kind} file: {exc.strerror}') from None
        if len(raw) > MAX_SCENE_BYTES:
            raise SceneError(f'{source}: not a {kind} file (over {MAX_SCENE_BYTES} bytes; '
                             f'{kind}s are a few kilobytes)')
        try:
            text = raw.decode('utf-8')
        except UnicodeDecodeError:
            raise SceneError(f'{source}: not a {kind} file (not UTF-8 text)') from None
    else:
        text, source = str(path_or_text), source or '<text>'   # not a path: the text
        if len(text) > MAX_SCENE_BYTES:
            raise SceneError(f'{source}: over {MAX_SCENE_BYTES} characters of scene text')
    try:
        loader = _StrictLoader(text)   # checks every character: may raise ReaderError
    except yaml.reader.ReaderError as exc:
        raise SceneError(f'{source}: YAML error: {_reader_problem(text, exc)}') from None
    try:
        _prescan(text, source, kind)   # counts before composing: composing is the cost
        try:
            node = loader.get_single_node()
        except RecursionError:   # PyYAML composes recursively: a few frames per level
            raise SceneError(f'{source}: values nested deeper than {MAX_SCENE_DEPTH} levels; '
                             'a scene is a few levels deep') from None
        if node is not None:
            _check_budget(node, source)
        data = loader.construct_document(node) if node is not None else None
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = f':{mark.line + 1}:{mark.column + 1}' if mark else ''
        what = ': '.join(p for p in (exc.context, exc.problem) if p)
        if exc.context_mark and mark and exc.context_mark.line != mark.line:
            what += f' (construct started on line {exc.context_mark.line + 1})'
        raise SceneError(f'{source}{where}: YAML error: {what}') from None
    except yaml.YAMLError as exc:
        raise SceneError(f'{source}: YAML error: {exc}') from None
    finally:
        loader.dispose()
    if not isinstance(data, dict):
        got = 'an empty document' if data is None else f'{type(data).__name__} {_describe(data)}'
        raise SceneError(f'{source}: a {kind} must be a mapping at top level; got {got}')
    return data


# --- overrides -------------------------------------------------------------------------------

_NAME_RE = re.compile(r'\s*([^.\[\]\s][^.\[\]]*?)\s*')
_INDEX_RE = re.compile(r'\[\s*(\d+)\s*\]')


def _override_tokens(path: str) -> list[tuple[str, int | str]] | None:
    """Split ``'a.b[2].c'`` / ``'a.b.2.c'`` into ``[('name', 'a'), ..., ('index', 2), ...]``."""
    tokens: list[tuple[str, int | str]] = []
    pos = 0
    while pos < len(path):
        if path.startswith('[', pos):
            match = _INDEX_RE.match(path, pos)
            kind = 'index'
        else:
            if tokens:
                if not path.startswith('.', pos):
                    return None
                pos += 1
            match = _NAME_RE.fullmatch(path, pos, _end_of_name(path, pos))
            kind = 'name'
        if match is None:
            return None
        text = match.group(1)
        # 'impactors.0.mass': a bare number is a list index (or an integer map key).
        tokens.append(('index', int(text)) if kind == 'index' else
                      ('number', int(text)) if text.isdigit() else ('name', text))
        pos = match.end()
    return tokens or None


def _end_of_name(path: str, pos: int) -> int:
    stops = [i for i in (path.find('.', pos), path.find('[', pos)) if i >= 0]
    return min(stops) if stops else len(path)


def _parse_yaml_value(text: str) -> Any:
    return yaml.load(text, Loader=_StrictLoader) if text.strip() else None


def apply_overrides(raw: object, overrides: Iterable[str]) -> dict[str, Any]:
    """Return a copy of a raw scene with ``key=value`` overrides applied.

    Parameters
    ----------
    raw : dict
        Raw scene (not modified).
    overrides : sequence of str
        Each ``'dotted.path=value'``; list indices as ``[0]`` or ``.0``
        (``'impactors[0].mass=2 lb'``, ``'impactors.0.mass=2 lb'``). The value is read as a
        YAML scalar or flow collection (``3``, ``2.5 mil``, ``[1, 2]``, ``{value: 2, unit: lb}``);
        an empty value is null. Missing mapping keys along the path are created, so a key the
        schema does not know is reported by :func:`~.schema.validate`, with its name.

    Returns
    -------
    dict
        The new raw scene (validate it next).

    Raises
    ------
    SceneError
        For malformed overrides, an index past a list's end, or a path through a scalar.
        All bad overrides are reported together.
    """
    if isinstance(overrides, str):
        raise TypeError('overrides must be a sequence of "key=value" strings, not one string')
    if not isinstance(raw, dict):
        raise SceneError(f'scene: expected a mapping at top level, {_got(raw)}')
    data = copy.deepcopy(raw)
    problems: list[str] = []
    for text in overrides:
        try:
            _apply_one(data, text)
        except SceneError as exc:
            problems.extend(exc.errors)
    if problems:
        raise SceneError(problems)
    return data


def _apply_one(data: dict[object, Any], text: str) -> None:

    if not isinstance(text, str) or '=' not in text:
        raise SceneError(f'override {text!r}: expected "key=value"')
    path, value_text = text.split('=', 1)
    tokens = _override_tokens(path.strip())
    if tokens is None or tokens[0][0] == 'index':
        raise SceneError(f'override {text!r}: cannot read key path {path.strip()!r}; write '
                         "e.g. 'impactors[0].mass' or 'impactors.0.mass'")
    try:
        value = _parse_yaml_value(value_text)
    except yaml.reader.ReaderError as exc:
        raise SceneError(f'override {text!r}: value is not valid YAML: '
                         f'{_reader_problem(value_text, exc)}') from None
    except yaml.YAMLError as exc:
        raise SceneError(f'override {text!r}: value is not valid YAML: '
                         f'{getattr(exc, "problem", None) or exc}') from None
    node, here = data, ''
    for i, (kind, key) in enumerate(tokens):
        last = i == len(tokens) - 1
        if isinstance(node, list):
            if kind == 'name':
                raise SceneError(f"override {text!r}: '{here}' is a list; index it with a "
                                 f"number, e.g. '{here}[0]'")
            if key >= len(node):
                raise SceneError(f"override {text!r}: index {key} is past the end of list "
                                 f"'{here}' (length {len(node)})")
            here = f'{here}[{key}]'
        elif isinstance(node, dict):
            if kind == 'index':
                raise SceneError(f"override {text!r}: '{here}' is a mapping, not a list; "
                                 f'cannot index it with [{key}]')
            if kind == 'number' and str(key) in node:
                key = str(key)   # an existing string key '3' wins over the integer 3
            here = _join(here, key)
            if not last and node.get(key) is None:
                if tokens[i + 1][0] == 'index':
                    raise SceneError(f"override {text!r}: index {tokens[i + 1][1]} is past the "
                                     f"end of list '{here}' (the key is absent: length 0)")
                node[key] = {}   # absent section: create it; validate() judges the key
        else:
            raise SceneError(f"override {text!r}: '{here}' is {type(node).__name__} "
                             f'{_describe(node)}, not a mapping or list')
        if last:
            node[key] = value
        else:
            node = node[key]


# --- load, override, validate ----------------------------------------------------------------

def load_scene(schema: Field, path_or_text: str | os.PathLike[str],
               overrides: Iterable[str] = (), *, source: str | None = None) -> Any:

    """Load, override and validate a scene in one call.

    Parameters
    ----------
    schema : Field
        Top-level schema.
    path_or_text : str or os.PathLike
        See :func:`load_yaml`.
    overrides : sequence of str, optional
        See :func:`apply_overrides`.
    source : str, optional
        Name used in messages (default: the path, if one was given).

    Returns
    -------
    dict
        Validated scene in SI units.
    """
    raw = load_yaml(path_or_text, source=source)
    if source is None and _is_path(path_or_text):
        source = os.fspath(path_or_text)
    return validate(schema, apply_overrides(raw, overrides), source=source)
