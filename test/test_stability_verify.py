"""``study stability --verify``: physical, not numerical, instability.

Each verdict is re-run with ``simulation.dt`` halved and with the other method (exact <->
Newmark) from the same perturbation; a verdict that changes would be numerical. The RBS cases
are those of the paper's Table 4.4.1 (``studies/validation_setup.py``); the HPOTP cases put a
cross-coupling at the pump-end bearing (node 4, as ``docs/validation.md`` Table 4.4.2) at half
and twice its linear onset (computed; 14,314 lb/in there), rotor stopped so that only the
perturbation drives the casing.
"""
import math

import pytest

from impact_damper_sim.scene.build import load
from impact_damper_sim.studies.stability import stability, verification_settings
from impact_damper_sim.studies.validation_setup import (
    KCC_KEY,
    RBS_CRITERION,
    rbs_cell_overrides,
    settings,
)

RBS_KWARGS = {k: v for k, v in RBS_CRITERION.items()}
HPOTP_BASE = ['structure.cross_couplings=[{node: 4, kcc: 0 lb/in}]', 'rotor=null',
              'simulation.duration=1 s', 'simulation.window=0.25 s']


def _verify(scene, kccs, overrides, **kwargs):
    r = stability(scene, KCC_KEY, kccs, overrides, verify=True, executor='serial',
                  progress=False, **kwargs)
    assert not r['failures']
    return r


def test_verification_settings():
    """exact scenes check with Newmark at a step under a tenth of the highest retained
    mode's period (hpotp: 1293 Hz, so 0.1 ms is halved to 50 us); dt/2 keeps the method."""
    v = verification_settings(load('hpotp'))
    assert v['half_dt'] == {'method': 'exact', 'dt_s': 5e-5,
                            'overrides': ['simulation.dt=5e-05']}
    assert v['other_method']['method'] == 'newmark' and v['other_method']['dt_s'] == 5e-5
    v = verification_settings(load('sdof', ['simulation.method=newmark']))
    assert v['other_method']['method'] == 'exact' and v['other_method']['dt_s'] == 1e-4


def test_rbs_verdicts_do_not_change_reduced():
    """Reduced RBS case (0.4 s, 0.1 s windows): the bare rotor at 8,000 lb/in (below the
    8,275 lb/in onset) is stable and at 11,250 lb/in unstable, whatever the step or method."""
    r = _verify('rbs_kcc', ['8000 lb/in', '11250 lb/in'],
                ['simulation.duration=0.4 s', 'simulation.window=0.1 s', 'impactors=[]'],
                **RBS_KWARGS)
    assert [row['verdict'] for row in r['rows']] == ['stable', 'unstable']
    assert all(row['verified'] for row in r['rows']), r['rows']
    assert r['verification']['other_method']['method'] == 'newmark'


def test_scene_default_rows_show_the_scene_impactors(capsys):
    """Rows that keep the scene's impactors print their weight and clearance, not None."""
    from impact_damper_sim.cli.study import main
    status = main(['stability', 'rbs_kcc', '--kcc-key', KCC_KEY, '--kcc', '11250 lb/in',
                   '--duration', '0.02', '--window', '0.01', '--executor', 'serial',
                   '--no-progress'])
    out = capsys.readouterr().out
    assert status == 0
    assert 'None' not in out
    assert '6 x 0.2268 kg' in out and '8.763e-05 m' in out


@pytest.fixture(scope='module')
def table_441():
    """Every cell of Table 4.4.1 as docs/validation.md runs it (1 s, 0.25 s windows),
    verified: rows of the impacting cells and, separately, of the bare rotor."""
    s = settings(quick=False)
    kccs = [f'{k} lb/in' for k in s['kccs']]
    bare = _verify('rbs_kcc', kccs, s['rbs_overrides'] + ['impactors=[]'], **RBS_KWARGS)['rows']
    cells = []
    for w in s['weights']:
        for d in s['gaps']:
            rows = _verify('rbs_kcc', kccs, s['rbs_overrides'] + rbs_cell_overrides(w, d),
                           baseline=False, **RBS_KWARGS)['rows']
            cells += [dict(r, w=w, d=d) for r in rows]
    return bare, cells


def _ratios(row):
    """Window-to-window growth of the three runs; inf for a run that outgrew floating point
    (stopped by the divergence guard, so no ratio: it grew by more than any window could)."""
    ratios = []
    for suffix in ('', '_half_dt', '_other_method'):
        ratio = row['growth_ratio' + suffix]
        if ratio is None and row['diverged_at_s' + suffix] is not None:
            ratio = math.inf
        assert ratio is not None, row
        ratios.append(ratio)
    return ratios


@pytest.mark.slow
def test_rbs_bare_rotor_is_unstable_whatever_the_numerics(table_441):
    """Without impactors every Kcc of the table is above the onset: all three runs grow by
    more than 100 x per 0.25 s window (measured 219 to 2e18), or outgrow floating point."""
    bare, _ = table_441
    for row in bare:
        assert row['verified'] and row['verdict'] == 'unstable'
        assert min(_ratios(row)) > 100


@pytest.mark.slow
def test_rbs_impacting_cells_stay_bounded_whatever_the_numerics(table_441):
    """With impactors every cell is a bounded rattling limit cycle in all three runs (the
    scene's dt, dt/2, Newmark): RMS radial amplitude below 1e-4 m (measured 1e-6 to 3e-5 m,
    clearances 1 and 6.9 mil) and no window-to-window growth beyond 10 x (measured 0.52 to
    2.6), against more than 100 x for the bare rotor. The impactors' stabilization is
    physical."""
    _, cells = table_441
    assert len(cells) == 18
    for row in cells:
        assert max(row['rms_radial_m'], row['rms_radial_m_half_dt'],
                   row['rms_radial_m_other_method']) < 1e-4
        assert max(_ratios(row)) < 10.0


@pytest.mark.slow
def test_rbs_table_441_verdicts_do_not_change(table_441):
    bare, cells = table_441
    changed = [(r['kcc'], r['w'], r['d'], r['verdict'], r['verdict_half_dt'],
                r['verdict_other_method']) for r in cells if not r['verified']]
    assert not changed


@pytest.mark.slow
def test_hpotp_verdicts_do_not_change():
    """HPOTP casing at 0.5 and 2 x its onset, bare and with its impactors: bare is stable
    below and unstable above; every verdict survives dt/2 and Newmark."""
    from impact_damper_sim.studies.stability import onset
    kcc = onset('hpotp', KCC_KEY, HPOTP_BASE, start_hi=1e5, rtol=1e-3)['onset_kcc_N_m']
    r = _verify('hpotp', [repr(0.5 * kcc), repr(2.0 * kcc)], HPOTP_BASE, perturbation=1e-6)
    bare = [row['verdict'] for row in r['rows'] if not row['impactors']]
    assert bare == ['stable', 'unstable']
    assert all(row['verified'] for row in r['rows']), r['rows']
