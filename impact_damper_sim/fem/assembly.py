"""Finite-element model builder: nodes, beams, lumped items, boundary conditions, assembly.

All contributions are kept as (row, column, value) triplets over the *full* DOF numbering
(six per node, nodes in ascending id order) and turned into sparse CSR matrices over the active
DOFs in :meth:`FEModel.assemble`; no dense global matrix is ever formed.
"""
from __future__ import annotations

import math
import numbers
from collections.abc import Collection, Iterable, Sequence

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp

from .beam import beam_mass, beam_stiffness
from .materials import Material
from .sections import Section
from .system import DOF_NAMES, DOFS_PER_NODE, AssembledSystem, component_index

_SYMMETRY_RTOL = 1e-10  # relative asymmetry tolerated in user-given symmetric matrices
_SECTION_FIELDS = ('A', 'Iy', 'Iz', 'J', 'Ip', 'shear_coefficients')


def _real(name: str, value: float, unit: str, *, lower: float | None = None) -> float:
    """Return ``value`` as a finite float (>= ``lower`` if given), or raise ValueError."""
    ok = isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))
    x = float(value) if ok else math.nan
    ok = math.isfinite(x) and (lower is None or x >= lower)
    if not ok:
        allowed = 'a finite number' + ('' if lower is None else f' >= {lower:g}')
        raise ValueError(f'{name} must be {allowed} ({unit}); got {value!r}')
    return x


def _component(name: str, component: int | str) -> int:
    try:
        return component_index(component)
    except (ValueError, TypeError) as exc:
        raise ValueError(f'{name}: {exc}') from None


def _symmetric_matrix(name: str, matrix: npt.ArrayLike, n: int, unit: str) -> np.ndarray:
    a = np.asarray(matrix) if _is_numeric(matrix) else None
    if a is None:
        raise ValueError(f'{name} must be a real numeric ({n}, {n}) matrix ({unit})')
    if a.shape != (n, n):
        raise ValueError(f'{name} must have shape ({n}, {n}) to match dofs; got {a.shape}')
    a = a.astype(float)
    if not np.all(np.isfinite(a)):
        raise ValueError(f'{name} must contain finite values only ({unit})')
    scale = np.abs(a).max(initial=0.0)
    if np.abs(a - a.T).max(initial=0.0) > _SYMMETRY_RTOL * scale:
        raise ValueError(f'{name} must be symmetric (to a relative {_SYMMETRY_RTOL:g}); '
                         f'use add_cross_coupling for a non-symmetric stiffness')
    return 0.5 * (a + a.T)  # exactly symmetric


class FEModel:
    """Builder of a 3D beam finite-element model.

    Each node carries six global DOFs ``ux, uy, uz, rx, ry, rz`` (m, rad). Add nodes first,
    then elements and lumped items, clamp, and call :meth:`assemble`.

    Examples
    --------
    >>> from impact_damper_sim.fem import FEModel, STEEL, SolidCircular
    >>> model = FEModel()
    >>> model.add_node(0, (0.0, 0.0, 0.0))
    >>> model.add_node(1, (1.0, 0.0, 0.0))
    >>> model.add_beam(0, 1, STEEL, SolidCircular(0.05))
    0
    >>> model.clamp(0)
    >>> model.assemble().n_dof
    6
    """

    def __init__(self) -> None:
        self._nodes: dict[int, np.ndarray] = {}
        # lists of (full-DOF keys, dense block)
        self._blocks: dict[str, list[tuple[list[tuple[int, int]], np.ndarray]]] = {
            'K': [], 'M': [], 'C': []}
        self._clamped: set[tuple[int, int]] = set()
        self._n_beams = 0

    # ----------------------------------------------------------------------------- queries
    @property
    def nodes(self) -> dict[int, tuple[float, ...]]:
        """dict: ``{node_id: (x, y, z)}`` coordinates (m), a copy."""
        return {k: tuple(float(x) for x in v) for k, v in self._nodes.items()}

    @property
    def clamped(self) -> list[tuple[int, int]]:
        """list of tuple: Clamped ``(node, component)`` DOFs, sorted."""
        return sorted(self._clamped)

    # ------------------------------------------------------------------------------ nodes
    def add_node(self, node_id: int, xyz: npt.ArrayLike) -> None:
        """Add a node.

        Parameters
        ----------
        node_id : int
            Node id (dimensionless), any integer >= 0 not used yet; ids need not be contiguous.
        xyz : array_like, shape (3,)
            Global coordinates (m), finite.
        """
        if not isinstance(node_id, numbers.Integral) or isinstance(node_id, (bool, np.bool_)) \
                or node_id < 0:
            raise ValueError(f'node_id must be an integer >= 0; got {node_id!r}')
        node_id = int(node_id)
        if node_id in self._nodes:
            raise ValueError(f'node_id {node_id} is already defined')
        p = np.asarray(xyz, dtype=float) if _is_numeric(xyz) else None
        if p is None or p.shape != (3,) or not np.all(np.isfinite(p)):
            raise ValueError(f'xyz must be 3 finite coordinates (m); got {xyz!r}')
        self._nodes[node_id] = p

    def _node(self, name: str, node: int) -> int:
        if isinstance(node, numbers.Integral) and not isinstance(node, (bool, np.bool_)) \
                and int(node) in self._nodes:
            return int(node)
        raise KeyError(f'{name}: node {node!r} is not defined; add it with add_node first '
                       f'(defined ids: {_id_range(self._nodes)})')

    # --------------------------------------------------------------------------- elements
    def add_beam(self, node_i: int, node_j: int, material: Material, section: Section, *,
                 shear: bool = True, rotary_inertia: bool = False,
                 orientation: npt.ArrayLike | None = None) -> int:
        """Add a two-node Timoshenko beam with a lumped mass.

        Parameters
        ----------
        node_i, node_j : int
            End node ids (dimensionless), distinct and at distinct positions.
        material : Material
            E (Pa), G (Pa), rho (kg/m^3).
        section : section object
            ``SolidCircular``, ``HollowCircular`` or ``GeneralSection`` (m^2, m^4).
        shear : bool
            Shear deformation (Timoshenko); False gives Euler-Bernoulli.
        rotary_inertia : bool
            Lump the section's rotary inertia on the end rotations (kg m^2).
        orientation : array_like, shape (3,), optional
            Reference vector setting local y (direction only, any unit); default global Z
            (global Y for an element parallel to Z). See :func:`beam_rotation`.

        Returns
        -------
        int
            Element id (dimensionless), 0, 1, 2, ... in order of creation.
        """
        ni = self._node('node_i', node_i)
        nj = self._node('node_j', node_j)
        if ni == nj:
            raise ValueError(f'node_i and node_j must differ; both are {ni}')
        if not isinstance(material, Material):
            raise ValueError(f'material must be a Material; got {type(material).__name__}')
        missing = [f for f in _SECTION_FIELDS if not hasattr(section, f)]
        if missing:
            raise ValueError(f'section must provide {_SECTION_FIELDS}; missing {missing}')
        xi, xj = self._nodes[ni], self._nodes[nj]
        keys = [(n, c) for n in (ni, nj) for c in range(DOFS_PER_NODE)]
        k = beam_stiffness(xi, xj, material, section, shear=shear, orientation=orientation)
        m = beam_mass(xi, xj, material, section, rotary_inertia=rotary_inertia,
                      orientation=orientation)
        self._blocks['K'].append((keys, k))
        self._blocks['M'].append((keys, m))
        self._n_beams += 1
        return self._n_beams - 1

    def add_point_mass(self, node: int, mass: float,
                       inertia: npt.ArrayLike | None = None) -> None:
        """Add a rigid lumped mass at a node.

        Parameters
        ----------
        node : int
            Node id (dimensionless).
        mass : float
            Mass (kg), finite and >= 0, on ``ux, uy, uz``.
        inertia : array_like, optional
            Rotary inertia on ``rx, ry, rz`` in the global frame (kg m^2): three principal
            values ``(Ixx, Iyy, Izz)`` >= 0, or a symmetric positive semi-definite 3x3 matrix.
        """
        node = self._node('node', node)
        mass = _real('mass', mass, 'kg', lower=0.0)
        keys = [(node, c) for c in range(3)]
        self._blocks['M'].append((keys, mass * np.eye(3)))
        if inertia is None:
            return
        a = np.asarray(inertia, dtype=float) if _is_numeric(inertia) else None
        if a is not None and a.shape == (3,):
            if not (np.all(np.isfinite(a)) and np.all(a >= 0.0)):
                raise ValueError(f'inertia values must be finite and >= 0 (kg m^2); got {a}')
            a = np.diag(a)
        elif a is not None and a.shape == (3, 3):
            a = _symmetric_matrix('inertia', a, 3, 'kg m^2')
            if np.linalg.eigvalsh(a).min() < -1e-12 * np.abs(a).max(initial=0.0):
                raise ValueError('inertia must be positive semi-definite (kg m^2)')
        else:
            raise ValueError('inertia must be 3 principal values or a 3x3 matrix (kg m^2); '
                             f'got {inertia!r}')
        self._blocks['M'].append(([(node, c) for c in range(3, 6)], a))

    def add_spring(self, node: int, component: int | str, stiffness: float) -> None:
        """Add a grounded spring on one DOF.

        Parameters
        ----------
        node : int
            Node id (dimensionless).
        component : int or str
            ``0..5`` or ``'ux'`` ... ``'rz'``.
        stiffness : float
            Stiffness (N/m on translations, N m/rad on rotations), finite and >= 0.
        """
        key = (self._node('node', node), _component('component', component))
        value = _real('stiffness', stiffness, 'N/m or N m/rad', lower=0.0)
        self._blocks['K'].append(([key], np.array([[value]])))

    def add_damper(self, node: int, component: int | str, damping: float) -> None:
        """Add a grounded viscous damper on one DOF.

        Parameters
        ----------
        node : int
            Node id (dimensionless).
        component : int or str
            ``0..5`` or ``'ux'`` ... ``'rz'``.
        damping : float
            Damping (N s/m on translations, N m s/rad on rotations), finite and >= 0.
        """
        key = (self._node('node', node), _component('component', component))
        value = _real('damping', damping, 'N s/m or N m s/rad', lower=0.0)
        self._blocks['C'].append(([key], np.array([[value]])))

    def add_super_element(self, dofs: Sequence[tuple[int, int | str]],
                          stiffness: npt.ArrayLike,
                          damping: npt.ArrayLike | None = None) -> None:
        """Add a general symmetric stiffness (and damping) on a set of DOFs.

        Parameters
        ----------
        dofs : sequence of (int, int or str)
            Distinct ``(node, component)`` pairs; matrix row/column ``k`` acts on ``dofs[k]``.
        stiffness : array_like, shape (n, n)
            Symmetric, finite stiffness (N/m, N/rad, N m/rad).
        damping : array_like, shape (n, n), optional
            Symmetric, finite damping (N s/m, N s, N m s/rad).
        """
        pairs = list(dofs) if isinstance(dofs, (list, tuple, np.ndarray)) else None
        if pairs is None or not all(len(np.atleast_1d(p)) == 2 for p in pairs):
            raise ValueError(f'dofs must be a sequence of (node, component) pairs; got {dofs!r}')
        keys = [(self._node(f'dofs[{k}]', n), _component(f'dofs[{k}]', c))
                for k, (n, c) in enumerate(pairs)]
        if not keys:
            raise ValueError('dofs must name at least one (node, component) pair')
        if len(set(keys)) != len(keys):
            raise ValueError(f'dofs must be distinct; got {pairs!r}')
        n = len(keys)
        self._blocks['K'].append((keys, _symmetric_matrix('stiffness', stiffness, n, 'N/m')))
        if damping is not None:
            self._blocks['C'].append((keys, _symmetric_matrix('damping', damping, n, 'N s/m')))

    def add_cross_coupling(self, node: int, kcc: float,
                           components: tuple[int | str, int | str] = ('uy', 'uz')) -> None:
        """Add a cross-coupled (circulatory) stiffness at a node.

        ``K[a, b] += kcc`` and ``K[b, a] -= kcc`` with ``(a, b) = components``; this makes
        ``K`` non-symmetric (a follower force, e.g. seal or aerodynamic cross-coupling).

        Parameters
        ----------
        node : int
            Node id (dimensionless).
        kcc : float
            Cross-coupled stiffness (N/m), finite, any sign.
        components : pair of int or str
            The two distinct DOFs ``(a, b)``; default ``('uy', 'uz')``.
        """
        node = self._node('node', node)
        kcc = _real('kcc', kcc, 'N/m')
        try:
            if isinstance(components, str):  # 'uy' would unpack into 'u', 'y'
                raise TypeError
            a, b = components
        except (TypeError, ValueError):
            raise ValueError(f'components must be a pair of DOF components; '
                             f'got {components!r}') from None
        a, b = _component('components[0]', a), _component('components[1]', b)
        if a == b:
            raise ValueError(f'components must be two distinct DOFs; got {components!r}')
        self._blocks['K'].append(([(node, a), (node, b)], np.array([[0.0, kcc], [-kcc, 0.0]])))

    # --------------------------------------------------------------- boundary conditions
    def clamp(self, node: int,
              components: int | str | Sequence[int | str] | None = None) -> None:
        """Fix DOFs of a node to zero (they are removed from the assembled system).

        Parameters
        ----------
        node : int
            Node id (dimensionless).
        components : int, str or sequence of them, optional
            DOFs to fix (``0..5`` or ``'ux'`` ... ``'rz'``); None fixes all six.
        """
        node = self._node('node', node)
        comps: Iterable[int]
        if components is None:
            comps = range(DOFS_PER_NODE)
        elif isinstance(components, (str, int, numbers.Integral)):
            comps = [_component('components', components)]
        else:
            comps = [_component('components', c) for c in components]
        self._clamped.update((node, c) for c in comps)

    # ------------------------------------------------------------------------- assembly
    def assemble(self) -> AssembledSystem:
        """Assemble sparse ``M``, ``C``, ``K`` over the unclamped DOFs.

        Returns
        -------
        AssembledSystem
            CSR matrices (kg, N s/m, N/m) and the ``(node, component)`` of each active DOF,
            ordered by node id then component.

        Raises
        ------
        ValueError
            If the model has no node, or an unclamped DOF has neither stiffness nor mass (an
            isolated node, a point mass without inertia on an unconnected node, ...).

        Examples
        --------
        A 1 m steel cantilever of 50 mm diameter under 1 kN at its tip deflects
        ``P L^3 / (3 E I)`` (Euler-Bernoulli, exact for one element):

        >>> import numpy as np
        >>> from impact_damper_sim.fem import STEEL, FEModel, SolidCircular
        >>> model = FEModel()
        >>> model.add_node(0, (0.0, 0.0, 0.0))
        >>> model.add_node(1, (1.0, 0.0, 0.0))
        >>> model.add_beam(0, 1, STEEL, SolidCircular(0.05), shear=False)
        0
        >>> model.clamp(0)
        >>> system = model.assemble()
        >>> force = np.zeros(system.n_dof)
        >>> force[system.index(1, 'uy')] = 1e3
        >>> tip = float(np.linalg.solve(system.K.toarray(), force)[system.index(1, 'uy')])
        >>> f'{tip * 1e3:.3f} mm', round(tip * 3 * STEEL.E * SolidCircular(0.05).Iz / 1e3, 9)
        ('5.432 mm', 1.0)
        """
        if not self._nodes:
            raise ValueError('the model has no nodes: add nodes and elements before assemble()')
        ids = sorted(self._nodes)
        full_keys = np.array([(n, c) for n in ids for c in range(DOFS_PER_NODE)], dtype=np.int64)
        active = np.array([tuple(k) not in self._clamped for k in full_keys.tolist()])
        # full DOF number -> active index, -1 when clamped
        position = np.full(full_keys.shape[0], -1, dtype=np.int64)
        position[active] = np.arange(np.count_nonzero(active))
        node_pos = {n: p for p, n in enumerate(ids)}
        n_act = int(np.count_nonzero(active))
        mats = {name: self._sparse(blocks, position, node_pos, n_act)
                for name, blocks in self._blocks.items()}
        K, M, C = mats['K'], mats['M'], mats['C']
        touched = (abs(K).sum(axis=0).A1 + abs(K).sum(axis=1).A1
                   + abs(M).sum(axis=1).A1) if n_act else np.zeros(0)
        loose = np.flatnonzero(touched == 0.0)
        dofs = full_keys[active]
        if loose.size:
            names = ', '.join(f'{DOF_NAMES[c]} at node {n}' for n, c in dofs[loose[:8]])
            more = f' and {loose.size - 8} more' if loose.size > 8 else ''
            raise ValueError(f'{loose.size} unclamped DOF(s) have no stiffness and no mass: '
                             f'{names}{more}; connect them to an element or clamp them')
        return AssembledSystem(M=M, C=C, K=K, dofs=dofs)

    @staticmethod
    def _sparse(blocks: list[tuple[list[tuple[int, int]], np.ndarray]], position: np.ndarray,
                node_pos: dict[int, int], n: int) -> sp.csr_matrix:
        rows, cols, vals = [], [], []
        for keys, block in blocks:
            idx = position[[node_pos[k] * DOFS_PER_NODE + c for k, c in keys]]
            rows.append(np.repeat(idx, idx.size))
            cols.append(np.tile(idx, idx.size))
            vals.append(block.ravel())
        if not rows:
            return sp.csr_matrix((n, n))
        r, c, v = np.concatenate(rows), np.concatenate(cols), np.concatenate(vals)
        keep = (r >= 0) & (c >= 0) & (v != 0.0)  # drop clamped rows/columns and exact zeros
        coo = sp.coo_matrix((v[keep], (r[keep], c[keep])), shape=(n, n))
        return coo.tocsr()  # sums the duplicate (row, column) entries


def _is_numeric(value: object) -> bool:
    try:
        return np.asarray(value).dtype.kind in 'iuf'
    except (TypeError, ValueError):
        return False


def _id_range(nodes: Collection[int]) -> str:
    if not nodes:
        return 'none'
    ids = sorted(nodes)
    return f'{ids}' if len(ids) <= 6 else f'{ids[:3]} ... {ids[-3:]} ({len(ids)} nodes)'


__all__ = ['FEModel']
