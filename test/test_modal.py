"""Modal reduction: closed-form frequencies, condensation, harmonic response, stability onset.

Test systems are hand-built spring-mass networks (no FE builder), so every reference value is
a closed form or an independent direct solve. Each test states its tolerance.
"""
import numpy as np
import pytest
import scipy.sparse as sp

from impact_damper_sim.fem.system import AssembledSystem
from impact_damper_sim.modal import (
    full_harmonic_response,
    harmonic_response,
    least_damped_eigenvalue,
    modal_reduction,
    onset_cross_coupling,
    state_matrix,
)


def network(masses, springs, dampers=(), dofs=None, extra_k=None):
    """Build an AssembledSystem from point masses, springs and dashpots.

    ``springs``/``dampers`` are ``(i, j, value)`` between DOFs ``i`` and ``j`` (N/m, N s/m);
    ``j = None`` ties ``i`` to ground. ``extra_k`` is added to K as is (N/m). By default DOF
    ``i`` is ``ux`` of node ``i + 1``.
    """
    n = len(masses)
    K = np.zeros((n, n))
    C = np.zeros((n, n))
    for mat, elems in ((K, springs), (C, dampers)):
        for i, j, v in elems:
            mat[i, i] += v
            if j is not None:
                mat[j, j] += v
                mat[i, j] -= v
                mat[j, i] -= v
    if extra_k is not None:
        K = K + extra_k
    if dofs is None:
        dofs = [[i + 1, 0] for i in range(n)]
    return AssembledSystem(M=sp.csr_matrix(np.diag(np.asarray(masses, dtype=float))),
                           C=sp.csr_matrix(C), K=sp.csr_matrix(K),
                           dofs=np.asarray(dofs, dtype=np.int64))


def fixed_free_chain(n, m, k):
    """n identical masses m (kg) and springs k (N/m), fixed at one end, free at the other."""
    return network([m] * n, [(0, None, k)] + [(i, i + 1, k) for i in range(n - 1)])


def damped_chain():
    """8-DOF chain with a massless DOF (index 2, grounded too) and discrete dashpots.

    The dashpots sit on DOFs with mass only, so the static condensation of C is exact and the
    full and the complete modal model are the same operator.
    """
    masses = [1.0, 1.5, 0.0, 2.0, 1.2, 0.8, 1.0, 0.5]
    springs = [(0, None, 2e4), (0, 1, 1.5e4), (1, 2, 1e4), (2, 3, 3e4), (2, None, 5e3),
               (3, 4, 2e4), (4, 5, 1e4), (5, 6, 1.2e4), (6, 7, 0.9e4)]
    dampers = [(1, None, 5.0), (4, 5, 3.0), (7, None, 2.0)]
    return network(masses, springs, dampers)


def jeffcott(m, k, c, kcc):
    """One node, translations uy/uz: mass m (kg), springs k (N/m), dashpots c (N s/m),
    cross-coupled stiffness K_yz = +kcc, K_zy = -kcc (N/m)."""
    skew = np.array([[0.0, kcc], [-kcc, 0.0]])
    return network([m, m], [(0, None, k), (1, None, k)], [(0, None, c), (1, None, c)],
                   dofs=[[1, 1], [1, 2]], extra_k=skew)


# 1. mass normalization, orthogonality, closed-form chain frequencies ---------------------

@pytest.mark.parametrize('method', ['dense', 'sparse'])
def test_chain_closed_form_and_normalization(method):
    """Tolerance: Phi^T M Phi = I and Phi^T K Phi = diag(omega^2) to 1e-12 (relative to
    omega_max^2 for K); omega_k = 2 sqrt(k/m) sin((2k-1) pi/(2(2n+1))) to 1e-12 relative."""
    n, m, k = 7, 2.5, 3.0e4
    n_modes = n if method == 'dense' else 4   # eigsh needs n_modes < n
    basis = modal_reduction(fixed_free_chain(n, m, k), n_modes=n_modes, method=method)
    j = np.arange(1, n_modes + 1)
    closed = 2.0 * np.sqrt(k / m) * np.sin((2 * j - 1) * np.pi / (2 * (2 * n + 1)))
    np.testing.assert_allclose(basis.omega, closed, rtol=1e-12, atol=0)
    phi = basis.shapes
    M = basis.condensation.M
    K = basis.condensation.K
    assert np.abs(phi.T @ M @ phi - np.eye(n_modes)).max() <= 1e-12
    kk = phi.T @ K @ phi
    assert np.abs(kk - np.diag(basis.omega ** 2)).max() <= 1e-12 * basis.omega[-1] ** 2
    assert basis.coupling_is_diagonal()
    np.testing.assert_allclose(basis.frequencies_hz, closed / (2 * np.pi), rtol=1e-12)


def test_sparse_matches_dense_on_long_chain():
    """Tolerance: lowest 12 omegas of a 300-DOF chain agree to 1e-10 relative (dense LAPACK
    loses about eps * omega_max^2/omega_1^2 ~ 1e-11 on the lowest ones), mass normalization of
    the eigsh + Rayleigh-Ritz basis to 1e-12."""
    n = 300
    masses = [1.0 + 0.01 * i for i in range(n)]
    springs = [(0, None, 1e4)] + [(i, i + 1, 1e4 * (1 + 0.003 * i)) for i in range(n - 1)]
    system = network(masses, springs)
    dense = modal_reduction(system, n_modes=12, method='dense')
    sparse = modal_reduction(system, n_modes=12, method='sparse')
    np.testing.assert_allclose(sparse.omega, dense.omega, rtol=1e-10)
    phi = sparse.shapes
    assert np.abs(phi.T @ sparse.condensation.M @ phi - np.eye(12)).max() <= 1e-12
    by_f = modal_reduction(system, f_max=2.0, method='sparse')
    assert by_f.n_modes == np.count_nonzero(modal_reduction(system).frequencies_hz <= 2.0)


def test_sparse_without_a_cutoff_keeps_every_mode():
    """``method='sparse'`` with neither ``n_modes`` nor ``f_max`` keeps every mode, as its
    docstring says (it raised TypeError before: Lanczos has no cut-off to reach). Tolerance:
    the same omegas as the dense solver to 1e-12 relative, all 7 closed-form ones."""
    n, m, k = 7, 2.5, 3.0e4
    system = fixed_free_chain(n, m, k)
    every = modal_reduction(system, method='sparse')
    assert every.n_modes == n
    j = np.arange(1, n + 1)
    closed = 2.0 * np.sqrt(k / m) * np.sin((2 * j - 1) * np.pi / (2 * (2 * n + 1)))
    np.testing.assert_allclose(every.omega, closed, rtol=1e-12, atol=0)
    np.testing.assert_allclose(every.omega, modal_reduction(system, method='dense').omega,
                               rtol=1e-12)


def test_selection_by_count_cutoff_and_both():
    """Exact counts; the reason string names the rule that decided."""
    system = fixed_free_chain(6, 1.0, 1e4)
    all_modes = modal_reduction(system)
    f = all_modes.frequencies_hz
    assert all_modes.n_modes == 6 and all_modes.selection_reason.startswith('all 6 modes')
    by_n = modal_reduction(system, n_modes=3)
    assert by_n.n_modes == 3 and 'by count (n_modes=3)' in by_n.selection_reason
    cut = 0.5 * (f[3] + f[4])
    by_f = modal_reduction(system, f_max=cut)
    assert by_f.n_modes == 4 and '(f_max)' in by_f.selection_reason
    assert modal_reduction(system, n_modes=2, f_max=cut).n_modes == 2
    both = modal_reduction(system, n_modes=5, f_max=cut)
    assert both.n_modes == 4 and 'fewer than n_modes=5' in both.selection_reason
    np.testing.assert_allclose(by_f.omega, all_modes.omega[:4], rtol=1e-12)  # other driver


def test_rigid_body_modes_rejected():
    """A free-free chain has a zero eigenvalue: the error gives the lowest eigenvalue."""
    free_free = network([1.0] * 4, [(i, i + 1, 1e4) for i in range(3)])
    for method in ('dense', 'sparse'):
        with pytest.raises(ValueError, match='not positive definite: lowest eigenvalue'):
            modal_reduction(free_free, n_modes=2, method=method)


# 2. massless DOFs --------------------------------------------------------------------------

def test_massless_dof_condensed_like_by_hand():
    """m1 -(k1)- s -(k2)- m2 with s massless and grounded through kg; m1 grounded through ka.

    By hand (star-delta): m1-m2 spring k1 k2/S, m1-ground ka + k1 kg/S, m2-ground k2 kg/S,
    S = k1 + k2 + kg; frequencies from the 2x2 characteristic quadratic.
    Tolerance: 1e-12 relative on omega and on the recovered slave displacement.
    """
    m1, m2, ka, k1, k2, kg = 1.3, 0.7, 2e4, 1e4, 3e4, 5e3
    system = network([m1, 0.0, m2], [(0, None, ka), (0, 1, k1), (1, 2, k2), (1, None, kg)])
    basis = modal_reduction(system)
    assert basis.condensation.slave.tolist() == [1]
    S = k1 + k2 + kg
    k11 = ka + k1 * k2 / S + k1 * kg / S
    k22 = k1 * k2 / S + k2 * kg / S
    k12 = -k1 * k2 / S
    a, b, c = m1 * m2, k11 * m2 + k22 * m1, k11 * k22 - k12 ** 2
    lam_hi = (b + np.sqrt(b * b - 4 * a * c)) / (2 * a)
    lam_lo = c / (a * lam_hi)   # Vieta: no cancellation
    np.testing.assert_allclose(basis.omega, np.sqrt([lam_lo, lam_hi]), rtol=1e-12, atol=0)
    # slave recovered from force balance at s: u_s = (k1 u1 + k2 u2)/S
    u_s = basis.rows(1)[0]
    u_m = basis.rows([0, 2])
    np.testing.assert_allclose(u_s, (k1 * u_m[0] + k2 * u_m[1]) / S, rtol=1e-12)
    np.testing.assert_array_equal(basis.rows_at([(2, 'ux'), (3, 0)]), basis.rows([1, 2]))


def test_effective_mass_complete_basis_is_lumped_mass():
    """Tolerance 1e-12: with all modes, 1/sum(phi^2) = M_ii and R R^T = diag(1/m);
    truncation raises the effective mass."""
    system = damped_chain()
    basis = modal_reduction(system)
    assert basis.effective_mass(7) == pytest.approx(0.5, rel=1e-12)
    np.testing.assert_allclose(basis.effective_mass([3, 4]), np.diag([1 / 2.0, 1 / 1.2]),
                               rtol=1e-12, atol=1e-12)
    masses = [modal_reduction(system, n_modes=n).effective_mass(7) for n in (7, 4, 2)]
    assert masses[0] < masses[1] < masses[2]


# 3. harmonic response: complete modal model vs full physical model -------------------------

def test_harmonic_response_complete_and_truncated():
    """Tolerance: all modes reproduce the full (uncondensed, sparse) receptance to 1e-8
    relative at masters and at the massless DOF, at Omega below, at and between resonances.
    Truncated models: max relative error over the same Omegas is printed and must decrease
    with 1, 2, 4 modes."""
    system = damped_chain()
    complete = modal_reduction(system)
    assert not complete.coupling_is_diagonal()   # physical dashpots couple the modes
    w = complete.omega
    omegas = np.array([0.3 * w[0], 0.98 * w[0], w[0], 0.5 * (w[0] + w[1]), 1.01 * w[2]])
    force, outputs = 7, [7, 2, 0]   # tip force; tip, massless and root outputs
    ref = full_harmonic_response(system, force, outputs, omegas)

    def response(basis):
        return harmonic_response(basis, basis.rows(force), basis.rows(outputs), omegas)[..., 0]

    exact = float((np.abs(response(complete) - ref) / np.abs(ref)).max())
    assert exact <= 1e-8
    # truncated: |h - ref| / |ref| over the three outputs, per Omega
    errors = {n: np.linalg.norm(response(modal_reduction(system, n_modes=n)) - ref, axis=1)
              / np.linalg.norm(ref, axis=1) for n in (1, 2, 4)}
    print(f'\nharmonic response vs full model, Omega/omega_1 = '
          f'{np.array2string(omegas / w[0], precision=3)}')
    print(f'  {complete.n_modes} modes (complete): max elementwise rel. error {exact:.2e}')
    for n, e in errors.items():
        print(f'  {n} modes: rel. error {np.array2string(e, precision=3)}, max {e.max():.3e}')
    assert errors[1].max() > errors[2].max() > errors[4].max() > 1e-8


def test_harmonic_response_with_cross_coupling():
    """Tolerance 1e-8 relative: a non-symmetric K (Kcc at one node) enters the modal model as
    Phi^T K_skew Phi; with all modes the receptance matrix matches the direct solve."""
    m, k = 2.0, 5e4
    masses = [m, m, 1.5 * m, 1.5 * m]   # nodes 1 and 2, uy and uz
    springs = [(0, None, k), (1, None, 1.2 * k), (0, 2, 0.8 * k), (1, 3, 0.8 * k),
               (2, None, 0.3 * k), (3, None, 0.35 * k)]
    dampers = [(2, None, 8.0), (3, None, 6.0)]
    skew = np.zeros((4, 4))
    skew[2, 3], skew[3, 2] = 3e3, -3e3
    system = network(masses, springs, dampers, dofs=[[1, 1], [1, 2], [2, 1], [2, 2]],
                     extra_k=skew)
    basis = modal_reduction(system, zeta=0.0)
    assert not np.allclose(basis.stiffness_matrix(), np.diag(basis.omega ** 2))
    omegas = np.concatenate([basis.omega * 0.999, [0.4 * basis.omega[0]]])
    for force in range(4):
        ref = full_harmonic_response(system, force, np.arange(4), omegas)
        h = harmonic_response(basis, basis.rows(force), basis.rows(np.arange(4)), omegas)
        np.testing.assert_allclose(h[..., 0], ref, rtol=1e-8, atol=0)


def test_tare_damping_enters_the_diagonal():
    """Exact: diag(2 zeta omega) with overrides; no physical dashpots -> diagonal coupling."""
    basis = modal_reduction(fixed_free_chain(4, 1.0, 1e4), zeta=0.02, zeta_overrides={1: 0.1})
    np.testing.assert_array_equal(basis.zeta, [0.02, 0.1, 0.02, 0.02])
    np.testing.assert_allclose(np.diag(basis.damping_matrix()), 2 * basis.zeta * basis.omega,
                               rtol=1e-15)
    assert basis.coupling_is_diagonal()


# 5. stability onset -----------------------------------------------------------------------

def test_jeffcott_onset_at_c_omega_n():
    """Tolerance 0.5% (achieved ~1e-8): the onset found by bisection through the modal
    coupling path (Phi^T K_skew Phi, Phi^T C Phi) is Kcc = c omega_n."""
    m, k, c = 3.0, 4e5, 60.0
    omega_n = np.sqrt(k / m)

    def modal_matrices(kcc):
        basis = modal_reduction(jeffcott(m, k, c, kcc))
        return basis.stiffness_matrix(), basis.damping_matrix()

    onset = onset_cross_coupling(modal_matrices, 0.0, 3 * c * omega_n, rtol=1e-8)
    ratio = onset / (c * omega_n)
    print(f'\nJeffcott onset Kcc/(c omega_n) = {ratio:.10f}')
    assert abs(ratio - 1) <= 5e-3
    # below onset the least-damped root is the forward whirl with Re = -c/(2m) at Kcc = 0
    lam = least_damped_eigenvalue(*modal_matrices(0.0))
    assert lam.real == pytest.approx(-c / (2 * m), rel=1e-10)


def test_state_matrix_with_physical_mass():
    """Exact: M q'' + C q' + K q = 0 in first-order form."""
    M, C, K = np.diag([2.0, 4.0]), np.eye(2), np.array([[6.0, 1.0], [1.0, 8.0]])
    A = state_matrix(K, C, M)
    np.testing.assert_array_equal(A[:2, 2:], np.eye(2))
    np.testing.assert_allclose(A[2:, :2], -np.linalg.solve(M, K), rtol=1e-15)


def test_onset_needs_a_sign_change():
    def stable(kcc):
        return np.eye(1) * 100.0, np.eye(1)
    with pytest.raises(ValueError, match='does not change sign'):
        onset_cross_coupling(stable, 0.0, 1.0)


# 6. bad inputs -----------------------------------------------------------------------------

@pytest.mark.parametrize('kwargs, match', [
    ({'zeta': 1.0}, r'zeta=1\.0 out of range \[0, 1\)'),
    ({'zeta': -0.01}, r'zeta=-0\.01 out of range'),
    ({'zeta': float('nan')}, r'zeta=nan out of range'),
    ({'zeta_overrides': {4: 0.1}}, r'zeta_overrides: mode index 4 out of range 0\.\.3'),
    ({'zeta_overrides': {-1: 0.1}}, r'zeta_overrides: mode index -1 out of range'),
    ({'zeta_overrides': {0: 1.5}}, r'zeta_overrides\[0\]=1\.5 out of range \[0, 1\)'),
    ({'n_modes': 0}, r'n_modes=0 must be >= 1'),
    ({'n_modes': 2.5}, r'n_modes must be an integer'),
    ({'n_modes': 9}, r'n_modes=9 exceeds the 4 modes'),
    ({'f_max': 0.0}, r'f_max=0\.0 Hz must be finite and > 0'),
    ({'f_max': -5.0}, r'f_max=-5\.0 Hz must be finite and > 0'),
    ({'f_max': 0.5}, r'f_max=0\.5 Hz is below the first natural frequency'),
    ({'method': 'lanczos'}, r"method='lanczos' unknown"),
])
def test_bad_inputs_name_the_field(kwargs, match):
    system = fixed_free_chain(4, 1.0, 1e4)   # first mode about 5.5 Hz
    with pytest.raises(ValueError, match=match):
        modal_reduction(system, **kwargs)


# optional: the beam FE builder, if present -------------------------------------------------

def test_fe_cantilever_complete_modal_model_matches_full():
    """Tolerance 1e-8 relative: FE cantilever with massless rotations (condensed), a tip
    dashpot and cross-coupling; the complete modal receptance equals the sparse direct solve at
    a translation and at a condensed rotation."""
    fem = pytest.importorskip('impact_damper_sim.fem')
    if not hasattr(fem, 'FEModel'):
        pytest.skip('FEModel not available')
    model = fem.FEModel()
    for i in range(7):
        model.add_node(i, (0.15 * i, 0.0, 0.0))
    for i in range(6):
        model.add_beam(i, i + 1, fem.STEEL, fem.SolidCircular(0.04))
    model.clamp(0)
    model.add_point_mass(6, 2.0)
    model.add_damper(6, 'uy', 40.0)
    model.add_damper(6, 'uz', 25.0)
    model.add_cross_coupling(3, 2e4)
    system = model.assemble()
    basis = modal_reduction(system)
    assert basis.condensation.slave.size > 0   # rotations carry no mass here
    force = system.index(6, 'uy')
    outputs = [system.index(6, 'uy'), system.index(6, 'uz'), system.index(4, 'rz')]
    omegas = np.array([0.5, 0.999, 1.0, 2.7]) * basis.omega[0]
    ref = full_harmonic_response(system, force, outputs, omegas)
    h = harmonic_response(basis, basis.rows(force), basis.rows(outputs), omegas)[..., 0]
    np.testing.assert_allclose(h, ref, rtol=1e-8, atol=0)
