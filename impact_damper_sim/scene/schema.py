"""Declarative, strict scene schema: validate YAML scenes and convert units once, at load.

A schema is a tree of fields::

    SCHEMA = Section({
        'impactors': ListOf(Section({
            'mass': Quantity('mass', min=0, min_inclusive=False, doc='impactor mass'),
            'clearance': Quantity('length', default='2.5 mil', min='1e-8 m', max='1 cm'),
        }), min_len=1),
        'solver': Section({'method': Choice(('event', 'penalty'), default='event')}),
    })
    scene = validate(SCHEMA, load_yaml('scene.yaml'))

Rules
-----
* Every physical value goes through :func:`impact_damper_sim.scene.units.parse_quantity`; the
  result holds SI floats only (m, kg, s, N, rad, ...). A bare number is already SI.
* Unknown keys, wrong types, wrong units, out-of-range values and missing required keys
  are errors. Nothing is silently ignored or silently defaulted: a key written with no
  value (``mass:``, i.e. YAML null) is an error unless the field's default is ``None``.
* All errors of a scene are collected and raised together as one :class:`SceneError`,
  one line per problem, each naming the key by its dotted path with list indices
  (``impactors[2].clearance``).
* Defaults are written like scene values (``default='2.5 mil'``) and pass through the
  same conversion; they are checked when the schema is built, so a bad schema fails at
  import, not in a user's run.

Result
------
:func:`validate` returns a fresh tree of plain ``dict`` / ``list`` / ``float`` / ``int`` /
``str`` / ``bool`` / ``None`` (YAML- and JSON-serialisable, safe to mutate). Every
:class:`Section` key appears in its dict, in schema order; absent optional keys are
``None``. :class:`Vector` values are lists of floats.
"""
from __future__ import annotations

import copy
import difflib
import os
import re
import reprlib
import stat
import unicodedata
from typing import NamedTuple

import yaml

from .units import SI_UNIT, UNITS, UnitError, _parse, allowed_units, format_quantity

__all__ = [
    'REQUIRED', 'SceneError', 'Field', 'Quantity', 'Integer', 'Boolean', 'Choice', 'String',
    'Section', 'ListOf', 'Vector', 'MapOf', 'Optional', 'KeyInfo', 'validate',
    'apply_overrides', 'describe', 'markdown_table', 'load_yaml', 'load_scene',
]


class _Required:
    """Sentinel: the key has no default and must be given."""

    def __repr__(self):
        return 'REQUIRED'


REQUIRED = _Required()
_INVALID = object()  # placeholder for a value that already produced an error


class SceneError(ValueError):
    """A scene (file, mapping or override) is invalid.

    Attributes
    ----------
    errors : tuple of str
        One message per problem, each naming the offending key.
    source : str or None
        File name or other origin of the scene, if known.
    """

    def __init__(self, errors, source=None):
        self.errors = (errors,) if isinstance(errors, str) else tuple(errors)
        self.source = source
        lines = list(self.errors)
        if source is not None and len(lines) > 1:
            lines.insert(0, f'invalid scene {source} ({len(lines)} errors):')
        elif source is not None:
            lines[0] = f'{source}: {lines[0]}'
        super().__init__('\n'.join(lines))


class _Errors:
    """Collects ``(path, message)`` pairs so that every problem is reported at once."""

    def __init__(self):
        self.items = []

    def add(self, path, message):
        self.items.append((path, message))

    def __len__(self):
        return len(self.items)

    def lines(self):
        return [f"scene key '{p}': {m}" if p else f'scene: {m}' for p, m in self.items]


def _join(path, key):
    return f'{path}.{key}' if path else str(key)


def _num(x):
    return f'{x:.12g}'


_REPR = reprlib.Repr()
_REPR.maxlevel, _REPR.maxstring, _REPR.maxother = 3, 50, 50
_REPR.maxlist = _REPR.maxtuple = _REPR.maxdict = _REPR.maxset = 6


def _describe(value):
    # bounded: a huge or aliased value (a YAML alias bomb) is never printed whole
    text = _REPR.repr(value)
    return text if len(text) <= 60 else text[:57] + '...'


def _got(value):
    return f'got {type(value).__name__} {_describe(value)}'


def _article(word):
    return ('an ' if word[:1] in 'aeiou' else 'a ') + word


def _interval(lo, hi, lo_inc, hi_inc, fmt=_num):
    if lo is None and hi is None:
        return ''
    # An absent bound is open: infinity itself is never a valid value.
    left = ('[' + fmt(lo) if lo_inc else '(' + fmt(lo)) if lo is not None else '(-inf'
    right = (fmt(hi) + ']' if hi_inc else fmt(hi) + ')') if hi is not None else 'inf)'
    return f'{left}, {right}'


def _outside(x, lo, hi, lo_inc, hi_inc):
    if lo is not None and (x < lo or (x == lo and not lo_inc)):
        return True
    return hi is not None and (x > hi or (x == hi and not hi_inc))


def _yaml_text(value):
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, (list, dict)):
        return yaml.safe_dump(value, default_flow_style=True, sort_keys=False).strip()
    return str(value)


class KeyInfo(NamedTuple):
    """One row of :func:`describe`: a scene key and what it accepts."""

    key: str       #: dotted path; ``[]`` stands for any list index, ``<key>`` for a map key
    kind: str      #: dimension or type, e.g. ``'stiffness'``, ``'integer'``, ``'list of section'``
    default: str   #: default as text (``'required'``, ``'none'``, ``'2.5 mil'``)
    range: str     #: allowed range/options, SI units for quantities; ``''`` if unrestricted
    doc: str       #: description


class Field:
    """Base of all schema fields.

    Parameters
    ----------
    default : object, optional
        Raw default, written as in a scene file and converted the same way. ``REQUIRED``
        (the default) makes the key mandatory; ``None`` makes it optional, with ``None``
        (YAML null) as its value when absent.
    doc : str, optional
        One-line description for :func:`describe`.
    """

    def __init__(self, default=REQUIRED, doc=''):
        self.default = default
        self.doc = doc

    # -- to be provided by subclasses --------------------------------------------------------
    def _convert(self, raw, path, errors):
        raise NotImplementedError

    def kind(self):
        """Return the type or dimension name shown to users (str)."""
        raise NotImplementedError

    def range_text(self):
        """Return the allowed range or options as text ('' if unrestricted)."""
        return ''

    def _subfields(self):
        return ()

    # -- shared machinery ---------------------------------------------------------------------
    def expects(self):
        """Return what this field accepts, for error messages (str)."""
        rng = self.range_text()
        return _article(self.kind()) + (f' in {rng}' if rng else '')

    def default_text(self):
        """Return the default as text for :func:`describe`."""
        if self.default is REQUIRED:
            return 'required'
        if self.default is None:
            return 'none'
        return _yaml_text(self.default)

    def _check_default(self):
        # Fail when the schema is built, not when a user's scene happens to omit the key.
        if self.default is REQUIRED or self.default is None:
            return
        errors = _Errors()
        self._convert(copy.deepcopy(self.default), '', errors)
        if errors:
            problems = '; '.join(m for _, m in errors.items)
            raise ValueError(f'invalid default {self.default!r} for {self.kind()}: {problems}')

    def resolve(self, present, raw, path, errors):
        """Return the converted value of one key (or a placeholder after an error).

        Parameters
        ----------
        present : bool
            Whether the key was written at all.
        raw : object
            The value as written (ignored when ``present`` is false).
        path : str
            Dotted key for messages.
        errors : _Errors
            Collector the problems are added to.
        """
        if not present:
            if self.default is REQUIRED:
                errors.add(path, f'missing required key; expected {self.expects()}')
                return _INVALID
            if self.default is None:
                return None
            return self._convert(copy.deepcopy(self.default), path, errors)
        if raw is None:
            if self.default is None:
                return None
            # 'mass:' with nothing after it is a mistake, not a request for the default.
            errors.add(path, f'is empty (null); expected {self.expects()}')
            return _INVALID
        return self._convert(raw, path, errors)

    def _rows(self, path):
        yield KeyInfo(path, self.kind(), self.default_text(), self.range_text(), self.doc)
        yield from self._child_rows(path)

    def _child_rows(self, path):
        return iter(())

    def _walk(self):
        yield self
        for sub in self._subfields():
            yield from sub._walk()

    def __repr__(self):
        return f'{type(self).__name__}({self.kind()!r}, default={self.default!r})'


class Quantity(Field):
    """A physical quantity, converted to SI.

    Parameters
    ----------
    dimension : str
        A key of :data:`impact_damper_sim.scene.units.UNITS` (``'length'``, ``'stiffness'``, ...).
    default : object, optional
        Raw default (``'2.5 mil'``, ``0.0``, ``{value: 25, unit: lb}``), ``REQUIRED`` or ``None``.
    min, max : float or str, optional
        Bounds, as SI numbers or quantity strings (``'1e-8 m'``, ``'1 cm'``).
    min_inclusive, max_inclusive : bool, optional
        Whether the bounds themselves are allowed.
    doc : str, optional
        Description.
    unit : str, optional
        Unit the default is shown in by :func:`describe`; by default the default's own
        unit, else SI.
    """

    def __init__(self, dimension, default=REQUIRED, min=None, max=None, min_inclusive=True,
                 max_inclusive=True, doc='', unit=None):
        super().__init__(default, doc)
        if dimension not in UNITS:
            raise ValueError(f'unknown dimension {dimension!r}; known: {", ".join(UNITS)}')
        self.dimension = dimension
        self.min = None if min is None else self._schema_value(min, 'min')[0]
        self.max = None if max is None else self._schema_value(max, 'max')[0]
        self.min_inclusive = bool(min_inclusive)
        self.max_inclusive = bool(max_inclusive)
        if self.min is not None and self.max is not None and self.min > self.max:
            raise ValueError(f'min {self.min} > max {self.max} for {dimension}')
        if unit is None and default is not REQUIRED and default is not None:
            unit = self._schema_value(default, 'default')[2]
        self.unit = unit if unit is not None else SI_UNIT[dimension]
        if self.unit not in UNITS[dimension]:
            raise ValueError(f'display unit {self.unit!r} is not a {dimension}')
        self._check_default()

    def _schema_value(self, value, what):
        try:
            return _parse(value, self.dimension)
        except UnitError as exc:
            raise ValueError(
                f'invalid {what} {value!r} for {self.dimension}: {exc.reason}') from None

    def kind(self):
        return self.dimension

    def si_unit(self):
        """Return the SI unit of this quantity (str, '' if dimensionless)."""
        return SI_UNIT[self.dimension]

    def range_text(self):
        rng = _interval(self.min, self.max, self.min_inclusive, self.max_inclusive)
        return f'{rng} {self.si_unit()}'.rstrip() if rng else ''

    def expects(self):
        units = ', '.join(u or '(no unit)' for u in allowed_units(self.dimension))
        return f'{super().expects()} (units: {units})'

    def default_text(self):
        if self.default is REQUIRED or self.default is None:
            return super().default_text()
        si = _parse(self.default, self.dimension)[0]
        return format_quantity(si, self.unit, dimension=self.dimension, digits=12)

    def _convert(self, raw, path, errors):
        try:
            si, number, unit = _parse(raw, self.dimension)
        except UnitError as exc:
            errors.add(path, exc.reason)
            return _INVALID
        if _outside(si, self.min, self.max, self.min_inclusive, self.max_inclusive):
            errors.add(path, self._range_problem(si, number, unit))
            return _INVALID
        return si

    def _range_problem(self, si, number, unit):
        si_unit = self.si_unit()
        shown = f'{_num(si)} {si_unit}'.rstrip()
        extra = ''
        if unit is not None and unit != si_unit:
            # Echo the user's own unit so the number they wrote is recognisable.
            shown = f'{_num(number)} {unit} = {shown}'
            factor = UNITS[self.dimension][unit]
            rng = _interval(self.min, self.max, self.min_inclusive, self.max_inclusive,
                            fmt=lambda v: f'{v / factor:.6g}')
            extra = f' (= {rng} {unit})'
        return f'{shown} is out of range {self.range_text()}{extra}'


class Integer(Field):
    """An integer (YAML int; floats and booleans are rejected).

    Parameters
    ----------
    default : int or None or REQUIRED, optional
        Default value (dimensionless).
    min, max : int, optional
        Inclusive bounds (dimensionless).
    doc : str, optional
        Description.
    """

    def __init__(self, default=REQUIRED, min=None, max=None, doc=''):
        super().__init__(default, doc)
        self.min, self.max = min, max
        self._check_default()

    def kind(self):
        return 'integer'

    def range_text(self):
        return _interval(self.min, self.max, True, True, fmt=str)

    def _convert(self, raw, path, errors):
        if isinstance(raw, bool) or not isinstance(raw, int):
            errors.add(path, f'expected an integer, {_got(raw)}')
            return _INVALID
        if _outside(raw, self.min, self.max, True, True):
            errors.add(path, f'{raw} is out of range {self.range_text()}')
            return _INVALID
        return int(raw)


class Boolean(Field):
    """A YAML boolean (``true``/``false``); numbers and strings are rejected."""

    def __init__(self, default=REQUIRED, doc=''):
        super().__init__(default, doc)
        self._check_default()

    def kind(self):
        return 'boolean'

    def range_text(self):
        return 'true | false'

    def _convert(self, raw, path, errors):
        if not isinstance(raw, bool):
            errors.add(path, f'expected true or false, {_got(raw)}')
            return _INVALID
        return raw


class Choice(Field):
    """One of a fixed set of options (compared by type and value; case-sensitive).

    Parameters
    ----------
    options : sequence
        Allowed values, usually strings.
    default : object, optional
        One of ``options``, ``REQUIRED`` or ``None``.
    doc : str, optional
        Description.
    """

    def __init__(self, options, default=REQUIRED, doc=''):
        super().__init__(default, doc)
        self.options = tuple(options)
        if not self.options:
            raise ValueError('Choice needs at least one option')
        self._check_default()

    def kind(self):
        return 'choice'

    def range_text(self):
        return ' | '.join(_yaml_text(o) for o in self.options)

    def _convert(self, raw, path, errors):
        # type check too: True == 1 in Python, but 'true' is not the option 1.
        if any(type(raw) is type(o) and raw == o for o in self.options):
            return raw
        names = [o for o in self.options if isinstance(o, str)]
        close = difflib.get_close_matches(raw, names, n=1) if isinstance(raw, str) else []
        hint = f"did you mean '{close[0]}'? " if close else ''
        errors.add(path, f'{_describe(raw)} is not allowed; {hint}use one of {self.range_text()}')
        return _INVALID


class String(Field):
    """A string, optionally matching a regular expression.

    Parameters
    ----------
    default : str or None or REQUIRED, optional
        Default value.
    doc : str, optional
        Description.
    pattern : str, optional
        Regular expression the whole string must match.
    allow_empty : bool, optional
        Whether ``''`` is accepted.
    """

    def __init__(self, default=REQUIRED, doc='', pattern=None, allow_empty=False):
        super().__init__(default, doc)
        self.pattern = pattern
        self._regex = re.compile(pattern) if pattern is not None else None
        self.allow_empty = allow_empty
        self._check_default()

    def kind(self):
        return 'string'

    def range_text(self):
        return f'matches {self.pattern}' if self.pattern else ''

    def _convert(self, raw, path, errors):
        if not isinstance(raw, str):
            errors.add(path, f'expected a string, {_got(raw)}')
        elif not raw and not self.allow_empty:
            errors.add(path, 'must not be an empty string')
        elif self._regex is not None and not self._regex.fullmatch(raw):
            errors.add(path, f'{raw!r} does not match {self.pattern}')
        else:
            return raw
        return _INVALID


class Section(Field):
    """A mapping with a fixed set of keys.

    An absent section is read as ``{}``, so its keys take their defaults (and missing
    required keys inside it are reported). Wrap it in :class:`Optional` to make the whole
    section ``None`` when absent.

    Parameters
    ----------
    fields : dict of str to Field
        The keys, in the order they are validated and returned.
    doc : str, optional
        Description.
    checks : sequence of callable, optional
        Cross-key checks ``check(values) -> None | str | iterable of str`` run on the
        converted (SI) dict, only when every key of the section was valid. Each returned
        string is reported as an error of this section.
    """

    def __init__(self, fields, doc='', checks=()):
        super().__init__({}, doc)
        for name, field in fields.items():
            if not isinstance(name, str) or not isinstance(field, Field):
                raise TypeError(f'Section fields must map str to Field; got {name!r}: {field!r}')
        self.fields = dict(fields)
        self.checks = tuple(checks)

    def kind(self):
        return 'section'

    def default_text(self):
        return ''

    def _subfields(self):
        return tuple(self.fields.values())

    def _convert(self, raw, path, errors):
        if not isinstance(raw, dict):
            errors.add(path, f'expected a mapping with keys {", ".join(self.fields)}; {_got(raw)}')
            return _INVALID
        before = len(errors)
        for key in raw:
            if key not in self.fields:
                errors.add(_join(path, key), self._unknown(key))
        out = {}
        for name, field in self.fields.items():
            out[name] = field.resolve(name in raw, raw.get(name), _join(path, name), errors)
        if len(errors) == before:
            for check in self.checks:
                found = check(out)
                for message in ([found] if isinstance(found, str) else (found or ())):
                    errors.add(path, message)
        return out

    def _unknown(self, key):
        known = list(self.fields)
        close = difflib.get_close_matches(str(key), known, n=1, cutoff=0.6)
        hint = f"; did you mean '{close[0]}'?" if close else ''
        return f'unknown key{hint} (known keys here: {", ".join(known)})'

    def _child_rows(self, path):
        for name, field in self.fields.items():
            yield from field._rows(_join(path, name))


def _item_rows(item, path):
    # A list/map of sections lists the section's keys; of scalars, one row for the item.
    inner = item.field if isinstance(item, Optional) else item
    if isinstance(inner, Section):
        return item._child_rows(path)
    rows = list(item._rows(path))
    # An item exists only when written, so its own default means nothing here.
    return [rows[0]._replace(default='')] + rows[1:]


def _count_text(lo, hi):
    if hi is None:
        return f'>= {lo} items' if lo else ''
    return f'{lo}..{hi} items'


class ListOf(Field):
    """A YAML list whose items all follow one field.

    Parameters
    ----------
    item : Field
        Schema of each item (a :class:`Section`, :class:`Quantity`, ...).
    min_len, max_len : int, optional
        Allowed number of items.
    default : list or None or REQUIRED, optional
        Raw default list.
    doc : str, optional
        Description.
    """

    def __init__(self, item, min_len=0, max_len=None, default=REQUIRED, doc=''):
        super().__init__(default, doc)
        self.item = item
        self.min_len, self.max_len = min_len, max_len
        self._check_default()

    def kind(self):
        return f'list of {self.item.kind()}'

    def range_text(self):
        return _count_text(self.min_len, self.max_len)

    def _subfields(self):
        return (self.item,)

    def _convert(self, raw, path, errors):
        if not isinstance(raw, list):
            errors.add(path, f'expected a list of {self.item.kind()}, {_got(raw)}')
            return _INVALID
        if len(raw) < self.min_len or (self.max_len is not None and len(raw) > self.max_len):
            errors.add(path, f'has {len(raw)} items; expected {self.range_text()}')
        return [self.item.resolve(True, v, f'{path}[{i}]', errors) for i, v in enumerate(raw)]

    def _child_rows(self, path):
        return _item_rows(self.item, f'{path}[]')


class Vector(Field):
    """A fixed-length list of quantities of one dimension (e.g. xyz coordinates).

    Accepts ``[1, 2, 3]`` (SI), ``['1 in', '2 in', 0]`` or ``{value: [1, 2, 3], unit: in}``.

    Parameters
    ----------
    dimension : str
        Dimension of every component.
    length : int
        Number of components.
    default : object, optional
        Raw default, ``REQUIRED`` or ``None``.
    min, max : float or str, optional
        Bounds applied to each component (SI numbers or quantity strings).
    doc : str, optional
        Description.
    unit : str, optional
        Unit the default is shown in by :func:`describe`.
    """

    def __init__(self, dimension, length, default=REQUIRED, min=None, max=None, doc='',
                 unit=None):
        super().__init__(default, doc)
        self.component = Quantity(dimension, min=min, max=max, unit=unit)
        self.dimension = dimension
        self.length = int(length)
        self.unit = unit
        self._check_default()

    def kind(self):
        return f'{self.length}-vector of {self.dimension}'

    def range_text(self):
        return self.component.range_text()

    def expects(self):
        return f'{super().expects()} (units: {", ".join(allowed_units(self.dimension))})'

    def default_text(self):
        if self.default is REQUIRED or self.default is None:
            return super().default_text()
        values = self._convert(copy.deepcopy(self.default), '', _Errors())
        unit = self.unit or SI_UNIT[self.dimension]
        factor = UNITS[self.dimension][unit]
        return f'[{", ".join(f"{v / factor:.12g}" for v in values)}] {unit}'.rstrip()

    def _convert(self, raw, path, errors):
        items = raw
        if isinstance(raw, dict):
            if set(raw) != {'value', 'unit'} or not isinstance(raw['value'], list):
                errors.add(path, 'a vector mapping must be {value: [...], unit: ...}; '
                           + _got(raw))
                return _INVALID
            items = [{'value': v, 'unit': raw['unit']} for v in raw['value']]
        if not isinstance(items, list):
            errors.add(path, f'expected {self.expects()}, {_got(raw)}')
            return _INVALID
        if len(items) != self.length:
            errors.add(path, f'has {len(items)} components; expected {self.length}')
            return _INVALID
        return [self.component.resolve(True, v, f'{path}[{i}]', errors)
                for i, v in enumerate(items)]


class MapOf(Field):
    """A mapping with free keys of one scalar field and values of another.

    Example: per-mode damping overrides ``{3: 0.0288, 5: '2 %'}`` is
    ``MapOf(Integer(min=1), Quantity('dimensionless', min=0, max=1), default={})``.

    Parameters
    ----------
    key : Integer or String or Choice
        Schema of the keys (no unit conversion is applied to keys).
    value : Field
        Schema of the values.
    min_len, max_len : int, optional
        Allowed number of entries.
    default : dict or None or REQUIRED, optional
        Raw default mapping.
    doc : str, optional
        Description.
    """

    def __init__(self, key, value, min_len=0, max_len=None, default=REQUIRED, doc=''):
        super().__init__(default, doc)
        if not isinstance(key, (Integer, String, Choice)):
            raise TypeError('MapOf keys must be Integer, String or Choice fields')
        self.key, self.value = key, value
        self.min_len, self.max_len = min_len, max_len
        self._check_default()

    def kind(self):
        return f'map of {self.key.kind()} to {self.value.kind()}'

    def range_text(self):
        parts = [f'keys {self.key.range_text()}' if self.key.range_text() else '',
                 _count_text(self.min_len, self.max_len).replace('items', 'entries')]
        return '; '.join(p for p in parts if p)

    def _subfields(self):
        return (self.key, self.value)

    def _convert(self, raw, path, errors):
        if not isinstance(raw, dict):
            errors.add(path, f'expected a mapping ({self.kind()}), {_got(raw)}')
            return _INVALID
        if len(raw) < self.min_len or (self.max_len is not None and len(raw) > self.max_len):
            errors.add(path, f'has {len(raw)} entries; expected {self.range_text()}')
        out = {}
        for k, v in raw.items():
            sub = _join(path, k)
            key_errors = _Errors()
            ck = self.key._convert(k, sub, key_errors)
            for _, message in key_errors.items:
                errors.add(sub, f'invalid key: {message}')
            value = self.value.resolve(True, v, sub, errors)
            if ck is not _INVALID:
                out[ck] = value
        return out

    def _child_rows(self, path):
        return _item_rows(self.value, f'{path}.<{self.key.kind()}>')


class Optional(Field):
    """Make any field optional: absent or null gives ``None``.

    Parameters
    ----------
    field : Field
        The wrapped field; its own default is ignored.
    doc : str, optional
        Description (defaults to the wrapped field's).
    """

    def __init__(self, field, doc=None):
        super().__init__(None, field.doc if doc is None else doc)
        self.field = field

    def kind(self):
        return self.field.kind()

    def range_text(self):
        return self.field.range_text()

    def expects(self):
        return self.field.expects()

    def _subfields(self):
        return (self.field,)

    def _convert(self, raw, path, errors):
        return self.field._convert(raw, path, errors)

    def _child_rows(self, path):
        return self.field._child_rows(path)


# --- validation ------------------------------------------------------------------------------

def validate(schema, raw, *, source=None):
    """Validate a raw scene and return it with defaults applied and units converted to SI.

    Parameters
    ----------
    schema : Field
        Usually a :class:`Section`.
    raw : dict
        Scene as loaded from YAML (see :func:`load_yaml`), possibly after
        :func:`apply_overrides`. Not modified.
    source : str, optional
        Scene origin (file name) for the error header.

    Returns
    -------
    dict
        Fresh plain tree; every physical value is an SI float.

    Raises
    ------
    SceneError
        With every problem found, one per line.
    """
    errors = _Errors()
    value = schema.resolve(True, raw, '', errors)
    if errors:
        raise SceneError(errors.lines(), source=source)
    return value


# --- overrides -------------------------------------------------------------------------------

_NAME_RE = re.compile(r'\s*([^.\[\]\s][^.\[\]]*?)\s*')
_INDEX_RE = re.compile(r'\[\s*(\d+)\s*\]')


def _override_tokens(path):
    """Split ``'a.b[2].c'`` / ``'a.b.2.c'`` into ``[('name', 'a'), ..., ('index', 2), ...]``."""
    tokens, pos = [], 0
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


def _end_of_name(path, pos):
    stops = [i for i in (path.find('.', pos), path.find('[', pos)) if i >= 0]
    return min(stops) if stops else len(path)


def _parse_yaml_value(text):
    return yaml.load(text, Loader=_StrictLoader) if text.strip() else None


def apply_overrides(raw, overrides):
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
        schema does not know is reported by :func:`validate`, with its name.

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
    problems = []
    for text in overrides:
        try:
            _apply_one(data, text)
        except SceneError as exc:
            problems.extend(exc.errors)
    if problems:
        raise SceneError(problems)
    return data


def _apply_one(data, text):
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


# --- documentation ---------------------------------------------------------------------------

def describe(schema):
    """List every scene key the schema accepts, for docs and a ``study keys`` command.

    Parameters
    ----------
    schema : Field
        Usually the top-level :class:`Section`.

    Returns
    -------
    list of KeyInfo
        ``(key, kind, default, range, doc)`` rows, in schema order. ``[]`` in a key stands
        for any list index, ``<integer>``/``<string>`` for a map key. Quantity ranges are
        in SI units.
    """
    rows = schema._child_rows('') if isinstance(schema, Section) else schema._rows('')
    return list(rows)


def _md(text):
    return str(text).replace('|', '\\|').replace('\n', ' ')


def markdown_table(schema, *, units=True):
    """Return a Markdown table of the scene keys (and, optionally, the accepted units).

    Parameters
    ----------
    schema : Field
        Usually the top-level :class:`Section`.
    units : bool, optional
        Append a second table with the accepted units of every dimension used.

    Returns
    -------
    str
        Markdown text ending in a newline.
    """
    lines = ['| Key | Type | Default | Range | Description |', '|---|---|---|---|---|']
    for row in describe(schema):
        default = f'`{_md(row.default)}`' if row.default else ''
        lines.append(f'| `{_md(row.key)}` | {_md(row.kind)} | {default} | {_md(row.range)} '
                     f'| {_md(row.doc)} |')
    if units:
        used = []
        for field in schema._walk():
            dim = getattr(field, 'dimension', None)
            if dim is not None and dim not in used:
                used.append(dim)
        if used:
            lines += ['', '| Dimension | SI unit | Accepted units |', '|---|---|---|']
            for dim in used:
                accepted = ', '.join(f'`{_md(u)}`' for u in allowed_units(dim) if u)
                lines.append(f'| {dim} | {_md(SI_UNIT[dim]) or "(none)"} | {accepted} |')
    return '\n'.join(lines) + '\n'


# --- YAML loading ----------------------------------------------------------------------------

#: What a typed tag's value must look like, for the message when its constructor cannot
#: convert it (``dof: !!int uy``)
_TAG_EXPECTS = {'int': 'an integer', 'float': 'a number', 'bool': 'true or false',
                'timestamp': 'a date or time, e.g. 2024-01-31 or 2024-01-31T12:00:00Z',
                'null': 'null or ~', 'binary': 'base64 text'}


class _StrictLoader(yaml.SafeLoader):
    """SafeLoader that rejects duplicate keys, reads ``1e-3`` as a float (YAML 1.2) and
    reports a tagged value it cannot convert as a YAML error, with its line and column."""

    def construct_object(self, node, deep=False):
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

    def construct_mapping(self, node, deep=False):
        if isinstance(node, yaml.MappingNode):
            seen = {}
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


def _check_budget(root, source):
    """Refuse a composed YAML node graph deeper than :data:`MAX_SCENE_DEPTH`, with more than
    :data:`MAX_SCENE_VALUES` values when its aliases are expanded, or with a recursive alias.

    Each node is visited once (sizes and depths memoised by node), so a bomb costs its
    size in text, not its expansion.
    """
    sizes, depths, active = {}, {}, set()
    stack = [(root, False)]
    while stack:
        node, done = stack.pop()
        key = id(node)
        children = []
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


def _is_path(path_or_text):
    # A one-line string naming a .yaml file is a path; anything else is YAML text.
    return isinstance(path_or_text, os.PathLike) or (
        isinstance(path_or_text, str) and '\n' not in path_or_text
        and path_or_text.strip().endswith(('.yaml', '.yml')))


def file_kind(path):
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


def _reader_problem(text, exc):
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


def load_yaml(path_or_text, *, source=None):
    """Read a scene file or YAML text into a raw mapping (no validation).

    Parameters
    ----------
    path_or_text : str or os.PathLike
        A path (``pathlib.Path``, or a one-line string ending in ``.yaml``/``.yml``) or the
        YAML text itself.
    source : str, optional
        Name used in messages (default: the path, or ``'<text>'``).

    Returns
    -------
    dict
        The top-level mapping.

    Raises
    ------
    SceneError
        For a missing file, one that is not a regular file, over :data:`MAX_SCENE_BYTES` or
        not UTF-8 text, a YAML syntax error (with line and column), a duplicate key, values
        nested or aliased over the budgets (:func:`_check_budget`), or a top level that is
        not a mapping.
    """
    if _is_path(path_or_text):
        path = os.fspath(path_or_text)
        source = source or path
        try:
            kind = file_kind(path)   # before opening: opening a FIFO blocks
            if kind:
                raise SceneError(f'{source}: not a scene file ({kind}, not a regular file)')
            with open(path, 'rb') as stream:
                kind = file_kind(stream.fileno())   # replaced in between
                if kind:
                    raise SceneError(f'{source}: not a scene file ({kind}, not a regular file)')
                raw = stream.read(MAX_SCENE_BYTES + 1)   # never more, whatever the file
        except OSError as exc:
            raise SceneError(f'{source}: cannot read scene file: {exc.strerror}') from None
        if len(raw) > MAX_SCENE_BYTES:
            raise SceneError(f'{source}: not a scene file (over {MAX_SCENE_BYTES} bytes; '
                             'scenes are a few kilobytes)')
        try:
            text = raw.decode('utf-8')
        except UnicodeDecodeError:
            raise SceneError(f'{source}: not a scene file (not UTF-8 text)') from None
    else:
        text, source = path_or_text, source or '<text>'
        if len(text) > MAX_SCENE_BYTES:
            raise SceneError(f'{source}: over {MAX_SCENE_BYTES} characters of scene text')
    try:
        loader = _StrictLoader(text)   # checks every character: may raise ReaderError
    except yaml.reader.ReaderError as exc:
        raise SceneError(f'{source}: YAML error: {_reader_problem(text, exc)}') from None
    try:
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
        raise SceneError(f'{source}: a scene must be a mapping at top level; got {got}')
    return data


def load_scene(schema, path_or_text, overrides=(), *, source=None):
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
