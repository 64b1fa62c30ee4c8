"""The scene keys a schema accepts, as rows (:func:`describe`, read by ``study keys``) and as the
Markdown table of docs/scenes.md (:func:`markdown_table`, written by ``tools/generated_docs.py
keys``). It only reads a built schema, never a scene, so it is apart from validation.
"""
from __future__ import annotations

from .containers import Section
from .schema import Field, KeyInfo
from .units import SI_UNIT, allowed_units

__all__ = ['describe', 'markdown_table']


def describe(schema: Field) -> list[KeyInfo]:
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


def _md(text: object) -> str:
    return str(text).replace('|', '\\|').replace('\n', ' ')


def markdown_table(schema: Field, *, units: bool = True) -> str:
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
