"""FEModel assembly: exact matrix entries, DOF bookkeeping and input validation.

Entries are compared exactly (or to 1e-15 relative where a value goes through a product), since
assembly only places and sums numbers.
"""
import math

import numpy as np
import pytest
import scipy.sparse as sp

from impact_damper_sim.fem import (
    STEEL,
    FEModel,
    GeneralSection,
    SolidCircular,
    beam_mass,
    beam_stiffness,
    is_symmetric,
)

SECTION = SolidCircular(0.05)


def two_beams():
    """Nodes 7 -- 3 -- 42 (non-contiguous ids) along x, clamped at 7."""
    model = FEModel()
    model.add_node(7, (0.0, 0.0, 0.0))
    model.add_node(3, (0.5, 0.0, 0.0))
    model.add_node(42, (1.0, 0.0, 0.0))
    model.add_beam(7, 3, STEEL, SECTION)
    model.add_beam(3, 42, STEEL, SECTION)
    model.clamp(7)
    return model


def test_dofs_are_ordered_by_node_id_then_component():
    system = two_beams().assemble()
    expected = [(n, c) for n in (3, 42) for c in range(6)]
    assert system.dofs.tolist() == [list(k) for k in expected]
    assert system.index(42, 'uz') == 8 and system.index(3, 5) == 5
    with pytest.raises(KeyError, match='ux at node 7 is clamped'):
        system.index(7, 'ux')


def test_matrices_are_sparse_csr():
    system = two_beams().assemble()
    for name in ('M', 'C', 'K'):
        assert sp.issparse(getattr(system, name)) and getattr(system, name).format == 'csr'
    assert system.C.nnz == 0


def test_beam_blocks_are_summed_at_the_shared_node():
    # K = sum of the element matrices over the shared node 3; clamped node 7 removed.
    system = two_beams().assemble()
    k1 = beam_stiffness((0, 0, 0), (0.5, 0, 0), STEEL, SECTION)
    k2 = beam_stiffness((0.5, 0, 0), (1, 0, 0), STEEL, SECTION)
    expected = np.zeros((12, 12))
    expected[:6, :6] = k1[6:, 6:] + k2[:6, :6]
    expected[:6, 6:] = k2[:6, 6:]
    expected[6:, :6] = k2[6:, :6]
    expected[6:, 6:] = k2[6:, 6:]
    np.testing.assert_array_equal(system.K.toarray(), expected)
    m = beam_mass((0, 0, 0), (0.5, 0, 0), STEEL, SECTION)
    np.testing.assert_array_equal(system.M.toarray()[:6, :6], 2 * m[:6, :6])


def test_point_mass_spring_damper_entries():
    model = two_beams()
    model.add_point_mass(42, 2.5, inertia=(0.1, 0.2, 0.3))
    model.add_point_mass(42, 0.5)  # accumulates
    inertia = np.array([[1.0, 0.2, 0.0], [0.2, 2.0, 0.1], [0.0, 0.1, 3.0]])
    model.add_point_mass(3, 1.0, inertia=inertia)
    model.add_spring(42, 'uy', 1e5)
    model.add_spring(42, 4, 2e3)
    model.add_damper(3, 'uz', 40.0)
    model.add_damper(3, 'uz', 2.0)
    bare = two_beams().assemble()
    system = model.assemble()
    dm = (system.M - bare.M).toarray()
    dk = (system.K - bare.K).toarray()
    expected_m = np.zeros((12, 12))
    expected_m[6:9, 6:9] = 3.0 * np.eye(3)
    expected_m[9:12, 9:12] = np.diag([0.1, 0.2, 0.3])
    expected_m[0:3, 0:3] = np.eye(3)
    expected_m[3:6, 3:6] = inertia
    np.testing.assert_allclose(dm, expected_m, rtol=0, atol=1e-15 * bare.M.max())
    expected_k = np.zeros((12, 12))
    expected_k[system.index(42, 'uy'), system.index(42, 'uy')] = 1e5
    expected_k[system.index(42, 'ry'), system.index(42, 'ry')] = 2e3
    np.testing.assert_allclose(dk, expected_k, rtol=0, atol=1e-15 * abs(bare.K).max())
    expected_c = np.zeros((12, 12))
    expected_c[2, 2] = 42.0
    np.testing.assert_array_equal(system.C.toarray(), expected_c)


def test_super_element_entries():
    # A dense boundary stiffness/damping on mixed DOFs of two nodes, named or numbered.
    model = two_beams()
    dofs = [(42, 'uy'), (3, 'uz'), (42, 5)]
    k = np.array([[4.0, -1.0, 0.5], [-1.0, 3.0, 0.0], [0.5, 0.0, 2.0]]) * 1e6
    c = np.array([[1.0, 0.2, 0.0], [0.2, 2.0, 0.0], [0.0, 0.0, 0.5]])
    model.add_super_element(dofs, k, damping=c)
    bare = two_beams().assemble()
    system = model.assemble()
    idx = [system.index(n, comp) for n, comp in dofs]
    expected_k = np.zeros((12, 12))
    expected_k[np.ix_(idx, idx)] = k
    np.testing.assert_allclose((system.K - bare.K).toarray(), expected_k, rtol=0,
                               atol=1e-15 * abs(bare.K).max())
    expected_c = np.zeros((12, 12))
    expected_c[np.ix_(idx, idx)] = c
    np.testing.assert_array_equal(system.C.toarray(), expected_c)


def test_clamp_removes_dofs_and_their_contributions():
    model = two_beams()
    model.clamp(42, ['uy', 'rz'])
    model.clamp(42, 'uy')  # idempotent
    model.add_spring(42, 'uy', 1e9)  # acts on a clamped DOF: dropped with it
    system = model.assemble()
    assert system.n_dof == 10
    assert (42, 1) not in map(tuple, system.dofs.tolist())
    full = two_beams().assemble()
    keep = [full.index(n, c) for n, c in system.dofs]
    np.testing.assert_array_equal(system.K.toarray(), full.K.toarray()[np.ix_(keep, keep)])
    assert model.clamped == [(7, c) for c in range(6)] + [(42, 1), (42, 5)]


def test_cross_coupling_makes_k_non_symmetric():
    # K[y, z] += +kcc and K[z, y] += -kcc (exactly), nothing else changes.
    kcc = 3.5e4
    model = two_beams()
    model.add_cross_coupling(42, kcc)
    bare = two_beams().assemble()
    system = model.assemble()
    y, z = system.index(42, 'uy'), system.index(42, 'uz')
    diff = (system.K - bare.K).toarray()
    expected = np.zeros((12, 12))
    expected[y, z], expected[z, y] = kcc, -kcc
    np.testing.assert_array_equal(diff, expected)
    assert system.K[y, z] - system.K[z, y] == 2 * kcc
    assert not is_symmetric(system.K)
    assert is_symmetric(bare.K)
    np.testing.assert_array_equal(system.skew_part().toarray(), 0.5 * (diff - diff.T))


def test_condensation_of_assembled_cantilever():
    # Without rotary inertia the rotations are massless and condensed; masses stay lumped.
    system = two_beams().assemble()
    cond = system.condense()
    assert system.dofs[cond.master, 1].tolist() == [0, 1, 2] * 2
    np.testing.assert_array_equal(np.diag(cond.M), STEEL.rho * SECTION.A * 0.5 * np.array(
        [1.0, 1.0, 1.0, 0.5, 0.5, 0.5]))


def test_isolated_node_is_rejected():
    model = two_beams()
    model.add_node(99, (5.0, 0.0, 0.0))
    with pytest.raises(ValueError, match=r'6 unclamped DOF\(s\) have no stiffness and no mass: '
                                         r'ux at node 99'):
        model.assemble()
    model.clamp(99)
    assert model.assemble().n_dof == 12


def test_point_mass_alone_leaves_rotations_unattached():
    model = two_beams()
    model.add_node(5, (0.0, 1.0, 0.0))
    model.add_point_mass(5, 1.0)
    model.add_damper(5, 'rx', 1.0)  # a damper is neither stiffness nor mass
    with pytest.raises(ValueError, match='3 unclamped DOF.*rx at node 5, ry at node 5'):
        model.assemble()


def test_empty_model_is_rejected():
    with pytest.raises(ValueError, match='no nodes'):
        FEModel().assemble()


def test_element_ids_and_nodes():
    model = FEModel()
    for k, x in ((10, 0.0), (0, 1.0), (5, 2.0)):
        model.add_node(k, (x, 0.0, 0.0))
    assert model.add_beam(10, 0, STEEL, SECTION) == 0
    assert model.add_beam(0, 5, STEEL, GeneralSection(1e-3, 1e-7, 2e-7, 1e-7),
                          shear=False, rotary_inertia=True, orientation=(0, 1, 1)) == 1
    assert model.nodes == {10: (0.0, 0.0, 0.0), 0: (1.0, 0.0, 0.0), 5: (2.0, 0.0, 0.0)}


# ---------------------------------------------------------------------------- bad input
def _model():
    model = FEModel()
    model.add_node(0, (0.0, 0.0, 0.0))
    model.add_node(1, (1.0, 0.0, 0.0))
    return model


BAD = [
    # (call, exception, message regex)
    (lambda m: m.add_node(-1, (0, 0, 0)), ValueError, r'node_id must be an integer >= 0'),
    (lambda m: m.add_node(2.0, (0, 0, 0)), ValueError, 'node_id must be an integer'),
    (lambda m: m.add_node(True, (0, 0, 0)), ValueError, 'node_id must be an integer'),
    (lambda m: m.add_node(1, (0, 0, 0)), ValueError, 'node_id 1 is already defined'),
    (lambda m: m.add_node(2, (0, 0)), ValueError, r'xyz must be 3 finite coordinates \(m\)'),
    (lambda m: m.add_node(2, (0, math.inf, 0)), ValueError, 'xyz must be 3 finite'),
    (lambda m: m.add_node(2, 'abc'), ValueError, 'xyz must be 3 finite'),
    (lambda m: m.add_beam(0, 9, STEEL, SECTION), KeyError, 'node_j: node 9 is not defined'),
    (lambda m: m.add_beam(0, 0, STEEL, SECTION), ValueError, 'node_i and node_j must differ'),
    (lambda m: m.add_beam(0, 1, 'steel', SECTION), ValueError, 'material must be a Material'),
    (lambda m: m.add_beam(0, 1, STEEL, 0.05), ValueError, r'section must provide'),
    (lambda m: m.add_beam(0, 1, STEEL, SECTION, shear=None), ValueError,
     'shear must be True or False'),
    (lambda m: m.add_beam(0, 1, STEEL, SECTION, rotary_inertia='no'), ValueError,
     'rotary_inertia must be True or False'),
    (lambda m: m.add_beam(0, 1, STEEL, SECTION, orientation=(3, 0, 0)), ValueError,
     'orientation must be a nonzero vector not parallel'),
    (lambda m: m.add_beam(0, 1, STEEL, SECTION, orientation=(0, 1)), ValueError,
     'orientation must be 3 finite'),
    (lambda m: m.add_beam(0, 1, STEEL, SECTION, bogus=1), TypeError, 'bogus'),
    (lambda m: m.add_point_mass(0, -1.0), ValueError, r'mass must be a finite number >= 0 \(kg\)'),
    (lambda m: m.add_point_mass(0, math.nan), ValueError, 'mass must be'),
    (lambda m: m.add_point_mass(0, 1.0, inertia=(1, 2)), ValueError,
     r'inertia must be 3 principal values or a 3x3 matrix \(kg m\^2\)'),
    (lambda m: m.add_point_mass(0, 1.0, inertia=(1, -2, 3)), ValueError,
     r'inertia values must be finite and >= 0'),
    (lambda m: m.add_point_mass(0, 1.0, inertia=np.diag([1.0, -1.0, 1.0])), ValueError,
     'inertia must be positive semi-definite'),
    (lambda m: m.add_point_mass(0, 1.0, inertia=np.triu(np.ones((3, 3)))), ValueError,
     'inertia must be symmetric'),
    (lambda m: m.add_point_mass(7, 1.0), KeyError, 'node: node 7 is not defined'),
    (lambda m: m.add_spring(0, 'uw', 1.0), ValueError, r"component: unknown DOF component 'uw'"),
    (lambda m: m.add_spring(0, 6, 1.0), ValueError, r'component: DOF component 6 out of range'),
    (lambda m: m.add_spring(0, 1.7, 1.0), ValueError, r'component: DOF component must be 0..5'),
    (lambda m: m.add_spring(0, 'ux', -5.0), ValueError,
     r'stiffness must be a finite number >= 0 \(N/m or N m/rad\)'),
    (lambda m: m.add_damper(0, 'ux', math.inf), ValueError,
     r'damping must be a finite number >= 0 \(N s/m'),
    (lambda m: m.add_damper(0, None, 1.0), ValueError, 'component: DOF component must be'),
    (lambda m: m.add_super_element([(0, 'uy'), (1, 'uy')], np.eye(3)), ValueError,
     r'stiffness must have shape \(2, 2\)'),
    (lambda m: m.add_super_element([(0, 'uy'), (1, 'uy')], [[1.0, 2.0], [0.0, 1.0]]),
     ValueError, 'stiffness must be symmetric'),
    (lambda m: m.add_super_element([(0, 'uy'), (1, 'uy')], [[1.0, math.nan], [math.nan, 1]]),
     ValueError, 'stiffness must contain finite values only'),
    (lambda m: m.add_super_element([(0, 'uy'), (1, 'uy')], np.eye(2), np.ones((2, 3))),
     ValueError, r'damping must have shape \(2, 2\)'),
    (lambda m: m.add_super_element([(0, 'uy'), (0, 1)], np.eye(2)), ValueError,
     'dofs must be distinct'),
    (lambda m: m.add_super_element([(0, 'uy'), (5, 'uy')], np.eye(2)), KeyError,
     r'dofs\[1\]: node 5 is not defined'),
    (lambda m: m.add_super_element([(0, 'uy'), (1, 'qq')], np.eye(2)), ValueError,
     r'dofs\[1\]: unknown DOF component'),
    (lambda m: m.add_super_element([0, 1], np.eye(2)), ValueError,
     r'dofs must be a sequence of \(node, component\) pairs'),
    (lambda m: m.add_super_element([], np.eye(0)), ValueError, 'dofs must name at least one'),
    (lambda m: m.add_super_element([(0, 'uy')], [['a']]), ValueError,
     'stiffness must be a real numeric'),
    (lambda m: m.clamp(0, ['ux', 'rw']), ValueError, 'components: unknown DOF component'),
    (lambda m: m.clamp(3), KeyError, 'node: node 3 is not defined'),
    (lambda m: m.add_cross_coupling(0, math.nan), ValueError,
     r'kcc must be a finite number \(N/m\)'),
    (lambda m: m.add_cross_coupling(0, 1.0, components=('uy', 'uy')), ValueError,
     'components must be two distinct DOFs'),
    (lambda m: m.add_cross_coupling(0, 1.0, components='uy'), ValueError,
     'components must be a pair'),
    (lambda m: m.add_cross_coupling(0, 1.0, components=('uy', 9)), ValueError,
     r'components\[1\]: DOF component 9 out of range'),
]


@pytest.mark.parametrize('call,exc,match', BAD, ids=[b[2][:40] for b in BAD])
def test_bad_inputs_raise_naming_the_argument(call, exc, match):
    with pytest.raises(exc, match=match):
        call(_model())
