"""HPOTP rotor unbalance (paper section 4.3, Tables 4.3.1 and 4.3.2).

The base unbalance of ``config/scenes/hpotp.yaml`` is ours, calibrated (docs/hpotp-model.md,
"Unbalance calibration") so that, at X = 1 without impactors, the worst-case acceleration at
node 1 (y or z, mean acceleration per sample period through the sensors' 800 Hz low-pass,
sampled at 4 kHz) is 5.7 g during the ramp (criticals, t < 5 s; Table 4.3.1: 4.1 g with
impactors x reduction 1.4) and 0.77 g at full speed (t > 5 s; Table 4.3.2).

Tolerances: the calibration targets are read off the paper's tables, so +-20 %. With the
scene's impactors (W = 25 lb, D = 1.7 mil) the paper's reductions during the ramp are 1.4 to
2.5 (Table 4.3.1). The reduction is the ratio of two worst cases of a chaotic run, so
roundoff moves it: the same X = 1 run with Taylor orders 4 to 8 of the event search (the same
physics, other roundoff) gave 1.32 to 1.44 (sd about 0.045) on 2026-11-26. A single run against 1.4
was a coin toss (it passed at 1.417 and failed at 1.397 after a change of roundoff alone), so
X = 1 takes the mean of those five runs and requires it within two standard deviations of
the paper's 1.4, itself one such run: >= 1.4 - 2 x 0.045 = 1.31 (measured mean 1.36 to
1.37). At full speed the paper's impactors *raise* the level
(0.77 -> 0.9 g, 7.2 -> 9.1 g, Table 4.3.2): we require that they do not reduce it by more
than 5 % (reduction <= 1.05). The runs with impactors take ~10 s (X = 1) to ~3 min
(X = 10) each: marked slow. The reduction at the criticals for X = 3, 7 and 10 is not reached
by this model (1.15, 1.10, 1.08 in docs/validation.md of 2026-11-27; 1.19, 1.09, 1.07
before the exact engine's rework): strict xfails, reported, not tuned. Why: the
damper removes a roughly fixed amplitude (~0.4 mil) whatever X is, see docs/hpotp-model.md,
"Why the reduction falls with X".
"""
import functools

import numpy as np
import pytest

from impact_damper_sim.integrate.exact import TAYLOR_ORDER
from impact_damper_sim.live.filters import scene_lowpass
from impact_damper_sim.scene.build import load
from impact_damper_sim.studies.analysis import G0

DT = 2.5e-4          # 4 kHz sampling (the 800 Hz low-pass is 0.4 Nyquist)
RAMP_END = 5.0       # s, Eq. (4.3.1)


@functools.lru_cache(maxsize=None)
def worst_g(scene_name, *overrides, duration=6.0, taylor_order=TAYLOR_ORDER):
    """Worst-case |acceleration| over the node-1 sensors (g): (criticals, full speed)."""
    scene = load(scene_name, list(overrides))
    sim = scene.make_simulation('exact', DT, ledger=False, taylor_order=taylor_order)
    lowpass = scene_lowpass(scene, DT)
    v0 = sim.integrator.model.sensors @ sim.integrator.state()[1]
    samples = sim.advance_to(duration)
    acc = np.abs(lowpass.apply(sim.mean_acceleration(samples, v0))).max(axis=1) / G0
    t = samples.t
    full = acc[t > RAMP_END]
    return float(acc[t < RAMP_END].max()), float(full.max()) if full.size else None


def test_rotor_section():
    rotor = load('hpotp').scene['rotor']
    assert rotor['speed']['kind'] == 'paper_ramp'
    assert rotor['speed']['final_speed'] == pytest.approx(2400.0)
    assert rotor['speed']['ramp_time'] == pytest.approx(5.0)
    assert sorted(u['node'] for u in rotor['unbalance']) == [4, 15]
    assert rotor['multiplier'] == 1
    assert load('hpotp_x10').scene['rotor']['multiplier'] == 10
    assert [s['lowpass'] for s in load('hpotp').scene['sensors']] == [800.0, 800.0]


def test_x1_calibration_without_impactors():
    crit, full = worst_g('hpotp', 'impactors=[]')
    assert crit == pytest.approx(5.7, rel=0.2)
    assert full == pytest.approx(0.77, rel=0.2)


def test_x10_is_ten_times_x1_without_impactors():
    """Linear without impactors: the X = 10 defect scene is exactly 10 x the base."""
    base = worst_g('hpotp', 'impactors=[]', duration=4.0)
    x10 = worst_g('hpotp_x10', 'impactors=[]', duration=4.0)
    assert x10[0] == pytest.approx(10 * base[0], rel=1e-9)


def _miss(x, without, with_, measured, paper, amplitude):
    return pytest.mark.xfail(strict=True, reason=(
        f'measured X = {x} reduction at the criticals {without} -> {with_} g = {measured} '
        f'(paper {paper}, Table 4.3.1): the fixed 0.85 mil clearance removes ~0.4 mil of a '
        f'{amplitude} mil response (docs/hpotp-model.md); reported, tolerance not loosened'))


#: Taylor orders of the event search: the same physics with five different roundoffs
ROUNDOFF_VARIANTS = (4, 5, 6, 7, 8)
#: The paper's X = 1 reduction (Table 4.3.1) less two standard deviations of one run's
#: ratio (0.045: the spread over ROUNDOFF_VARIANTS, 2026-11-26)
X1_REDUCTION_MIN = 1.4 - 2 * 0.045


@pytest.mark.slow
def test_impactors_reduce_the_criticals_x1():
    """Ramp (t < 5 s), X = 1: the mean reduction over roundoff variants is the paper's 1.4
    within the spread of one run. Measured 1.36 to 1.37 (runs 1.32 to 1.44)."""
    without = worst_g('hpotp', 'impactors=[]')[0]
    ratios = [without / worst_g('hpotp', taylor_order=order)[0]
              for order in ROUNDOFF_VARIANTS]
    # the variants do differ (else the mean would be one run again)
    assert np.ptp(ratios) > 0.01
    assert np.mean(ratios) >= X1_REDUCTION_MIN


@pytest.mark.slow
@pytest.mark.parametrize('scene_name, overrides', [
    pytest.param('hpotp', ('rotor.multiplier=3',), id='X3',
                 marks=_miss(3, 16.9, 14.8, 1.15, 1.8, 2.9)),
    pytest.param('hpotp', ('rotor.multiplier=7',), id='X7',
                 marks=_miss(7, 39.5, 36.1, 1.10, 2.5, 6.7)),
    pytest.param('hpotp_x10', (), id='X10', marks=_miss(10, 56.5, 52.6, 1.08, 2.1, 9.6))])
def test_impactors_reduce_the_criticals(scene_name, overrides):
    """Ramp (t < 5 s): reduction >= 1.4 (Table 4.3.1), one run (these miss it by far)."""
    without = worst_g(scene_name, 'impactors=[]', *overrides)[0]
    assert without / worst_g(scene_name, *overrides)[0] >= 1.4


@pytest.mark.slow
@pytest.mark.parametrize('scene_name', ['hpotp', 'hpotp_x10'])
def test_impactors_do_not_reduce_full_speed(scene_name):
    """Full speed (t > 5 s): no reduction (Table 4.3.2). docs/validation.md (2026-11-27): X = 1
    0.77 -> 0.83 g, X = 10 7.70 -> 12.01 g."""
    assert worst_g(scene_name, 'impactors=[]')[1] / worst_g(scene_name)[1] <= 1.05
