"""Sensor faults (issue 36, item 3): each fault in its window and nowhere else, its closed form
or statistics, chunking and seeds, and the refusals' exact one-line messages.

Sample n is at t = n / fs (as LiveSimulation's, from n = 1); a fault of onset t0 and duration
d acts on the samples with t0 < t <= t0 + d. Statistical tolerances are 4 standard deviations
of the estimate, stated at each test; the measured values are in the commit message.
"""
import json
import math

import numpy as np
import pytest

from impact_damper_sim.live.channel import SensorChannel
from impact_damper_sim.live.channel_keys import SPEC_KEYS
from impact_damper_sim.live.fault_spec import (
    FAULT,
    KINDS,
    FaultError,
    FaultSpec,
    parse_command,
    parse_fault,
    parse_faults,
)
from impact_damper_sim.live.faults import OPEN_OVERDRIVE, FaultInjector, channel_rail
from impact_damper_sim.scene.containers import ListOf, Section
from impact_damper_sim.scene.schema import Quantity, SceneError, validate

G = 9.80665
FS = 1000.0
NAMES = ['casing', 'bearing']
RAIL = 50 * G


def times(n0, k, fs=FS):
    return np.arange(n0, n0 + k) / fs


def signal(k, seed=0):
    """Nonzero random samples (a zero's sign would blur 'bit-identical')."""
    x = np.random.default_rng(seed).normal(0.0, 10.0, (k, 3))
    x[x == 0] = 1.0
    return x


def bits(a):
    return np.ascontiguousarray(a).view(np.uint64)


def injector(*specs, seed=0, fs=FS, rails=(RAIL, None)):
    inj = FaultInjector(NAMES, fs, seed, rails=list(rails))
    for s in specs:
        inj.add({'accelerometer': 'casing', **s})
    return inj


def run(inj, x, chunks=None, acc=0, n0=1, limit=None):
    """The injector over ``x`` in chunks (sizes; default one pass)."""
    chunks = [len(x)] if chunks is None else chunks
    ys, vs, i = [], [], 0
    for k in chunks:
        y, v = inj.apply(times(n0 + i, k, inj.sample_rate_hz), x[i:i + k], acc, limit=limit)
        ys.append(y)
        vs.append(v)
        i += k
    assert i == len(x)
    return np.concatenate(ys), np.concatenate(vs)


# the window of every test below: 0.25 s < t <= 0.75 s, samples 251 .. 750 (index 250 .. 749)
WINDOW = {'onset': '250 ms', 'duration': '0.5 s'}
IN = np.zeros(1000, bool)
IN[250:750] = True

KIND_SPECS = {
    'stuck': {'kind': 'stuck'},
    'dropout': {'kind': 'dropout'},
    'spikes': {'kind': 'spikes', 'rate': '40 Hz', 'amplitude': '3 g', 'width': 2, 'seed': 1},
    'bias': {'kind': 'bias', 'step': '0.5 g', 'drift': '2 g/s'},
    'gain': {'kind': 'gain', 'gain': 5},
    'intermittent': {'kind': 'intermittent', 'mean_on': '20 ms', 'mean_off': '10 ms',
                     'seed': 2},
    'intermittent_dropout': {'kind': 'intermittent', 'mean_on': '20 ms', 'mean_off': '10 ms',
                             'off': 'dropout', 'seed': 2},
}


@pytest.mark.parametrize('kind', sorted(KIND_SPECS))
def test_each_fault_appears_in_its_window_and_nowhere_else(kind):
    x = signal(1000)
    inj = injector({**KIND_SPECS[kind], **WINDOW})
    y, valid = run(inj, x)
    # outside: bit-identical and there
    assert np.array_equal(bits(y[~IN]), bits(x[~IN]))
    assert valid[~IN].all()
    changed = (y != x).any(axis=1)
    missing = ~valid
    assert (changed | missing)[IN].any()
    assert inj.labels()[0]['onset_s'] == 0.25 and inj.labels()[0]['end_s'] == 0.75
    assert inj.labels()[0]['samples'] == 500
    if kind in ('dropout', 'intermittent_dropout'):
        assert np.array_equal(bits(y), bits(x))   # missing, not changed (nor zeros)
    else:
        assert valid.all()
    if kind in ('dropout', 'stuck', 'bias', 'gain'):
        assert (changed | missing)[IN].all()


def test_a_fault_on_some_axes_leaves_the_others_bit_identical():
    x = signal(1000)
    for kind in ('stuck', 'spikes', 'bias', 'gain', 'intermittent'):
        y, _ = run(injector({**KIND_SPECS[kind], **WINDOW, 'axes': 'xz'}), x)
        assert np.array_equal(bits(y[:, 1]), bits(x[:, 1])), kind
        assert (y[IN][:, [0, 2]] != x[IN][:, [0, 2]]).any(), kind


def test_another_accelerometer_is_untouched():
    x = signal(1000)
    inj = injector(*[{**KIND_SPECS[k], **WINDOW, 'name': k} for k in KIND_SPECS])
    y, valid = run(inj, x, acc=1)
    assert np.array_equal(bits(y), bits(x)) and valid.all()


@pytest.mark.parametrize('chunks', [None, [250, 750], [249, 1, 750], [100] * 10])
def test_stuck_holds_the_last_pre_onset_value_exactly(chunks):
    """Sample 250 (index 249) is the last before the onset; with [250, 750] it is the last of
    the previous chunk."""
    x = signal(1000)
    y, _ = run(injector({'kind': 'stuck', **WINDOW}), x, chunks)
    assert np.array_equal(bits(y[IN]), bits(np.broadcast_to(x[249], (500, 3))))


def test_stuck_added_live_holds_the_last_value_published():
    x = signal(1000)
    inj = injector()
    y1, _ = inj.apply(times(1, 400), x[:400], 0)
    name = inj.add({'kind': 'stuck', 'accelerometer': 'casing', 'duration': '100 ms'})
    y2, _ = inj.apply(times(401, 600), x[400:], 0)
    assert np.array_equal(bits(y2[:100]), bits(np.broadcast_to(x[399], (100, 3))))
    assert np.array_equal(bits(y2[100:]), bits(x[500:]))
    label = inj.labels()[0]
    assert (name, label['onset_s'], label['end_s']) == ('stuck-1', 0.4, 0.5)


def test_stuck_from_the_first_sample_holds_that_sample():
    x = signal(10)
    y, _ = run(injector({'kind': 'stuck', 'onset': 0}), x)
    assert np.array_equal(bits(y), bits(np.broadcast_to(x[0], (10, 3))))


def test_dropout_mask_is_false_exactly_in_the_window_and_valid_at_agrees():
    x = signal(1000)
    inj = injector({'kind': 'dropout', **WINDOW})
    _, valid = run(inj, x, [333, 333, 334])
    assert np.array_equal(valid, ~IN)
    assert np.array_equal(inj.valid_at(times(1, 1000), 0), ~IN)
    # e.g. an Imu stream at a tenth of the rate: the samples its values stand for
    assert np.array_equal(inj.valid_at(np.arange(10, 1001, 10) / FS, 0), ~IN[9::10])
    assert inj.valid_at(times(1, 1000), 1).all()


def test_spikes_at_the_stated_rate_and_amplitude():
    """Poisson: 100 /s for 100 s at 10 kHz. Count N within 4 sqrt(N) of 10000; counts per
    0.1 s bin with an index of dispersion (variance / mean) within 1 +- 0.2 (4 sd of the
    estimate, sqrt(2 / 999) = 0.045); the output is the input plus +-amplitude over width
    samples at every labelled start, exactly."""
    fs, rate, span, amp, width = 10000.0, 100.0, 100.0, 20.0, 3
    x = np.zeros((int(fs * span), 3))
    inj = FaultInjector(NAMES, fs, 5)
    inj.add({'kind': 'spikes', 'accelerometer': 'casing', 'onset': 0, 'duration': span,
             'rate': rate, 'amplitude': amp, 'width': width})
    y, _ = run(inj, x, [100000] * 10)
    events = inj.labels()[0]['events']
    starts = np.rint(np.array(events['t_s']) * fs).astype(int)
    n = len(starts)
    expected = rate * span
    assert abs(n - expected) < 4 * math.sqrt(expected), n
    counts = np.bincount(((starts - 1) // int(0.1 * fs)), minlength=1000)[:1000]
    dispersion = counts.var(ddof=1) / counts.mean()
    assert abs(dispersion - 1.0) < 0.2, dispersion
    rebuilt = np.zeros(len(x))
    for k in range(width):   # reconstruct from the labels (start index n is row n - 1)
        rows = starts - 1 + k
        np.add.at(rebuilt, rows[rows < len(x)], amp * np.array(events['sign'])[rows < len(x)])
    assert np.array_equal(y, np.repeat(rebuilt[:, None], 3, axis=1))
    single = np.abs(rebuilt[rebuilt != 0])
    assert np.mean(single == amp) > 0.9 and set(np.unique(single)) <= {amp, 2 * amp, 3 * amp}
    gaps = np.diff(starts) / fs
    assert abs(gaps.mean() - 1 / rate) < 4 * (1 / rate) / math.sqrt(n)


def test_bias_step_and_drift_follow_their_closed_form():
    """bias(t) = step + drift (t - onset), relative error < 1e-12."""
    x = np.zeros((1000, 3))
    inj = injector({'kind': 'bias', 'step': '0.5 g', 'drift': '2 g/s', **WINDOW})
    y, _ = run(inj, x, [300, 700])
    t = times(1, 1000)
    onset = inj.labels()[0]['onset_s']
    closed = 0.5 * G + 2 * G * (t[IN] - onset)
    assert np.allclose(y[IN], closed[:, None], rtol=1e-12, atol=0)
    assert abs(y[250, 0] - (0.5 * G + 2 * G / FS)) < 1e-12   # one period after the onset
    assert not y[~IN].any()


def test_gain_is_exact_before_clipping():
    x = signal(1000)
    y, _ = run(injector({'kind': 'gain', 'gain': 5, **WINDOW}), x)
    assert np.array_equal(bits(y[IN]), bits(x[IN] * 5.0))


def test_a_gain_drives_the_channel_into_clipping_through_the_hook():
    """x5 on a +-50 g, 100 mV/g, 24-bit channel: in the window the samples are the channel's
    limit of 5 x the fault-free ones; the clip count is the values 5x puts beyond the range;
    every sample stays on the ADC grid; outside the window nothing changes."""
    spec = {k: None for k in SPEC_KEYS}
    spec.update(preset='test', sensitivity=0.1 / G, range=50 * G,
                adc={'bits': 24, 'full_scale': 5.0, 'noise': 0.0})

    def make():
        return SensorChannel(spec, step_rate_hz=FS, decimation=1, lowpass_hz=400.0,
                             name='casing')

    acc = np.zeros((1000, 3))
    acc[:, 0] = 30 * G * np.sin(2 * np.pi * 7 * np.arange(1000) / FS)   # peak 30 g, x5 = 150 g
    clean = make().process(acc)
    channel = make()
    inj = FaultInjector.for_channels([channel], seed=0)
    top = 2.0 ** 23 - 1   # the ADC's top code: 50 g - 1 LSB
    assert inj.rails == [channel_rail(channel)] == [top * channel.lsb]
    inj.add({'kind': 'gain', 'accelerometer': 'casing', 'gain': 5, **WINDOW})
    t = times(1, 1000)
    out = channel.process(acc, before_limit=inj.hook(t, 0))
    y, valid = inj.after_limit(t, out.samples, 0)
    # the signal before the limit: the same chain without range and ADC
    scaled = 5 * SensorChannel(None, step_rate_hz=FS, decimation=1,
                               lowpass_hz=400.0).process(acc).samples[IN]
    codes = np.rint(np.clip(scaled, -50 * G, 50 * G) / channel.lsb)
    assert np.array_equal(y[IN], np.clip(codes, -top - 1, top) * channel.lsb)
    assert np.array_equal(bits(y[~IN]), bits(clean.samples[~IN]))
    assert out.clipped == np.count_nonzero((np.abs(scaled) > 50 * G) | (codes > top)) > 100
    assert clean.clipped == 0 and np.max(np.abs(y)) < 50 * G and valid.all()
    assert np.array_equal(np.rint(y / channel.lsb) * channel.lsb, y)
    assert inj.hook(times(1, 200), 0) is None   # nothing before the onset: no work


def test_intermittent_on_off_fractions_and_periods():
    """Mean on 20 ms, off 5 ms, 200 s at 10 kHz: open fraction 0.2 within 4 sd of an
    alternating renewal process's, sqrt(2 m_on^2 m_off^2 / ((m_on + m_off)^3 T)) = 0.0025;
    the mean open period 5 ms within 4 sd of a mean of N exponentials (5 ms / sqrt(N)) plus
    1 % (open periods between two samples are not seen: ~1 % of them at 50 samples)."""
    fs, on, off, span = 10000.0, 0.02, 0.005, 200.0
    inj = FaultInjector(NAMES, fs, 3)
    inj.add({'kind': 'intermittent', 'accelerometer': 'bearing', 'onset': 0, 'mean_on': on,
             'mean_off': off, 'off': 'dropout'})
    valid = inj.valid_at(times(1, int(span * fs), fs), 1)
    inj.apply(times(1, int(span * fs), fs), np.zeros((int(span * fs), 3)), 1)
    fraction = 1.0 - valid.mean()
    sd = math.sqrt(2 * on ** 2 * off ** 2 / ((on + off) ** 3 * span))
    assert abs(fraction - off / (on + off)) < 4 * sd, (fraction, sd)
    periods = np.array(inj.labels()[0]['events']['open_s'])
    lengths = periods[:, 1] - periods[:, 0]
    assert abs(lengths.mean() - off) < 4 * off / math.sqrt(len(lengths)) + 0.01 * off
    assert abs(len(lengths) - span / (on + off)) < 0.05 * span / (on + off)
    assert not valid[0]   # the connection opens at the onset


def test_intermittent_rail_reads_the_rail_while_open_and_the_signal_while_closed():
    x = signal(1000)
    inj = injector({**KIND_SPECS['intermittent'], **WINDOW})
    y, valid = run(inj, x, limit=lambda v: np.clip(v, -RAIL, RAIL, out=v))
    limited = np.clip(x, -RAIL, RAIL)
    opened = (y != limited).any(axis=1)
    assert valid.all() and opened[250] and not opened[~IN].any()
    assert (y[opened] == RAIL).all()
    assert np.array_equal(y[IN & ~opened], limited[IN & ~opened])
    assert inj.labels()[0]['parameters']['level'] == OPEN_OVERDRIVE * RAIL
    periods = np.array(inj.labels()[0]['events']['open_s'])
    t = times(1, 1000)
    from_labels = ((t[:, None] > periods[:, 0]) & (t[:, None] <= periods[:, 1])).any(axis=1)
    assert np.array_equal(from_labels, opened)


def test_chunked_is_one_pass_bit_for_bit():
    x = signal(3000, seed=4)
    specs = [{**KIND_SPECS[k], 'name': k, 'onset': f'{0.1 + 0.3 * i} s', 'duration': '1.2 s'}
             for i, k in enumerate(KIND_SPECS)]
    one, v_one = run(injector(*specs), x)
    rng = np.random.default_rng(9)
    edges = np.sort(rng.integers(1, 3000, 60))   # some repeat: empty chunks
    sizes = [0, 1] + list(np.diff(np.concatenate([[1], edges, [3000]])))
    chunked, v_chunked = run(injector(*specs), x, sizes)
    assert np.array_equal(bits(one), bits(chunked)) and np.array_equal(v_one, v_chunked)
    a, b = injector(*specs), injector(*specs)
    run(a, x), run(b, x, sizes)
    assert json.dumps(a.labels()) == json.dumps(b.labels())


def test_same_seed_same_output_and_another_seed_another():
    x = signal(1000)
    random = [{**KIND_SPECS[k], **WINDOW, 'name': k, 'seed': None}
              for k in ('spikes', 'intermittent')]
    first = run(injector(*random, seed=7), x)[0]
    assert np.array_equal(bits(first), bits(run(injector(*random, seed=7), x)[0]))
    assert not np.array_equal(first, run(injector(*random, seed=8), x)[0])
    labels = injector(*random, seed=7).labels()
    pinned = [{**r, 'seed': lab['seed']} for r, lab in zip(random, labels)]
    assert np.array_equal(bits(first), bits(run(injector(*pinned, seed=0), x)[0]))


def test_live_add_and_clear():
    """A fault added at sim time t0 starts with the next sample; clear ends it after the
    last sample published; cleared before its onset it touches nothing."""
    x = signal(1000)
    inj = injector()
    inj.apply(times(1, 300), x[:300], 0)
    inj.add({'kind': 'gain', 'accelerometer': 'casing', 'gain': 2, 'name': 'g'})
    inj.add({'kind': 'dropout', 'accelerometer': 'casing', 'onset': 0.9, 'name': 'late'})
    y, _ = inj.apply(times(301, 200), x[300:500], 0)
    assert np.array_equal(y, 2 * x[300:500])
    assert inj.active() == ['g', 'late']
    assert inj.clear() == ['g', 'late'] and inj.active() == []
    y, valid = inj.apply(times(501, 500), x[500:], 0)
    assert np.array_equal(bits(y), bits(x[500:])) and valid.all()
    g, late = inj.labels()
    assert (g['onset_s'], g['end_s'], g['cleared_at_s'], g['samples']) == (0.3, 0.5, 0.5, 200)
    assert late['samples'] == 0 and late['requested'] == {'onset_s': 0.9, 'duration_s': None}


def test_specs_read_units_and_round_trip():
    spec = parse_fault({'kind': 'bias', 'accelerometer': 'casing', 'onset': '2 s',
                        'step': '10 mg', 'drift': '6 mg/min'}, NAMES)
    assert spec.params == {'step': pytest.approx(0.01 * G), 'drift': pytest.approx(1e-4 * G)}
    assert parse_fault(spec.as_dict(), NAMES) == spec
    spikes = parse_fault({'kind': 'spikes', 'accelerometer': 'bearing', 'rate': '120 cpm',
                          'amplitude': {'value': 3, 'unit': 'g'}, 'axes': 'z'}, NAMES)
    assert (spikes.params['rate'], spikes.params['width'], spikes.axes) == (2.0, 1, 'z')
    assert set(KINDS) == set(KIND_SPECS) - {'intermittent_dropout'}


def test_node_commands_in_yaml_and_json():
    add = parse_command('{"kind": "dropout", "accelerometer": "casing", "duration": "50 ms"}',
                        NAMES, key='fault_command')
    assert add.action == 'add' and add.spec == FaultSpec('dropout', 'casing', duration=0.05)
    assert parse_command('clear: all').name is None
    assert parse_command('{clear: g}').name == 'g'
    with pytest.raises(FaultError) as err:
        parse_command('kind: stuck\naccelerometer: casnig', NAMES, key='fault_command')
    assert str(err.value) == ("key 'fault_command.accelerometer': 'casnig' is not an "
                              "accelerometer of this scene; did you mean 'casing'? the "
                              'accelerometers: casing, bearing')


def test_a_schedule_embeds_the_field_and_names_the_entry():
    schema = Section({'schedule': ListOf(Section({'at': Quantity('time'), 'fault': FAULT}))})
    raw = {'schedule': [{'at': '1 s', 'fault': {'kind': 'gain', 'accelerometer': 'casing',
                                                'gain': 5, 'duration': '0.5 s'}},
                        {'at': '2 s', 'fault': {'kind': 'gain', 'accelerometer': 'casing',
                                                'gain': '5 x'}}]}
    with pytest.raises(SceneError) as err:
        validate(schema, raw)
    assert str(err.value) == ("scene key 'schedule[1].fault.gain': unknown unit 'x' for a "
                              'dimensionless; use one of (no unit), %')
    value = validate(schema, {'schedule': raw['schedule'][:1]})
    entry = value['schedule'][0]
    spec = parse_fault(entry['fault'], NAMES)
    assert (spec.kind, spec.params, spec.duration) == ('gain', {'gain': 5.0}, 0.5)
    inj = injector()
    inj.add(spec, now=entry['at'])
    assert inj.labels()[0]['onset_s'] == 1.0


CASING = {'accelerometer': 'casing'}
REFUSED = [
    ({'kind': 'spike', **CASING}, "key 'fault.kind': 'spike' is not allowed; did you mean "
     "'spikes'? use one of gain | bias | spikes | intermittent | stuck | dropout"),
    ({'kind': 'stuck', 'accelerometer': 'casnig'}, "key 'fault.accelerometer': 'casnig' is "
     "not an accelerometer of this scene; did you mean 'casing'? the accelerometers: casing, "
     'bearing'),
    ({'kind': 'spikes', 'rate': '0 Hz', 'amplitude': '3 g', **CASING},
     "key 'fault.rate': 0 Hz is out of range (0, 100000] Hz"),
    ({'kind': 'spikes', 'rate': '20 Hz', 'amplitude': '-3 g', **CASING},
     "key 'fault.amplitude': -3 g = -29.41995 m/s^2 is out of range (0, 1000000] m/s^2 "
     '(= (0, 101972] g)'),
    ({'kind': 'spikes', 'rate': '20 Hz', 'amplitude': '3 g', 'width': 0, **CASING},
     "key 'fault.width': 0 is out of range [1, 10000]"),
    ({'kind': 'spikes', 'rate': '20 Hz', 'amplitude': '3 g', 'seed': -1, **CASING},
     "key 'fault.seed': -1 is out of range [0, 4294967295]"),
    ({'kind': 'stuck', 'duration': '0 s', **CASING},
     "key 'fault.duration': 0 s is out of range (0, 1000000] s"),
    ({'kind': 'stuck', 'onset': '1 m', **CASING}, "key 'fault.onset': unit 'm' is not a time "
     '(it is a length); use one of s, ms, us, min, h'),
    ({'kind': 'stuck', 'seed': 3, **CASING}, "key 'fault.seed': unknown key (known keys here: "
     'kind, accelerometer, name, onset, duration, axes)'),
    ({'kind': 'dropout', 'axes': 'x', **CASING}, "key 'fault.axes': unknown key (known keys "
     'here: kind, accelerometer, name, onset, duration)'),
    ({'kind': 'gain', 'gain': 5000, **CASING},
     "key 'fault.gain': 5000 is out of range [-1000, 1000]"),
    ({'kind': 'gain', 'gain': 5, 'axes': 'zx', **CASING}, "key 'fault.axes': 'zx' is not "
     "allowed; did you mean 'z'? use one of x | y | z | xy | xz | yz | xyz"),
    ({'kind': 'bias', **CASING}, "key 'fault': a bias needs a non-zero 'step' and/or 'drift'"),
    ({'kind': 'bias', 'drift': '5 mg/week', **CASING}, "key 'fault.drift': unknown unit "
     "'mg/week' for an acceleration rate; use m/s^3 or an acceleration unit over a time unit "
     '(m/s^2/s, g/s, mg/min, ug/h)'),
    ({'kind': 'bias', 'drift': '2e6 m/s^3', **CASING},
     "key 'fault.drift': 2000000 m/s^3 is out of range [-1000000, 1000000] m/s^3"),
    ({'kind': 'intermittent', 'mean_on': '10 ms', 'mean_off': '0 s', **CASING},
     "key 'fault.mean_off': 0 s is out of range (0, 1000000] s"),
    ({'kind': 'intermittent', 'mean_on': '10 ms', 'mean_off': '1 ms', 'off': 'zero', **CASING},
     "key 'fault.off': 'zero' is not allowed; use one of rail | dropout"),
    ({'kind': 'intermittent', 'mean_on': '10 ms', 'mean_off': '1 ms', 'off': 'dropout',
      'axes': 'x', **CASING}, "key 'fault': 'axes' 'x' with off: dropout: a dropout removes "
     'whole samples (xyz)'),
    ({'kind': 'gain', 'gain': 2, 'name': 'all', **CASING},
     "key 'fault.name': 'all' is reserved ({clear: all} clears every fault)"),
    ('stuck', "key 'fault': expected a fault mapping (kind, accelerometer, ...); got str "
     "'stuck'"),
]


@pytest.mark.parametrize('raw, message', REFUSED, ids=[m.split(':')[0] + str(i) for i, (_, m)
                                                       in enumerate(REFUSED)])
def test_a_bad_spec_is_refused_in_one_line_naming_the_key(raw, message):
    with pytest.raises(FaultError) as err:
        parse_fault(raw, NAMES)
    assert str(err.value) == message


def test_the_injector_refuses_in_one_line():
    inj = injector({'kind': 'stuck', 'name': 's1'})
    cases = [
        ({'kind': 'stuck', 'name': 's1'},
         "key 'fault.name': 's1' names an earlier fault of this run; give another name"),
        ({'kind': 'stuck', 'duration': '0.1 ms'}, "key 'fault.duration': 0.0001 s holds no "
         'output sample at 1000 Hz (one every 0.001 s)'),
        ({'kind': 'intermittent', 'mean_on': '1 s', 'mean_off': '1 s',
          'accelerometer': 'bearing'}, "key 'fault.level': accelerometer 'bearing' has no "
         'range or ADC to rail at; give level (the reading while open, m/s^2) or off: '
         'dropout'),
        ({'kind': 'stuck', 'accelerometer': 'rotor'}, "key 'fault.accelerometer': 'rotor' is "
         'not an accelerometer of this scene; the accelerometers: casing, bearing'),
    ]
    for raw, message in cases:
        with pytest.raises(FaultError) as err:
            inj.add({**CASING, **raw})
        assert str(err.value) == message
    inj.apply(times(1, 1000), signal(1000), 0)
    with pytest.raises(FaultError) as err:
        inj.add({'kind': 'stuck', 'onset': '0.2 s', 'duration': '0.3 s', **CASING})
    assert str(err.value) == ("key 'fault.onset': the window 0.2 s + 0.3 s has passed: the "
                              'stream is at 1 s')
    with pytest.raises(FaultError) as err:
        inj.clear('nope')
    assert str(err.value) == "key 'clear': no fault named 'nope'; the faults: s1"
    with pytest.raises(FaultError) as err:
        parse_faults([{'kind': 'stuck', 'name': 'a', **CASING},
                      {'kind': 'stuck', 'name': 'a', **CASING}], NAMES)
    assert str(err.value) == "key 'faults': fault name 'a' is given twice; names must be unique"
