"""Units for study output: show a swept value in the unit the user gave it in.

A user who sweeps ``impactors.0.clearance=2 mil,6.9 mil`` or maps ``--kcc '8500 lb/in'``
reads plots and results in mil and lb/in; everything is computed in SI. These helpers find
the scene key's dimension (from the schema) and the unit of the values as written.
"""
from __future__ import annotations

import re

# a list index, or the sweep's '*' (every element)
_INDEX_RE = re.compile(r'\.(\d+|\*)(?=\.|$)|\[(\d+|\*)\]')


def key_dimension(key):
    """Dimension of a scene key (``'length'``, ``'stiffness'``, ...) or None.

    Parameters
    ----------
    key : str
        Dotted scene key, list indices as ``.0``, ``[0]`` or ``*``.
    """
    from ..scene.keytable import describe
    from ..scene.spec import SCHEMA
    from ..scene.units import SI_UNIT
    pattern = _INDEX_RE.sub('[]', key)
    for row in describe(SCHEMA):
        if row.key == pattern:
            return row.kind if row.kind in SI_UNIT else None
    return None


def given_unit(texts, dimension):
    """The unit shared by every value as written, or None (plain numbers or mixed units).

    Parameters
    ----------
    texts : sequence of str
        Values as given, e.g. ``['2 mil', '6.9 mil']``.
    dimension : str
        Their dimension.
    """
    from ..scene.units import SI_UNIT, UnitError, parse_quantity
    units = set()
    for text in texts:
        m = re.match(r'^\s*[-+]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?\s*(.*?)\s*$',
                     str(text))
        if not m:
            return None
        unit = m.group(1) or SI_UNIT.get(dimension, '')
        try:
            parse_quantity(f'1 {unit}' if unit else '1', dimension)
        except (UnitError, ValueError, KeyError):
            return None
        units.add(unit)
    return units.pop() if len(units) == 1 else None


def axis_unit(key, texts):
    """``(unit, factor)`` to show values of ``key``: SI value / factor is in ``unit``.

    The unit the values were written in if they share one, else the key's SI unit, else
    ``('', 1.0)`` (dimensionless or unknown key).
    """
    from ..scene.units import SI_UNIT, to_unit
    dim = key_dimension(key)
    if dim is None:
        return '', 1.0
    unit = given_unit(texts, dim) or SI_UNIT[dim]
    try:
        return unit, 1.0 / to_unit(1.0, unit, dimension=dim) if unit else 1.0
    except (ValueError, KeyError):
        return SI_UNIT[dim], 1.0


__all__ = ['axis_unit', 'given_unit', 'key_dimension']
