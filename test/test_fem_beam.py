"""Closed-form checks of the 3D Timoshenko beam element, its materials and sections.

Reference problem: a clamped-free solid circular steel beam, L = 1 m, d = 0.05 m (L/d = 20).
Frequencies come from ``eigh(K_c, M_c)`` after static condensation of the massless DOFs.
"""
import math

import numpy as np
import pytest
import scipy.linalg as sla
from scipy.optimize import brentq

from impact_damper_sim.fem import (
    STEEL,
    FEModel,
    GeneralSection,
    HollowCircular,
    Material,
    SolidCircular,
    beam_local_mass,
    beam_local_stiffness,
    beam_mass,
    beam_rotation,
    beam_stiffness,
    cowper_hollow_circle,
    dense_symmetric_part,
    shear_parameters,
)

LENGTH = 1.0  # m
DIAMETER = 0.05  # m
SECTION = SolidCircular(DIAMETER)
MESHES = (5, 10, 20, 40, 64)
# Clamped-free Euler-Bernoulli roots of 1 + cos(bL) cosh(bL) = 0.
BETA_L_EB = np.array([1.875104071, 4.694091133, 7.854757438, 10.99554073])
SKEW_AXIS = np.array([1.0, 2.0, 3.0]) / math.sqrt(14.0)
SKEW_ORIENTATION = (0.3, -0.5, 0.8)
SKEW_ORIGIN = np.array([0.1, -0.2, 0.3])  # m


# --------------------------------------------------------------------------------- helpers
def cantilever(n_el, *, shear=True, rotary_inertia=False, section=SECTION, length=LENGTH,
               axis=(1.0, 0.0, 0.0), origin=(0.0, 0.0, 0.0), orientation=None, tip_mass=None):
    """Clamped-free beam of ``n_el`` equal elements from ``origin`` along ``axis``."""
    axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    model = FEModel()
    for k in range(n_el + 1):
        model.add_node(k, np.asarray(origin) + axis * length * k / n_el)
    for k in range(n_el):
        model.add_beam(k, k + 1, STEEL, section, shear=shear, rotary_inertia=rotary_inertia,
                       orientation=orientation)
    if tip_mass is not None:
        model.add_point_mass(n_el, tip_mass)
    model.clamp(0)
    return model


def plane_frequencies(model, components):
    """Angular frequencies (rad/s) of the condensed system restricted to ``components``.

    A beam along global x decouples exactly into the axial (ux), torsional (rx) and the two
    bending planes (uy, rz) and (uz, ry), so each can be solved on its own.
    """
    system = model.assemble()
    cond = system.condense()
    sel = np.flatnonzero(np.isin(system.dofs[cond.master, 1], components))
    k = dense_symmetric_part(cond.K)[np.ix_(sel, sel)]
    return np.sqrt(sla.eigh(k, cond.M[np.ix_(sel, sel)], eigvals_only=True))


def all_modes(model):
    """Angular frequencies (rad/s) and master-DOF mode shapes of the condensed system."""
    system = model.assemble()
    cond = system.condense()
    w2, vec = sla.eigh(dense_symmetric_part(cond.K), cond.M)
    return np.sqrt(w2), vec, system.dofs[cond.master]


def eb_omega(beta_l, section=SECTION, length=LENGTH):
    """Euler-Bernoulli omega = (beta L)^2 sqrt(E I/(rho A L^4)) (rad/s)."""
    return np.asarray(beta_l) ** 2 * math.sqrt(
        STEEL.E * section.Iz / (STEEL.rho * section.A * length ** 4))


def timoshenko_clamped_free(n_modes, *, rotary_inertia, section=SECTION, length=LENGTH):
    """First ``n_modes`` clamped-free Timoshenko angular frequencies (rad/s).

    Exact solution of the Timoshenko equations in one bending plane, written for the
    deflection W, rotation Psi, moment M = E I Psi' and shear force Q = kappa G A (W' - Psi):
        W' = Psi + Q/(kappa G A),  Psi' = M/(E I),  M' = -Q - rho I w^2 Psi,  Q' = -rho A w^2 W
    (rho I -> 0 without rotary inertia). In x/L, W/L, M L/(E I), Q L^2/(E I) this is
    y' = A y with A = [[0, 1, 0, s], [0, 0, 1, 0], [0, -lam^4 r^2, 0, -1], [-lam^4, 0, 0, 0]],
    lam = beta L = (rho A w^2 L^4/(E I))^(1/4), s = E I/(kappa G A L^2), r^2 = I/(A L^2),
    so y(L) = expm(A) y(0) exactly. The 4x4 boundary-condition matrix has rows W(0) = 0,
    Psi(0) = 0 (clamp) and M(L) = 0, Q(L) = 0 (free); its determinant vanishes at the natural
    frequencies, bracketed on a grid in lam and refined with brentq.
    """
    kappa = section.shear_coefficients(STEEL.nu)[0]
    s = STEEL.E * section.Iz / (kappa * STEEL.G * section.A * length ** 2)
    r2 = section.Iz / (section.A * length ** 2) if rotary_inertia else 0.0

    def det(lam):
        a = np.array([[0.0, 1.0, 0.0, s],
                      [0.0, 0.0, 1.0, 0.0],
                      [0.0, -lam ** 4 * r2, 0.0, -1.0],
                      [-lam ** 4, 0.0, 0.0, 0.0]])
        # expm(A) through the eigenvalues +-alpha, +-i beta (distinct for lam > 0): fast, and
        # as exact as expm here.
        mu, v = np.linalg.eig(a)
        e = ((v * np.exp(mu)) @ np.linalg.inv(v)).real
        return np.linalg.det(np.vstack([np.eye(4)[:2], e[2:]]))

    grid = np.arange(0.5, BETA_L_EB[n_modes - 1] + 0.5, 0.1)  # roots are ~3 apart
    values = [det(b) for b in grid]
    roots = [brentq(det, a, b, xtol=1e-14, rtol=4 * np.finfo(float).eps)
             for a, b, fa, fb in zip(grid[:-1], grid[1:], values[:-1], values[1:]) if fa * fb < 0]
    assert len(roots) >= n_modes
    return eb_omega(roots[:n_modes], section, length)


def observed_order(errors):
    """Least-squares slope of log|error| against log h over the meshes (dimensionless)."""
    return np.polyfit(np.log(1.0 / np.asarray(MESHES, float)), np.log(np.abs(errors)), 1)[0]


# ------------------------------------------------------------------- bending convergence
MODELS = {
    # name: (shear, rotary_inertia, closed form)
    'euler-bernoulli': (False, False, lambda: eb_omega(BETA_L_EB)),
    'timoshenko-shear': (True, False, lambda: timoshenko_clamped_free(4, rotary_inertia=False)),
    'timoshenko-full': (True, True, lambda: timoshenko_clamped_free(4, rotary_inertia=True)),
}


@pytest.fixture(scope='module')
def bending_errors():
    """{model: relative errors, shape (len(MESHES), 4)} of the first four bending modes."""
    out = {}
    for name, (shear, rot, exact) in MODELS.items():
        ref = exact()
        out[name] = np.array([
            plane_frequencies(cantilever(n, shear=shear, rotary_inertia=rot), (1, 5))[:4] / ref
            - 1.0 for n in MESHES])
    return out


def test_timoshenko_solver_tends_to_euler_bernoulli():
    # Tolerance 1e-6: for L/d = 1e4 the shear and rotary-inertia corrections are of order
    # (beta_n r)^2 (1 + E/(kappa G)) ~ 2e-7 for mode 4 (r = d/4 the radius of gyration).
    section = SolidCircular(1e-4)
    w = timoshenko_clamped_free(4, rotary_inertia=True, section=section)
    np.testing.assert_allclose(w, eb_omega(BETA_L_EB, section), rtol=1e-6)
    assert np.all(w < eb_omega(BETA_L_EB, section))


def test_timoshenko_closed_form_lowers_higher_modes():
    # Sanity of the reference at L/d = 20: shear and rotary inertia each lower the frequencies,
    # mode 4 by a few percent (numerics.md).
    eb = eb_omega(BETA_L_EB)
    shear_only = timoshenko_clamped_free(4, rotary_inertia=False)
    full = timoshenko_clamped_free(4, rotary_inertia=True)
    assert np.all(full < shear_only) and np.all(shear_only < eb)
    assert 0.02 < 1.0 - full[3] / eb[3] < 0.06


@pytest.mark.parametrize('model', MODELS)
def test_bending_error_decreases_monotonically(bending_errors, model):
    # Lumped mass under-estimates every frequency; |error| must shrink at every refinement.
    err = bending_errors[model]
    assert np.all(err < 0.0)
    assert np.all(np.diff(np.abs(err), axis=0) < 0.0)


@pytest.mark.parametrize('model', MODELS)
def test_bending_convergence_order_is_two(bending_errors, model):
    # Lumped mass with the exact (condensed) beam stiffness: error O(h^2). Tolerance on the
    # fitted order, 5..40 elements: |p - 2| < 0.1 (measured 1.93 .. 1.99).
    orders = [observed_order(bending_errors[model][:, n]) for n in range(4)]
    np.testing.assert_allclose(orders, 2.0, atol=0.1)


# Measured at 40 elements, mode 3 / mode 4: EB -0.163% / -0.229%, shear -0.162% / -0.232%,
# shear + rotary inertia -0.161% / -0.227% (O(h^2): about 64 elements would be needed).
LUMPED_MISS = pytest.mark.xfail(
    strict=True, reason='lumped mass misses 0.1% at 40 elements (mode 3 ~0.16%, mode 4 ~0.23%); '
                        'reported, tolerance not loosened')


@pytest.mark.parametrize('mode', [1, 2, pytest.param(3, marks=LUMPED_MISS),
                                  pytest.param(4, marks=LUMPED_MISS)])
@pytest.mark.parametrize('model', MODELS)
def test_bending_within_0p1_percent_at_40_elements(bending_errors, model, mode):
    # Issue acceptance: |f_FE / f_exact - 1| < 0.1% at 40 elements, against beta_n L (EB) or
    # the Timoshenko clamped-free frequency equation (shear, with or without rotary inertia).
    assert abs(bending_errors[model][MESHES.index(40), mode - 1]) < 1e-3


# ------------------------------------------------------------------- axial and torsion
def test_axial_frequencies():
    # f_n = (2n-1)/(4L) sqrt(E/rho); within 0.1% at 40 elements for n = 1, 2. The lumped chain
    # obeys the discrete dispersion omega = (2c/h) sin(k h/2) exactly (checked to 1e-10), so
    # n = 3, 4 miss the continuum by (k h)^2/24 = 0.16%, 0.31%.
    n_el = 40
    w = plane_frequencies(cantilever(n_el), (0,))[:4]
    c = math.sqrt(STEEL.E / STEEL.rho)
    k = (2 * np.arange(1, 5) - 1) * np.pi / (2 * LENGTH)
    np.testing.assert_allclose(w[:2], k[:2] * c, rtol=1e-3)
    np.testing.assert_allclose(w, 2 * c * n_el / LENGTH * np.sin(k * LENGTH / n_el / 2),
                               rtol=1e-10)


@pytest.mark.parametrize('section', [SECTION, GeneralSection(A=2e-3, Iy=3e-7, Iz=5e-7,
                                                             J=2e-7, Ip=8e-7)],
                         ids=['circle', 'J-not-Ip'])
def test_torsional_frequencies(section):
    # f_n = (2n-1)/(4L) sqrt(G J/(rho Ip)) with rotary inertia rho Ip L/2 lumped; 0.1% at 40
    # elements for n = 1, 2 (n = 3, 4 follow the discrete dispersion, as for the axial case).
    n_el = 40
    w = plane_frequencies(cantilever(n_el, rotary_inertia=True, section=section), (3,))[:4]
    c = math.sqrt(STEEL.G * section.J / (STEEL.rho * section.Ip))
    k = (2 * np.arange(1, 5) - 1) * np.pi / (2 * LENGTH)
    np.testing.assert_allclose(w[:2], k[:2] * c, rtol=1e-3)
    np.testing.assert_allclose(w, 2 * c * n_el / LENGTH * np.sin(k * LENGTH / n_el / 2),
                               rtol=1e-10)


def test_no_torsion_modes_without_rotary_inertia():
    # rx carries no mass then and is condensed out: only bending and axial modes remain.
    system = cantilever(5).assemble()
    assert set(system.dofs[system.condense().master, 1]) == {0, 1, 2}


# -------------------------------------------------------------------------- tip mass
@pytest.mark.parametrize('ratio', [0.2, 1.0, 5.0])
def test_tip_mass_cantilever_first_frequency(ratio):
    # 1 + cos(bL)cosh(bL) + (M_t/(rho A L)) bL (cos(bL)sinh(bL) - sin(bL)cosh(bL)) = 0
    # (Euler-Bernoulli, tip point mass without rotary inertia); 0.1% at 40 elements.
    def char(b):
        return 1 + math.cos(b) * math.cosh(b) + ratio * b * (
            math.cos(b) * math.sinh(b) - math.sin(b) * math.cosh(b))

    beta_l = brentq(char, 0.1, BETA_L_EB[0], xtol=1e-14)
    tip = ratio * STEEL.rho * SECTION.A * LENGTH
    w = plane_frequencies(cantilever(40, shear=False, tip_mass=tip), (1,))[0]
    assert abs(w / eb_omega(beta_l) - 1.0) < 1e-3


# ------------------------------------------------------------------- static deflection
STUBBY = GeneralSection(A=3e-3, Iy=4e-7, Iz=9e-7, J=6e-7, kappa_y=0.85, kappa_z=0.6)


def _tip_deflection(section, xyz_j, orientation, local_axis):
    """Tip displacement along a local axis (m) of one clamped element under P = 1 kN."""
    model = FEModel()
    model.add_node(3, SKEW_ORIGIN)
    model.add_node(8, SKEW_ORIGIN + xyz_j)
    model.add_beam(3, 8, STEEL, section, orientation=orientation)
    model.clamp(3)
    system = model.assemble()
    direction = beam_rotation(SKEW_ORIGIN, SKEW_ORIGIN + xyz_j, orientation)[local_axis]
    force = np.zeros(system.n_dof)
    rows = [system.index(8, c) for c in ('ux', 'uy', 'uz')]
    force[rows] = 1e3 * direction
    u = np.linalg.solve(system.K.toarray(), force)  # 6x6
    return u[rows] @ direction


@pytest.mark.parametrize('section', [SECTION, STUBBY], ids=['circle', 'general'])
@pytest.mark.parametrize('skew', [False, True], ids=['along-x', 'skew'])
@pytest.mark.parametrize('local_axis', [1, 2], ids=['local-y', 'local-z'])
def test_one_element_tip_deflection_is_exact(section, skew, local_axis):
    # delta = P L^3/(3 E I) + P L/(kappa G A), exact for the Przemieniecki element: 1e-12.
    # Force along local y bends in the x-y plane (Iz, kappa_y); along local z, x-z (Iy, kappa_z).
    length = 0.25  # m, L/d = 5 so shear is ~10% of the deflection
    axis = SKEW_AXIS if skew else np.array([1.0, 0.0, 0.0])
    orientation = SKEW_ORIENTATION if skew else None
    delta = _tip_deflection(section, length * axis, orientation, local_axis)
    inertia = section.Iz if local_axis == 1 else section.Iy
    kappa = section.shear_coefficients(STEEL.nu)[local_axis - 1]
    p = 1e3
    exact = p * length ** 3 / (3 * STEEL.E * inertia) + p * length / (kappa * STEEL.G * section.A)
    assert abs(delta / exact - 1.0) < 1e-12


def test_shear_parameter_pairing():
    # Phi_y = 12 E Iz/(kappa_y G A L^2) (x-y plane), Phi_z = 12 E Iy/(kappa_z G A L^2).
    phi_y, phi_z = shear_parameters(STEEL, STUBBY, 0.5)
    gal2 = STEEL.G * STUBBY.A * 0.25
    assert phi_y == pytest.approx(12 * STEEL.E * STUBBY.Iz / (0.85 * gal2), rel=1e-15)
    assert phi_z == pytest.approx(12 * STEEL.E * STUBBY.Iy / (0.6 * gal2), rel=1e-15)
    assert shear_parameters(STEEL, STUBBY, 0.5, shear=False) == (0.0, 0.0)
    assert shear_parameters(STEEL, GeneralSection(1.0, 1.0, 1.0, 1.0), 0.5) == (0.0, 0.0)


# --------------------------------------------------------------- orientation invariance
def _skew_rotation(orientation):
    """Q with u_x-model = Q u_skew (global frames of the two models, same local frame)."""
    r_x = beam_rotation((0, 0, 0), (1, 0, 0))
    r_s = beam_rotation(SKEW_ORIGIN, SKEW_ORIGIN + SKEW_AXIS, orientation)
    return r_x.T @ r_s


@pytest.mark.parametrize('section', [SECTION, STUBBY], ids=['circle', 'general'])
@pytest.mark.parametrize('shear,rot', [(False, False), (True, True)], ids=['eb', 'timoshenko'])
def test_skew_beam_has_the_same_frequencies(section, shear, rot):
    # A rigid rotation of the structure leaves every frequency unchanged: 1e-9 relative.
    w_x = all_modes(cantilever(10, shear=shear, rotary_inertia=rot, section=section))[0]
    w_s = all_modes(cantilever(10, shear=shear, rotary_inertia=rot, section=section,
                               axis=SKEW_AXIS, origin=SKEW_ORIGIN,
                               orientation=SKEW_ORIENTATION))[0]
    np.testing.assert_allclose(w_s, w_x, rtol=1e-9)


@pytest.mark.parametrize('shear,rot', [(False, False), (True, True)], ids=['eb', 'timoshenko'])
def test_degenerate_bending_pairs_match_as_subspaces(shear, rot):
    # Circular section: bending modes come in equal-frequency pairs whose eigenvectors are
    # arbitrary within the pair. Compare each eigen-cluster of the x-beam with the skew beam's,
    # rotated back, by principal angles: < 1e-6 rad.
    w_x, v_x, dofs_x = all_modes(cantilever(10, shear=shear, rotary_inertia=rot))
    w_s, v_s, dofs_s = all_modes(cantilever(10, shear=shear, rotary_inertia=rot,
                                            axis=SKEW_AXIS, origin=SKEW_ORIGIN,
                                            orientation=SKEW_ORIENTATION))
    np.testing.assert_array_equal(dofs_x, dofs_s)
    assert np.all(dofs_x[:, 1].reshape(-1, 3 if not rot else 6) ==
                  np.arange(3 if not rot else 6))  # whole translation/rotation triplets
    q = np.kron(np.eye(dofs_x.shape[0] // 3), _skew_rotation(SKEW_ORIENTATION))
    v_s = q @ v_s
    # Clusters: consecutive frequencies equal to 1e-8 relative.
    starts = np.flatnonzero(np.r_[True, np.diff(w_x) > 1e-8 * w_x[1:]])
    bounds = np.r_[starts, w_x.size]
    sizes = np.diff(bounds)
    assert np.count_nonzero(sizes == 2) >= 8  # at least eight degenerate bending pairs
    for a, b in zip(bounds[:-1], bounds[1:]):
        angles = sla.subspace_angles(v_x[:, a:b], v_s[:, a:b])
        assert angles.max() < 1e-6, f'modes {a}..{b - 1}: {angles.max():.2e} rad'


# ---------------------------------------------------------------------- element basics
def test_default_orientation_rule():
    # Local y = global Z projected; global Y for an element parallel to Z.
    np.testing.assert_array_equal(beam_rotation((0, 0, 0), (2, 0, 0)),
                                  [[1, 0, 0], [0, 0, 1], [0, -1, 0]])
    np.testing.assert_array_equal(beam_rotation((0, 0, 1), (0, 0, 3)),
                                  [[0, 0, 1], [0, 1, 0], [-1, 0, 0]])
    r = beam_rotation((0, 0, 0), (1, 0, 1))
    np.testing.assert_allclose(r[1], np.array([-1, 0, 1]) / math.sqrt(2), atol=1e-15)


def test_orientation_vector_sets_local_y():
    r = beam_rotation(SKEW_ORIGIN, SKEW_ORIGIN + SKEW_AXIS, SKEW_ORIENTATION)
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-15)
    assert np.linalg.det(r) == pytest.approx(1.0, abs=1e-15)
    o = np.asarray(SKEW_ORIENTATION)
    # y lies in the plane of the axis and the orientation vector, on the side of o.
    assert abs(np.linalg.det(np.vstack([SKEW_AXIS, o, r[1]]))) < 1e-15
    assert r[1] @ o > 0.0


@pytest.mark.parametrize('shear,rot', [(False, False), (True, True)])
def test_skew_element_rigid_body_modes_and_mass(shear, rot):
    # Six rigid-body motions give zero force (to 1e-12 of the largest stiffness term), and the
    # translational mass is rho A L in every direction.
    xi, xj = SKEW_ORIGIN, SKEW_ORIGIN + 0.7 * SKEW_AXIS
    k = beam_stiffness(xi, xj, STEEL, STUBBY, shear=shear, orientation=SKEW_ORIENTATION)
    m = beam_mass(xi, xj, STEEL, STUBBY, rotary_inertia=rot, orientation=SKEW_ORIENTATION)
    rigid = []
    for e in np.eye(3):
        rigid.append(np.r_[e, 0, 0, 0, e, 0, 0, 0])  # translation
        rigid.append(np.r_[np.cross(e, xi), e, np.cross(e, xj), e])  # rotation about origin
    assert np.abs(k @ np.array(rigid).T).max() < 1e-12 * np.abs(k).max()
    np.testing.assert_allclose(k, k.T, rtol=0, atol=1e-12 * np.abs(k).max())
    translation = np.array(rigid[0::2])
    np.testing.assert_allclose(translation @ m @ translation.T,
                               STEEL.rho * STUBBY.A * 0.7 * np.eye(3), rtol=0, atol=1e-13)


def test_local_matrices_entries():
    # Przemieniecki, local frame, L = 0.5 m: axial EA/L, torsion GJ/L, bending 12EI/(L^3(1+Phi))
    # with the x-z coupling sign flipped; lumped rho A L/2 and rho (Ip, Iy, Iz) L/2.
    length = 0.5
    k = beam_local_stiffness(STEEL, STUBBY, length)
    phi_y, phi_z = shear_parameters(STEEL, STUBBY, length)
    e = STEEL.E
    assert k[0, 0] == pytest.approx(e * STUBBY.A / length, rel=1e-15)
    assert k[3, 9] == pytest.approx(-STEEL.G * STUBBY.J / length, rel=1e-15)
    assert k[1, 1] == pytest.approx(12 * e * STUBBY.Iz / (length ** 3 * (1 + phi_y)), rel=1e-15)
    assert k[2, 2] == pytest.approx(12 * e * STUBBY.Iy / (length ** 3 * (1 + phi_z)), rel=1e-15)
    assert k[1, 5] > 0 and k[2, 4] < 0
    assert k[5, 11] == pytest.approx(
        (2 - phi_y) * e * STUBBY.Iz / (length * (1 + phi_y)), rel=1e-14)
    m = beam_local_mass(STEEL, STUBBY, length, rotary_inertia=True)
    half = STEEL.rho * length / 2
    np.testing.assert_allclose(
        np.diag(m)[:6], half * np.array([STUBBY.A] * 3 + [STUBBY.Ip, STUBBY.Iy, STUBBY.Iz]),
        rtol=1e-15)
    assert np.count_nonzero(beam_local_mass(STEEL, STUBBY, length)[3:6, 3:6]) == 0


@pytest.mark.parametrize('kwargs,match', [
    (dict(orientation=(2.0, 4.0, 6.0)), 'orientation'),
    (dict(orientation=(0.0, 0.0, 0.0)), 'orientation'),
    (dict(shear='yes'), 'shear'),
    (dict(orientation=(1.0, math.nan, 0.0)), 'orientation'),
])
def test_element_bad_inputs(kwargs, match):
    with pytest.raises(ValueError, match=match):
        beam_stiffness((0, 0, 0), (1, 2, 3), STEEL, SECTION, **kwargs)


def test_element_bad_geometry():
    with pytest.raises(ValueError, match='length must be > 0'):
        beam_mass((1, 1, 1), (1, 1, 1), STEEL, SECTION)
    with pytest.raises(ValueError, match='rotary_inertia'):
        beam_mass((0, 0, 0), (1, 0, 0), STEEL, SECTION, rotary_inertia=1)
    with pytest.raises(ValueError, match='xyz_j'):
        beam_rotation((0, 0, 0), (1, 0))


# ------------------------------------------------------------- materials and sections
def test_material():
    assert STEEL.E == 200e9 and STEEL.rho == 7850.0
    assert STEEL.nu == pytest.approx(0.3, rel=1e-15)
    assert STEEL.G == pytest.approx(200e9 / 2.6, rel=1e-15)
    assert Material(E=210e9, G=80e9, rho=7800).nu == pytest.approx(210 / 160 - 1, rel=1e-15)


@pytest.mark.parametrize('kwargs,match', [
    (dict(E=-1.0, G=1.0, rho=1.0), r'E must be a finite number > 0 \(Pa\)'),
    (dict(E=1.0, G=math.inf, rho=1.0), r'G must be a finite number > 0 \(Pa\)'),
    (dict(E=1.0, G=1.0, rho=0.0), r'rho must be a finite number > 0 \(kg/m\^3\)'),
    (dict(E=3.0, G=0.9, rho=1.0), r'G must lie in \(E/3, inf\)'),
    (dict(E='steel', G=1.0, rho=1.0), 'E must be'),
])
def test_material_validation(kwargs, match):
    with pytest.raises(ValueError, match=match):
        Material(**kwargs)


@pytest.mark.parametrize('nu', [0.5, -1.0, 0.7, math.nan, None])
def test_material_poisson_range(nu):
    with pytest.raises(ValueError, match=r'nu must lie in the open interval \(-1.0, 0.5\)'):
        Material.from_poisson(200e9, nu, 7850)


def test_circular_sections():
    d = 0.05
    s = SolidCircular(d)
    assert s.A == pytest.approx(math.pi * d ** 2 / 4, rel=1e-15)
    assert s.Iy == s.Iz == pytest.approx(math.pi * d ** 4 / 64, rel=1e-15)
    assert s.J == s.Ip == pytest.approx(math.pi * d ** 4 / 32, rel=1e-15)
    nu = 0.3
    assert s.shear_coefficients(nu) == pytest.approx((6 * 1.3 / (7 + 1.8),) * 2, rel=1e-15)
    t = HollowCircular(0.1, 0.06)
    assert t.A == pytest.approx(math.pi * (0.01 - 0.0036) / 4, rel=1e-14)
    assert t.Ip == pytest.approx(math.pi * (0.1 ** 4 - 0.06 ** 4) / 32, rel=1e-14)
    m2 = 0.36
    kappa = 6 * 1.3 * (1 + m2) ** 2 / ((7 + 1.8) * (1 + m2) ** 2 + (20 + 3.6) * m2)
    assert t.shear_coefficients(nu) == pytest.approx((kappa, kappa), rel=1e-15)
    # Cowper's limits: m = 0 is the solid circle, m -> 1 the thin tube 2(1+nu)/(4+3nu).
    assert HollowCircular(0.05, 0.0).shear_coefficients(nu) == s.shear_coefficients(nu)
    assert cowper_hollow_circle(nu, 1 - 1e-9) == pytest.approx(2 * 1.3 / 4.9, rel=1e-8)


def test_general_section_defaults():
    g = GeneralSection(A=1e-3, Iy=2e-7, Iz=3e-7, J=4e-7)
    assert g.Ip == pytest.approx(5e-7, rel=1e-15)
    assert g.shear_coefficients(0.3) == (math.inf, math.inf)
    assert STUBBY.shear_coefficients(0.3) == (0.85, 0.6)


@pytest.mark.parametrize('factory,match', [
    (lambda: SolidCircular(0.0), r'diameter must be a finite number > 0 \(m\)'),
    (lambda: HollowCircular(-0.1, 0.0), 'outer_diameter must be'),
    (lambda: HollowCircular(0.1, 0.1), r'inner_diameter must lie in \[0, outer_diameter\)'),
    (lambda: HollowCircular(0.1, -0.01), 'inner_diameter'),
    (lambda: GeneralSection(A=1.0, Iy=1.0, Iz=-1.0, J=1.0), r'Iz must be .* \(m\^4\)'),
    (lambda: GeneralSection(A=1.0, Iy=1.0, Iz=1.0, J=1.0, Ip=0.0), 'Ip must be'),
    (lambda: GeneralSection(A=1.0, Iy=1.0, Iz=1.0, J=1.0, kappa_z=0.0), 'kappa_z must be'),
    (lambda: SECTION.shear_coefficients(0.5), 'nu must lie'),
])
def test_section_validation(factory, match):
    with pytest.raises(ValueError, match=match):
        factory()


@pytest.mark.parametrize('model', MODELS)
def test_bending_within_0p1_percent_at_64_elements(bending_errors, model):
    # The lumped mass is O(h^2): the 0.1% of the issue is reached at 64 elements for all four
    # bending modes (measured worst: mode 4, about 0.09%).
    assert np.all(np.abs(bending_errors[model][MESHES.index(64)]) < 1e-3)
