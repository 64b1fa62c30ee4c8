"""Scene schema fields that hold other fields: :class:`Section` (fixed keys, cross-key
checks), :class:`ListOf`, :class:`Vector` (fixed-length quantities), :class:`MapOf` (free keys)
and :class:`Optional`. They recurse into their children to convert, to report unknown keys and
to list key rows, while the leaf fields and the error collector they build on live in
:mod:`.schema`; kept apart so that each module holds one kind of field.
"""
from __future__ import annotations

import copy
import difflib
from collections.abc import Callable, Iterable, Iterator, Mapping
from typing import Any, cast

from .schema import (
    _INVALID,
    REQUIRED,
    Choice,
    Field,
    Integer,
    KeyInfo,
    Quantity,
    String,
    _Errors,
    _got,
    _join,
)
from .units import SI_UNIT, UNITS, allowed_units

#: A cross-key check of a :class:`Section` on its converted values (SI, of any type per
#: key): no problem (None), one, or several messages
SectionCheck = Callable[[dict[str, Any]], str | Iterable[str] | None]

__all__ = ['Section', 'ListOf', 'Vector', 'MapOf', 'Optional']


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

    def __init__(self, fields: Mapping[str, Field], doc: str = '',
                 checks: Iterable[SectionCheck] = ()) -> None:
        super().__init__({}, doc)
        for name, field in fields.items():
            if not isinstance(name, str) or not isinstance(field, Field):
                raise TypeError(f'Section fields must map str to Field; got {name!r}: {field!r}')
        self.fields = dict(fields)
        self.checks = tuple(checks)

    def kind(self) -> str:
        return 'section'

    def default_text(self) -> str:
        return ''

    def _subfields(self) -> tuple[Field, ...]:
        return tuple(self.fields.values())

    def _convert(self, raw: object, path: str, errors: _Errors) -> object:
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

    def _unknown(self, key: object) -> str:
        known = list(self.fields)
        close = difflib.get_close_matches(str(key), known, n=1, cutoff=0.6)
        hint = f"; did you mean '{close[0]}'?" if close else ''
        return f'unknown key{hint} (known keys here: {", ".join(known)})'

    def _child_rows(self, path: str) -> Iterator[KeyInfo]:
        for name, field in self.fields.items():
            yield from field._rows(_join(path, name))


def _item_rows(item: Field, path: str) -> Iterable[KeyInfo]:
    # A list/map of sections lists the section's keys; of scalars, one row for the item.
    inner = item.field if isinstance(item, Optional) else item
    if isinstance(inner, Section):
        return item._child_rows(path)
    rows = list(item._rows(path))
    # An item exists only when written, so its own default means nothing here.
    return [rows[0]._replace(default='')] + rows[1:]


def _count_text(lo: int, hi: int | None) -> str:
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

    def __init__(self, item: Field, min_len: int = 0, max_len: int | None = None,
                 default: object = REQUIRED, doc: str = '') -> None:
        super().__init__(default, doc)
        self.item = item
        self.min_len, self.max_len = min_len, max_len
        self._check_default()

    def kind(self) -> str:
        return f'list of {self.item.kind()}'

    def range_text(self) -> str:
        return _count_text(self.min_len, self.max_len)

    def _subfields(self) -> tuple[Field, ...]:
        return (self.item,)

    def _convert(self, raw: object, path: str, errors: _Errors) -> object:
        if not isinstance(raw, list):
            errors.add(path, f'expected a list of {self.item.kind()}, {_got(raw)}')
            return _INVALID
        if len(raw) < self.min_len or (self.max_len is not None and len(raw) > self.max_len):
            errors.add(path, f'has {len(raw)} items; expected {self.range_text()}')
        return [self.item.resolve(True, v, f'{path}[{i}]', errors) for i, v in enumerate(raw)]

    def _child_rows(self, path: str) -> Iterable[KeyInfo]:
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
        Unit the default is shown in by :func:`~.keytable.describe`.
    """

    def __init__(self, dimension: str, length: int, default: object = REQUIRED,
                 min: float | str | None = None, max: float | str | None = None, doc: str = '',
                 unit: str | None = None) -> None:
        super().__init__(default, doc)
        self.component = Quantity(dimension, min=min, max=max, unit=unit)
        self.dimension = dimension
        self.length = int(length)
        self.unit = unit
        self._check_default()

    def kind(self) -> str:
        return f'{self.length}-vector of {self.dimension}'

    def range_text(self) -> str:
        return self.component.range_text()

    def expects(self) -> str:
        return f'{super().expects()} (units: {", ".join(allowed_units(self.dimension))})'

    def default_text(self) -> str:
        if self.default is REQUIRED or self.default is None:
            return super().default_text()
        # the default was converted when the field was built: a list of SI numbers
        values = cast(list[float], self._convert(copy.deepcopy(self.default), '', _Errors()))
        unit = self.unit or SI_UNIT[self.dimension]
        factor = UNITS[self.dimension][unit]
        return f'[{", ".join(f"{v / factor:.12g}" for v in values)}] {unit}'.rstrip()

    def _convert(self, raw: object, path: str, errors: _Errors) -> object:
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

    def __init__(self, key: Integer | String | Choice, value: Field, min_len: int = 0,
                 max_len: int | None = None, default: object = REQUIRED,
                 doc: str = '') -> None:
        super().__init__(default, doc)
        if not isinstance(key, (Integer, String, Choice)):
            raise TypeError('MapOf keys must be Integer, String or Choice fields')
        self.key, self.value = key, value
        self.min_len, self.max_len = min_len, max_len
        self._check_default()

    def kind(self) -> str:
        return f'map of {self.key.kind()} to {self.value.kind()}'

    def range_text(self) -> str:
        parts = [f'keys {self.key.range_text()}' if self.key.range_text() else '',
                 _count_text(self.min_len, self.max_len).replace('items', 'entries')]
        return '; '.join(p for p in parts if p)

    def _subfields(self) -> tuple[Field, ...]:
        return (self.key, self.value)

    def _convert(self, raw: object, path: str, errors: _Errors) -> object:
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

    def _child_rows(self, path: str) -> Iterable[KeyInfo]:
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

    def __init__(self, field: Field, doc: str | None = None) -> None:
        super().__init__(None, field.doc if doc is None else doc)
        self.field = field

    def kind(self) -> str:
        return self.field.kind()

    def range_text(self) -> str:
        return self.field.range_text()

    def expects(self) -> str:
        return self.field.expects()

    def _subfields(self) -> tuple[Field, ...]:
        return (self.field,)

    def _convert(self, raw: object, path: str, errors: _Errors) -> object:
        return self.field._convert(raw, path, errors)

    def _child_rows(self, path: str) -> Iterable[KeyInfo]:
        return self.field._child_rows(path)
