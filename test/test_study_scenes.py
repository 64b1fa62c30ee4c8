"""Every ``study`` command on every shipped scene, with its defaults.

Each command gets only its required arguments. It either runs (exit 0) or, where the scene
cannot answer the question (an FRF of a scene without harmonic forcing, a stability map of a
scene without cross-coupled stiffness, a Campbell diagram of a scene without a rotor),
refuses it up front in one line (exit 2). Never a
traceback, never exit 1 (every point failed) or 3 (diverged) on a shipped scene.

The default selection shortens each run (``--duration 0.1 --window 0.05``: the option
defaults that broke, mode counts and time steps, are untouched) and runs ``convergence``
on the SDOF and the cantilever only; ``make test-slow`` adds convergence on the rotor
scenes (short runs) and runs the other commands with the scenes' own durations.
"""
import pytest

from impact_damper_sim.cli.study import main
from impact_damper_sim.scene.build import load
from impact_damper_sim.scene.catalog import available_scenes

SCENES = available_scenes()
SHORT = ['--duration', '0.1', '--window', '0.05']
KCC_KEY = 'structure.cross_couplings.0.kcc'


def test_the_shipped_scenes_are_all_here():
    assert set(SCENES) >= {'cantilever', 'hpotp', 'hpotp_x10', 'rbs', 'rbs_kcc', 'sdof'}


def command(name, scene):
    """Required arguments of ``name`` on ``scene``, and the exit status expected."""
    s = load(scene).scene
    if name == 'modes':
        return ['modes', scene], 0, None
    if name == 'simulate':
        return ['simulate', scene], 0, None
    if name == 'frf':
        expect = (0, None) if s['forcing'] else (2, 'no forcing to sweep')
        return ['frf', scene, '--ratio', '1', '--executor', 'serial'], *expect
    if name == 'sweep':
        expect = (0, None) if s['impactors'] else (2, 'does not apply to scene')
        return ['sweep', scene, '--grid', 'impactors.0.cor=0.5', '--executor', 'serial'], *expect
    if name == 'stability':
        expect = ((0, None) if s['structure'].get('cross_couplings')
                  else (2, 'a stability map needs a cross-coupled stiffness'))
        return ['stability', scene, '--kcc-key', KCC_KEY, '--kcc', '1000',
                '--executor', 'serial'], *expect
    if name == 'convergence':
        return ['convergence', scene, '--executor', 'serial'], 0, None
    if name == 'campbell':
        expect = (0, None) if s['rotor'] else (2, 'a Campbell diagram needs a rotor')
        return ['campbell', scene, '--speeds', '0:10000:11'], *expect
    raise ValueError(name)


COMMANDS = ['modes', 'simulate', 'frf', 'sweep', 'stability', 'convergence', 'campbell']
DURATION_COMMANDS = {'simulate', 'frf', 'sweep', 'stability', 'convergence'}


def check(capsys, argv, status, message):
    got = main(argv)
    out, err = capsys.readouterr()
    assert 'Traceback' not in err
    assert got == status, err
    if message:
        assert message in err and err.count('\n') == 1
    else:
        assert out


#: Convergence crosses 4 methods x 4 steps x 2 mode counts against a reference at dt/8:
#: minutes on the rotor scenes even for 0.1 s (rbs_kcc: 13 min on a loaded 2-core
#: machine), so those run in the slow selection only.
SLOW_CONVERGENCE = {'rbs', 'rbs_kcc', 'hpotp', 'hpotp_x10'}


@pytest.mark.parametrize('name, scene', [
    (name, scene) for name in COMMANDS for scene in SCENES
    if not (name == 'convergence' and scene in SLOW_CONVERGENCE)])
def test_command_runs_with_defaults_on_scene(name, scene, capsys):
    argv, status, message = command(name, scene)
    if name in DURATION_COMMANDS:
        argv = argv + SHORT
    check(capsys, argv, status, message)


@pytest.mark.slow
@pytest.mark.parametrize('scene', sorted(SLOW_CONVERGENCE))
def test_convergence_runs_with_defaults_on_rotor_scene(scene, capsys):
    argv, status, message = command('convergence', scene)
    check(capsys, argv + SHORT, status, message)


@pytest.mark.slow
@pytest.mark.parametrize('scene', SCENES)
@pytest.mark.parametrize('name', sorted(DURATION_COMMANDS - {'convergence'}))
def test_command_runs_with_the_scene_duration(name, scene, capsys):
    argv, status, message = command(name, scene)
    check(capsys, argv, status, message)
