"""The finite-element structure of a scene, and the collector of a scene's model problems.

:func:`_build_fe` turns the validated ``structure`` section into a
:class:`~impact_damper_sim.fem.FEModel` and its assembled system: an SDOF mass on a spring, or
beams (nodes, generated lines, elements) with point masses, springs, dampers, super elements,
clamps and cross-couplings. Each problem becomes one ``scene key 'path': message`` line of
the scene's error collector (:class:`~.schema._Errors`), which :mod:`.modes` and
:class:`~.build.SceneModel` report through too.
Kept apart from :mod:`.build` because it reads the ``structure`` section only and knows
nothing of modes, forcing, sensors or impactors.
"""
from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from .schema import _Errors
from .spec import DOF_NAMES, ROTATIONS, SDOF_NODE
from .units import UNITS

if TYPE_CHECKING:
    from ..fem import AssembledSystem, FEModel, Material
    from ..fem.sections import Section


def _has_node(fe: FEModel, node: int, path: str, errors: _Errors) -> bool:
    nodes = fe.nodes
    if node in nodes:
        return True
    ids = sorted(nodes)
    shown = f'{ids}' if len(ids) <= 8 else f'{ids[:4]} ... {ids[-2:]}'
    errors.add(path, f'node {node} is not defined (defined nodes: {shown or "none"})')
    return False


# --- structure ------------------------------------------------------------------------------

def _build_sdof(st: Mapping[str, Any], fe: FEModel) -> None:
    """One node with a point mass, a grounded spring (and dashpot) in one DOF."""
    mass = st['mass']
    if st['stiffness'] is not None:
        stiffness = st['stiffness']
    else:
        stiffness = mass * (2.0 * np.pi * st['natural_frequency']) ** 2
    dof = st['dof'] or 'uy'
    fe.add_node(SDOF_NODE, (0.0, 0.0, 0.0))
    fe.add_point_mass(SDOF_NODE, mass)
    fe.add_spring(SDOF_NODE, dof, stiffness)
    zeta = st['damping_ratio'] or 0.0
    if zeta > 0.0:
        # a physical dashpot, so that 'direct' (physical coordinates) sees it too
        fe.add_damper(SDOF_NODE, dof, 2.0 * zeta * np.sqrt(stiffness * mass))
    fe.clamp(SDOF_NODE, [c for c in DOF_NAMES if c != dof])


def _make_section(spec: Mapping[str, Any]) -> Section:
    from ..fem import GeneralSection, HollowCircular, SolidCircular
    shape = spec['shape']
    if shape == 'solid_circular':
        return SolidCircular(spec['diameter'])
    if shape == 'hollow_circular':
        return HollowCircular(spec['outer_diameter'], spec['inner_diameter'])
    return GeneralSection(A=spec['A'], Iy=spec['Iy'], Iz=spec['Iz'], J=spec['J'], Ip=spec['Ip'],
                          kappa_y=spec['kappa_y'], kappa_z=spec['kappa_z'])


def _section_of(name: str, sections: Mapping[str, Section | None], path: str,
                errors: _Errors) -> Section | None:
    if name in sections:
        return sections[name]
    errors.add(path, f"unknown section '{name}' (defined sections: "
                     f"{', '.join(sections) or 'none'})")
    return None


def _beam_options(item: Mapping[str, Any]) -> dict[str, Any]:
    return dict(shear=item['shear'], rotary_inertia=item['rotary_inertia'],
                orientation=item['orientation'])


def _xyz(point: Iterable[float]) -> str:
    return '[' + ', '.join(f'{float(v):.6g}' for v in point) + ']'


def _add_line(fe: FEModel, line: Mapping[str, Any], path: str, material: Material | None,
              sections: Mapping[str, Section | None], errors: _Errors) -> None:
    """Nodes and elements of one straight line (consecutive node ids)."""
    section = _section_of(line['section'], sections, f'{path}.section', errors)
    p0, p1 = np.asarray(line['from']), np.asarray(line['to'])
    n = line['n_elements']
    nodes = fe.nodes
    first = line['first_node']
    if first is None:
        first = max(nodes) + 1 if nodes else 0
    tol = 1e-9 * float(np.linalg.norm(p1 - p0))
    for k in range(n + 1):
        nid = first + k
        xyz = p1 if k == n else p0 + (p1 - p0) * (k / n)
        if nid in nodes:
            if k == 0 and np.linalg.norm(np.asarray(nodes[nid]) - p0) <= tol:
                continue   # joins an existing node
            where = 'first_node' if k == 0 else 'n_elements'
            errors.add(f'{path}.{where}', f'generated node {nid} already exists at '
                       f'{_xyz(nodes[nid])} m (generated point {_xyz(xyz)} m); choose '
                       'first_node so that only the node at from may already exist')
            return
        fe.add_node(nid, xyz)
    if section is None or material is None:
        return
    for k in range(n):
        errors.call(path, fe.add_beam, first + k, first + k + 1, material, section,
                    **_beam_options(line))


def _super_element_matrix(rows: npt.ArrayLike, dofs: Sequence[Mapping[str, Any]],
                          force_unit: str, length_unit: str) -> npt.NDArray[np.float64]:
    """Matrix in SI from entries in (force_unit, length_unit, rad)."""
    f = UNITS['force'][force_unit]
    length = UNITS['length'][length_unit]
    rot = np.array([d['dof'] in ROTATIONS for d in dofs])
    # row i is a force (or a moment: x length), column j per length (or per rad)
    scale = f * np.where(rot, length, 1.0)[:, None] / np.where(rot, 1.0, length)[None, :]
    return np.asarray(rows, dtype=float) * scale


def _build_beam(st: Mapping[str, Any], fe: FEModel, errors: _Errors) -> None:
    from ..fem import Material
    material: Material | None = None
    if st['material'] is not None:
        m = st['material']
        material = errors.call('structure.material', Material.from_poisson, m['E'], m['nu'],
                               m['rho'])
    sections: dict[str, Section | None] = {}
    for name, spec in (st['sections'] or {}).items():
        sections[name] = errors.call(f'structure.sections.{name}', _make_section, spec)
    for i, node in enumerate(st['nodes'] or []):
        errors.call(f'structure.nodes[{i}].id', fe.add_node, node['id'], node['xyz'])
    for i, line in enumerate(st['lines'] or []):
        _add_line(fe, line, f'structure.lines[{i}]', material, sections, errors)
    for i, el in enumerate(st['elements'] or []):
        path = f'structure.elements[{i}]'
        section = _section_of(el['section'], sections, f'{path}.section', errors)
        ok = all([_has_node(fe, n, f'{path}.nodes', errors) for n in el['nodes']])
        if ok and section is not None and material is not None:
            errors.call(path, fe.add_beam, *el['nodes'], material, section, **_beam_options(el))
    _build_lumped(st, fe, errors)


def _build_lumped(st: Mapping[str, Any], fe: FEModel, errors: _Errors) -> None:
    """Point masses, springs, dampers, super elements, clamps and cross-couplings."""
    def each(key: str) -> Iterator[tuple[str, Any]]:
        for i, item in enumerate(st[key] or []):
            path = f'structure.{key}[{i}]'
            if 'node' not in item or _has_node(fe, item['node'], f'{path}.node', errors):
                yield path, item

    for path, pm in each('point_masses'):
        errors.call(path, fe.add_point_mass, pm['node'], pm['mass'], pm['inertia'])
    for path, sp in each('springs'):
        value = sp['stiffness'] if sp['stiffness'] is not None else sp['rotational_stiffness']
        errors.call(path, fe.add_spring, sp['node'], sp['dof'], value)
    for path, dp in each('dampers'):
        value = dp['damping'] if dp['damping'] is not None else dp['rotational_damping']
        errors.call(path, fe.add_damper, dp['node'], dp['dof'], value)
    for path, se in each('super_elements'):
        if not all([_has_node(fe, d['node'], f'{path}.dofs[{k}].node', errors)
                    for k, d in enumerate(se['dofs'])]):
            continue
        units = (se['force_unit'], se['length_unit'])
        K = _super_element_matrix(se['stiffness'], se['dofs'], *units)
        C = None if se['damping'] is None else _super_element_matrix(se['damping'],
                                                                      se['dofs'], *units)
        errors.call(path, fe.add_super_element, [(d['node'], d['dof']) for d in se['dofs']],
                    K, C)
    for path, cl in each('clamps'):
        errors.call(path, fe.clamp, cl['node'], cl['dofs'])
    for path, cc in each('cross_couplings'):
        errors.call(path, fe.add_cross_coupling, cc['node'], cc['kcc'], tuple(cc['dofs']))


def _build_fe(structure: Mapping[str, Any], source: str | None
              ) -> tuple[FEModel, AssembledSystem]:

    from ..fem import FEModel
    fe = FEModel()
    errors = _Errors()
    if structure['kind'] == 'sdof':
        errors.call('structure', _build_sdof, structure, fe)
    else:
        _build_beam(structure, fe, errors)
    errors.raise_if_any(source)
    system = errors.call('structure', fe.assemble)
    errors.raise_if_any(source)
    return fe, system
