"""The RBS scene (paper sections 4.2, 4.4, Appendix A): DOF count, mode labels and the
calibrated stability onset without impactors, and the damper acting in the default run."""
import numpy as np
import pytest

from impact_damper_sim.integrate.events import EVENT_KINDS
from impact_damper_sim.modal import least_damped_eigenvalue, onset_cross_coupling
from impact_damper_sim.scene.build import load
from impact_damper_sim.scene.units import parse_quantity
from impact_damper_sim.studies.validation_setup import PAPER_4_4_1

LBIN = parse_quantity('1 lb/in', 'stiffness')
PAPER_ONSET = 8250.0 * LBIN
LOWER = 4   # lower bearing node
ZETA = {'1-Y': 0.0105, '1-Z': 0.0188, '2-Y': 0.016, '2-Z': 0.0288}


@pytest.fixture(scope='module')
def rbs():
    return load('rbs')


def mode_labels(scene):
    """Label each retained mode by its dominant DOF kind (sum of squared shape values):
    n-Y / n-Z for the n-th lateral mode in that plane, else the DOF name."""
    system, basis = scene.system, scene.basis
    energy = {}
    for comp in ('ux', 'uy', 'uz', 'rx'):
        idx = []
        for node in range(scene.n_nodes):
            try:
                idx.append(system.index(node, comp))
            except KeyError:
                pass
        energy[comp] = np.sum(basis.rows(idx) ** 2, axis=0)
    labels, count = [], {}
    for k in range(basis.n_modes):
        comp = max(energy, key=lambda c: energy[c][k])
        count[comp] = count.get(comp, 0) + 1
        labels.append(f'{count[comp]}-{comp[1].upper()}' if comp in ('uy', 'uz') else comp)
    return labels


def test_dof_count_is_the_papers(rbs):
    counts = rbs.dof_counts()
    assert rbs.n_nodes == 38
    assert counts['active'] == 227 and counts['after_condensation'] == 227
    assert rbs.basis.n_modes == 10 and len(rbs.impactors) == 6


def test_tare_damping_follows_the_mode_shapes(rbs):
    labels = mode_labels(rbs)
    print('\nRBS modes:', ', '.join(f'{f:.1f} Hz {lab}' for f, lab in
                                    zip(rbs.basis.frequencies_hz, labels)))
    assert labels[:2] == ['1-Y', '1-Z']
    for k, label in enumerate(labels):
        assert rbs.basis.zeta[k] == pytest.approx(ZETA.get(label, 0.005), rel=1e-12), label


def test_onset_cross_coupling_matches_the_paper(rbs):
    """Tolerance +-10 % of the paper's 8250 lb/in (calibrated to +0.3 %). Kcc enters the modal
    model as Kcc (phi_y phi_z^T - phi_z phi_y^T) on the fixed basis, checked against a scene
    built with the cross-coupling."""
    basis = rbs.basis
    iy, iz = rbs.system.index(LOWER, 'uy'), rbs.system.index(LOWER, 'uz')
    py, pz = basis.rows([iy])[0], basis.rows([iz])[0]
    unit = np.outer(py, pz) - np.outer(pz, py)
    K0, C0 = basis.stiffness_matrix(), basis.damping_matrix()

    def matrices(kcc):
        return K0 + kcc * unit, C0

    built = load('rbs', [f'structure.cross_couplings=[{{node: {LOWER}, kcc: 9000 lb/in}}]'])
    np.testing.assert_allclose(built.basis.stiffness_matrix(), matrices(9000 * LBIN)[0],
                               rtol=1e-9, atol=1e-9 * np.abs(K0).max())
    onset = onset_cross_coupling(matrices, 0.0, 3 * PAPER_ONSET, rtol=1e-6)
    lam = least_damped_eigenvalue(*matrices(onset))
    print(f'\nRBS onset Kcc = {onset / LBIN:.1f} lb/in, whirl {lam.imag / (2 * np.pi):.2f} Hz')
    assert abs(onset / PAPER_ONSET - 1) <= 0.10
    assert least_damped_eigenvalue(*matrices(11250 * LBIN)).real > 0   # rbs_kcc is unstable


# --- stability with impactors (Table 4.4.1) -------------------------------------------------
# The criterion is the stability study's own (impact_damper_sim.studies.stability.verdict):
# unstable when the RMS radial amplitude of the last window over the previous one exceeds
# 1 + growth_tol, or is not finite. Radial amplitude from both lower-bearing sensors.

KCC_KEY = 'structure.cross_couplings.0.kcc'
from impact_damper_sim.studies.validation_setup import RBS_CRITERION  # noqa: E402

MIL = parse_quantity('1 mil', 'length')
LB = parse_quantity('1 lb', 'mass')
CRITERION = dict(RBS_CRITERION)   # the validation's (growth_tol 4, see its comment)


def cell_overrides(weight_lb, gap_mil, n=6):
    """Overrides for Table 4.4.1's (W, D): six impactors of W/6 each, housing mass W, radial
    clearance D/2, initial positions at half the clearance round the cage."""
    ov = []
    for j in range(n):
        r = 0.5 * gap_mil / 2
        a = 2 * np.pi * j / n
        y, z = float(r * np.cos(a)), float(r * np.sin(a))
        ov += [f'impactors.{j}.mass={weight_lb / n!r} lb',
               f'impactors.{j}.housing_mass={weight_lb!r} lb',
               f'impactors.{j}.clearance={gap_mil / 2!r} mil',
               f"impactors.{j}.position=['{y!r} mil', '{z!r} mil']"]
    return ov


def run_cell(kcc, duration, window, extra=(), baseline=False):
    """Verdicts of one Kcc (lb/in) with the scene's impactors plus ``extra`` overrides (and
    without impactors if ``baseline``): list of (with_impactors, verdict dict)."""
    from impact_damper_sim.studies.stability import make_points, verdict
    base = [f'simulation.duration={duration}', f'simulation.window={window}']
    points = make_points('rbs_kcc', KCC_KEY, [f'{kcc} lb/in'], base + list(extra),
                         baseline=baseline, params=CRITERION)
    return [(p.labels['impactors'], verdict(p)) for p in points]


def test_rbs_kcc_defaults_are_w3_d6p9():
    """The scene's impactors are Table 4.4.1's W = 3 lb, D = 6.9 mil (diametral gap)."""
    s = load('rbs_kcc')
    imps = s.scene['impactors']
    assert len(imps) == 6
    assert sum(i['mass'] for i in imps) == pytest.approx(3 * LB, rel=1e-12)
    for i in imps:
        assert i['housing_mass'] == pytest.approx(3 * LB, rel=1e-12)
        assert 2 * i['clearance'] == pytest.approx(6.9 * MIL, rel=1e-12)
    assert s.scene['structure']['cross_couplings'][0]['kcc'] == pytest.approx(11250 * LBIN)


def _check_stabilized(duration, window):
    rows = run_cell(11250, duration, window, baseline=True)
    (imp0, bare), (imp1, damped) = rows
    assert not imp0 and imp1
    print(f'\nKcc 11250 lb/in, {duration}: without impactors growth ratio '
          f"{bare['growth_ratio']}, rate {bare['growth_rate_1_s']} 1/s; with W 3 lb, D 6.9 mil: "
          f"{damped['rms_radial_m'] / MIL:.3f} mil rms, ratio {damped['growth_ratio']:.3f}, "
          f"{damped['impacts_per_second']:.0f} impacts/s")
    assert not bare['stable']
    assert damped['stable']
    assert damped['rms_radial_m'] < 10 * MIL and damped['impacts_per_second'] > 100


def test_impactors_stabilize_kcc_11250_fast():
    """Table 4.4.1 trend: unstable without impactors, stable with W = 3 lb, D = 6.9 mil."""
    _check_stabilized('0.2 s', '0.05 s')


@pytest.mark.slow
def test_impactors_stabilize_kcc_11250_long():
    _check_stabilized('1 s', '0.25 s')


# Table 4.4.1 as the validation document states it (one copy of the paper's numbers)
PAPER_TABLE = PAPER_4_4_1


@pytest.mark.slow
def test_table_4_4_1_paper_vs_ours():
    """Measure every Table 4.4.1 cell (1 s, last 0.25 s window) and print paper vs ours;
    asserts only the cells of the stabilized trend (W = 3 lb, D = 6.9 mil stable at every Kcc,
    every Kcc unstable without impactors). The table is in docs/rbs-model.md."""
    lines = ['| Kcc (lb/in) | W (lb) | D (mil) | paper | ours | paper rms (mil) | ours rms (mil) '
             '| paper impacts/s | ours impacts/s |', '|---|---|---|---|---|---|---|---|---|']
    ours = {}
    for kcc in (8500, 11250, 13500):
        (_, bare), = run_cell(kcc, '1 s', '0.25 s', ['impactors=[]'])
        assert not bare['stable']
        lines.append(f'| {kcc} | none | - | unst | unst | - | - | - | - |')
        for w in (1.5, 3.0, 6.0):
            for d in (6.9, 1.0):
                (_, v), = run_cell(kcc, '1 s', '0.25 s', cell_overrides(w, d))
                ours[kcc, w, d] = v
                p_st, p_rms, p_ips = PAPER_TABLE[kcc, w, d]
                rms = v['rms_radial_m']
                if v['stable'] and rms is not None:
                    rms_txt, ips_txt = f'{rms / MIL:.2f}', f"{v['impacts_per_second']:.0f}"
                else:
                    rms_txt = ips_txt = '-'
                verdicts = ['stab' if p_st else 'unst', 'stab' if v['stable'] else 'unst']
                lines.append(f'| {kcc} | {w} | {d} | {verdicts[0]} | {verdicts[1]} | '
                             f"{p_rms or '-'} | {rms_txt} | {p_ips or '-'} | {ips_txt} |")
    print('\n' + '\n'.join(lines))
    for kcc in (8500, 11250, 13500):
        assert ours[kcc, 3.0, 6.9]['stable'], kcc


def _impacts_per_impactor(overrides, t_settle, t_end):
    """Impacts of each impactor between ``t_settle`` and ``t_end`` (s) of a run from rest."""
    sim = load('rbs', overrides).make_simulation('exact', None)
    sim.advance_to(t_settle)
    sim.take_events()
    sim.advance_to(t_end)
    events = sim.take_events()
    hits = events[events['kind'] == EVENT_KINDS.index('impact')]
    return np.bincount(hits['impactor'], minlength=6)


def test_default_run_shows_the_damper_at_the_first_critical():
    """Issue 38: the default run must show the damper. At the scene's 3920 rpm (the 1-Y
    critical, 65.3 Hz) the lower-bearing orbit reaches the 43.8 um gap: measured, four of the
    six impactors rattle at about 600 impacts/s each (2,400/s in all) from 1 s on. Floors: at
    least three impactors and 1,200 impacts/s, half the measured rate. At the paper's
    7878 rpm the bearing moves 1.2 um and no impactor ever moves: the reason for the default."""
    assert load('rbs').scene['rotor']['speed']['speed'] == pytest.approx(3920 * 2 * np.pi / 60)
    at_critical = _impacts_per_impactor([], 1.0, 2.0)
    assert np.count_nonzero(at_critical) >= 3, at_critical
    assert at_critical.sum() / 1.0 > 1200.0, at_critical
    at_paper_speed = _impacts_per_impactor(['rotor.speed.speed=7878 rpm'], 1.0, 2.0)
    assert at_paper_speed.sum() == 0, at_paper_speed
