"""Parameter studies: FRF correlation, executors, failures, Dask, CLI, stability, onset."""
import csv
import json

import numpy as np
import pytest

from impact_damper_sim.cli.study import main
from impact_damper_sim.studies.frf import frf
from impact_damper_sim.studies.runner import Point, run_points
from impact_damper_sim.studies.stability import onset, stability
from impact_damper_sim.studies.sweep import split_values, sweep

RATIOS = [0.9, 0.97, 1.0, 1.03, 1.1]
# the SDOF scene with the cantilever's (paper section 4.1) F0, mu, e and D
SDOF_AS_CANTILEVER = ['impactors.0.mass_ratio=0.04', 'impactors.0.cor=0.6',
                      'impactors.0.clearance=2 mil', 'forcing.0.amplitude=0.0172 lbf']
SHORT = ['simulation.duration=6 s']
# Jeffcott-like: the cantilever made isotropic (Iy = Iz), two modes, a cross-coupling at the
# tip, y and z sensors, no forcing. Onset Kcc = c omega_n = 2 zeta m omega_n^2 = 2000 N/m.
KCC_KEY = 'structure.cross_couplings.0.kcc'
JEFFCOTT = ['structure.sections.analog.Iy=12 in^4', 'modal.n_modes=2',
            'structure.cross_couplings=[{node: 5, kcc: 0 N/m}]', 'forcing=[]',
            'sensors=[{name: y, node: 5, dof: uy}, {name: z, node: 5, dof: uz}]',
            'simulation.duration=3 s']
JEFFCOTT_ONSET = 2 * 0.02 * 2.0 * (2 * np.pi * 25.16460605224352) ** 2


def test_frf_sdof_and_cantilever_agree():
    # paper Figs. 4.1.2 and 4.1.3: the same frequency response with and without impactors
    a = frf('sdof', RATIOS, overrides=SDOF_AS_CANTILEVER + SHORT, executor='serial')
    b = frf('cantilever', RATIOS, overrides=SHORT, executor='serial')
    assert not a['failures'] and not b['failures']
    for case in ('with', 'without'):
        pa, pb = a['peaks']['primary'][case], b['peaks']['tip'][case]
        assert pa['amplitude_m'] == pytest.approx(pb['amplitude_m'], rel=0.02)
        assert pa['frequency_ratio'] == pb['frequency_ratio']
        for ra, rb in zip(a['rows'], b['rows']):
            assert ra[f'primary_{case}_m'] == pytest.approx(rb[f'tip_{case}_m'], rel=0.02)
    # the damper helps at the centre frequency: 25 F0/K without, 8.885 F0/K with (2 mil)
    centre = a['rows'][RATIOS.index(1.0)]
    assert centre['primary_reduction'] == pytest.approx(25 / 8.885, rel=0.01)


def test_serial_and_process_executors_agree():
    kw = dict(overrides=SHORT, seed=3)
    serial = frf('sdof', [0.95, 1.0, 1.05], executor='serial', **kw)
    process = frf('sdof', [0.95, 1.0, 1.05], executor='process', workers=2, **kw)
    assert serial['rows'] == process['rows']
    assert [p['result'] for p in serial['points']] == [p['result'] for p in process['points']]
    assert [p['seed'] for p in serial['points']] == [p['seed'] for p in process['points']]


def test_failing_point_is_reported_and_others_kept():
    grid = [('impactors.0.cor', ['0.5', '7', '0.6'])]   # cor 7 is out of range
    r = sweep('sdof', grid, overrides=['simulation.duration=1 s'], executor='process',
              workers=2)
    assert len(r['failures']) == 1
    assert "impactors" in r['failures'][0]['error'] and r['failures'][0]['labels']['grid'] == {
        'impactors.0.cor': '7'}
    ok = [row for row in r['rows'] if row['error'] is None]
    assert [row['impactors.0.cor'] for row in ok] == ['0.5', '0.6']
    assert all(row['run_worst_displacement_m'] > 0 for row in ok)


def test_runner_keeps_order_and_errors():
    def_point = Point(_boom, 'sdof')
    res = run_points([def_point, Point(_double, 'sdof', params={'x': 2})], 'serial')
    assert res[0].error == 'RuntimeError: boom' and res[0].value is None
    assert res[1].value == {'y': 4}


def _boom(point):
    raise RuntimeError('boom')


def _double(point):
    return {'y': 2 * point.params['x']}


def test_dask_local_cluster_sweep():
    distributed = pytest.importorskip('dask.distributed')
    with distributed.LocalCluster(n_workers=1, processes=False, dashboard_address=None) as c:
        r = sweep('sdof', [('impactors.0.clearance', ['3 mm', '4.8 mm'])],
                  overrides=['simulation.duration=1 s'], executor='dask',
                  dask_address=c.scheduler_address)
    serial = sweep('sdof', [('impactors.0.clearance', ['3 mm', '4.8 mm'])],
                   overrides=['simulation.duration=1 s'], executor='serial')
    assert not r['failures'] and r['rows'] == serial['rows']
    assert r['best'] and r['best'][0]['impactors.0.clearance'] in ('3 mm', '4.8 mm')
    assert r['rows'][0]['impactors.0.clearance_si'] == pytest.approx(3e-3)


def test_cli_frf_writes_json_csv_and_plot(tmp_path, capsys):
    csv_path, png = tmp_path / 'x.csv', tmp_path / 'x.png'
    status = main(['frf', 'sdof', '--ratio', '0.95:1.05:3', '--duration', '2 s', '--json',
                   '--csv', str(csv_path), '--plot', str(png), '--executor', 'serial',
                   '--seed', '1'])
    out, err = capsys.readouterr()
    assert status == 0, err
    data = json.loads(out)
    assert [r['frequency_ratio'] for r in data['rows']] == [0.95, 1.0, 1.05]
    rows = list(csv.DictReader(csv_path.open()))
    assert len(rows) == 3 and float(rows[1]['primary_without_m']) > 0
    assert png.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


@pytest.mark.parametrize('argv, message', [
    (['frf', 'sdof', '--ratio', '1:2'], 'START:STOP:N'),
    (['frf', 'sdof', '--ratio', '1', '--set', 'impactors.0.cor=9'], 'impactors'),
    (['sweep', 'sdof'], '--grid'),
    (['stability', 'sdof', '--kcc-key', 'x'], '--kcc'),
])
def test_cli_errors_exit_2(capsys, argv, message):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith('study: error:') and message in err and 'Traceback' not in err


def test_stability_verdicts_and_onset():
    r = stability('cantilever', KCC_KEY, ['1600 N/m', '2400 N/m'], JEFFCOTT,
                  weight_keys=['impactors.0.mass_ratio'], weights=['0.04'],
                  clearance_keys=['impactors.0.clearance'], clearances=['0.2 mil'],
                  find_onset=True, executor='serial')
    verdicts = {(row['kcc'], row['impactors']): row for row in r['rows']}
    assert verdicts[('1600 N/m', False)]['verdict'] == 'stable'
    assert verdicts[('2400 N/m', False)]['verdict'] == 'unstable'
    # growth rate of the linear Jeffcott rotor: (Kcc/m - c omega/m) / (2 omega), 1/s
    omega = 2 * np.pi * 25.16460605224352
    expected = (2400 - JEFFCOTT_ONSET) / 2.0 / (2 * omega)
    assert verdicts[('2400 N/m', False)]['growth_rate_1_s'] == pytest.approx(expected, rel=0.02)
    # a small-gap impact damper stabilizes the unstable case
    assert verdicts[('2400 N/m', True)]['verdict'] == 'stable'
    assert verdicts[('2400 N/m', True)]['impacts_per_second'] > 0
    assert r['onset']['onset_kcc_N_m'] == pytest.approx(JEFFCOTT_ONSET, rel=0.005)


def test_onset_bisection_matches_c_omega():
    o = onset('cantilever', KCC_KEY, JEFFCOTT, start_hi=100.0)
    assert o['onset_kcc_N_m'] == pytest.approx(JEFFCOTT_ONSET, rel=0.005)
    assert o['whirl_frequency_hz'] == pytest.approx(25.1646, rel=1e-3)


def test_split_values_keeps_brackets():
    assert split_values('1 mil, 2 mil') == ['1 mil', '2 mil']
    assert split_values('[1, 2],{value: 2, unit: lb}') == ['[1, 2]', '{value: 2, unit: lb}']


# --- sweeps over every impactor ('impactors.*.key', issue 38) -----------------------------------

def test_wildcard_sets_every_impactor_in_the_built_scene():
    """``impactors.*.clearance`` gives each of hpotp's 12 impactors the point's clearance;
    ``impactors.0.clearance`` moved only the first."""
    from impact_damper_sim.scene.build import load
    from impact_damper_sim.studies.sweep import expand_key, make_points
    base = load('hpotp', [])
    keys = expand_key('impactors.*.clearance', base.scene)
    assert keys == [f'impactors.{k}.clearance' for k in range(12)]
    points = make_points('hpotp', [('impactors.*.clearance', ['1 mil', '2 mil'])],
                         expansions={'impactors.*.clearance': keys})
    grid = [p for p in points if not p.labels['reference']]
    assert [p.labels['grid'] for p in grid] == [{'impactors.*.clearance': '1 mil'},
                                                {'impactors.*.clearance': '2 mil'}]
    for point, mil in zip(grid, (1, 2)):
        scene = load('hpotp', list(point.overrides))
        assert [imp['clearance'] for imp in scene.scene['impactors']] == pytest.approx(
            [mil * 25.4e-6] * 12, rel=1e-12)
    # the reference keeps the scene without impactors (one, the key is an impactor key)
    (ref,) = [p for p in points if p.labels['reference']]
    assert ref.overrides[-1] == 'impactors=[]'


@pytest.mark.parametrize('grid, message', [
    ('forcing.*.amplitude=1 N', "--grid forcing.*.amplitude: '*' matches nothing"),
    ('impactors.*.bogus=1', '--grid impactors.*.bogus: does not apply'),
])
def test_wildcard_that_matches_nothing_or_misses_an_impactor_is_refused(capsys, grid, message):
    assert main(['sweep', 'hpotp', '--grid', grid, '--executor', 'serial']) == 2
    err = capsys.readouterr().err
    assert err.startswith(f'study: error: {message}') and err.count('\n') == 1, err


def test_stability_wildcard_sets_every_impactor_in_the_built_scene(monkeypatch):
    """``--weight-key impactors.*.mass`` and ``--clearance-key impactors.*.clearance`` set
    each of rbs_kcc's six impactors in every point with impactors, as a sweep's grid does."""
    from impact_damper_sim.scene.build import load
    from impact_damper_sim.studies import stability as stability_module
    made = []
    monkeypatch.setattr(stability_module, 'run_points',
                        lambda points, *a, **k: made.extend(points) or [])
    stability('rbs_kcc', KCC_KEY, ['11250 lb/in'], weight_keys=['impactors.*.mass'],
              weights=['0.25 lb'], clearance_keys=['impactors.*.clearance'],
              clearances=['2 mil'], executor='serial')
    (point,) = [p for p in made if p.labels['impactors']]
    scene = load('rbs_kcc', list(point.overrides))
    imps = scene.scene['impactors']
    assert len(imps) == 6
    assert [imp['mass'] for imp in imps] == pytest.approx([0.25 * 0.45359237] * 6, rel=1e-12)
    assert [imp['clearance'] for imp in imps] == pytest.approx([2 * 25.4e-6] * 6, rel=1e-12)


@pytest.mark.parametrize('option, key', [('--weight-key', 'forcing.*.mass'),
                                         ('--clearance-key', 'impactors.*.clearance')])
def test_stability_wildcard_that_matches_nothing_is_refused(capsys, option, key):
    values = '--weights' if option == '--weight-key' else '--clearances'
    argv = ['stability', 'rbs_kcc', '--kcc-key', KCC_KEY, '--kcc', '11250 lb/in', option, key,
            values, '1', '--executor', 'serial']
    if key.startswith('impactors'):   # no impactors: nothing for the wildcard to match
        argv += ['--set', 'impactors=[]']
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"study: error: {option} {key}: '*' matches nothing") \
        and err.count('\n') == 1, err


def test_sweep_table_says_reduction_in_words(capsys):
    status = main(['sweep', 'sdof', '--grid', 'impactors.*.cor=0.5,0.6', '--duration', '1 s',
                   '--executor', 'serial'])
    out = capsys.readouterr().out
    assert status == 0
    header = next(line for line in out.splitlines() if line.startswith('impactors.*.cor'))
    words = header.split()
    assert 'red' not in words and words.count('reduction') == 4, header
    assert 'run displacement (m)' in header and 'steady acceleration (g)' in header


def test_sweep_plot_draws_the_level_without_impactors_and_both_phases(tmp_path, monkeypatch):
    """The reference level is a labelled horizontal line at the no-impactor value (in g);
    run and steady differ in line style, marker and fill, so coinciding lines both show."""
    pytest.importorskip('matplotlib')
    from matplotlib.figure import Figure

    from impact_damper_sim.studies.analysis import G0
    from impact_damper_sim.studies.sweep import plot
    figs = []
    original = Figure.savefig
    monkeypatch.setattr(Figure, 'savefig',
                        lambda self, *a, **k: (figs.append(self), original(self, *a, **k)))
    rows = [{'impactors.*.clearance': gap, 'impactors.*.clearance_si': si,
             'run_worst_acceleration_g': 2.0, 'steady_worst_acceleration_g': 2.0,
             'run_without_acceleration_m_s2': 5 * G0, 'steady_without_acceleration_m_s2': 3 * G0}
            for gap, si in (('1 mil', 25.4e-6), ('2 mil', 50.8e-6))]
    plot({'scene': 'hpotp', 'objective': 'acceleration', 'best_over': 'impactors.*.clearance',
          'grid': [{'key': 'impactors.*.clearance', 'values': ['1 mil', '2 mil']}],
          'phases': [{'name': 'run'}, {'name': 'steady'}], 'rows': rows}, tmp_path / 's.png')
    lines = {line.get_label(): line for line in figs[0].axes[0].get_lines()}
    ref = {k: v for k, v in lines.items() if k.startswith('without impactors')}
    assert sorted(ref) == ['without impactors (run)', 'without impactors (steady)']
    assert list(ref['without impactors (run)'].get_ydata()) == pytest.approx([5.0, 5.0])
    assert list(ref['without impactors (steady)'].get_ydata()) == pytest.approx([3.0, 3.0])
    run, steady = lines['with impactors (run)'], lines['with impactors (steady)']
    assert run.get_linestyle() != steady.get_linestyle()
    assert run.get_marker() != steady.get_marker()
    assert steady.get_markerfacecolor() == 'none' and steady.get_markersize() > run.get_markersize()
    assert figs[0].axes[0].get_xlabel() == 'impactors.*.clearance (mil)'
