"""Blow-ups end in one typed error (what, when, which setting), never in inf/NaN results or a
traceback; runs too large for memory are refused before they start."""
import pickle

import numpy as np
import pytest

from impact_damper_sim._exit_status import EXIT_DIVERGED
from impact_damper_sim.cli.study import main
from impact_damper_sim.integrate.divergence import (
    MAX_DISPLACEMENT,
    Divergence,
    check_samples,
    check_state,
    from_engine_error,
)
from impact_damper_sim.integrate.events import Samples
from impact_damper_sim.integrate.memory import TooLarge, check_allocation, sample_bytes
from impact_damper_sim.integrate.simulation import CHECK_EVERY
from impact_damper_sim.scene.advice import scene_advice
from impact_damper_sim.scene.build import load

HUGE_FORCE = 'forcing.0.amplitude=1e300 N'


def samples(disp, dt=1e-3):
    disp = np.asarray(disp, dtype=float).reshape(-1, 1)
    t = dt * np.arange(1, disp.shape[0] + 1)
    return Samples(t, disp, np.zeros_like(disp), np.zeros_like(disp))


def test_divergence_message_fields_and_pickle():
    exc = Divergence("sensor 'a' displacement 2e+03 m exceeds 1000 m", 0.25, 'change x')
    assert str(exc) == ("diverged at t = 0.25 s: sensor 'a' displacement 2e+03 m exceeds "
                        '1000 m; change x')
    assert exc.code == EXIT_DIVERGED == 3 and isinstance(exc, RuntimeError)
    back = pickle.loads(pickle.dumps(exc))   # crosses process pools with its fields
    assert (back.what, back.t, back.setting) == (exc.what, exc.t, exc.setting)
    assert str(exc.with_setting('y')).endswith('; y')


@pytest.mark.parametrize('bad, what', [(np.inf, 'displacement is inf m'),
                                       (np.nan, 'displacement is nan m'),
                                       (2 * MAX_DISPLACEMENT, 'exceeds 1000 m')])
def test_check_samples_reports_the_first_bad_sample(bad, what):
    disp = [0.0, 1.0, bad, bad, 0.0]
    with pytest.raises(Divergence, match=what) as info:
        check_samples(samples(disp), ['a'])
    assert info.value.t == pytest.approx(3e-3)   # the third sample's time
    check_samples(samples([0.0, MAX_DISPLACEMENT, -MAX_DISPLACEMENT]), ['a'])   # at the bound


@pytest.mark.parametrize('field', ['velocity', 'acceleration'])
@pytest.mark.parametrize('bad', [np.inf, -np.inf, np.nan])
def test_check_samples_reports_a_bad_rate(field, bad):
    # the clean-chunk test sums the rates: a NaN or inf anywhere must still be reported
    s = samples([0.0, 1.0, 2.0, 3.0])
    getattr(s, field)[2, 0] = bad
    with pytest.raises(Divergence, match=f"sensor 'a' {field} is") as info:
        check_samples(s, ['a'])
    assert info.value.t == pytest.approx(3e-3)
    huge = samples([0.0, 1.0])   # finite rates whose sum overflows are not a divergence
    getattr(huge, field)[:, 0] = 1e308
    check_samples(huge, ['a'])
    check_samples(Samples(huge.t, np.zeros((2, 0)), np.zeros((2, 0)), np.zeros((2, 0))))


@pytest.mark.parametrize('bad', [np.inf, -np.inf, np.nan])
def test_check_samples_needs_no_error_state(bad):
    # the clean-chunk test uses no sums: under np.errstate(all='raise') huge finite values
    # pass and a bad one is still a Divergence, never a FloatingPointError
    with np.errstate(all='raise'):
        huge = samples([0.0, 1.0, -1.0])
        huge.velocity[:, 0] = huge.acceleration[:, 0] = [1e308, 1e308, -1e308]
        check_samples(huge, ['a'])
        huge.acceleration[1, 0] = bad
        with pytest.raises(Divergence, match="sensor 'a' acceleration is"):
            check_samples(huge, ['a'])
        with pytest.raises(Divergence, match="displacement"):
            check_samples(samples([0.0, bad]), ['a'])
    # other dtypes are examined entry by entry, with the same answers
    ints = Samples(np.array([1e-3, 2e-3]), np.array([[1], [2000]]), np.zeros((2, 1), int),
                   np.zeros((2, 1), int))
    with pytest.raises(Divergence, match='exceeds 1000 m') as info:
        check_samples(ints, ['a'])
    assert info.value.t == 2e-3
    single = Samples(np.array([1e-3]), np.float32([[1.0]]), np.float32([[bad]]),
                     np.float32([[0.0]]))
    with pytest.raises(Divergence, match="sensor 'a' velocity is"):
        check_samples(single, ['a'])


@pytest.mark.parametrize('bad', [np.inf, -np.inf, np.nan])
def test_check_state_reports_the_first_bad_mode(bad):
    q, qd = np.zeros(4), np.full(4, 1e308)
    with np.errstate(all='raise'):
        check_state(q, qd, 0.5)   # huge is finite
        check_state(np.zeros(0), np.zeros(0), 0.5)
        qd[2] = bad
        qd[3] = bad
        with pytest.raises(Divergence, match=r'modal velocities not finite \(mode 3 of 4\)'):
            check_state(q, qd, 0.5)
        q[1] = bad
        with pytest.raises(Divergence, match=r'modal coordinates not finite \(mode 2 of 4\)') \
                as info:
            check_state(q, qd, 0.5)
    assert info.value.t == 0.5
    with pytest.raises(Divergence, match='mode 1 of 2'):   # not real: entry by entry
        check_state(np.array([bad, 0.0], dtype=complex), np.zeros(2), 0.5)


def test_engine_errors_that_mean_divergence():
    assert isinstance(from_engine_error(FloatingPointError('x'), 1.0), Divergence)
    div = from_engine_error(RuntimeError('chatter not resolved at t = 1 s'), 1.0)
    assert 'chatter' in div.what and div.t == 1.0
    assert from_engine_error(RuntimeError('some bug'), 1.0) is None   # bugs stay bugs
    assert from_engine_error(ValueError('chatter'), 1.0) is None


def test_allocation_estimate_and_refusal():
    assert sample_bytes(10, 2) == 2 * 8 * 10 * 7
    check_allocation(1000, 2, limit=sample_bytes(1000, 2))   # exactly at the limit: allowed
    with pytest.raises(TooLarge, match=r'1e\+09 samples would need about 59.6 GiB'):
        check_allocation(10 ** 9, 1, limit=2 ** 30)


def test_simulation_diverges_within_the_first_chunk():
    scene = load('sdof', [HUGE_FORCE])
    sim = scene.make_simulation()
    with pytest.raises(Divergence, match="sensor 'primary' displacement") as info:
        sim.advance(20 * CHECK_EVERY)
    assert 0 < info.value.t <= CHECK_EVERY * sim.dt
    assert sim.t <= CHECK_EVERY * sim.dt * (1 + 1e-12)   # stopped at the first chunk
    assert 'forcing.0.amplitude (1e+300 N)' in scene_advice(scene, info.value)


def test_chunked_advance_equals_one_engine_call():
    """The divergence checks cut a run into chunks. The engine stamps a sample
    ``t_start + k dt`` from the chunk's start, so a chunk boundary moves sample times by at
    most one ulp (2.2e-16 relative); that perturbation reaches the state through the impacts
    (measured: 5e-14 relative on the SDOF over 0.51 s, 17 events). Bounds: times 2 eps
    relative, same
    event sequence with times within 1e-13 s, responses within 1e-11 relative (200 x the
    measurement: the impact amplification varies with the orbit)."""
    n = 5 * CHECK_EVERY + 17
    a = load('sdof').make_simulation()
    b = load('sdof').make_simulation()
    sa = a.advance(n)
    sb = b.integrator.advance(n)
    assert a.t == b.t   # the time base ends where one call leaves it
    eps = np.finfo(float).eps
    assert np.abs(sa.t - sb.t).max() <= 2 * eps * sb.t.max()
    for field in ('displacement', 'velocity'):
        ref = getattr(sb, field)
        assert np.abs(getattr(sa, field) - ref).max() <= 1e-11 * np.abs(ref).max(), field
    ea, eb = a.take_events(), b.take_events()
    assert len(ea) == len(eb) >= 10
    assert np.array_equal(ea['kind'], eb['kind'])
    assert np.abs(ea['t'] - eb['t']).max() <= 1e-13


def test_linearly_unstable_scene_names_the_cross_coupling():
    scene = load('rbs_kcc', ['structure.cross_couplings.0.kcc=1e10'])
    advice = scene_advice(scene)
    assert advice.startswith('the structure is linearly unstable')
    assert 'structure.cross_couplings.0.kcc (1e+10 N/m)' in advice


def cli(capsys, *argv):
    status = main(list(argv))
    out, err = capsys.readouterr()
    return status, out, err


def test_cli_blow_up_is_one_line_with_exit_3(capsys):
    status, out, err = cli(capsys, 'simulate', 'sdof', '--duration', '2', '--window', '0.5',
                           '--set', HUGE_FORCE)
    assert status == EXIT_DIVERGED and out == ''
    assert err.count('\n') == 1 and 'Traceback' not in err
    assert err.startswith('study: error: diverged at t = ')
    assert 'forcing.0.amplitude' in err


def test_cli_chatter_is_a_divergence(capsys):
    status, _, err = cli(capsys, 'simulate', 'rbs', '--duration', '0.2', '--window', '0.1',
                         '--set',
                         'rotor.multiplier=1e8')
    assert status == EXIT_DIVERGED and err.count('\n') == 1
    assert 'rotor.multiplier (1e+08)' in err


def test_cli_refuses_a_run_too_large_for_memory(capsys):
    status, out, err = cli(capsys, 'simulate', 'sdof', '--dt', '1e-9', '--duration', '1')
    assert status == 2 and out == ''
    assert 'simulation.dt = 1e-09 s over simulation.duration = 1 s' in err and 'GiB' in err


def test_cli_does_not_echo_a_file_that_is_not_a_scene(capsys, tmp_path):
    status, _, err = cli(capsys, 'simulate', '/etc/passwd')
    assert status == 2 and 'root' not in err and 'not a scene file' in err
    binary = tmp_path / 'x.yaml'
    binary.write_bytes(b'\xff\xfe secret \x00')
    status, _, err = cli(capsys, 'modes', str(binary))
    assert status == 2 and 'secret' not in err and 'not UTF-8' in err


def test_study_point_that_diverges_exits_3_and_keeps_the_others(capsys):
    status, out, err = cli(capsys, 'frf', 'sdof', '--hz', '20,25', '--executor', 'serial',
                           '--duration', '0.3', '--window', '0.1', '--set', HUGE_FORCE)
    assert status == EXIT_DIVERGED
    assert 'Traceback' not in err and 'Divergence: diverged at t =' in err
    assert 'forcing.0.amplitude' in err


def test_study_refuses_existing_csv_before_running(capsys, tmp_path):
    out = tmp_path / 't.csv'
    out.write_text('mine')
    status, _, err = cli(capsys, 'frf', 'sdof', '--hz', '25', '--executor', 'serial',
                         '--csv', str(out))
    assert status == 2 and f'{out} exists; pass --overwrite' in err
    assert out.read_text() == 'mine'


def test_convergence_whose_reference_diverges_exits_3(capsys):
    status, _, err = cli(capsys, 'convergence', 'sdof', '--executor', 'serial', '--methods',
                         'exact', '--dts', '1e-4', '--duration', '0.2', '--window', '0.1',
                         '--set', HUGE_FORCE)
    assert status == EXIT_DIVERGED and err.count('\n') == 1
    assert 'the reference run diverged: Divergence: diverged at t =' in err


@pytest.mark.parametrize('argv', [['frf', 'sdof', '--hz', '25'],
                                  ['sweep', 'sdof', '--grid', 'impactors.0.cor=0.5'],
                                  ['convergence', 'sdof', '--dts', '1e-9']])
def test_studies_refuse_runs_too_large_for_memory_up_front(capsys, argv):
    status, _, err = cli(capsys, *argv, '--executor', 'serial',
                         *([] if 'convergence' in argv else ['--dt', '1e-9']))
    assert status == 2 and 'GiB' in err and err.count('\n') == 1
