"""Engineering units, converted once to SI at the boundary (REP-103).

Everything inside the package is SI (m, kg, s, N, rad). Scene files and command lines may
state engineering units; :func:`parse_quantity` turns them into SI floats, and
:func:`format_quantity` turns SI back into a unit for reports.

Units are looked up in a *table per dimension* (:data:`UNITS`), not derived by algebra, so
the dimension a key expects decides how a spelling is read and every accepted spelling is
listed in error messages. Two consequences are deliberate:

* ``lb`` alone is **pound-mass** (0.45359237 kg) and ``lbf`` is **pound-force**
  (0.45359237 kg x 9.80665 m/s^2). A *weight* given in lb (the paper's ``W = 25 lb``) is
  read as a mass of 25 lbm, the same number. A plain force must be written ``lbf``
  (``'3 lb'`` for a force is rejected), but inside compound units of stiffness, damping
  and density the customary ``lb/in``, ``lb*s/in`` are accepted and mean what they
  mean in US practice (``lb/in`` = ``lbf/in``; ``lb/in^3`` = lbm per cubic inch).
* ``g`` is the **gram** for a mass and the **standard gravity** g0 = 9.80665 m/s^2 for an
  acceleration; the two never meet because the expected dimension picks the table.

All rational factors are computed with :class:`fractions.Fraction` from the exact
definitions (in = 0.0254 m, lb = 0.45359237 kg, g0 = 9.80665 m/s^2) and rounded once, so
each factor is the correctly rounded double of its exact value. The factors involving
pi (rpm, deg) are float products.

A unit string is normalised before lookup: surrounding and operator-adjacent blanks go,
``·``, ``×``, a blank or a hyphen between two unit names mean ``*`` (``'lbf s/in'``,
``'lbf-s/in'``), ``**`` and superscripts mean ``^`` (``'in²'`` = ``'in^2'``); ``µ`` and
``μ`` may stand for ``u``. Case matters (``mm`` is not ``Mm``).

The accelerometer channel (:mod:`.channel_spec`) adds the electrical and noise dimensions:
``voltage`` (V, mV, uV), ``sensitivity`` (V/(m/s^2), mV/(m/s^2), V/g, mV/g: g is g0 here),
``acceleration_density`` (a noise density, (m/s^2)/sqrt(Hz), g, mg or ug over sqrt(Hz)) and
``acceleration_per_sqrt_time`` (a bias random walk or Gauss-Markov driving strength,
(m/s^2)/sqrt(s) = m/s^3/sqrt(Hz), Kalibr's spelling; g, mg, ug over sqrt(s) or sqrt(h)).
``mg`` and ``ug`` are milli- and micro-g0 for an acceleration (``mg`` is the milligram for a
mass). A square root is written ``sqrt(Hz)``; ``√Hz``, ``rtHz``, ``rt(Hz)`` and ``sqrt Hz``
mean the same, and a parenthesised numerator may stand first (``(m/s^2)/sqrt(Hz)``).
"""
from __future__ import annotations

import difflib
import math
import re
from fractions import Fraction
from numbers import Real

__all__ = [
    'G0', 'INCH', 'MIL', 'FOOT', 'POUND_MASS', 'POUND_FORCE', 'PSI', 'UNITS', 'SI_UNIT',
    'UnitError', 'parse_quantity', 'format_quantity', 'to_unit', 'unit_factor',
    'allowed_units', 'dimensions', 'normalize_unit',
]

# --- exact definitions (Fractions; rounded once when the table is built) -------------------
_G0 = Fraction('9.80665')          # standard gravity, m/s^2 (CGPM 1901, exact)
_IN = Fraction('0.0254')           # international inch, m (1959, exact)
_MIL = _IN / 1000                  # thou
_FT = 12 * _IN
_LB = Fraction('0.45359237')       # international avoirdupois pound, kg (1959, exact)
_OZ = _LB / 16
_LBF = _LB * _G0                   # pound-force, N
_KIP = 1000 * _LBF
_PSI = _LBF / _IN ** 2
_MIN = 60
_HOUR = 3600
_MILLI = Fraction(1, 1000)
_MICRO = Fraction(1, 10 ** 6)
_PI = math.pi                      # irrational factors are plain float products

G0 = float(_G0)
"""Standard gravity g0 (m/s^2), exactly 9.80665."""
INCH = float(_IN)
"""One inch in metres (m), exactly 0.0254."""
MIL = float(_MIL)
"""One mil (thou) in metres (m)."""
FOOT = float(_FT)
"""One foot in metres (m)."""
POUND_MASS = float(_LB)
"""One pound-mass in kilograms (kg), exactly 0.45359237."""
POUND_FORCE = float(_LBF)
"""One pound-force in newtons (N): 0.45359237 x 9.80665."""
PSI = float(_PSI)
"""One psi in pascals (Pa): lbf / in^2."""


def _table(*pairs: tuple[str, float | Fraction]) -> dict[str, float]:
    return {name: float(factor) for name, factor in pairs}


_PRESSURE = _table(
    ('Pa', 1), ('kPa', 1000), ('MPa', 10 ** 6), ('GPa', 10 ** 9), ('bar', 10 ** 5),
    ('psi', _PSI), ('ksi', 1000 * _PSI), ('Msi', 10 ** 6 * _PSI),
)

#: Factor to SI for every accepted unit spelling, per dimension. The first unit of each
#: table is the SI unit ('' is "no unit" for dimensionless).
UNITS: dict[str, dict[str, float]] = {
    'dimensionless': _table(('', 1), ('%', Fraction(1, 100))),
    'length': _table(
        ('m', 1), ('cm', Fraction(1, 100)), ('mm', Fraction(1, 1000)),
        ('um', Fraction(1, 10 ** 6)), ('in', _IN), ('mil', _MIL), ('ft', _FT),
    ),
    'area': _table(
        ('m^2', 1), ('cm^2', Fraction(1, 10 ** 4)), ('mm^2', Fraction(1, 10 ** 6)),
        ('in^2', _IN ** 2), ('ft^2', _FT ** 2),
    ),
    'second_moment': _table(   # second moment of area (area moment of inertia)
        ('m^4', 1), ('cm^4', Fraction(1, 10 ** 8)), ('mm^4', Fraction(1, 10 ** 12)),
        ('in^4', _IN ** 4),
    ),
    'mass': _table(
        ('kg', 1), ('g', _MILLI), ('mg', _MICRO), ('lb', _LB), ('lbm', _LB), ('oz', _OZ),
        ('lbf*s^2/in', _LBF / _IN),   # the "slinch" of US rotordynamics codes
    ),
    'mass_moment': _table(     # mass moment of inertia
        ('kg*m^2', 1), ('g*cm^2', Fraction(1, 10 ** 7)), ('lb*in^2', _LB * _IN ** 2),
        ('lbf*in*s^2', _LBF * _IN),
    ),
    'unbalance': _table(       # mass x eccentricity
        ('kg*m', 1), ('g*mm', Fraction(1, 10 ** 6)), ('g*cm', Fraction(1, 10 ** 5)),
        ('oz*in', _OZ * _IN), ('lb*in', _LB * _IN),
    ),
    'density': _table(
        ('kg/m^3', 1), ('g/cm^3', 1000), ('lb/in^3', _LB / _IN ** 3),
        ('lb/ft^3', _LB / _FT ** 3),
    ),
    'time': _table(
        ('s', 1), ('ms', Fraction(1, 1000)), ('us', Fraction(1, 10 ** 6)),
        ('min', _MIN), ('h', _HOUR),
    ),
    # Cycles per second. rad/s is *not* a frequency here: it is an angular_speed, and
    # mixing them is the classic 2*pi error.
    'frequency': _table(('Hz', 1), ('kHz', 1000), ('cpm', Fraction(1, _MIN))),
    'angular_speed': {'rad/s': 1.0, 'rpm': 2.0 * _PI / 60.0},
    'angular_acceleration': {'rad/s^2': 1.0, 'rpm/s': 2.0 * _PI / 60.0},
    'angle': {'rad': 1.0, 'mrad': 1e-3, 'deg': _PI / 180.0},
    'velocity': _table(
        ('m/s', 1), ('mm/s', Fraction(1, 1000)), ('in/s', _IN), ('ft/s', _FT),
    ),
    'acceleration': _table(
        ('m/s^2', 1), ('mm/s^2', _MILLI), ('g', _G0), ('mg', _MILLI * _G0),
        ('ug', _MICRO * _G0), ('in/s^2', _IN), ('ft/s^2', _FT),
    ),
    # The accelerometer channel (see the module notes). g is standard gravity throughout.
    'voltage': _table(('V', 1), ('mV', _MILLI), ('uV', _MICRO)),
    'sensitivity': _table(     # accelerometer output voltage per acceleration
        ('V/(m/s^2)', 1), ('mV/(m/s^2)', _MILLI), ('V/g', 1 / _G0), ('mV/g', _MILLI / _G0),
    ),
    'acceleration_density': _table(    # amplitude spectral density of acceleration noise
        ('m/s^2/sqrt(Hz)', 1), ('g/sqrt(Hz)', _G0), ('mg/sqrt(Hz)', _MILLI * _G0),
        ('ug/sqrt(Hz)', _MICRO * _G0),
    ),
    'acceleration_per_sqrt_time': _table(   # bias random walk, Gauss-Markov driving strength
        ('m/s^2/sqrt(s)', 1), ('m/s^3/sqrt(Hz)', 1), ('g/sqrt(s)', _G0),
        ('mg/sqrt(s)', _MILLI * _G0), ('ug/sqrt(s)', _MICRO * _G0),
        ('mg/sqrt(h)', _MILLI * _G0 / 60), ('ug/sqrt(h)', _MICRO * _G0 / 60),
    ),
    'force': _table(('N', 1), ('kN', 1000), ('lbf', _LBF), ('kip', _KIP)),
    'moment': _table(
        ('N*m', 1), ('N*mm', Fraction(1, 1000)), ('lbf*in', _LBF * _IN), ('lbf*ft', _LBF * _FT),
    ),
    'stiffness': _table(
        ('N/m', 1), ('N/mm', 1000), ('kN/mm', 10 ** 6), ('MN/m', 10 ** 6),
        ('lbf/in', _LBF / _IN), ('lb/in', _LBF / _IN), ('kip/in', _KIP / _IN),
    ),
    'rotational_stiffness': _table(
        ('N*m/rad', 1), ('lbf*in/rad', _LBF * _IN),
    ),
    'damping': _table(
        ('N*s/m', 1), ('N*s/mm', 1000), ('lbf*s/in', _LBF / _IN), ('lb*s/in', _LBF / _IN),
    ),
    'rotational_damping': _table(
        ('N*m*s/rad', 1), ('lbf*in*s/rad', _LBF * _IN),
    ),
    'pressure': _PRESSURE,
    'modulus': _PRESSURE,      # Young's / shear modulus: same units as pressure
}

#: The SI unit of each dimension ('' for dimensionless).
SI_UNIT = {dim: next(iter(table)) for dim, table in UNITS.items()}

_NUMBER = r'[-+]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?'
_QUANTITY_RE = re.compile(rf'^\s*({_NUMBER})\s*(.*?)\s*$')
_NONFINITE_RE = re.compile(r'^\s*[-+]?\.?(nan|inf|infinity)\b', re.IGNORECASE)
_ROOT_RE = re.compile(r'/\s*(?:√|rt|sqrt)\s*(?:\(\s*(Hz|s|h)\s*\)|(Hz|s|h)\b)')
_SUPERSCRIPTS = str.maketrans({'²': '^2', '³': '^3', '⁴': '^4', 'µ': 'u', 'μ': 'u',
                               '·': '*', '×': '*'})


class UnitError(ValueError):
    """A quantity could not be read: not a number, unknown unit, or wrong dimension.

    Attributes
    ----------
    key : str or None
        Name of the offending parameter (dotted path), if the caller gave one.
    reason : str
        The problem, without the key.
    """

    def __init__(self, reason: str, key: str | None = None) -> None:
        self.key = key
        self.reason = reason
        super().__init__(f"'{key}': {reason}" if key else reason)


def dimensions() -> tuple[str, ...]:
    """Return the names of all known dimensions.

    Returns
    -------
    tuple of str
        Dimension names, in table order.
    """
    return tuple(UNITS)


def _table_for(dimension: str) -> dict[str, float]:
    try:
        return UNITS[dimension]
    except KeyError:
        raise ValueError(f'unknown dimension {dimension!r}; known: {", ".join(UNITS)}') from None


def allowed_units(dimension: str) -> tuple[str, ...]:
    """Return the accepted unit spellings of a dimension, SI unit first.

    Parameters
    ----------
    dimension : str
        A key of :data:`UNITS`.

    Returns
    -------
    tuple of str
        Unit spellings ('' means "no unit", i.e. SI, for dimensionless).
    """
    return tuple(_table_for(dimension))


def _units_text(dimension: str) -> str:
    return ', '.join(u if u else '(no unit)' for u in allowed_units(dimension))


def normalize_unit(unit: str) -> str:
    """Return the canonical spelling of a unit string (see the module notes).

    Parameters
    ----------
    unit : str
        Unit as written, e.g. ``'lbf s / in'``, ``'in²'``.

    Returns
    -------
    str
        Canonical spelling, e.g. ``'lbf*s/in'``, ``'in^2'``.
    """
    text = unit.strip().translate(_SUPERSCRIPTS).replace('**', '^')
    # square roots of a time or frequency unit: '√Hz', 'rtHz', 'rt(Hz)', 'sqrt Hz' -> 'sqrt(Hz)'
    text = _ROOT_RE.sub(lambda m: f'/sqrt({m.group(1) or m.group(2)})', text)
    text = re.sub(r'\s*([*/^])\s*', r'\1', text)
    # '(m/s^2)/sqrt(Hz)' = 'm/s^2/sqrt(Hz)': a leading parenthesised numerator
    text = re.sub(r'^\(([^()]*)\)(?=/)', r'\1', text)
    # A blank or hyphen between two unit names is a product: 'lbf s/in', 'lbf-s/in'.
    text = re.sub(r'(?<=[A-Za-z0-9])(?:\s+|-)(?=[A-Za-z])', '*', text)
    return text


def _a(word: str) -> str:
    return ('an ' if word[:1] in 'aeiou' else 'a ') + word


def _dimensions_of(unit: str) -> str:
    names = [dim for dim, table in UNITS.items() if unit in table and dim != 'modulus']
    return ' or '.join(_a(n) for n in names)


def unit_factor(unit: str, dimension: str) -> float:
    """Return the factor that converts a value in ``unit`` to SI.

    Parameters
    ----------
    unit : str
        Unit spelling (normalised first).
    dimension : str
        Expected dimension, a key of :data:`UNITS`.

    Returns
    -------
    float
        SI value of one ``unit`` (SI unit per ``unit``).

    Raises
    ------
    UnitError
        If the unit is unknown or belongs to another dimension.
    """
    table = _table_for(dimension)
    canon = normalize_unit(unit)
    if canon in table:
        return table[canon]
    raise UnitError(_unit_problem(unit, canon, dimension))


def _unit_problem(unit: str, canon: str, dimension: str) -> str:
    allowed = _units_text(dimension)
    other = _dimensions_of(canon)
    if other:
        # 'lb' is pound-mass here; a force in pounds must say so explicitly.
        hint = "; pound-force is 'lbf'" if dimension == 'force' and canon in ('lb', 'lbm') else ''
        return (f"unit '{unit}' is not {_a(dimension)} (it is {other}{hint}); "
                f'use one of {allowed}')
    candidates = [u for u in UNITS[dimension] if u]
    lower = [u for u in candidates if u.lower() == canon.lower()]
    close = lower or difflib.get_close_matches(canon, candidates, n=1, cutoff=0.6)
    hint = f"did you mean '{close[0]}'? " if close else ''
    return f"unknown unit '{unit}' for {_a(dimension)}; {hint}use one of {allowed}"


def _describe(value: object) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + '...'


def _check_number(number: object, key: str | None, shown: str) -> float:
    if isinstance(number, bool) or not isinstance(number, Real):
        raise UnitError(f'expected a number, got {type(number).__name__} {_describe(number)}',
                        key)
    value = float(number)
    if not math.isfinite(value):
        raise UnitError(f'{shown} is not a finite number', key)
    return value


def _parse(value: object, dimension: str, key: str | None = None
           ) -> tuple[float, float, str | None]:
    """Return ``(si_value, number, unit)``: the SI float and the number and unit as given.

    ``unit`` is the canonical spelling, or ``None`` when the value was a bare number.
    """
    table = _table_for(dimension)
    if isinstance(value, bool):
        # bool is an int subclass in Python; 'clearance: true' is never a length.
        raise UnitError(f'expected {_a(dimension)}, got boolean {value!r}', key)
    number: float
    unit: str | None
    if isinstance(value, Real):
        return _check_number(value, key, _describe(value)), float(value), None
    if isinstance(value, str):
        number, unit = _split(value, dimension, key)
    elif isinstance(value, dict):
        number, unit = _split_mapping(value, key)
    else:
        raise UnitError(
            f'expected {_a(dimension)} (a number in {SI_UNIT[dimension] or "SI"}, a '
            f"'value unit' string or a {{value, unit}} mapping), got "
            f'{type(value).__name__} {_describe(value)}', key)
    if unit is None:
        return number, number, None
    canon = normalize_unit(unit)
    if canon not in table:
        raise UnitError(_unit_problem(unit, canon, dimension), key)
    si = number * table[canon]
    if not math.isfinite(si):
        raise UnitError(f'{number!r} {unit} overflows in SI', key)
    return si, number, canon


def _split(text: str, dimension: str, key: str | None) -> tuple[float, str | None]:
    if _NONFINITE_RE.match(text):
        raise UnitError(f'{text!r} is not a finite number', key)
    match = _QUANTITY_RE.match(text)
    if not match:
        example = {'length': '2.5 mil', 'stiffness': '32000 lb/in',
                   'angular_speed': '7878 rpm'}.get(dimension, '1.5 ' + SI_UNIT[dimension])
        raise UnitError(f"cannot read {text!r} as {_a(dimension)}; write e.g. '{example.strip()}' "
                        f'or {{value: 1.5, unit: {SI_UNIT[dimension] or "%"}}}', key)
    number = _check_number(float(match.group(1)), key, repr(text))
    unit = match.group(2)
    # A bare number in a string ('1e-3', which YAML 1.1 leaves as text) is SI, like a number.
    return number, (unit if unit else None)


def _split_mapping(mapping: dict[object, object], key: str | None) -> tuple[float, str]:
    expected = {'value', 'unit'}
    extra = [k for k in mapping if k not in expected]
    if extra:
        bad = extra[0]
        close = difflib.get_close_matches(str(bad), sorted(expected), n=1)
        hint = f" (did you mean '{close[0]}'?)" if close else ''
        raise UnitError(f"unknown key {bad!r} in a {{value, unit}} quantity{hint}", key)
    missing = sorted(expected - set(mapping))
    if missing:
        raise UnitError(f"a {{value, unit}} quantity needs both keys; missing "
                        f"{', '.join(repr(m) for m in missing)}", key)
    unit = mapping['unit']
    if unit is None:
        unit = ''
    if not isinstance(unit, str):
        raise UnitError(f'unit must be a string, got {type(unit).__name__} {_describe(unit)}',
                        key)
    number = _check_number(mapping['value'], key, _describe(mapping['value']))
    return number, unit


def parse_quantity(value: object, dimension: str, *, key: str | None = None) -> float:
    """Read a physical quantity and return it in SI.

    Parameters
    ----------
    value : float or int or str or dict
        A plain number (already SI), a string ``'<number> <unit>'`` such as ``'2.5 mil'``,
        ``'32000 lb/in'``, ``'7878 rpm'``, ``'1e-3 m'`` (a string holding only a number is
        SI too), or a mapping ``{'value': 2.5, 'unit': 'mil'}``. Booleans, NaN and
        infinities are rejected.
    dimension : str
        Expected dimension, a key of :data:`UNITS` (e.g. ``'length'``, ``'stiffness'``).
    key : str, optional
        Parameter name (dotted path) to put in error messages.

    Returns
    -------
    float
        The value in the SI unit of ``dimension`` (e.g. m, N/m, rad/s).

    Raises
    ------
    UnitError
        If the value is not a finite number, the unit is unknown, or the unit belongs to
        another dimension; the message names ``key``, the unit and the allowed units.

    Examples
    --------
    >>> parse_quantity('2.5 mil', 'length')
    6.35e-05
    >>> parse_quantity({'value': 60, 'unit': 'rpm'}, 'angular_speed') == 2 * math.pi
    True
    """
    return _parse(value, dimension, key)[0]


def _unique_factor(unit: str, dimension: str | None) -> tuple[float, str]:
    canon = normalize_unit(unit)
    if dimension is not None:
        return unit_factor(canon, dimension), canon
    factors = {table[canon] for dim, table in UNITS.items() if canon in table}
    if not factors:
        raise UnitError(f"unknown unit '{unit}'")
    if len(factors) > 1:
        raise UnitError(f"unit '{unit}' is ambiguous ({_dimensions_of(canon)}); "
                        'pass dimension=')
    return factors.pop(), canon


def to_unit(value_si: float, unit: str, *, dimension: str | None = None) -> float:
    """Convert an SI value to ``unit``.

    Parameters
    ----------
    value_si : float
        Value in the SI unit of the dimension of ``unit``.
    unit : str
        Target unit, e.g. ``'mil'``.
    dimension : str, optional
        Needed only when ``unit`` is ambiguous across dimensions (``'g'``).

    Returns
    -------
    float
        The value in ``unit``.
    """
    factor, _ = _unique_factor(unit, dimension)
    return float(value_si) / factor


def format_quantity(value_si: float, unit: str, *, dimension: str | None = None,
                    digits: int = 6) -> str:

    """Format an SI value in an engineering unit, for reports.

    Parameters
    ----------
    value_si : float
        Value in SI (e.g. m for ``unit='mil'``).
    unit : str
        Unit to show it in.
    dimension : str, optional
        Needed only when ``unit`` is ambiguous across dimensions (``'g'``).
    digits : int, optional
        Significant digits (dimensionless).

    Returns
    -------
    str
        E.g. ``'2.5 mil'``.
    """
    factor, canon = _unique_factor(unit, dimension)
    number = f'{float(value_si) / factor:.{digits}g}'
    return f'{number} {canon}' if canon else number
