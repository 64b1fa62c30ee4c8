"""``modal.cutoff: auto``: f_max from the sensor bandwidth and the excitation range."""
import numpy as np
import pytest

from impact_damper_sim.cli.study import main as study_main
from impact_damper_sim.scene.build import load
from impact_damper_sim.scene.modes import excitation_frequencies
from impact_damper_sim.scene.schema import SceneError
from impact_damper_sim.scene.spec import CUTOFF_FACTOR

RPM = 2 * np.pi / 60
# rbs without the count limit and its per-mode damping (mode numbers depend on the selection)
FREE = ['modal.cutoff=auto', 'modal.n_modes=null', 'modal.damping.modes={}',
        'rotor.speed.speed=7878 rpm']   # the paper's speed (the scene runs at its critical)


def test_default_factor_is_documented_value():
    assert CUTOFF_FACTOR == 1.5
    assert load('rbs').scene['modal']['cutoff'] == 'none'   # opt-in


def test_rotor_speed_governs_below_the_sensor_band():
    s = load('rbs', FREE + ['sensors.0.lowpass=100 Hz', 'sensors.1.lowpass=100 Hz'])
    f_rotor = 7878 * RPM / (2 * np.pi)                     # 131.3 Hz
    f_max = 1.5 * f_rotor
    # every mode up to f_max and none above: compare with the complete basis
    full = load('rbs', ['modal.n_modes=20', 'modal.damping.modes={}']).basis.frequencies_hz
    np.testing.assert_allclose(s.basis.frequencies_hz, full[full <= f_max], rtol=1e-8)
    assert s.basis.n_modes == 3
    reason = s.basis.selection_reason
    assert 'cutoff auto' in reason and 'max rotor speed' in reason
    assert f'{f_max:.6g} Hz' in reason


def test_sensor_lowpass_governs_and_factor_is_a_key():
    s = load('rbs', FREE + ['modal.cutoff_factor=1.2'])
    assert 'sensor lower_brg_y low-pass' in s.basis.selection_reason
    assert s.basis.frequencies_hz[-1] <= 1.2 * 5000
    full = load('rbs', ['modal.n_modes=null', 'modal.damping.modes={}']).basis.frequencies_hz
    assert s.basis.n_modes == np.count_nonzero(full <= 6000.0)


def test_forcing_ratio_and_n_modes_keep_the_smaller_set():
    """The cantilever is forced at r = 1 of its first mode: f_max = 1.5 f1 keeps one mode; with
    the scene's n_modes = 1 too the smaller set (one mode) is kept."""
    s = load('cantilever', ['modal.cutoff=auto', 'modal.n_modes=null'])
    f1 = s.basis.frequencies_hz[0]
    assert s.basis.n_modes == 1
    assert f'{1.5 * f1:.6g} Hz' in s.basis.selection_reason
    assert 'forcing[0]' in s.basis.selection_reason
    assert excitation_frequencies(s.scene, f1) == [('forcing[0]', pytest.approx(f1))]
    both = load('cantilever', ['modal.cutoff=auto'])
    assert both.basis.n_modes == 1 and 'by count' in both.basis.selection_reason


def test_conflicts_and_missing_sources_are_errors():
    with pytest.raises(SceneError, match='modal'):
        load('rbs', ['modal.cutoff=auto', 'modal.f_max=1000 Hz'])
    with pytest.raises(SceneError, match='modal.cutoff'):
        load('cantilever', ['modal.cutoff=auto', 'modal.n_modes=null', 'forcing=[]'])


def test_study_modes_prints_the_reason(capsys):
    study_main(['modes', 'rbs', *[a for o in FREE for a in ('--set', o)],
                '--set', 'sensors.0.lowpass=100 Hz', '--set', 'sensors.1.lowpass=100 Hz'])
    out = capsys.readouterr().out
    assert 'retained:' in out and 'cutoff auto: f_max = 1.5 x 131.3 Hz (max rotor speed' in out
