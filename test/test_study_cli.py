"""The ``study`` command, run in-process through ``main([...])``."""
import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from impact_damper_sim.cli.study import main
from impact_damper_sim.integrate.simulation import METHODS
from impact_damper_sim.scene.keytable import markdown_table
from impact_damper_sim.scene.spec import SCHEMA

README = Path(__file__).resolve().parents[1] / 'README.md'


def run(capsys, *argv):
    """Return (exit status, stdout, stderr) of ``study argv``."""
    status = main(list(argv))
    out, err = capsys.readouterr()
    return status, out, err


def documented_json_fields():
    """The ``study simulate --json`` fields listed in docs/study.md (``<name>`` placeholders)."""
    text = (README.parent / 'docs' / 'study.md').read_text()
    region = text.split('<!-- simulate-json:start -->')[1].split('<!-- simulate-json:end -->')[0]
    return set(re.findall(r'^\| `([^`]+)` \|', region, flags=re.M))


def flatten(data, names, prefix=''):
    """Dotted keys of nested dicts; keys in ``names`` become their placeholder."""
    out = set()
    for key, value in data.items():
        key = names.get(prefix, {}).get(key, key)
        path = f'{prefix}{key}'
        if isinstance(value, dict):
            out |= flatten(value, names, path + '.')
        else:
            out.add(path)
    return out


def test_modes_json(capsys):
    status, out, err = run(capsys, 'modes', 'cantilever', '--json')
    assert status == 0 and err == ''
    data = json.loads(out)
    assert data['scene'] == 'cantilever'
    assert data['dofs'] == {'total': 36, 'active': 30, 'clamped': 6, 'condensed': 15,
                            'after_condensation': 15}
    assert data['selection_reason'].startswith('1 mode by count (n_modes=1)')
    (mode,) = data['modes']
    assert set(mode) == {'mode', 'frequency_hz', 'omega_rad_s', 'tare_damping_ratio',
                         'damping_ratio'}
    assert mode['frequency_hz'] == pytest.approx(25.1646060522, rel=1e-6)
    assert [(s['role'], s['node'], s['dof']) for s in data['shapes']] == [
        ('sensor', 5, 'uy'), ('impactor', 5, 'uy'), ('force', 5, 'uy')]
    assert data['impactors'][0]['effective_mass_kg'][0] == pytest.approx(2.0, rel=1e-5)


def test_modes_text(capsys):
    status, out, _ = run(capsys, 'modes', 'sdof', '--set', 'impactors.0.cor=0.6')
    assert status == 0
    assert 'DOFs: 6 total, 1 active (5 clamped), 1 after condensation' in out
    assert '25.1646061' in out and 'mode shapes' in out


def test_simulate_json_has_the_documented_fields(capsys):
    status, out, err = run(capsys, 'simulate', 'sdof', '--duration', '2', '--json')
    assert status == 0 and err == ''
    data = json.loads(out)
    names = {'sensors.': {n: '<sensor>' for n in data['sensors']},
             'impactors.': {n: '<impactor>' for n in data['impactors']}}
    assert flatten(data, names) == documented_json_fields()
    assert data['duration_s'] == pytest.approx(2.0)
    assert data['n_samples'] == 20000 and data['method'] == 'exact'
    assert data['overrides'] == ['simulation.duration=2']
    sensor = data['sensors']['primary']
    assert sensor['peak_acceleration_g'] == pytest.approx(
        sensor['peak_acceleration_m_s2'] / 9.80665)
    impactor = data['impactors']['damper']
    assert impactor['impacts'] > 0 and impactor['steady_impacts_per_second'] == \
        pytest.approx(2 * 25.16, abs=4.1)     # two impacts per cycle in a 0.5 s window
    assert abs(data['energy_J']['relative_residual']) < 1e-9
    assert data['real_time_factor'] > 0


def test_simulate_text(capsys):
    status, out, _ = run(capsys, 'simulate', 'sdof', '--duration', '500 ms', '--window',
                         '0.2', '--dt', '0.2 ms')
    assert status == 0
    for text in ('steady amp (m)', 'impacts/s', 'energy balance residual', 'real-time factor'):
        assert text in out


def test_keys(capsys):
    status, out, _ = run(capsys, 'keys', '--markdown')
    assert status == 0 and out == markdown_table(SCHEMA)
    status, out, _ = run(capsys, 'keys')
    assert status == 0 and 'impactors[].clearance' in out


@pytest.mark.parametrize('argv, fragment', [
    (['modes', 'no_such_scene'], "unknown scene 'no_such_scene'"),
    (['modes', 'sdof', '--set', 'impactors.0.bogus=1'], "'impactors[0].bogus': unknown key"),
    (['modes', 'sdof', '--set', 'impactors.0.clearance=3 kg'], "'impactors[0].clearance'"),
    (['modes', 'sdof', '--set', 'impactors.0.cor=1.5'], "'impactors[0].cor'"),
    (['modes', 'sdof', '--set', 'impactors.0.mass=1'], "'mass' and 'mass_ratio'"),
    (['modes', 'sdof', '--set', 'impactors[3].cor=1'], 'index 3 is past the end'),
    (['modes', 'sdof', '--set', 'nonsense'], 'expected "key=value"'),
    (['simulate', 'sdof', '--duration', '-1'], "'simulation.duration'"),
    (['simulate', 'sdof', '--duration', '0.1'], 'given as --duration'),
    (['simulate', 'sdof', '--dt', 'fast'], "'simulation.dt'"),
    (['simulate', 'sdof', '--method', 'rk4'], "'simulation.method'"),
    (['simulate'], 'the following arguments are required: SCENE'),
    (['frobnicate'], 'invalid choice'),
])
def test_errors_exit_2_with_a_message(capsys, argv, fragment):
    status, out, err = run(capsys, *argv)
    assert status == 2
    assert fragment in err
    assert 'Traceback' not in err


def test_method_help_lists_every_method(capsys):
    status, out, _ = run(capsys, 'simulate', '--help')
    assert status == 0
    assert all(method in out for method in METHODS)


def test_missing_method_module_is_a_clean_error(capsys, monkeypatch):
    # as when integrate/direct.py is absent from an installation
    monkeypatch.setitem(sys.modules, 'impact_damper_sim.integrate.direct', None)
    status, _, err = run(capsys, 'simulate', 'sdof', '--method', 'direct', '--duration', '1')
    assert status == 2 and "method 'direct' is not available" in err
    assert 'Traceback' not in err


def test_importing_the_cli_is_light():
    code = ('import sys, impact_damper_sim.cli.study as s; '
            'heavy = [m for m in ("numpy", "scipy", "numba") if m in sys.modules]; '
            's.main(["keys"]); '
            'heavy += [m for m in ("scipy", "numba") if m in sys.modules]; '
            'print(heavy)')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip().splitlines()[-1] == '[]'
