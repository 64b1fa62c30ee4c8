"""The accelerometer channel's scene side (issue 36 items 1 and 8): the keys and their units,
the presets, per-node precedence, the refusals, and the shipped scenes' presets."""
import copy
import json
import math
from fractions import Fraction

import pytest
import yaml

from impact_damper_sim.scene.accelerometers import (
    accelerometer_channels,
    channel_of,
    resonance_problem,
)
from impact_damper_sim.scene.build import load
from impact_damper_sim.scene.catalog import available_scenes, resolve_scene
from impact_damper_sim.scene.channel_spec import PRESETS, STAGES, preset_channel
from impact_damper_sim.scene.keytable import describe
from impact_damper_sim.scene.schema import SceneError
from impact_damper_sim.scene.spec import SCHEMA

G0 = Fraction('9.80665')      # exact, independent of the module under test
PRESET_LIST = 'ideal | iepe_100mv_50g | iepe_10mv_500g | mems_16g'
OFF = {stage: None for stage in STAGES}

# A cantilever with a triaxial-ish accelerometer at the tip (node 5: uy, uz) and one at node 3.
THREE_SENSORS = ('sensors=[{name: tip_y, node: 5, dof: uy}, {name: tip_z, node: 5, dof: uz}, '
                 '{name: mid_y, node: 3, dof: uy}]')


def f(x):
    """The correctly rounded double of an exact value."""
    return float(x)


def channel(value, scene='sdof', extra=()):
    """The resolved top-level channel of ``scene`` with ``channel`` set to ``value``."""
    return load(scene, [f'channel={json.dumps(value)}', *extra]).scene['channel']


def refusal(overrides, scene='sdof'):
    """The lines of the SceneError of loading ``scene`` with ``overrides``."""
    with pytest.raises(SceneError) as info:
        load(scene, overrides)
    return info.value.errors


# --- units: each key converts to SI (closed forms) ------------------------------------------

def test_every_key_converts_its_units_to_si():
    c = channel({
        'preset': 'ideal',
        'sensitivity': '98.7 mV/g',
        'sensitivity_error': ['2 %', -0.01, '0 %'],
        'orientation': ['90 deg', '-45 deg', '10 mrad'],
        'transverse': {'fraction': '3 %', 'angle': '30 deg'},
        'resonance': {'frequency': '35 kHz', 'q': 25},
        'highpass': {'corner': '0.5 Hz'},
        'noise_density': '1.5 ug/sqrt(Hz)',
        'bias': {'turn_on': '20 mg', 'gauss_markov': {'sigma': '60 ug/sqrt(h)', 'tau': '5 min'},
                 'random_walk': '3e-3 m/s^3/sqrt(Hz)'},
        'range': '50 g',
        'adc': {'bits': 24, 'full_scale': '5000 mV', 'noise': '50 uV'},
    })
    assert c['preset'] == 'ideal'
    assert c['sensitivity'] == pytest.approx(f(Fraction('0.0987') / G0), rel=1e-15)
    assert c['sensitivity_error'] == pytest.approx([0.02, -0.01, 0.0], rel=1e-15)
    assert c['orientation'] == pytest.approx([math.pi / 2, -math.pi / 4, 0.01], rel=1e-15)
    assert c['transverse'] == pytest.approx({'fraction': 0.03, 'angle': math.pi / 6}, rel=1e-15)
    assert c['resonance'] == {'frequency': 35000.0, 'q': 25.0}
    assert c['highpass'] == {'corner': 0.5}
    assert c['noise_density'] == pytest.approx(f(Fraction('1.5e-6') * G0), rel=1e-15)
    assert c['bias']['turn_on'] == pytest.approx(f(Fraction('0.02') * G0), rel=1e-15)
    # 60 ug/sqrt(h) = 60e-6 g0 / sqrt(3600 s) = 1e-6 g0 per sqrt(s)
    assert c['bias']['gauss_markov'] == pytest.approx({'sigma': f(Fraction('1e-6') * G0),
                                                       'tau': 300.0}, rel=1e-15)
    assert c['bias']['random_walk'] == 3e-3
    assert c['range'] == pytest.approx(f(50 * G0), rel=1e-15)
    assert c['adc'] == pytest.approx({'bits': 24, 'full_scale': 5.0, 'noise': 5e-5}, rel=1e-15)
    assert isinstance(c['adc']['bits'], int)
    json.dumps(c)   # plain, serialisable


@pytest.mark.parametrize('text, si', [
    ('100 mV/g', Fraction('0.1') / G0),
    ('0.1 V/g', Fraction('0.1') / G0),
    ('10.2 mV/(m/s^2)', Fraction('0.0102')),
    ('0.0102 V/(m/s²)', Fraction('0.0102')),
    (0.0102, Fraction('0.0102')),
])
def test_sensitivity_spellings(text, si):
    assert channel({'sensitivity': text})['sensitivity'] == pytest.approx(f(si), rel=1e-15)


@pytest.mark.parametrize('text', ['25 ug/sqrt(Hz)', '25 ug/rtHz', '25 µg/√Hz', '25 ug/rt(Hz)',
                                  '0.025 mg/sqrt(Hz)', '2.5e-5 g/sqrt(Hz)'])
def test_noise_density_spellings(text):
    assert channel({'noise_density': text})['noise_density'] == pytest.approx(
        f(Fraction('25e-6') * G0), rel=1e-15)


def test_noise_density_in_si():
    assert channel({'noise_density': '4e-3 (m/s^2)/sqrt(Hz)'})['noise_density'] == 4e-3
    assert channel({'noise_density': 4e-3})['noise_density'] == 4e-3


def test_highpass_time_constant_is_a_corner():
    assert channel({'highpass': {'time_constant': '2 s'}})['highpass'] == {
        'corner': 1 / (2 * math.pi * 2.0)}


# --- presets ---------------------------------------------------------------------------------

IEPE_DAQ = {'bits': 24, 'full_scale': 5.0, 'noise': f(50 * Fraction(1, 10 ** 6))}
DOCUMENTED = {
    'ideal': OFF,
    'iepe_100mv_50g': {
        **OFF, 'sensitivity': f(Fraction('0.1') / G0), 'range': f(50 * G0),
        'noise_density': f(Fraction('1.5e-6') * G0), 'highpass': {'corner': 0.5},
        'resonance': {'frequency': 35e3, 'q': 25.0},
        'transverse': {'fraction': 0.02, 'angle': 0.0}, 'adc': IEPE_DAQ},
    'iepe_10mv_500g': {
        **OFF, 'sensitivity': f(Fraction('0.01') / G0), 'range': f(500 * G0),
        'noise_density': f(Fraction('15e-6') * G0), 'highpass': {'corner': 0.5},
        'resonance': {'frequency': 50e3, 'q': 25.0},
        'transverse': {'fraction': 0.02, 'angle': 0.0}, 'adc': IEPE_DAQ},
    'mems_16g': {
        **OFF, 'sensitivity': f(1 / G0), 'range': f(16 * G0),
        'noise_density': f(Fraction('70e-6') * G0),
        'bias': {'turn_on': f(Fraction('0.02') * G0),
                 'gauss_markov': {'sigma': 3e-3, 'tau': 300.0}, 'random_walk': None},
        'transverse': {'fraction': 0.02, 'angle': 0.0},
        'adc': {'bits': 16, 'full_scale': 16.0, 'noise': 0.0}},
}


def test_the_presets_are_the_documented_ones():
    assert tuple(PRESETS) == tuple(DOCUMENTED)


@pytest.mark.parametrize('name', list(DOCUMENTED))
def test_each_preset_resolves_to_its_documented_si_values(name):
    expected = {'preset': name, **DOCUMENTED[name]}
    assert _nested_equal(preset_channel(name), expected)
    # by name, as a mapping, and through a scene: the same resolved channel
    assert channel(name) == preset_channel(name)
    assert channel({'preset': name}) == preset_channel(name)


def _nested_equal(a, b):
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_nested_equal(a[k], b[k]) for k in a)
    if isinstance(a, float) and isinstance(b, float):
        return math.isclose(a, b, rel_tol=1e-15)
    return a == b


def test_preset_values_in_their_own_units():
    c = preset_channel('iepe_100mv_50g')
    assert c['sensitivity'] * float(G0) * 1e3 == pytest.approx(100.0, rel=1e-15)   # mV/g
    assert c['adc']['full_scale'] / c['sensitivity'] == pytest.approx(c['range'], rel=1e-15)
    lsb_g = 2 * c['adc']['full_scale'] / 2 ** 24 / c['sensitivity'] / float(G0)
    assert lsb_g == pytest.approx(5.96e-6, rel=1e-3)                    # notes: ~6 ug
    mems = preset_channel('mems_16g')
    lsb_g = 2 * mems['adc']['full_scale'] / 2 ** 16 / mems['sensitivity'] / float(G0)
    assert lsb_g == pytest.approx(1 / 2048, rel=1e-15)                 # 2048 LSB/g
    gm = mems['bias']['gauss_markov']
    assert gm['sigma'] * math.sqrt(gm['tau'] / 2) == pytest.approx(3e-3 * math.sqrt(150), rel=1e-15)


def test_a_scene_without_channel_is_ideal():
    raw = yaml.safe_load(resolve_scene('sdof').read_text())
    del raw['channel']
    from impact_damper_sim.scene.schema import validate
    scene = validate(SCHEMA, raw)
    assert scene['channel'] == {'preset': 'ideal', **OFF}
    assert scene['sensors'][0]['channel'] is None


def test_resolved_channels_are_fresh_copies():
    first = preset_channel('mems_16g')
    first['bias']['turn_on'] = 1.0
    assert preset_channel('mems_16g')['bias']['turn_on'] != 1.0


# --- overriding and nulling stages -----------------------------------------------------------

def test_a_stage_key_overrides_the_preset_and_null_switches_one_off():
    c = channel({'preset': 'iepe_100mv_50g', 'sensitivity': '98.7 mV/g', 'transverse': None})
    expected = preset_channel('iepe_100mv_50g')
    expected.update(sensitivity=f(Fraction('0.0987') / G0), transverse=None)
    assert _nested_equal(c, expected)


def test_a_stage_is_overridden_key_by_key():
    """A dotted override changes one key of a preset's stage and keeps the rest (it replaced
    the whole stage: 'channel.resonance.frequency=40 kHz' was refused for a missing q, and
    'bias.turn_on' dropped mems_16g's Gauss-Markov bias); null switches a part off; a
    highpass given replaces the preset's (one of corner and time_constant)."""
    preset = preset_channel('mems_16g')
    c = channel({'preset': 'mems_16g', 'bias': {'turn_on': '5 mg'}})
    assert c['bias'] == {'turn_on': pytest.approx(f(Fraction('0.005') * G0), rel=1e-15),
                         'gauss_markov': preset['bias']['gauss_markov'], 'random_walk': None}
    c = channel({'preset': 'mems_16g', 'bias': {'gauss_markov': {'tau': '100 s'}}})
    assert c['bias']['gauss_markov'] == {'sigma': preset['bias']['gauss_markov']['sigma'],
                                         'tau': 100.0}
    assert channel({'preset': 'mems_16g', 'bias': {'gauss_markov': None}})['bias'] == {
        'turn_on': preset['bias']['turn_on'], 'gauss_markov': None, 'random_walk': None}
    assert channel({'preset': 'mems_16g', 'bias': {'turn_on': None, 'gauss_markov': None}}
                   )['bias'] is None   # nothing left of it
    c = channel({'preset': 'iepe_100mv_50g', 'resonance': {'frequency': '40 kHz'}})
    assert c['resonance'] == {'frequency': 40000.0, 'q': 25.0}
    c = channel({'preset': 'iepe_100mv_50g', 'highpass': {'time_constant': '1 s'}})
    assert c['highpass'] == {'corner': pytest.approx(1 / (2 * math.pi), rel=1e-15)}
    scene = load('hpotp', overrides=['channel.resonance.frequency=40 kHz',
                                     'channel.adc.noise=10 uV'])
    assert scene.scene['channel']['resonance'] == {'frequency': 40000.0, 'q': 25.0}
    assert scene.scene['channel']['adc'] == dict(preset_channel('iepe_10mv_500g')['adc'],
                                                 noise=pytest.approx(1e-5, rel=1e-15))


def test_channel_ideal_override_switches_a_shipped_preset_off():
    assert load('hpotp', ['channel=ideal']).scene['channel'] == preset_channel('ideal')
    assert load('hpotp', ['channel.preset=ideal']).scene['channel'] == preset_channel('ideal')
    assert load('hpotp', ['channel.adc=']).scene['channel']['adc'] is None


# --- per-node precedence ---------------------------------------------------------------------

def test_a_sensor_channel_applies_to_its_accelerometer_only():
    scene = load('cantilever', [THREE_SENSORS, 'sensors.0.channel=mems_16g'])
    assert scene.scene['sensors'][0]['channel'] == preset_channel('mems_16g')
    assert scene.scene['sensors'][1]['channel'] is None
    # node 5: tip_y states it and tip_z does not: one accelerometer, mems_16g
    assert channel_of(scene, 5) == preset_channel('mems_16g')
    # node 3 states none: the scene's channel
    assert channel_of(scene, 3) == preset_channel('iepe_100mv_50g')
    assert channel_of(scene.scene, 3) == scene.scene['channel']
    assert accelerometer_channels(scene) == {5: preset_channel('mems_16g'),
                                             3: preset_channel('iepe_100mv_50g')}


def test_the_same_channel_in_other_units_is_one_channel():
    scene = load('cantilever', [THREE_SENSORS,
                                'sensors.0.channel={sensitivity: 100 mV/g}',
                                'sensors.1.channel={sensitivity: 0.1 V/g}'])
    assert channel_of(scene, 5)['sensitivity'] == pytest.approx(f(Fraction('0.1') / G0))


def test_two_channels_at_one_node_are_refused_naming_both():
    assert refusal([THREE_SENSORS, 'sensors.0.channel=mems_16g',
                    'sensors.1.channel=iepe_100mv_50g'], 'cantilever') == (
        "scene key 'sensors': node 5 has sensors with different channels: sensors[0].channel "
        '(preset mems_16g) and sensors[1].channel (preset iepe_100mv_50g); one node is one '
        'triaxial accelerometer: give its sensors one channel',)
    assert refusal([THREE_SENSORS, 'sensors.0.channel={sensitivity: 100 mV/g}',
                    'sensors.1.channel={sensitivity: 99 mV/g}'], 'cantilever') == (
        "scene key 'sensors': node 5 has sensors with different channels: sensors[0].channel "
        '(preset ideal, sensitivity 0.0101972 V/(m/s^2)) and sensors[1].channel (preset ideal, '
        'sensitivity 0.0100952 V/(m/s^2)); one node is one triaxial accelerometer: give its '
        'sensors one channel',)


def test_channel_of_a_node_without_sensors():
    with pytest.raises(ValueError, match=r'^no accelerometer at node 2; accelerometers are at '
                                         r'nodes \[3, 5\]$'):
        channel_of(load('cantilever', [THREE_SENSORS]), 2)


# --- refusals: one line naming the key and its allowed range ----------------------------------

@pytest.mark.parametrize('overrides, line', [
    (['channel=iepe'],
     "scene key 'channel': 'iepe' is not a channel preset; did you mean 'iepe_100mv_50g' or "
     f"'iepe_10mv_500g'? use one of {PRESET_LIST}"),
    (['channel={preset: mems16g}'],
     "scene key 'channel.preset': 'mems16g' is not a channel preset; did you mean 'mems_16g'? "
     f'use one of {PRESET_LIST}'),
    (['channel=12'],
     "scene key 'channel': expected a channel preset (" + PRESET_LIST + ') or a mapping of '
     'preset and stage keys (preset, sensitivity, sensitivity_error, orientation, transverse, '
     'resonance, highpass, noise_density, bias, range, adc); got int 12'),
    (['channel={preset: iepe_100mv_50g, sensitivty: 98 mV/g}'],
     "scene key 'channel.sensitivty': unknown key; did you mean 'sensitivity'? (known keys "
     'here: preset, sensitivity, sensitivity_error, orientation, transverse, resonance, '
     'highpass, noise_density, bias, range, adc)'),
    (['channel={bias: {turn_on: 1 mg, drift: 2 mg}}'],
     "scene key 'channel.bias.drift': unknown key (known keys here: turn_on, gauss_markov, "
     'random_walk)'),
    (['channel={preset: iepe_100mv_50g, adc: {bits: 0, full_scale: 5 V}}'],
     "scene key 'channel.adc.bits': 0 is out of range [8, 32]"),
    (['channel={noise_density: -1.5 ug/sqrt(Hz)}'],
     "scene key 'channel.noise_density': -1.5 ug/sqrt(Hz) = -1.4709975e-05 m/s^2/sqrt(Hz) is "
     'out of range [0, inf) m/s^2/sqrt(Hz) (= [0, inf) ug/sqrt(Hz))'),
    (['channel={resonance: {frequency: 30 kHz, q: 0.5}}'],
     "scene key 'channel.resonance.q': 0.5 is out of range (0.5, 1000]"),
    (['channel={resonance: {frequency: 30 kHz, q: 2000}}'],
     "scene key 'channel.resonance.q': 2000 is out of range (0.5, 1000]"),
    (['channel={adc: {bits: 16, full_scale: 5 V}}'],
     "scene key 'channel.adc': needs a sensitivity to turn acceleration into volts "
     "(sensitivity is off); give 'sensitivity' (e.g. 100 mV/g) or adc: null"),
    (['channel={preset: iepe_100mv_50g, sensitivity: null}'],
     "scene key 'channel.adc': needs a sensitivity to turn acceleration into volts "
     "(sensitivity is off); give 'sensitivity' (e.g. 100 mV/g) or adc: null"),
    (['channel={highpass: {corner: 0.5 Hz, time_constant: 1 s}}'],
     "scene key 'channel.highpass': give exactly one of 'corner' and 'time_constant' (got "
     'corner, time_constant)'),
    (['channel={sensitivity_error: [0, 60 %, 0]}'],
     "scene key 'channel.sensitivity_error[1]': 60 % = 0.6 is out of range [-0.5, 0.5] "
     '(= [-50, 50] %)'),
    (['channel={transverse: {fraction: 0.25}}'],
     "scene key 'channel.transverse.fraction': 0.25 is out of range [0, 0.2]"),
    (['channel={range: 0 g}'],
     "scene key 'channel.range': 0 g = 0 m/s^2 is out of range (0, inf) m/s^2 (= (0, inf) g)"),
    (['channel={sensitivity: 100 mV/s}'],
     "scene key 'channel.sensitivity': unknown unit 'mV/s' for a sensitivity; did you mean "
     "'mV/g'? use one of V/(m/s^2), mV/(m/s^2), V/g, mV/g"),
    (['sensors.0.channel=iepe'],
     "scene key 'sensors[0].channel': 'iepe' is not a channel preset; did you mean "
     f"'iepe_100mv_50g' or 'iepe_10mv_500g'? use one of {PRESET_LIST}"),
])
def test_bad_channel_is_refused_in_one_line(overrides, line):
    assert refusal(overrides) == (line,)


def test_resonance_below_the_anti_alias_band_edge_is_refused_naming_both():
    assert refusal(['sensors.0.lowpass=800 Hz',
                    'channel={resonance: {frequency: 500 Hz, q: 10}}'], 'cantilever') == (
        "scene key 'channel.resonance.frequency': 500 Hz is not above the anti-alias band edge "
        '800 Hz (sensors[0].lowpass, node 5); a mounted resonance must lie above the measured '
        'band: raise it, or lower the lowpass',)
    # stated by a sensor, from a preset: that sensor's key, and the preset named
    assert refusal([THREE_SENSORS, 'sensors.1.lowpass=2 kHz', 'sensors.0.lowpass=5 kHz',
                    'sensors.0.channel={preset: mems_16g, resonance: {frequency: 1.5 kHz, '
                    'q: 5}}'], 'cantilever') == (
        "scene key 'sensors[0].channel.resonance.frequency': 1500 Hz (preset mems_16g) is not "
        'above the anti-alias band edge 2000 Hz (sensors[1].lowpass, node 5); a mounted '
        'resonance must lie above the measured band: raise it, or lower the lowpass',)
    # above the band edge: accepted
    assert load('cantilever', ['sensors.0.lowpass=800 Hz', 'channel={resonance: {frequency: '
                               '801 Hz, q: 10}}']).scene['channel']['resonance']['q'] == 10.0


def test_the_run_time_band_edge_check():
    iepe = preset_channel('iepe_100mv_50g')
    assert resonance_problem(iepe, 8000.0) is None
    assert resonance_problem(preset_channel('ideal'), 1e9) is None
    assert resonance_problem(iepe, 40e3, 'default lowpass 0.4 x 100 kHz') == (
        '35000 Hz (preset iepe_100mv_50g) is not above the anti-alias band edge 40000 Hz '
        '(default lowpass 0.4 x 100 kHz); a mounted resonance must lie above the measured '
        'band: raise it, or lower the lowpass')


def test_every_problem_of_a_channel_is_reported_together():
    lines = refusal(['channel={adc: {bits: 40, full_scale: -5 V}, q: 3}'])
    assert [line.split("'")[1] for line in lines] == ['channel.q', 'channel.adc.bits',
                                                      'channel.adc.full_scale']


# --- the shipped scenes ----------------------------------------------------------------------

SHIPPED = {'sdof': 'iepe_10mv_500g', 'cantilever': 'iepe_100mv_50g', 'rbs': 'iepe_100mv_50g',
           'rbs_kcc': 'iepe_10mv_500g', 'hpotp': 'iepe_10mv_500g',
           'hpotp_x10': 'iepe_10mv_500g', 'ross_rotor': 'mems_16g'}


def test_every_shipped_scene_is_listed_here():
    assert sorted(SHIPPED) == available_scenes()


@pytest.mark.parametrize('name', sorted(SHIPPED))
def test_every_shipped_scene_names_a_realistic_preset_and_loads(name):
    text = resolve_scene(name).read_text()
    raw = yaml.safe_load(text)
    assert raw['channel'] == {'preset': SHIPPED[name]}    # a mapping: channel.<stage>= works
    assert '# Accelerometer channel' in text              # with the reason why
    scene = load(name)
    assert scene.scene['channel'] == preset_channel(SHIPPED[name])
    assert all(s['channel'] is None for s in scene.scene['sensors'])
    for node in {s['node'] for s in scene.scene['sensors']}:
        assert channel_of(scene, node) == preset_channel(SHIPPED[name])


# --- the key table ----------------------------------------------------------------------------

def test_the_key_table_lists_the_channel_keys():
    rows = {row.key: row for row in describe(SCHEMA)}
    for key in ['channel', 'channel.preset', 'sensors[].channel', 'channel.adc.bits',
                'channel.highpass.time_constant', 'channel.bias.gauss_markov.tau',
                *(f'channel.{stage}' for stage in STAGES)]:
        assert key in rows and rows[key].doc, key
    assert rows['channel'].default == 'ideal'
    assert rows['sensors[].channel'].default == 'none'
    assert rows['channel.sensitivity'].default == 'preset'
    assert rows['channel.noise_density'].range == '[0, inf) m/s^2/sqrt(Hz)'
    assert rows['channel.resonance.q'].range == '(0.5, 1000]'
    assert rows['channel.adc.bits'].range == '[8, 32]'
    assert not any(key.startswith('sensors[].channel.') for key in rows)   # listed once


def test_presets_are_plain_data():
    before = copy.deepcopy(PRESETS)
    load('hpotp', ['channel={preset: iepe_10mv_500g, range: 200 g}'])
    assert PRESETS == before
