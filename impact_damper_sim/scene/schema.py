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
:class:`~.containers.Section` key appears in its dict, in schema order; absent optional keys
are ``None``. :class:`~.containers.Vector` values are lists of floats.

Modules
-------
The engine is split by job: this module holds :class:`SceneError`, the :class:`Field` base,
the leaf fields (:class:`Quantity`, :class:`Integer`, :class:`Boolean`, :class:`Choice`,
:class:`String`) and :func:`validate`; :mod:`.containers` the fields that hold other fields
(:class:`~.containers.Section`, :class:`~.containers.ListOf`, :class:`~.containers.Vector`,
:class:`~.containers.MapOf`, :class:`~.containers.Optional`); :mod:`.loading` reading YAML
under budgets, ``key=value`` overrides and :func:`~.loading.load_scene`; :mod:`.keytable`
the key rows and Markdown table. :mod:`.spec` is the scene schema itself.
"""
from __future__ import annotations

import copy
import difflib
import re
import reprlib
from collections.abc import Callable, Iterable, Iterator
from typing import Any, NamedTuple

import yaml

from .units import SI_UNIT, UNITS, UnitError, _parse, allowed_units, format_quantity

__all__ = [
    'REQUIRED', 'SceneError', 'Field', 'Quantity', 'Integer', 'Boolean', 'Choice', 'String',
    'KeyInfo', 'validate',
]


class _Required:
    """Sentinel: the key has no default and must be given."""

    def __repr__(self) -> str:
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

    def __init__(self, errors: str | Iterable[str], source: str | None = None) -> None:
        self.errors = (errors,) if isinstance(errors, str) else tuple(errors)
        self.source = source
        lines = list(self.errors)
        if source is not None and len(lines) > 1:
            lines.insert(0, f'invalid scene {source} ({len(lines)} errors):')
        elif source is not None:
            lines[0] = f'{source}: {lines[0]}'
        super().__init__('\n'.join(lines))


class _Errors:
    """Collects ``(path, message)`` pairs so that every problem of a scene is reported at
    once: the schema's, the structure's and the model's (:mod:`.structure`, :mod:`.modes`,
    :mod:`.build`), one ``scene key 'path': message`` line each."""

    def __init__(self) -> None:
        self.items: list[tuple[str, str]] = []

    def add(self, path: str, message: str) -> None:
        """Record ``message`` for the scene key ``path`` (``''``: the scene as a whole)."""
        self.items.append((path, message))

    def __len__(self) -> int:
        return len(self.items)

    def lines(self) -> list[str]:
        """The problems, one line each, in the order found (list of str)."""
        return [f"scene key '{p}': {m}" if p else f'scene: {m}' for p, m in self.items]

    def call(self, path: str, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
        """Return ``fn(*args, **kwargs)``; a ValueError, KeyError or TypeError becomes a
        problem of ``path`` instead, and the result ``None``."""
        try:
            return fn(*args, **kwargs)
        except (ValueError, KeyError, TypeError) as exc:
            self.add(path, exc.args[0] if exc.args else str(exc))
            return None

    def raise_if_any(self, source: str | None = None) -> None:
        """Raise :class:`SceneError` with every problem so far, if there is one."""
        if self.items:
            raise SceneError(self.lines(), source=source)


def _join(path: str, key: object) -> str:
    return f'{path}.{key}' if path else str(key)


def _num(x: float) -> str:
    return f'{x:.12g}'


_REPR = reprlib.Repr()
_REPR.maxlevel, _REPR.maxstring, _REPR.maxother = 3, 50, 50
_REPR.maxlist = _REPR.maxtuple = _REPR.maxdict = _REPR.maxset = 6


def _describe(value: object) -> str:
    # bounded: a huge or aliased value (a YAML alias bomb) is never printed whole
    text = _REPR.repr(value)
    return text if len(text) <= 60 else text[:57] + '...'


def _got(value: object) -> str:
    return f'got {type(value).__name__} {_describe(value)}'


def _article(word: str) -> str:
    return ('an ' if word[:1] in 'aeiou' else 'a ') + word


def _interval(lo: float | None, hi: float | None, lo_inc: bool, hi_inc: bool,
              fmt: Callable[[float], str] = _num) -> str:
    if lo is None and hi is None:
        return ''
    # An absent bound is open: infinity itself is never a valid value.
    left = ('[' + fmt(lo) if lo_inc else '(' + fmt(lo)) if lo is not None else '(-inf'
    right = (fmt(hi) + ']' if hi_inc else fmt(hi) + ')') if hi is not None else 'inf)'
    return f'{left}, {right}'


def _outside(x: float, lo: float | None, hi: float | None, lo_inc: bool, hi_inc: bool
             ) -> bool:
    if lo is not None and (x < lo or (x == lo and not lo_inc)):
        return True
    return hi is not None and (x > hi or (x == hi and not hi_inc))


def _yaml_text(value: object) -> str:
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, (list, dict)):
        return yaml.safe_dump(value, default_flow_style=True, sort_keys=False).strip()
    return str(value)


class KeyInfo(NamedTuple):
    """One row of :func:`~.keytable.describe`: a scene key and what it accepts."""

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
        One-line description for :func:`~.keytable.describe`.
    """

    def __init__(self, default: object = REQUIRED, doc: str = '') -> None:
        self.default = default
        self.doc = doc

    # -- to be provided by subclasses --------------------------------------------------------
    def _convert(self, raw: object, path: str, errors: _Errors) -> object:
        raise NotImplementedError

    def kind(self) -> str:
        """Return the type or dimension name shown to users (str)."""
        raise NotImplementedError

    def range_text(self) -> str:
        """Return the allowed range or options as text ('' if unrestricted)."""
        return ''

    def _subfields(self) -> tuple[Field, ...]:
        return ()

    # -- shared machinery ---------------------------------------------------------------------
    def expects(self) -> str:
        """Return what this field accepts, for error messages (str)."""
        rng = self.range_text()
        return _article(self.kind()) + (f' in {rng}' if rng else '')

    def default_text(self) -> str:
        """Return the default as text for :func:`~.keytable.describe`."""
        if self.default is REQUIRED:
            return 'required'
        if self.default is None:
            return 'none'
        return _yaml_text(self.default)

    def _check_default(self) -> None:
        # Fail when the schema is built, not when a user's scene happens to omit the key.
        if self.default is REQUIRED or self.default is None:
            return
        errors = _Errors()
        self._convert(copy.deepcopy(self.default), '', errors)
        if errors:
            problems = '; '.join(m for _, m in errors.items)
            raise ValueError(f'invalid default {self.default!r} for {self.kind()}: {problems}')

    def resolve(self, present: bool, raw: object, path: str, errors: _Errors) -> Any:

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

    def _rows(self, path: str) -> Iterator[KeyInfo]:
        yield KeyInfo(path, self.kind(), self.default_text(), self.range_text(), self.doc)
        yield from self._child_rows(path)

    def _child_rows(self, path: str) -> Iterable[KeyInfo]:
        return iter(())

    def _walk(self) -> Iterator[Field]:
        yield self
        for sub in self._subfields():
            yield from sub._walk()

    def __repr__(self) -> str:
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
        Unit the default is shown in by :func:`~.keytable.describe`; by default the default's own
        unit, else SI.
    """

    def __init__(self, dimension: str, default: object = REQUIRED,
                 min: float | str | None = None, max: float | str | None = None,
                 min_inclusive: bool = True, max_inclusive: bool = True, doc: str = '',
                 unit: str | None = None) -> None:
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

    def _schema_value(self, value: object, what: str) -> tuple[float, float, str | None]:
        try:
            return _parse(value, self.dimension)
        except UnitError as exc:
            raise ValueError(
                f'invalid {what} {value!r} for {self.dimension}: {exc.reason}') from None

    def kind(self) -> str:
        return self.dimension

    def si_unit(self) -> str:
        """Return the SI unit of this quantity (str, '' if dimensionless)."""
        return SI_UNIT[self.dimension]

    def range_text(self) -> str:
        rng = _interval(self.min, self.max, self.min_inclusive, self.max_inclusive)
        return f'{rng} {self.si_unit()}'.rstrip() if rng else ''

    def expects(self) -> str:
        units = ', '.join(u or '(no unit)' for u in allowed_units(self.dimension))
        return f'{super().expects()} (units: {units})'

    def default_text(self) -> str:
        if self.default is REQUIRED or self.default is None:
            return super().default_text()
        si = _parse(self.default, self.dimension)[0]
        return format_quantity(si, self.unit, dimension=self.dimension, digits=12)

    def _convert(self, raw: object, path: str, errors: _Errors) -> object:
        try:
            si, number, unit = _parse(raw, self.dimension)
        except UnitError as exc:
            errors.add(path, exc.reason)
            return _INVALID
        if _outside(si, self.min, self.max, self.min_inclusive, self.max_inclusive):
            errors.add(path, self._range_problem(si, number, unit))
            return _INVALID
        return si

    def _range_problem(self, si: float, number: float, unit: str | None) -> str:
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

    def __init__(self, default: object = REQUIRED, min: int | None = None,
                 max: int | None = None, doc: str = '') -> None:
        super().__init__(default, doc)
        self.min, self.max = min, max
        self._check_default()

    def kind(self) -> str:
        return 'integer'

    def range_text(self) -> str:
        return _interval(self.min, self.max, True, True, fmt=str)

    def _convert(self, raw: object, path: str, errors: _Errors) -> object:

        if isinstance(raw, bool) or not isinstance(raw, int):
            errors.add(path, f'expected an integer, {_got(raw)}')
            return _INVALID
        if _outside(raw, self.min, self.max, True, True):
            errors.add(path, f'{raw} is out of range {self.range_text()}')
            return _INVALID
        return int(raw)


class Boolean(Field):
    """A YAML boolean (``true``/``false``); numbers and strings are rejected."""

    def __init__(self, default: object = REQUIRED, doc: str = '') -> None:
        super().__init__(default, doc)
        self._check_default()

    def kind(self) -> str:
        return 'boolean'

    def range_text(self) -> str:
        return 'true | false'

    def _convert(self, raw: object, path: str, errors: _Errors) -> object:
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

    def __init__(self, options: Iterable[object], default: object = REQUIRED,
                 doc: str = '') -> None:
        super().__init__(default, doc)
        self.options = tuple(options)
        if not self.options:
            raise ValueError('Choice needs at least one option')
        self._check_default()

    def kind(self) -> str:
        return 'choice'

    def range_text(self) -> str:
        return ' | '.join(_yaml_text(o) for o in self.options)

    def _convert(self, raw: object, path: str, errors: _Errors) -> object:
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

    def __init__(self, default: object = REQUIRED, doc: str = '', pattern: str | None = None,
                 allow_empty: bool = False) -> None:
        super().__init__(default, doc)
        self.pattern = pattern
        self._regex = re.compile(pattern) if pattern is not None else None
        self.allow_empty = allow_empty
        self._check_default()

    def kind(self) -> str:
        return 'string'

    def range_text(self) -> str:
        return f'matches {self.pattern}' if self.pattern else ''

    def _convert(self, raw: object, path: str, errors: _Errors) -> object:
        if not isinstance(raw, str):
            errors.add(path, f'expected a string, {_got(raw)}')
        elif not raw and not self.allow_empty:
            errors.add(path, 'must not be an empty string')
        elif self._regex is not None and not self._regex.fullmatch(raw):
            errors.add(path, f'{raw!r} does not match {self.pattern}')
        else:
            return raw
        return _INVALID


# --- validation ------------------------------------------------------------------------------

def validate(schema: Field, raw: object, *, source: str | None = None) -> Any:

    """Validate a raw scene and return it with defaults applied and units converted to SI.

    Parameters
    ----------
    schema : Field
        Usually a :class:`~.containers.Section`.
    raw : dict
        Scene as loaded from YAML (see :func:`~.loading.load_yaml`), possibly after
        :func:`~.loading.apply_overrides`. Not modified.
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
