"""The RBS scene (paper sections 4.2, 4.4, Appendix A): DOF count, mode labels and the
calibrated stability onset without impactors."""
import numpy as np
import pytest

from impact_damper_sim.modal import least_damped_eigenvalue, onset_cross_coupling
from impact_damper_sim.scene.build import load
from impact_damper_sim.units import parse_quantity

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
