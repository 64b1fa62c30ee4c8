"""Tests of the declarative scene schema: validation, overrides, YAML loading, docs."""
import copy
import subprocess
import sys
from pathlib import Path

import pytest

from impact_damper_sim.scene import (
    Boolean,
    Choice,
    Integer,
    KeyInfo,
    ListOf,
    MapOf,
    Optional,
    Quantity,
    SceneError,
    Section,
    String,
    Vector,
    apply_overrides,
    describe,
    load_scene,
    load_yaml,
    markdown_table,
    validate,
)

IN = 0.0254
LB = 0.45359237
LBF_PER_IN = LB * 9.80665 / IN


def _gap_check(values):
    if values['clearance_min'] is not None and values['clearance_min'] > values['clearance']:
        return 'clearance_min must not exceed clearance'
    return None


SCHEMA = Section({
    'structure': Section({
        'bearings': Section({
            'lower': Section({
                'ky': Quantity('stiffness', min=0, doc='lower bearing stiffness'),
                'kz': Quantity('stiffness', default='32000 lb/in', min=0),
            }),
        }),
        'E': Quantity('modulus', default='29 Msi', min=0, min_inclusive=False),
    }),
    'impactors': ListOf(Section({
        'mass': Quantity('mass', min=0, min_inclusive=False, doc='weight W (lb = lbm)'),
        'clearance': Quantity('length', default='2.5 mil', min='1e-8 m', max='1 cm'),
        'clearance_min': Optional(Quantity('length', min=0)),
        'position': Vector('length', 3, default=[0, 0, 0], unit='in'),
        'restitution': Quantity('dimensionless', default=0.6, min=0, max=1,
                                max_inclusive=False),
    }, checks=[_gap_check]), min_len=1, max_len=3, doc='impact dampers'),
    'speed': Quantity('angular_speed', default='7878 rpm', min=0),
    'modal': Section({
        'n_modes': Integer(default=10, min=1, max=200),
        'zeta': MapOf(Integer(min=1), Quantity('dimensionless', min=0, max=1), default={}),
        'method': Choice(('eigsh', 'dense'), default='eigsh'),
        'export': Boolean(default=False),
        'name': String(default=None),
    }),
})

GOOD = """
structure:
  bearings:
    lower: {ky: 1e6}
impactors:
  - {mass: 25 lb, clearance: 5 mil, position: {value: [1, 2, 3], unit: in}}
  - mass: {value: 2, unit: kg}
modal:
  zeta: {3: 0.0288, 5: 2 %}
"""


def good():
    return load_yaml(GOOD)


def check(raw, pattern, schema=SCHEMA):
    with pytest.raises(SceneError, match=pattern) as info:
        validate(schema, raw)
    return info.value


def with_(path, value, base=None):
    """Return a copy of the good scene with one nested key set (path as a tuple)."""
    raw = copy.deepcopy(base if base is not None else good())
    node = raw
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    return raw


# --- happy path ----------------------------------------------------------------------------

def test_converts_units_and_applies_defaults():
    scene = validate(SCHEMA, good())
    lower = scene['structure']['bearings']['lower']
    assert lower['ky'] == 1e6
    assert lower['kz'] == pytest.approx(32000 * LBF_PER_IN, rel=1e-15)
    assert scene['structure']['E'] == pytest.approx(29e6 * LB * 9.80665 / IN ** 2, rel=1e-15)
    first, second = scene['impactors']
    assert first['mass'] == pytest.approx(25 * LB, rel=1e-15)
    assert first['clearance'] == pytest.approx(5e-3 * IN, rel=1e-15)
    assert first['position'] == pytest.approx([IN, 2 * IN, 3 * IN], rel=1e-15)
    assert first['clearance_min'] is None
    assert second['mass'] == 2.0
    assert second['clearance'] == pytest.approx(2.5e-3 * IN, rel=1e-15)
    assert second['position'] == [0.0, 0.0, 0.0]
    assert second['restitution'] == 0.6
    assert scene['speed'] == pytest.approx(7878 * 2 * 3.141592653589793 / 60, rel=1e-15)
    assert scene['modal'] == {'n_modes': 10, 'zeta': {3: 0.0288, 5: 0.02}, 'method': 'eigsh',
                              'export': False, 'name': None}


def test_result_is_plain_fresh_and_input_untouched():
    raw = good()
    before = copy.deepcopy(raw)
    scene = validate(SCHEMA, raw)
    assert raw == before
    assert type(scene) is dict and type(scene['impactors']) is list
    assert list(scene) == ['structure', 'impactors', 'speed', 'modal']   # schema order
    scene['modal']['zeta'][7] = 0.1                                        # mutable, not shared
    assert validate(SCHEMA, good())['modal']['zeta'] == {3: 0.0288, 5: 0.02}


def test_inclusive_bounds_accepted():
    raw = with_(('impactors', 0, 'clearance'), '1 cm')
    raw['impactors'][1]['clearance'] = 1e-8
    raw['impactors'][1]['restitution'] = 0
    scene = validate(SCHEMA, raw)
    assert scene['impactors'][0]['clearance'] == pytest.approx(0.01, rel=1e-15)
    assert scene['impactors'][1]['clearance'] == 1e-8


def test_optional_accepts_null_and_value():
    raw = with_(('impactors', 0, 'clearance_min'), None)
    assert validate(SCHEMA, raw)['impactors'][0]['clearance_min'] is None
    raw = with_(('impactors', 0, 'clearance_min'), '1 mil')
    assert validate(SCHEMA, raw)['impactors'][0]['clearance_min'] == pytest.approx(1e-3 * IN)


# --- unknown keys ----------------------------------------------------------------------------

def test_unknown_key_with_suggestion():
    raw = with_(('impactors', 0, 'masss'), 3)
    check(raw, r"^scene key 'impactors\[0\]\.masss': unknown key; did you mean 'mass'\? "
               r'\(known keys here: mass, clearance, clearance_min, position, restitution\)$')


def test_unknown_key_without_suggestion_lists_known_keys():
    check(with_(('zzz',), 1), r"scene key 'zzz': unknown key \(known keys here: structure, "
                              r'impactors, speed, modal\)')


def test_unknown_nested_key():
    raw = with_(('structure', 'bearings', 'lower', 'kyy'), 1)
    check(raw, r"'structure\.bearings\.lower\.kyy': unknown key; did you mean 'ky'\?")


# --- units -------------------------------------------------------------------------------------

def test_wrong_unit_names_key_and_allowed_units():
    raw = with_(('structure', 'bearings', 'lower', 'ky'), '3 mil')
    check(raw, r"^scene key 'structure\.bearings\.lower\.ky': unit 'mil' is not a stiffness "
               r'\(it is a length\); use one of N/m, N/mm, kN/mm, MN/m, lbf/in, lb/in, kip/in$')


def test_unknown_unit():
    check(with_(('speed',), '100 rmp'), r"'speed': unknown unit 'rmp' for an angular_speed; "
                                        r"did you mean 'rpm'\? use one of rad/s, rpm")


# --- ranges ------------------------------------------------------------------------------------

def test_above_inclusive_max_si():
    raw = with_(('impactors', 0, 'clearance'), 5.0)
    check(raw, r"^scene key 'impactors\[0\]\.clearance': 5 m is out of range \[1e-08, 0\.01\] m$")


def test_above_max_echoes_given_unit():
    raw = with_(('impactors', 0, 'clearance'), '5 in')
    check(raw, r"'impactors\[0\]\.clearance': 5 in = 0\.127 m is out of range \[1e-08, 0\.01\] m "
               r'\(= \[3\.93701e-07, 0\.393701\] in\)')


def test_below_inclusive_min():
    raw = with_(('impactors', 1, 'clearance'), 1e-9)
    check(raw, r"'impactors\[1\]\.clearance': 1e-09 m is out of range \[1e-08, 0\.01\] m")


def test_exclusive_min_rejects_the_bound():
    raw = with_(('impactors', 1, 'mass'), 0)
    check(raw, r"'impactors\[1\]\.mass': 0 kg is out of range \(0, inf\) kg")


def test_exclusive_max_rejects_the_bound():
    raw = with_(('impactors', 1, 'restitution'), 1)
    check(raw, r"'impactors\[1\]\.restitution': 1 is out of range \[0, 1\)")


def test_negative_below_open_ended_range():
    raw = with_(('structure', 'bearings', 'lower', 'ky'), '-1 lb/in')
    check(raw, r"'structure\.bearings\.lower\.ky': -1 lb/in = -175\.126835246 N/m is out of "
               r'range \[0, inf\) N/m')


def test_integer_range():
    check(with_(('modal', 'n_modes'), 0), r"'modal\.n_modes': 0 is out of range \[1, 200\]")
    check(with_(('modal', 'n_modes'), 201), r"'modal\.n_modes': 201 is out of range \[1, 200\]")


# --- missing, null, types ------------------------------------------------------------------------

def test_missing_required_names_key_range_and_units():
    raw = good()
    del raw['structure']['bearings']['lower']['ky']
    check(raw, r"^scene key 'structure\.bearings\.lower\.ky': missing required key; expected a "
               r'stiffness in \[0, inf\) N/m \(units: N/m, .*lb/in, kip/in\)$')


def test_missing_required_inside_absent_section():
    raw = good()
    del raw['structure']
    check(raw, r"'structure\.bearings\.lower\.ky': missing required key")


def test_missing_required_list():
    raw = good()
    del raw['impactors']
    check(raw, r"'impactors': missing required key; expected a list of section in 1\.\.3 items")


def test_null_is_not_the_default():
    check(with_(('speed',), None), r"'speed': is empty \(null\); expected an angular_speed")


@pytest.mark.parametrize('path, value, pattern', [
    (('structure',), [1, 2], r"'structure': expected a mapping with keys bearings, E; got list"),
    (('impactors',), {'mass': 1}, r"'impactors': expected a list of section, got dict"),
    (('impactors', 0), 'heavy', r"'impactors\[0\]': expected a mapping with keys mass, "),
    (('speed',), [1], r"'speed': expected an angular_speed \(a number in rad/s, "),
    (('modal', 'n_modes'), 2.0, r"'modal\.n_modes': expected an integer, got float 2\.0"),
    (('modal', 'n_modes'), True, r"'modal\.n_modes': expected an integer, got bool True"),
    (('modal', 'n_modes'), '10', r"'modal\.n_modes': expected an integer, got str '10'"),
    (('modal', 'export'), 1, r"'modal\.export': expected true or false, got int 1"),
    (('modal', 'export'), 'yes', r"'modal\.export': expected true or false, got str 'yes'"),
    (('modal', 'name'), 3, r"'modal\.name': expected a string, got int 3"),
    (('modal', 'name'), '', r"'modal\.name': must not be an empty string"),
    (('modal', 'method'), 'Eigsh', r"'modal\.method': 'Eigsh' is not allowed; did you mean "
                                   r"'eigsh'\? use one of eigsh \| dense"),
    (('modal', 'zeta'), [0.1], r"'modal\.zeta': expected a mapping \(map of integer to "),
])
def test_wrong_types(path, value, pattern):
    check(with_(path, value), pattern)


def test_choice_compares_types():
    schema = Section({'order': Choice((1, 2), default=1)})
    assert validate(schema, {'order': 2}) == {'order': 2}
    check({'order': True}, r"'order': True is not allowed; use one of 1 \| 2", schema)


@pytest.mark.parametrize('value', [True, False])
def test_bool_is_not_a_quantity(value):
    check(with_(('structure', 'bearings', 'lower', 'ky'), value),
          r"'structure\.bearings\.lower\.ky': expected a stiffness, got boolean")


@pytest.mark.parametrize('text', ['.nan', '.inf', '-.inf', '.NaN'])
def test_nan_inf_from_yaml_rejected(text):
    raw = load_yaml(f'structure: {{bearings: {{lower: {{ky: {text}}}}}}}\n'
                    'impactors: [{mass: 1}]')
    check(raw, r"'structure\.bearings\.lower\.ky': .* is not a finite number")


def test_nan_string_rejected():
    check(with_(('speed',), 'nan rpm'), r"'speed': 'nan rpm' is not a finite number")


# --- lists, vectors, maps, checks ---------------------------------------------------------------

def test_list_length():
    check(with_(('impactors',), []), r"'impactors': has 0 items; expected 1\.\.3 items")
    raw = with_(('impactors',), [{'mass': 1}] * 4)
    check(raw, r"'impactors': has 4 items; expected 1\.\.3 items")


def test_list_item_null():
    check(with_(('impactors', 1), None), r"'impactors\[1\]': is empty \(null\)")


def test_vector_forms_and_errors():
    raw = with_(('impactors', 1, 'position'), ['1 in', 0, '2 mm'])
    assert validate(SCHEMA, raw)['impactors'][1]['position'] == pytest.approx([IN, 0, 2e-3])
    check(with_(('impactors', 1, 'position'), [1, 2]),
          r"'impactors\[1\]\.position': has 2 components; expected 3")
    check(with_(('impactors', 1, 'position'), [1, '2 lb', 3]),
          r"'impactors\[1\]\.position\[1\]': unit 'lb' is not a length")
    check(with_(('impactors', 1, 'position'), {'value': 1, 'unit': 'in'}),
          r"'impactors\[1\]\.position': a vector mapping must be "
          r'\{value: \[\.\.\.\], unit: \.\.\.\}')
    check(with_(('impactors', 1, 'position'), 'here'),
          r"'impactors\[1\]\.position': expected a 3-vector of length")


def test_map_keys_and_values():
    check(with_(('modal', 'zeta'), {'x': 0.1}),
          r"^scene key 'modal\.zeta\.x': invalid key: expected an integer, got str 'x'$")
    check(with_(('modal', 'zeta'), {0: 0.1}),
          r"'modal\.zeta\.0': invalid key: 0 is out of range \[1, inf\)")
    check(with_(('modal', 'zeta'), {3: 2}), r"'modal\.zeta\.3': 2 is out of range \[0, 1\]")


def test_section_check_reported_with_section_path():
    raw = with_(('impactors', 0, 'clearance_min'), '6 mil')
    check(raw, r"^scene key 'impactors\[0\]': clearance_min must not exceed clearance$")


def test_section_check_skipped_when_keys_invalid():
    raw = with_(('impactors', 0, 'clearance_min'), '6 lb')
    err = check(raw, r"clearance_min")
    assert len(err.errors) == 1


def test_all_errors_collected_one_per_line():
    raw = good()
    raw['impactors'][0]['masss'] = 1
    raw['impactors'][1]['clearance'] = '5 in'
    raw['structure']['bearings']['lower']['ky'] = '3 mil'
    raw['modal']['n_modes'] = 2.5
    del raw['impactors'][0]['mass']
    err = check(raw, 'masss')
    assert len(err.errors) == 5
    assert str(err).splitlines() == list(err.errors)
    assert all(line.startswith("scene key '") for line in err.errors)
    assert isinstance(err, ValueError)


def test_source_header():
    with pytest.raises(SceneError, match=r"^bad\.yaml: scene key 'zzz'") as info:
        validate(SCHEMA, with_(('zzz',), 1), source='bad.yaml')
    assert info.value.source == 'bad.yaml'
    raw = with_(('zzz',), 1)
    raw['yyy'] = 2
    with pytest.raises(SceneError, match=r'^invalid scene bad\.yaml \(2 errors\):\n'):
        validate(SCHEMA, raw, source='bad.yaml')


def test_top_level_not_a_mapping():
    check([1, 2], r"^scene: expected a mapping with keys structure, ")


# --- schema construction ----------------------------------------------------------------------

@pytest.mark.parametrize('build, pattern', [
    (lambda: Quantity('length', default='3 lb'), r"invalid default '3 lb' for length"),
    (lambda: Quantity('length', default=2.0, max=1.0), r'invalid default 2\.0 for length.*out of'),
    (lambda: Quantity('lenght'), r"unknown dimension 'lenght'"),
    (lambda: Quantity('length', min=2, max=1), r'min 2\.0 > max 1\.0'),
    (lambda: Integer(default=1.5), r'invalid default 1\.5 for integer'),
    (lambda: Choice(('a', 'b'), default='c'), r"invalid default 'c' for choice"),
    (lambda: Choice(()), r'at least one option'),
    (lambda: ListOf(Integer(), default=[1, 'x']), r'invalid default'),
    (lambda: Vector('length', 3, default=[0, 0]), r'invalid default'),
])
def test_bad_schema_fails_when_built(build, pattern):
    with pytest.raises(ValueError, match=pattern):
        build()


def test_bad_schema_types():
    with pytest.raises(TypeError, match='Section fields must map str to Field'):
        Section({'a': 1.0})
    with pytest.raises(TypeError, match='MapOf keys must be'):
        MapOf(Quantity('length'), Integer())


# --- YAML loading ----------------------------------------------------------------------------

def test_duplicate_key_rejected_with_line():
    with pytest.raises(SceneError, match=r"^<text>:3:1: YAML error: found duplicate key 'speed' "
                                         r'\(first defined on line 1\)$'):
        load_yaml('speed: 1\nmodal: {}\nspeed: 2\n')


def test_nested_duplicate_key_rejected():
    with pytest.raises(SceneError, match=r":2:23: YAML error: found duplicate key 'mass'"):
        load_yaml('impactors:\n  - {mass: 1, gap: 2, mass: 3}\n')


def test_merge_key_may_be_overridden():
    data = load_yaml('base: &b {mass: 1, gap: 2}\nother:\n  <<: *b\n  mass: 3\n')
    assert data['other'] == {'mass': 3, 'gap': 2}


def test_syntax_error_has_line_number():
    with pytest.raises(SceneError, match=r'^scene\.yaml:3:\d+: YAML error: '):
        load_yaml('a: 1\nb: [1, 2\nc: 3\n', source='scene.yaml')


@pytest.mark.parametrize('text, pattern', [
    ('- 1\n- 2\n', r'a scene must be a mapping at top level; got list \[1, 2\]'),
    ('', r'got an empty document'),
    ('# only a comment\n', r'got an empty document'),
    ('just text\n', r"got str 'just text'"),
])
def test_top_level_must_be_mapping(text, pattern):
    with pytest.raises(SceneError, match=pattern):
        load_yaml(text)


def test_exponent_without_dot_is_a_float():
    data = load_yaml('a: 1e-3\nb: 2E+6\nc: 1.5e3\nd: 7\ne: 1.5\n')
    assert data == {'a': 1e-3, 'b': 2e6, 'c': 1500.0, 'd': 7, 'e': 1.5}
    assert type(data['a']) is float and type(data['d']) is int


def test_load_from_file(tmp_path):
    path = tmp_path / 'scene.yaml'
    path.write_text(GOOD, encoding='utf-8')
    assert load_yaml(path) == good()
    assert load_yaml(str(path)) == good()
    with pytest.raises(SceneError, match=r'missing\.yaml: cannot read scene file'):
        load_yaml(tmp_path / 'missing.yaml')


def test_load_scene(tmp_path):
    path = tmp_path / 'scene.yaml'
    path.write_text(GOOD + 'speed: 3000 rpm\n', encoding='utf-8')
    scene = load_scene(SCHEMA, path, ['impactors[1].mass=4 lb'])
    assert scene['impactors'][1]['mass'] == pytest.approx(4 * LB)
    assert scene['speed'] == pytest.approx(100 * 3.141592653589793)
    with pytest.raises(SceneError, match=r"^.*scene\.yaml: scene key 'speed': unit 'Hz'"):
        load_scene(SCHEMA, path, ['speed=50 Hz'])


# --- overrides ---------------------------------------------------------------------------------

def test_overrides_both_index_syntaxes_and_yaml_values():
    raw = good()
    out = apply_overrides(raw, [
        'impactors[0].mass=2 lb',
        'impactors.1.clearance = 3 mil',
        'speed=1e3',
        'modal.zeta.4=0.01',
        'modal.export=true',
        'impactors[1].position=[1, 2, 3]',
        'structure.bearings.lower={ky: 32000 lb/in}',
    ])
    assert raw == good()   # input untouched
    scene = validate(SCHEMA, out)
    assert scene['impactors'][0]['mass'] == pytest.approx(2 * LB)
    assert scene['impactors'][1]['clearance'] == pytest.approx(3e-3 * IN)
    assert scene['speed'] == 1000.0
    assert scene['modal']['zeta'] == {3: 0.0288, 4: 0.01, 5: 0.02}
    assert scene['modal']['export'] is True
    assert scene['impactors'][1]['position'] == [1.0, 2.0, 3.0]
    assert scene['structure']['bearings']['lower']['ky'] == pytest.approx(32000 * LBF_PER_IN)


def test_override_creates_absent_section_with_defaults():
    raw = good()
    del raw['modal']
    scene = validate(SCHEMA, apply_overrides(raw, ['modal.n_modes=4']))
    assert scene['modal']['n_modes'] == 4 and scene['modal']['method'] == 'eigsh'


def test_override_of_unknown_key_fails_at_validation():
    out = apply_overrides(good(), ['modal.n_mode=4'])
    check(out, r"^scene key 'modal\.n_mode': unknown key; did you mean 'n_modes'\?")
    out = apply_overrides(good(), ['solver.dt=1e-5'])
    check(out, r"^scene key 'solver': unknown key")


def test_override_bad_value_fails_at_validation():
    out = apply_overrides(good(), ['impactors[0].clearance=3 lb'])
    check(out, r"'impactors\[0\]\.clearance': unit 'lb' is not a length")


@pytest.mark.parametrize('override, pattern', [
    ('impactors[2].mass=2 lb', r"^override 'impactors\[2\]\.mass=2 lb': index 2 is past the end "
                               r"of list 'impactors' \(length 2\)$"),
    ('impactors.5.mass=2 lb', r"index 5 is past the end of list 'impactors' \(length 2\)"),
    ('impactors[0].position.value[3]=1',
     r"index 3 is past the end of list 'impactors\[0\]\.position\.value' \(length 3\)"),
    ('impactors[0].position[0]=1', r"'impactors\[0\]\.position' is a mapping, not a list"),
    ('sensors[0].x=1', r"index 0 is past the end of list 'sensors' \(the key is absent"),
    ('impactors.mass=1', r"'impactors' is a list; index it with a number"),
    ('modal[0]=1', r"'modal' is a mapping, not a list"),
    ('speed.value=3', r"'speed' is str '7878 rpm', not a mapping or list"),
    ('impactors[0].mass.value=3', r"'impactors\[0\]\.mass' is str '25 lb'"),
    ('speed', r"override 'speed': expected \"key=value\""),
    ('a..b=1', r"cannot read key path 'a\.\.b'"),
    ('[0].a=1', r"cannot read key path"),
    ('a[x]=1', r"cannot read key path"),
    ('=1', r"cannot read key path ''"),
    ('speed=[1, 2', r"override 'speed=\[1, 2': value is not valid YAML"),
    ('speed={a: 1, a: 2}', r"value is not valid YAML: found duplicate key 'a'"),
])
def test_bad_overrides(override, pattern):
    raw = with_(('speed',), '7878 rpm')
    with pytest.raises(SceneError, match=pattern):
        apply_overrides(raw, [override])


def test_all_bad_overrides_reported_together():
    with pytest.raises(SceneError) as info:
        apply_overrides(good(), ['impactors[9].mass=1', 'x', 'speed=3'])
    assert len(info.value.errors) == 2


def test_overrides_must_be_a_sequence():
    with pytest.raises(TypeError, match='sequence'):
        apply_overrides(good(), 'speed=3')


def test_empty_override_value_is_null():
    out = apply_overrides(good(), ['impactors[0].clearance_min='])
    assert validate(SCHEMA, out)['impactors'][0]['clearance_min'] is None
    check(apply_overrides(good(), ['speed=']), r"'speed': is empty \(null\)")


# --- describe / markdown -----------------------------------------------------------------------

def test_describe_rows():
    rows = {row.key: row for row in describe(SCHEMA)}
    assert all(isinstance(row, KeyInfo) for row in rows.values())
    assert rows['structure.bearings.lower.ky'] == KeyInfo(
        'structure.bearings.lower.ky', 'stiffness', 'required', '[0, inf) N/m',
        'lower bearing stiffness')
    assert rows['structure.bearings.lower.kz'].default == '32000 lb/in'
    assert rows['structure.E'].range == '(0, inf) Pa'
    assert rows['impactors'].kind == 'list of section'
    assert rows['impactors'].range == '1..3 items'
    assert rows['impactors[].clearance'] == KeyInfo(
        'impactors[].clearance', 'length', '2.5 mil', '[1e-08, 0.01] m', '')
    assert rows['impactors[].clearance_min'].default == 'none'
    assert rows['impactors[].position'].default == '[0, 0, 0] in'
    assert rows['impactors[].restitution'].range == '[0, 1)'
    assert rows['speed'].default == '7878 rpm'
    assert rows['modal.zeta'].kind == 'map of integer to dimensionless'
    assert rows['modal.zeta.<integer>'].range == '[0, 1]'
    assert rows['modal.method'].range == 'eigsh | dense'
    assert rows['modal.export'].default == 'false'
    assert 'impactors[]' not in rows   # a list of sections lists the section's keys
    assert [r.key for r in describe(SCHEMA)][:3] == [
        'structure', 'structure.bearings', 'structure.bearings.lower']


def test_describe_list_of_scalars():
    schema = Section({'gaps': ListOf(Quantity('length', min=0), default=[], doc='gaps')})
    rows = describe(schema)
    assert [r.key for r in rows] == ['gaps', 'gaps[]']
    assert rows[1].kind == 'length' and rows[1].default == ''


def test_markdown_table():
    text = markdown_table(SCHEMA)
    lines = text.splitlines()
    assert lines[0] == '| Key | Type | Default | Range | Description |'
    assert ('| `structure.bearings.lower.ky` | stiffness | `required` | [0, inf) N/m '
            '| lower bearing stiffness |') in lines
    assert '| `modal.method` | choice | `eigsh` | eigsh \\| dense |  |' in lines
    assert '| Dimension | SI unit | Accepted units |' in lines
    assert any(line.startswith('| stiffness | N/m | `N/m`') and '`lb/in`' in line
               for line in lines)
    assert '| Dimension' not in markdown_table(SCHEMA, units=False)


# --- import weight -----------------------------------------------------------------------------

def test_core_import_is_light():
    code = ('import sys, impact_damper_sim.scene, impact_damper_sim.scene.units; '
            "heavy = [m for m in ('numpy', 'scipy', 'numba', 'rclpy') if m in sys.modules]; "
            'assert not heavy, heavy')
    root = Path(__file__).resolve().parents[1]
    subprocess.run([sys.executable, '-c', code], cwd=root, check=True)
