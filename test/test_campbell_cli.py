"""``study modes`` whirl output and ``study campbell``: JSON, text, CSV, plots, refusals.

Issue 26, items 1 to 3. The small rotors are the closed-form ones of ``test_whirl.py``; the
plots are checked with the rules of ``test_plots.py`` (8 pt and more at the saved DPI,
nothing clipped, nothing overlapping, a legend entry only for what is drawn) plus what a
Campbell diagram must show.
"""
import csv
import json

import numpy as np
import pytest

from impact_damper_sim.cli.study import main
from impact_damper_sim.modal.stability import state_matrix
from impact_damper_sim.scene.build import load
from test_whirl import DISK, JEFFCOTT, C, K, M

WHIRL_FIELDS = {'mode', 'frequency_hz', 'direction', 'log_dec', 'damping_ratio',
                'growth_rate_1_s', 'whirl_index'}


def run(capsys, *argv):
    status = main(list(argv))
    out, err = capsys.readouterr()
    return status, out, err


@pytest.fixture
def disk(tmp_path):
    path = tmp_path / 'disk.yaml'
    path.write_text(DISK)
    return str(path)


@pytest.fixture
def jeffcott(tmp_path):
    path = tmp_path / 'jeffcott.yaml'
    path.write_text(JEFFCOTT)
    return str(path)


# --- study modes -------------------------------------------------------------------------------

def test_modes_json_whirl_of_ross_rotor(capsys):
    # At the scene's 5000 rpm: the damped frequencies are the eigenvalues of the simulated
    # K and C (1e-9), sorted; the conical pair (3, 4) whirls backward then forward, the 4th
    # pair (7, 8) too; undamped: log decrements 0. The gyroscopic coupling makes C dense:
    # coupled is true.
    status, out, err = run(capsys, 'modes', 'ross_rotor', '--json')
    assert status == 0 and err == ''
    data = json.loads(out)
    assert data['coupled'] is True and data['spin_axis'] is True
    assert data['rotor_speed_rpm'] == pytest.approx(5000.0, rel=1e-12)
    whirl = data['whirl']
    assert all(set(w) == WHIRL_FIELDS for w in whirl)
    freq = [w['frequency_hz'] for w in whirl]
    assert freq == sorted(freq) and len(whirl) == 16
    scene = load('ross_rotor')
    lam = np.linalg.eigvals(state_matrix(scene.model.K, scene.model.C))
    np.testing.assert_allclose(freq, np.sort(lam.imag[lam.imag > 0]) / (2 * np.pi), rtol=1e-9)
    assert [w['direction'] for w in whirl[2:4]] == ['backward', 'forward']
    assert [w['direction'] for w in whirl[6:8]] == ['backward', 'forward']
    assert all(w['log_dec'] == 0.0 for w in whirl)
    assert len(data['modes']) == 16   # the undamped modal basis stays


def test_modes_follows_the_rotor_speed(capsys):
    # The new user: --set the speed, and the whirl list moves with it. At rest the
    # anisotropic bearings give planar modes; at 7878 rpm the conical pair (3, 4) splits
    # into backward and forward whirl, more than twice as wide as at rest, and the undamped
    # modal basis (the simulation's coordinates) stays the same.
    lists = {}
    for rpm in (0, 7878):
        status, out, _ = run(capsys, 'modes', 'ross_rotor', '--json', '--set',
                             f'rotor.speed.speed={rpm} rpm')
        assert status == 0
        lists[rpm] = json.loads(out)
    rest, fast = lists[0]['whirl'], lists[7878]['whirl']
    assert {w['direction'] for w in rest} == {'none'}
    assert [w['direction'] for w in fast[2:4]] == ['backward', 'forward']
    split = [w[3]['frequency_hz'] - w[2]['frequency_hz'] for w in (rest, fast)]
    assert split[1] > 2 * split[0]   # 16.6 Hz against 6.8 Hz
    assert lists[0]['modes'] == lists[7878]['modes']


def test_modes_json_without_rotor(capsys):
    # no spin axis: a damped mode without a direction; the SDOF's modal matrices are diagonal
    status, out, _ = run(capsys, 'modes', 'sdof', '--json')
    assert status == 0
    data = json.loads(out)
    assert data['spin_axis'] is False and data['coupled'] is False
    assert data['rotor_speed_rpm'] is None
    (w,) = data['whirl']
    assert w['direction'] == 'none'
    assert w['frequency_hz'] == pytest.approx(data['modes'][0]['frequency_hz'], rel=1e-3)


def test_modes_json_jeffcott_log_decrement(capsys, jeffcott):
    # the two members of the isotropic pair: damped frequency and log decrement closed form
    status, out, _ = run(capsys, 'modes', jeffcott, '--json')
    assert status == 0
    whirl = json.loads(out)['whirl']
    zeta = C / (2 * np.sqrt(K * M))
    assert sorted(w['direction'] for w in whirl) == ['backward', 'forward']
    for w in whirl:
        assert w['frequency_hz'] == pytest.approx(np.sqrt(K / M * (1 - zeta ** 2)) / (2 * np.pi),
                                                  rel=1e-12)
        assert w['log_dec'] == pytest.approx(2 * np.pi * zeta / np.sqrt(1 - zeta ** 2),
                                             rel=1e-10)
        assert w['damping_ratio'] == pytest.approx(zeta, rel=1e-10)


def test_modes_text_names_both_tables(capsys):
    status, out, _ = run(capsys, 'modes', 'ross_rotor')
    assert status == 0
    assert 'undamped modal basis (modes of the non-rotating structure' in out
    assert 'damped whirl modes of the rotating model at 5000 rpm' in out
    table = out.split('damped whirl modes')[1].splitlines()
    assert table[1].split() == ['mode', 'frequency', '(Hz)', 'whirl', 'log', 'dec', 'damping',
                                'ratio']
    rows = [line.split() for line in table[2:] if line.strip()]
    assert [r[2] for r in rows[2:4]] == ['backward', 'forward'] and len(rows) == 16


# --- study campbell ----------------------------------------------------------------------------

def test_campbell_json_fields(capsys, disk):
    status, out, err = run(capsys, 'campbell', disk, '--speeds', '0:6000:13',
                           '--harmonics', '1,2', '--json')
    assert status == 0 and err == ''
    r = json.loads(out)
    assert set(r) == {'study', 'scene', 'source', 'overrides', 'model', 'speeds_rpm',
                      'harmonics', 'branches', 'critical_speeds', 'onset', 'rows',
                      'wall_time_s'}
    assert r['speeds_rpm'] == [500.0 * k for k in range(13)] and r['harmonics'] == [1.0, 2.0]
    assert r['model']['gyroscopic_nodes'] == [0] and r['model']['n_modes'] == 4
    assert len(r['branches']) == 4 and len(r['rows']) == 4 * 13
    for b in r['branches']:
        assert set(b) == {'branch', 'frequency_hz', 'log_dec', 'damping_ratio', 'direction'}
        assert len(b['frequency_hz']) == 13
    for c in r['critical_speeds']:
        assert set(c) == {'harmonic', 'branch', 'speed_rpm', 'frequency_hz', 'direction',
                          'log_dec'}
        # on its harmonic line: f = h rpm / 60
        assert c['frequency_hz'] == pytest.approx(c['harmonic'] * c['speed_rpm'] / 60,
                                                  rel=1e-9)
    assert {c['harmonic'] for c in r['critical_speeds']} == {1.0, 2.0}
    assert r['onset'] is None


def test_campbell_text_and_csv(capsys, disk, tmp_path):
    path = tmp_path / 'c.csv'
    status, out, _ = run(capsys, 'campbell', disk, '--speeds', '0,3000,6000', '--csv',
                         str(path))
    assert status == 0
    assert out.splitlines()[2].split()[:2] == ['branch', 'f']
    assert 'critical speeds (1X lines crossing the branches):' in out
    assert 'stable over the range' in out
    with open(path) as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0]) == ['speed_rpm', 'branch', 'frequency_hz', 'log_dec',
                             'damping_ratio', 'direction', 'whirl_index']
    assert len(rows) == 3 * 4
    _, out, _ = run(capsys, 'campbell', disk, '--speeds', '0,3000,6000', '--json')
    branches = json.loads(out)['branches']
    for row in rows:
        b = branches[int(row['branch']) - 1]
        k = [0.0, 3000.0, 6000.0].index(float(row['speed_rpm']))
        assert float(row['frequency_hz']) == b['frequency_hz'][k]
        assert row['direction'] == b['direction'][k]


def test_campbell_reports_the_onset(capsys, jeffcott):
    # Kcc = 2 c omega_n: the forward member grows from the first speed
    kcc = 2 * C * np.sqrt(K / M)
    status, out, _ = run(capsys, 'campbell', jeffcott, '--speeds', '0:3000:4', '--set',
                         f'structure.cross_couplings.0.kcc={kcc}')
    assert status == 0
    assert 'unstable at the first speed of the range: branch' in out
    assert '(forward whirl' in out


@pytest.mark.parametrize('argv, words', [
    (['campbell', 'sdof', '--speeds', '0:100:3'], 'needs a rotor'),
    (['campbell', 'ross_rotor', '--speeds', '5'], 'at least two speeds'),
    (['campbell', 'ross_rotor', '--speeds', '0:x:3'], 'expected START:STOP:N'),
    (['campbell', 'ross_rotor', '--speeds', '100,50'], 'strictly increasing'),
    (['campbell', 'ross_rotor', '--speeds=-5,50'], '>= 0 rpm'),
    (['campbell', 'ross_rotor', '--speeds', '0:10:3', '--harmonics', '0'], '> 0'),
    (['campbell', 'ross_rotor', '--speeds', '0:10:3', '--plot', 'c.xyz'], "'.xyz' plot"),
    (['modes', 'ross_rotor', '--plot', 'm.png', '--plot-modes', '99'], 'out of range 1..16'),
])
def test_bad_input_is_refused_in_one_line(capsys, argv, words, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    status, out, err = run(capsys, *argv)
    assert status == 2
    assert words in err and err.count('\n') == 1, err
    assert not (tmp_path / 'm.png').exists()


def test_existing_outputs_need_overwrite(capsys, disk, tmp_path):
    # refused before the work, the file kept
    plot = tmp_path / 'c.png'
    plot.write_text('keep')
    status, _, err = run(capsys, 'campbell', disk, '--speeds', '0:100:3', '--plot', str(plot))
    assert status == 2 and 'pass --overwrite' in err and plot.read_text() == 'keep'
    status, _, err = run(capsys, 'modes', disk, '--plot', str(plot))
    assert status == 2 and 'pass --overwrite' in err and plot.read_text() == 'keep'


# --- plots -------------------------------------------------------------------------------------

pytest.importorskip('matplotlib')
import test_plots  # noqa: E402
from test_plots import check_readable, only  # noqa: E402

saved = test_plots.saved   # the fixture catching saved figures


def test_campbell_plot(capsys, jeffcott, saved, tmp_path):
    """A textbook Campbell diagram: frequency over rpm; forward solid, backward dashed; one
    marker per speed and branch coloured by its log decrement (negative ones too); the 1X
    and 2X lines; every critical speed circled; unstable from the start in the title."""
    from matplotlib.collections import PathCollection
    kcc = 2 * C * np.sqrt(K / M)
    argv = ['campbell', jeffcott, '--speeds', '0:6000:25', '--harmonics', '1,2', '--set',
            f'structure.cross_couplings.0.kcc={kcc}', '--json']
    status, out, _ = run(capsys, *argv, '--plot', str(tmp_path / 'c.png'))
    assert status == 0
    r = json.loads(out)
    fig, dpi = only(saved)
    ax = fig.axes[0]
    problems = []
    if ax.get_xlabel() != 'rotor speed (rpm)' or 'frequency (Hz)' not in ax.get_ylabel():
        problems.append(f'axes {ax.get_xlabel()!r}, {ax.get_ylabel()!r}')
    styles = {}
    for line in ax.get_lines():
        if line.get_color() == '0.25':
            styles.setdefault(line.get_linestyle(), 0)
            styles[line.get_linestyle()] += 1
    if set(styles) != {'-', '--'}:
        problems.append(f'branch line styles {styles} (want solid forward, dashed backward)')
    (dots,) = [c for c in ax.collections if isinstance(c, PathCollection)]
    log_dec = np.array([b['log_dec'] for b in r['branches']], dtype=float).ravel()
    if sorted(np.asarray(dots.get_array())) != pytest.approx(sorted(log_dec)):
        problems.append('marker colours are not the log decrements')
    if not (log_dec < 0).any():
        problems.append('the scene should have a negative log decrement')
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    for want in ('forward whirl', 'backward whirl', '1X excitation', '2X excitation',
                 'critical speed (branch, whirl, rpm)'):
        if want not in labels:
            problems.append(f'legend lacks {want!r}: {labels}')
    if 'unstable from the first speed: branch' not in ax.get_title():
        problems.append(f'title {ax.get_title()!r} does not say it is unstable')
    circles = [line for line in ax.get_lines() if line.get_marker() == 'o']
    if sum(len(c.get_xdata()) for c in circles) != len(r['critical_speeds']):
        problems.append('not every critical speed circled')
    drawn = check_readable(fig, dpi, extra=problems)
    speeds = {f"{c['branch']}{c['direction'][0].upper()} {c['speed_rpm']:.0f}"
              for c in r['critical_speeds']}
    placed = [s for s in drawn.strings() if s in speeds]
    assert placed, 'no critical speed labelled'


def test_modes_plot(capsys, saved, tmp_path):
    """One panel per mode asked, titled with frequency and direction; the major semi-axis
    is 1 at its largest; the signed minor semi-axis has the sign of the mode's direction at
    every station (ross_rotor at 5000 rpm: the conical pair and the 4th pair's backward)."""
    status, _, _ = run(capsys, 'modes', 'ross_rotor', '--plot', str(tmp_path / 'm.png'),
                       '--plot-modes', '3,4,7')
    assert status == 0
    fig, dpi = only(saved)
    panels = [a for a in fig.axes if a.get_title()]
    problems = []
    if [a.get_title().split(':')[0] for a in panels] != ['3', '4', '7']:
        problems.append(f'panels {[a.get_title() for a in panels]}')
    for ax, direction in zip(panels, ('backward', 'forward', 'backward')):
        _, major, minor = ax.get_lines()
        if direction not in ax.get_title():
            problems.append(f'{ax.get_title()}: expected {direction}')
        if max(major.get_ydata()) != pytest.approx(1.0):
            problems.append(f'{ax.get_title()}: major axis not scaled to 1')
        sign = 1.0 if direction == 'forward' else -1.0
        turns = sign * np.asarray(minor.get_ydata())
        # the conical pair turns one way everywhere; mode 7 turns against its direction
        # next to its nodal points (ROSS: 'Mixed'), with the mode over the span
        if ax.get_title().split(':')[0] in ('3', '4') and turns.min() < -1e-9:
            problems.append(f'{ax.get_title()}: a station turning against the mode')
        if np.sum(turns * np.asarray(major.get_ydata())) <= 0:
            problems.append(f'{ax.get_title()}: most of the orbit turns against the mode')
        if len(major.get_xdata()) != 49:
            problems.append(f'{ax.get_title()}: {len(major.get_xdata())} stations, not 49')
    check_readable(fig, dpi, extra=problems)
