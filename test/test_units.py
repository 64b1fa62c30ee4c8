"""Tests of impact_damper_sim.scene.units: exact factors, parsing, rejection, formatting."""
import math
from fractions import Fraction

import pytest

from impact_damper_sim.scene import units
from impact_damper_sim.scene.units import (
    UNITS,
    UnitError,
    allowed_units,
    format_quantity,
    normalize_unit,
    parse_quantity,
    to_unit,
    unit_factor,
)

# Exact definitions, independent of the module under test.
IN = Fraction('0.0254')
LB = Fraction('0.45359237')
G0 = Fraction('9.80665')
LBF = LB * G0


def rel(a, b):
    return abs(a - b) / abs(b)


# --- exactness of the factors ----------------------------------------------------------------

@pytest.mark.parametrize('unit, dimension, exact', [
    ('in', 'length', IN),
    ('mil', 'length', IN / 1000),
    ('ft', 'length', 12 * IN),
    ('lb', 'mass', LB),
    ('lbf', 'force', LBF),
    ('lb/in', 'stiffness', LBF / IN),
    ('lbf/in', 'stiffness', LBF / IN),
    ('lbf*s/in', 'damping', LBF / IN),
    ('psi', 'pressure', LBF / IN ** 2),
    ('Msi', 'modulus', 10 ** 6 * LBF / IN ** 2),
    ('lb/in^3', 'density', LB / IN ** 3),
    ('in^4', 'second_moment', IN ** 4),
    ('g', 'acceleration', G0),
    ('lbf*s^2/in', 'mass', LBF / IN),
    ('mg', 'acceleration', G0 / 1000),
    ('ug', 'acceleration', G0 / 10 ** 6),
    ('mg', 'mass', Fraction(1, 10 ** 6)),
    ('uV', 'voltage', Fraction(1, 10 ** 6)),
    ('mV/g', 'sensitivity', Fraction(1, 1000) / G0),
    ('V/g', 'sensitivity', 1 / G0),
    ('mV/(m/s^2)', 'sensitivity', Fraction(1, 1000)),
    ('ug/sqrt(Hz)', 'acceleration_density', G0 / 10 ** 6),
    ('g/sqrt(Hz)', 'acceleration_density', G0),
    ('ug/sqrt(h)', 'acceleration_per_sqrt_time', G0 / 10 ** 6 / 60),
    ('mg/sqrt(s)', 'acceleration_per_sqrt_time', G0 / 1000),
    ('m/s^3/sqrt(Hz)', 'acceleration_per_sqrt_time', Fraction(1)),
])
def test_factor_is_correctly_rounded_exact_value(unit, dimension, exact):
    factor = unit_factor(unit, dimension)
    assert rel(factor, float(exact)) <= 1e-15
    assert factor == float(exact)   # built from Fractions: rounded once


def test_lb_per_in_in_newton_per_metre():
    assert rel(parse_quantity('1 lb/in', 'stiffness'), 175.12683524647638) <= 1e-15
    assert rel(parse_quantity('32000 lb/in', 'stiffness'), float(32000 * LBF / IN)) <= 1e-15


def test_constants():
    assert units.G0 == 9.80665
    assert units.INCH == 0.0254
    assert units.POUND_MASS == 0.45359237
    assert units.POUND_FORCE == float(LBF)
    assert units.PSI == float(LBF / IN ** 2)
    assert units.MIL == float(IN / 1000)


def test_rpm_to_rad_per_s():
    assert parse_quantity('60 rpm', 'angular_speed') == pytest.approx(2 * math.pi, rel=1e-15)
    assert parse_quantity('7878 rpm', 'angular_speed') == pytest.approx(
        7878 * 2 * math.pi / 60, rel=1e-15)
    assert parse_quantity('1 rad/s', 'angular_speed') == 1.0


def test_g_is_standard_gravity_for_acceleration_and_gram_for_mass():
    assert parse_quantity('1 g', 'acceleration') == 9.80665
    assert parse_quantity('2 g', 'acceleration') == pytest.approx(19.6133, rel=1e-15)
    assert parse_quantity('1 g', 'mass') == 1e-3


def test_weight_in_lb_is_read_as_pound_mass():
    assert parse_quantity('25 lb', 'mass') == pytest.approx(25 * 0.45359237, rel=1e-15)
    assert parse_quantity('25 lbm', 'mass') == parse_quantity('25 lb', 'mass')


def test_deg_and_percent():
    assert parse_quantity('180 deg', 'angle') == pytest.approx(math.pi, rel=1e-15)
    assert parse_quantity('2.88 %', 'dimensionless') == pytest.approx(0.0288, rel=1e-15)


def test_si_unit_first_with_factor_one_and_spellings_canonical():
    for dimension, table in UNITS.items():
        first = next(iter(table))
        assert table[first] == 1.0, dimension
        assert allowed_units(dimension)[0] == first
        for unit in table:
            assert normalize_unit(unit) == unit, (dimension, unit)


# --- accepted forms ----------------------------------------------------------------------------

@pytest.mark.parametrize('value, dimension, expected', [
    (2.5, 'length', 2.5),                       # plain number is SI
    (3, 'length', 3.0),
    ('1e-3 m', 'length', 1e-3),
    ('1e-3', 'length', 1e-3),                   # YAML 1.1 leaves this a string
    ('2.5mil', 'length', 2.5 * float(IN) / 1000),
    ('  3   in ', 'length', 3 * 0.0254),
    ('-2 mm', 'length', -2e-3),
    ('.5 in', 'length', 0.5 * 0.0254),
    ('5 um', 'length', 5e-6),
    ('5 µm', 'length', 5e-6),
    ('2 in²', 'area', 2 * 0.0254 ** 2),
    ('2 in**2', 'area', 2 * 0.0254 ** 2),
    ('1 lbf s/in', 'damping', float(LBF / IN)),
    ('1 lbf-s/in', 'damping', float(LBF / IN)),
    ('1 lbf·s/in', 'damping', float(LBF / IN)),
    ('1 lbf * s / in', 'damping', float(LBF / IN)),
    ('10 N m/rad', 'rotational_stiffness', 10.0),
    ({'value': 2.5, 'unit': 'mil'}, 'length', 2.5 * float(IN) / 1000),
    ({'value': 3, 'unit': ''}, 'dimensionless', 3.0),
    ('200 GPa', 'modulus', 200e9),
    ('100 Hz', 'frequency', 100.0),
    ('60 cpm', 'frequency', 1.0),
    ('100 mV/g', 'sensitivity', 0.1 / 9.80665),
    ('100 mV / g', 'sensitivity', 0.1 / 9.80665),
    ('10 mV/(m/s²)', 'sensitivity', 0.01),
    ('1.5 ug/sqrt(Hz)', 'acceleration_density', 1.5e-6 * 9.80665),
    ('1.5 µg/√Hz', 'acceleration_density', 1.5e-6 * 9.80665),
    ('1.5 ug/rtHz', 'acceleration_density', 1.5e-6 * 9.80665),
    ('1.5 ug/rt(Hz)', 'acceleration_density', 1.5e-6 * 9.80665),
    ('1.5 ug / sqrt Hz', 'acceleration_density', 1.5e-6 * 9.80665),
    ('4e-3 (m/s^2)/sqrt(Hz)', 'acceleration_density', 4e-3),
    ('4e-3 (m/s²)/√Hz', 'acceleration_density', 4e-3),
    ('3e-3 m/s^2/sqrt(s)', 'acceleration_per_sqrt_time', 3e-3),
    ('3e-3 (m/s^2)/√s', 'acceleration_per_sqrt_time', 3e-3),
    ('50 uV', 'voltage', 5e-5),
    ('25 mg', 'acceleration', 0.025 * 9.80665),
])
def test_accepted_forms(value, dimension, expected):
    assert parse_quantity(value, dimension) == pytest.approx(expected, rel=1e-15)
    assert isinstance(parse_quantity(value, dimension), float)


@pytest.mark.parametrize('dimension', sorted(UNITS))
def test_round_trip_every_unit(dimension):
    for unit in allowed_units(dimension):
        si = parse_quantity(f'1.2345 {unit}', dimension)
        assert to_unit(si, unit, dimension=dimension) == pytest.approx(1.2345, rel=1e-15)


def test_round_trip_mil():
    si = parse_quantity('2.5 mil', 'length')
    assert si == pytest.approx(6.35e-5, rel=1e-15)
    assert to_unit(si, 'mil') == pytest.approx(2.5, rel=1e-15)
    assert format_quantity(si, 'mil') == '2.5 mil'


def test_format_quantity():
    assert format_quantity(175.12683524647638, 'lb/in') == '1 lb/in'
    assert format_quantity(2 * math.pi, 'rpm') == '60 rpm'
    assert format_quantity(1 / 3, 'm', digits=3) == '0.333 m'
    assert format_quantity(0.02, '%') == '2 %'
    assert format_quantity(9.80665, 'g', dimension='acceleration') == '1 g'
    assert format_quantity(1e-3, 'g', dimension='mass') == '1 g'
    with pytest.raises(UnitError, match=r"unit 'g' is ambiguous .*pass dimension="):
        format_quantity(1.0, 'g')
    with pytest.raises(UnitError, match=r"unknown unit 'furlong'"):
        format_quantity(1.0, 'furlong')


# --- rejection ---------------------------------------------------------------------------------

def test_wrong_dimension_names_key_unit_and_allowed_units():
    pattern = (r"^'rotor.gap': unit 'lb' is not a length \(it is a mass\); "
               r'use one of m, cm, mm, um, in, mil, ft$')
    with pytest.raises(UnitError, match=pattern):
        parse_quantity('3 lb', 'length', key='rotor.gap')


def test_wrong_dimension_stiffness():
    pattern = r"unit 'mil' is not a stiffness .*use one of N/m, .*lb/in"
    with pytest.raises(UnitError, match=pattern):
        parse_quantity('3 mil', 'stiffness', key='k')


def test_lb_is_not_a_force():
    with pytest.raises(UnitError, match=r"unit 'lb' is not a force \(it is a mass; pound-force is "
                                        r"'lbf'\)"):
        parse_quantity('3 lb', 'force', key='f')


def test_rad_per_s_is_not_a_frequency():
    with pytest.raises(UnitError, match=r"'rad/s' is not a frequency \(it is an angular_speed\); "
                                        r'use one of Hz, kHz, cpm'):
        parse_quantity('3 rad/s', 'frequency', key='f')


def test_milli_g_is_an_acceleration_and_a_milligram_a_mass():
    assert parse_quantity('5 mg', 'acceleration') == pytest.approx(5e-3 * 9.80665, rel=1e-15)
    assert parse_quantity('5 mg', 'mass') == pytest.approx(5e-6, rel=1e-15)


def test_a_density_is_not_a_random_walk():
    with pytest.raises(UnitError, match=r"'n': unit 'ug/rtHz' is not an "
                                        r'acceleration_per_sqrt_time \(it is an '
                                        r'acceleration_density\); use one of m/s\^2/sqrt\(s\)'):
        parse_quantity('1 ug/rtHz', 'acceleration_per_sqrt_time', key='n')


def test_ambiguous_unit_named_with_both_dimensions():
    pattern = r"'g' is not a length \(it is a mass or an acceleration\)"
    with pytest.raises(UnitError, match=pattern):
        parse_quantity('3 g', 'length', key='x')


@pytest.mark.parametrize('text, hint', [('3 mill', 'mil'), ('3 MM', 'mm'), ('3 inch', 'in')])
def test_unknown_unit_suggests(text, hint):
    pattern = rf"unknown unit '.*' for a length; did you mean '{hint}'\?"
    with pytest.raises(UnitError, match=pattern):
        parse_quantity(text, 'length', key='x')


@pytest.mark.parametrize('value', [True, False])
def test_bool_is_not_a_number(value):
    with pytest.raises(UnitError, match=r"'x': expected a length, got boolean"):
        parse_quantity(value, 'length', key='x')
    with pytest.raises(UnitError, match=r'expected a number, got bool'):
        parse_quantity({'value': value, 'unit': 'm'}, 'length', key='x')


@pytest.mark.parametrize('value', [
    float('nan'), float('inf'), -float('inf'), 'nan', 'inf mm', '-inf', '.nan', '.inf m',
    'NaN', {'value': float('nan'), 'unit': 'm'},
])
def test_non_finite_rejected(value):
    with pytest.raises(UnitError, match=r"'x': .* is not a finite number"):
        parse_quantity(value, 'length', key='x')


def test_overflow_rejected():
    with pytest.raises(UnitError, match='overflows'):
        parse_quantity('1e308 Msi', 'modulus', key='E')


@pytest.mark.parametrize('value, message', [
    ('abc', r"cannot read 'abc' as a length; write e.g. '2.5 mil'"),
    ('', r"cannot read '' as a length"),
    ([1, 2], r'expected a length \(a number in m, .*got list \[1, 2\]'),
    (None, r'expected a length .*got NoneType None'),
    ({'value': 1}, r"needs both keys; missing 'unit'"),
    ({'unit': 'm'}, r"needs both keys; missing 'value'"),
    ({'value': 1, 'units': 'm'}, r"unknown key 'units' .*did you mean 'unit'"),
    ({'value': '1', 'unit': 'm'}, r"expected a number, got str '1'"),
    ({'value': 1, 'unit': 3}, r'unit must be a string, got int 3'),
])
def test_malformed_values(value, message):
    with pytest.raises(UnitError, match=message):
        parse_quantity(value, 'length', key='x')


def test_error_attributes_and_keyless_message():
    with pytest.raises(UnitError) as info:
        parse_quantity('3 lb', 'length')
    assert info.value.key is None
    assert str(info.value).startswith("unit 'lb'")
    assert isinstance(info.value, ValueError)


def test_unknown_dimension():
    with pytest.raises(ValueError, match=r"unknown dimension 'lenght'"):
        parse_quantity(1.0, 'lenght')
