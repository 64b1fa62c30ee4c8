"""Scene files to models: finite-element system, modal basis, linear model and forcing.

>>> from impact_damper_sim.scene.build import load
>>> scene = load('sdof', overrides=['impactors.0.cor=0.6'])   # doctest: +SKIP
>>> sim = scene.make_simulation()                              # doctest: +SKIP
>>> samples = sim.advance_to(1.0)                              # doctest: +SKIP

Every problem a scene can have is reported as a :class:`~.schema.SceneError` naming the key:
schema problems by :func:`~.schema.validate`, model problems (an undefined node, a clamped
sensor DOF, too many modes) here, with the same ``scene key 'path': message`` format.
Everything is SI.
"""
from __future__ import annotations

import dataclasses
import functools
import os
import re
from pathlib import Path

import numpy as np

import impact_damper_sim

from .units import UNITS
from .schema import SceneError, apply_overrides, file_kind, load_yaml, validate
from .spec import DOF_NAMES, ROTATIONS, SCHEMA, SDOF_NODE, STUCK_MODELS

__all__ = ['SceneModel', 'available_scenes', 'build', 'load', 'resolve_scene', 'scene_dirs']

_NAME_RE = re.compile(r'[A-Za-z0-9][A-Za-z0-9_.-]*')
_ROW_ZERO_RTOL = 1e-12   # a mode-shape row this small (relative) does not move the DOF


# --- finding scene files ------------------------------------------------------------------

def scene_dirs():
    """Return the directories searched for scene names, in search order.

    The source tree's ``config/scenes`` first (editable installs, checkouts), then the
    installed ``share/impact_damper_sim/config/scenes`` found through the ament index when
    ROS is available.

    Returns
    -------
    list of pathlib.Path
        Existing directories, without duplicates.
    """
    dirs = [Path(impact_damper_sim.__file__).resolve().parents[1] / 'config' / 'scenes']
    try:
        from ament_index_python.packages import get_package_share_directory
        dirs.append(Path(get_package_share_directory('impact_damper_sim')) / 'config' / 'scenes')
    except Exception:   # no ROS, AMENT_PREFIX_PATH unset, or package not installed
        pass
    out = []
    for d in dirs:
        if d.is_dir() and d.resolve() not in [o.resolve() for o in out]:
            out.append(d)
    return out


def available_scenes():
    """Return the names of the ready-made scenes (sorted list of str)."""
    return sorted({p.stem for d in scene_dirs() for p in d.glob('*.yaml')})


def _is_path(text):
    return (isinstance(text, os.PathLike) or '/' in text or os.sep in text
            or text.endswith(('.yaml', '.yml')))


def resolve_scene(scene_name_or_path):
    """Return the file of a scene given by name (``'sdof'``) or path.

    Parameters
    ----------
    scene_name_or_path : str or os.PathLike
        A bare name is looked up as ``<name>.yaml`` in :func:`scene_dirs`; anything with a
        directory separator or a ``.yaml``/``.yml`` suffix is a path.

    Returns
    -------
    pathlib.Path
        The scene file.

    Raises
    ------
    SceneError
        If the file does not exist or the name is unknown (the message lists the known ones).
    """
    if _is_path(scene_name_or_path):
        path = Path(scene_name_or_path)
        if not path.exists():
            raise SceneError(f'scene file {str(path)!r} does not exist')
        if not path.is_file():   # a directory, a FIFO, a device: never opened
            try:
                kind = file_kind(path)
            except OSError as exc:
                kind = exc.strerror
            raise SceneError(f'{str(path)!r} is not a scene file ({kind}, not a regular '
                             'file)')
        return path
    name = str(scene_name_or_path)
    if _NAME_RE.fullmatch(name):
        for d in scene_dirs():
            path = d / f'{name}.yaml'
            if path.is_file():
                return path
    known = ', '.join(available_scenes()) or 'none'
    searched = ', '.join(str(d) for d in scene_dirs()) or 'no scene directory found'
    raise SceneError(f'unknown scene {name!r}; ready-made scenes: {known} (searched {searched}); '
                     'or give a path to a .yaml file')


def validated(scene_name_or_path, overrides=()):
    """Read, override and validate a scene file without building it.

    Parameters
    ----------
    scene_name_or_path : str or os.PathLike
        Scene name or path to a YAML file.
    overrides : sequence of str, optional
        ``'dotted.key=value'`` overrides, checked like the file's keys.

    Returns
    -------
    scene : dict
        The validated scene (SI units).
    path : pathlib.Path
        The file it came from.

    Raises
    ------
    SceneError
        For any problem, each line naming the scene key.
    """
    path = resolve_scene(scene_name_or_path)
    raw = load_yaml(path)
    return validate(SCHEMA, apply_overrides(raw, list(overrides)), source=str(path)), path


def load(scene_name_or_path, overrides=()):
    """Load, override, validate and build a scene.

    Parameters
    ----------
    scene_name_or_path : str or os.PathLike
        Scene name (``'sdof'``, ``'cantilever'``) or path to a YAML file.
    overrides : sequence of str, optional
        ``'dotted.key=value'`` overrides (``'impactors.0.cor=0.6'``), applied before
        validation, so their units and ranges are checked like the file's.

    Returns
    -------
    SceneModel
        The built scene.

    Raises
    ------
    SceneError
        For any problem, each line naming the scene key.
    """
    scene, path = validated(scene_name_or_path, overrides)
    return build(scene, source=str(path), overrides=overrides)


# --- errors -------------------------------------------------------------------------------

class _Errors:
    """Collects model problems as ``scene key 'path': message`` lines."""

    def __init__(self):
        self.lines = []

    def add(self, path, message):
        self.lines.append(f"scene key '{path}': {message}")

    def call(self, path, fn, *args, **kwargs):
        """Call ``fn``; a ValueError/KeyError becomes a problem of ``path``."""
        try:
            return fn(*args, **kwargs)
        except (ValueError, KeyError, TypeError) as exc:
            self.add(path, exc.args[0] if exc.args else str(exc))
            return None

    def raise_if_any(self, source):
        if self.lines:
            raise SceneError(self.lines, source=source)


def _has_node(fe, node, path, errors):
    nodes = fe.nodes
    if node in nodes:
        return True
    ids = sorted(nodes)
    shown = f'{ids}' if len(ids) <= 8 else f'{ids[:4]} ... {ids[-2:]}'
    errors.add(path, f'node {node} is not defined (defined nodes: {shown or "none"})')
    return False


# --- structure ------------------------------------------------------------------------------

def _build_sdof(st, fe):
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


def _make_section(spec):
    from ..fem import GeneralSection, HollowCircular, SolidCircular
    shape = spec['shape']
    if shape == 'solid_circular':
        return SolidCircular(spec['diameter'])
    if shape == 'hollow_circular':
        return HollowCircular(spec['outer_diameter'], spec['inner_diameter'])
    return GeneralSection(A=spec['A'], Iy=spec['Iy'], Iz=spec['Iz'], J=spec['J'], Ip=spec['Ip'],
                          kappa_y=spec['kappa_y'], kappa_z=spec['kappa_z'])


def _section_of(name, sections, path, errors):
    if name in sections:
        return sections[name]
    errors.add(path, f"unknown section '{name}' (defined sections: "
                     f"{', '.join(sections) or 'none'})")
    return None


def _beam_options(item):
    return dict(shear=item['shear'], rotary_inertia=item['rotary_inertia'],
                orientation=item['orientation'])


def _xyz(point):
    return '[' + ', '.join(f'{float(v):.6g}' for v in point) + ']'


def _add_line(fe, line, path, material, sections, errors):
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


def _super_element_matrix(rows, dofs, force_unit, length_unit):
    """Matrix in SI from entries in (force_unit, length_unit, rad)."""
    f = UNITS['force'][force_unit]
    length = UNITS['length'][length_unit]
    rot = np.array([d['dof'] in ROTATIONS for d in dofs])
    # row i is a force (or a moment: x length), column j per length (or per rad)
    scale = f * np.where(rot, length, 1.0)[:, None] / np.where(rot, 1.0, length)[None, :]
    return np.asarray(rows, dtype=float) * scale


def _build_beam(st, fe, errors):
    from ..fem import Material
    material = None
    if st['material'] is not None:
        m = st['material']
        material = errors.call('structure.material', Material.from_poisson, m['E'], m['nu'],
                               m['rho'])
    sections = {}
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


def _build_lumped(st, fe, errors):
    """Point masses, springs, dampers, super elements, clamps and cross-couplings."""
    def each(key):
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


def _build_fe(structure, source):
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


#: Samples per rotor revolution at least when the unbalance force is sampled (first-order
#: hold of a rotation at N samples per revolution: amplitude sinc^2(pi/N), 3.3 % low at 10)
MIN_SAMPLES_PER_REVOLUTION = 10


def excitation_frequencies(scene, first_hz=None):
    """The frequencies of interest of a scene, for ``modal.cutoff: auto``.

    Parameters
    ----------
    scene : dict
        A validated scene (SI units).
    first_hz : float, optional
        First natural frequency of the structure (Hz), needed only for forcing given by
        ``frequency_ratio``.

    Returns
    -------
    list of (str, float)
        ``(source, frequency in Hz)``: each sensor low-pass cutoff, each forcing frequency and
        the highest rotor speed over 2 pi (rev/s); a ``commanded`` speed counts with its
        initial speed, a ``paper_ramp`` without ``final_speed`` with the paper's 2400 rad/s.
    """
    out = [(f"sensor {s['name']} low-pass", s['lowpass']) for s in scene['sensors']
           if s['lowpass'] is not None]
    for i, f in enumerate(scene['forcing']):
        hz = f['frequency'] if f['frequency'] is not None else f['frequency_ratio'] * first_hz
        out.append((f'forcing[{i}]', hz))
    rotor = scene['rotor']
    if rotor is not None:
        sp = rotor['speed']
        kind = sp['kind']
        if kind == 'constant':
            omega = sp['speed']
        elif kind == 'paper_ramp':
            omega = sp['final_speed'] if sp['final_speed'] is not None else 2400.0
        elif kind == 'piecewise':
            omega = max(sp['speeds'])
        else:
            omega = sp['speed']
        label = 'initial commanded rotor speed' if kind == 'commanded' else 'max rotor speed'
        if omega > 0:
            out.append((label, omega / (2.0 * np.pi)))
    return out


def auto_cutoff(system, scene, method='auto'):
    """The ``f_max`` of ``modal.cutoff: auto`` and why.

    ``f_max = cutoff_factor * max(f)`` over :func:`excitation_frequencies`: modes above the
    measured band and the excitation respond quasi-statically and are dropped; the factor
    keeps the modes just above the band, whose static tail the sensors still see.

    Parameters
    ----------
    system : AssembledSystem
        The structure (for the first natural frequency, if a forcing is given as a ratio).
    scene : dict
        A validated scene (SI units).
    method : str
        Eigen solver for the first mode (see :func:`~impact_damper_sim.modal.modal_reduction`).

    Returns
    -------
    f_max : float
        Cutoff (Hz).
    reason : str
        Human readable: the governing source, its frequency and the factor.

    Raises
    ------
    ValueError
        No sensor low-pass, forcing or rotor to derive a cutoff from.
    """
    from ..modal import modal_reduction
    first = None
    if any(f['frequency'] is None for f in scene['forcing']):
        first = float(modal_reduction(system, n_modes=1, method=method).frequencies_hz[0])
    sources = excitation_frequencies(scene, first)
    if not sources:
        raise ValueError('cutoff: auto needs a sensor low-pass, a forcing frequency or a rotor '
                         'speed to derive f_max from; give modal.f_max or modal.n_modes')
    label, top = max(sources, key=lambda item: item[1])
    factor = scene['modal']['cutoff_factor']
    return factor * top, (f'cutoff auto: f_max = {factor:g} x {top:.6g} Hz ({label}, the '
                          f'highest of {len(sources)} frequencies of interest) = '
                          f'{factor * top:.6g} Hz')


def _build_basis(system, modal, source, scene=None):
    from dataclasses import replace

    from ..modal import modal_reduction
    errors = _Errors()
    f_max, auto_reason = modal['f_max'], None
    if modal.get('cutoff') == 'auto':
        try:
            f_max, auto_reason = auto_cutoff(system, scene, modal['solver'])
        except ValueError as exc:
            errors.add('modal.cutoff', str(exc))
        errors.raise_if_any(source)
    kwargs = dict(n_modes=modal['n_modes'], f_max=f_max,
                  zeta=modal['damping']['default'], method=modal['solver'])
    try:
        basis = modal_reduction(system, **kwargs)
    except ValueError as exc:
        message = str(exc)
        # a selection problem names its key; anything else is the structure's (a mechanism)
        key = next((f'modal.{k}' for k in ('n_modes', 'f_max') if message.startswith(k)),
                   'structure')
        if key == 'modal.f_max' and auto_reason:
            key, message = 'modal.cutoff', f'{message} ({auto_reason})'
        errors.add(key, message)
    errors.raise_if_any(source)
    if auto_reason:
        basis = replace(basis, selection_reason=f'{basis.selection_reason}; {auto_reason}')
    per_mode = modal['damping']['modes']
    for mode in sorted(per_mode):
        if mode > basis.n_modes:
            errors.add(f'modal.damping.modes.{mode}', f'mode {mode} is not retained '
                       f'({basis.selection_reason})')
    errors.raise_if_any(source)
    if per_mode:
        # the scene numbers modes from 1, modal_reduction from 0
        overrides = {mode - 1: ratio for mode, ratio in per_mode.items()}
        basis = modal_reduction(system, zeta_overrides=overrides, **kwargs)
        if auto_reason:
            basis = replace(basis, selection_reason=f'{basis.selection_reason}; {auto_reason}')
    return basis


# --- the scene model ------------------------------------------------------------------------

class SceneModel:
    """A built scene: the validated scene, its structure, modal basis, model and forcing.

    Build it with :func:`load` (or :func:`build` from a validated dict).

    Attributes
    ----------
    scene : dict
        The validated scene, SI units (see :mod:`.spec`).
    source : str or None
        Scene file.
    overrides : tuple of str
        The ``key=value`` overrides applied.
    system : AssembledSystem
        Physical matrices over the active DOFs (kg, N s/m, N/m).
    basis : ModalBasis
        Retained modes.
    model : LinearModel
        Modal model: ``M = I``, ``C`` = modal damping (1/s), ``K`` = modal stiffness (1/s^2),
        ``B`` = force-DOF rows transposed, sensors = sensor-DOF rows, impactors bound to their
        housing rows (1/sqrt(kg)).
    forcing : Forcing
        One harmonic input per ``forcing`` entry (N).
    n_nodes : int
        Number of nodes of the finite-element model.
    sensor_dofs, force_dofs : tuple of int
        Active DOF index of each sensor and force.
    unbalance_dofs : tuple of (int, int)
        Active (uy, uz) DOF indices of each ``rotor.unbalance`` entry; their force inputs
        follow the ``forcing`` inputs (see :attr:`input_dofs`, :attr:`input_names`).
    speed_profile : SpeedProfile or None
        The rotor speed profile (rad/s); a :class:`~impact_damper_sim.scene.excitation.CommandedSpeed`
        takes run-time commands. None without ``rotor``.
    unbalance : UnbalanceForce or None
        The unbalance forces (N), None without unbalance.
    impactor_dofs : tuple of tuple of int
        Active DOF indices of each impactor housing (one for sdof, two for planar).
    """

    def __init__(self, scene, source, overrides, fe, system, basis):
        self.scene = scene
        self.source = source
        self.overrides = tuple(overrides)
        self.system = system
        self.basis = basis
        self.n_nodes = len(fe.nodes)
        errors = _Errors()
        self.sensor_dofs = tuple(
            self._dof(fe, s['node'], s['dof'], f'sensors[{i}]', errors)
            for i, s in enumerate(scene['sensors']))
        self.force_dofs = tuple(
            self._dof(fe, f['node'], f['dof'], f'forcing[{i}]', errors)
            for i, f in enumerate(scene['forcing']))
        rotor = scene['rotor']
        # each unbalance adds two force inputs (uy, uz) after the forcing entries
        self.unbalance_dofs = tuple(
            tuple(self._dof(fe, u['node'], d, f'rotor.unbalance[{i}]', errors)
                  for d in ('uy', 'uz'))
            for i, u in enumerate(rotor['unbalance'] if rotor else ()))
        self.impactor_dofs = tuple(
            tuple(self._dof(fe, imp['node'], d, f'impactors[{i}]', errors,
                            'dof' if imp['kind'] == 'sdof' else 'plane')
                  for d in ([imp['dof']] if imp['kind'] == 'sdof' else imp['plane']))
            for i, imp in enumerate(scene['impactors']))
        errors.raise_if_any(source)
        self.speed_profile, self.unbalance = self._make_rotor()
        self.forcing = self._make_forcing()
        impactors = self._make_impactors(errors)
        errors.raise_if_any(source)
        self.model = self._make_model(impactors)

    # -- construction helpers --------------------------------------------------------------
    def _dof(self, fe, node, dof, path, errors, dof_key='dof'):
        if not _has_node(fe, node, f'{path}.node', errors):
            return -1
        try:
            return self.system.index(node, dof)
        except KeyError:
            errors.add(f'{path}.{dof_key}', f'DOF {dof} at node {node} is clamped')
            return -1

    @property
    def input_dofs(self):
        """tuple of int: Active DOF of every force input: forcing entries, then (uy, uz) of
        each unbalance."""
        return self.force_dofs + tuple(d for pair in self.unbalance_dofs for d in pair)

    def _make_rotor(self):
        """The speed profile and the unbalance force (None, None without a rotor)."""
        from .excitation import (CommandedSpeed, ConstantSpeed, PaperRamp,
                                  PiecewiseLinearSpeed, UnbalanceForce)
        rotor = self.scene['rotor']
        if rotor is None:
            return None, None
        sp = rotor['speed']
        kind = sp['kind']
        if kind == 'constant':
            profile = ConstantSpeed(sp['speed'])
        elif kind == 'paper_ramp':
            ramp = {k: v for k, v in (('omega_f', sp['final_speed']),
                                      ('t_ramp', sp['ramp_time'])) if v is not None}
            profile = PaperRamp(**ramp)
        elif kind == 'piecewise':
            profile = PiecewiseLinearSpeed(sp['times'], sp['speeds'])
        else:
            profile = CommandedSpeed(sp['speed'], sp['max_rate'])
        if not self.unbalance_dofs:
            return profile, None
        first = len(self.force_dofs)
        pairs = [(first + 2 * i, first + 2 * i + 1) for i in range(len(self.unbalance_dofs))]
        unbalances = [(u['amount'], u['phase']) for u in rotor['unbalance']]
        force = UnbalanceForce(profile, unbalances, pairs, rotor['multiplier'],
                               n_inputs=len(self.input_dofs))
        return profile, force

    def _make_forcing(self):
        from .excitation import unbalance_forcing
        from ..integrate.forcing import Forcing, Harmonic
        omega1 = float(self.basis.omega[0])
        forcing = Forcing(len(self.input_dofs))
        for k, f in enumerate(self.scene['forcing']):
            if f['frequency'] is not None:
                omega = 2.0 * np.pi * f['frequency']
            else:
                omega = f['frequency_ratio'] * omega1
            forcing.add(Harmonic(k, f['amplitude'], omega, f['phase']))
        if self.unbalance is not None:
            # exact harmonics at constant speed; otherwise a sampled term that follows the
            # live profile (commands) and multiplier
            rotor_forcing = unbalance_forcing(forcing.n_inputs, self.unbalance)
            for term in rotor_forcing.harmonics + rotor_forcing.sampled:
                forcing.add(term)
        return forcing

    def _housing_mass(self, i, imp, errors):
        if imp['housing_mass'] is not None:
            return imp['housing_mass']
        lumped = float(self.system.M[self.impactor_dofs[i][0], self.impactor_dofs[i][0]])
        if lumped <= 0.0 and imp['mass_ratio'] is not None:
            errors.add(f'impactors[{i}].mass_ratio', 'the housing DOF carries no lumped mass, '
                       'so mass_ratio has no reference; give housing_mass or mass')
        return lumped

    def _make_impactors(self, errors):
        from ..dampers.impactors import Impactor
        out = []
        for i, imp in enumerate(self.scene['impactors']):
            rows = self.basis.rows(list(self.impactor_dofs[i]))
            if np.abs(rows).max() <= _ROW_ZERO_RTOL * np.abs(self.basis.shapes).max():
                errors.add(f'impactors[{i}].node', 'no retained mode moves the housing DOF(s); '
                           'retain more modes (modal.n_modes, modal.f_max)')
                continue
            housing = self._housing_mass(i, imp, errors)
            mass = imp['mass'] if imp['mass'] is not None else imp['mass_ratio'] * housing
            if not mass > 0.0:
                continue
            position = None if imp['position'] is None else np.asarray(imp['position'])
            out.append(errors.call(f'impactors[{i}]', Impactor, imp['name'], imp['kind'], mass,
                                   imp['cor'], imp['clearance'], rows, housing_mass=housing,
                                   position=position))
        return tuple(out)

    def _make_model(self, impactors):
        from ..integrate.model import LinearModel
        basis = self.basis
        n = basis.n_modes
        inputs = list(self.input_dofs)
        B = basis.rows(inputs).T if inputs else np.zeros((n, 0))
        S = basis.rows(list(self.sensor_dofs)) if self.sensor_dofs else np.zeros((0, n))
        return LinearModel(
            M=np.eye(n), C=basis.damping_matrix() + self._gyroscopic_coupling(),
            K=basis.stiffness_matrix(), B=B, sensors=S,
            sensor_names=tuple(s['name'] for s in self.scene['sensors']),
            impactors=impactors, kind='modal',
            input_names=self.input_names)

    def command_rotor(self, initial, max_rate):
        """Make the rotor speed *commanded* in place, without rebuilding the structure.

        The same as loading with the override ``rotor.speed={kind: commanded, speed:
        initial, max_rate: max_rate}`` (which is appended to :attr:`overrides`), but the
        finite elements and the modal basis are kept.

        Parameters
        ----------
        initial : float
            Speed at t = 0 (rad/s), >= 0.
        max_rate : float
            Rate limit of speed changes (rad/s^2), > 0.

        Raises
        ------
        SceneError
            No rotor, or a gyroscopic coupling (built for one constant speed).
        """
        rotor = self.scene['rotor']
        if rotor is None:
            raise SceneError("scene key 'rotor': the scene has no rotor to command", self.source)
        if rotor['gyroscopic'] is not None:
            raise SceneError("scene key 'rotor.gyroscopic': the coupling is built for one "
                             'constant speed, so the speed cannot be commanded', self.source)
        speed = dict(rotor['speed'])
        speed.update(kind='commanded', speed=float(initial), max_rate=float(max_rate),
                     final_speed=None, ramp_time=None, times=None, speeds=None)
        rotor['speed'] = speed
        self.overrides += (f'rotor.speed={{kind: commanded, speed: {float(initial)!r}, '
                           f'max_rate: {float(max_rate)!r}}}',)
        self.speed_profile, self.unbalance = self._make_rotor()
        self.forcing = self._make_forcing()

    def _gyroscopic_coupling(self):
        """Modal gyroscopic coupling ``Omega Phi^T G Phi`` (1/s); zero without ``rotor.gyroscopic``.

        A disk of polar inertia ``Ip`` spinning at ``Omega`` about global X adds
        ``Ip Omega theta_z'`` to the ``ry`` equation and ``-Ip Omega theta_y'`` to the ``rz``
        one (the small-tilt change of its angular momentum): a skew-symmetric matrix that does
        no work and splits each whirl pair into forward and backward modes.
        """
        n = self.basis.n_modes
        rotor = self.scene['rotor']
        gyro = rotor['gyroscopic'] if rotor else None
        if gyro is None:
            return np.zeros((n, n))
        from .excitation import ConstantSpeed
        if not isinstance(self.speed_profile, ConstantSpeed):
            raise SceneError("scene key 'rotor.gyroscopic': needs rotor.speed.kind constant "
                             '(the flow is linear time-invariant per configuration)',
                             self.source)
        polar = {}
        for pm in self.scene['structure']['point_masses'] or ():
            if pm['inertia'] is not None:
                polar[pm['node']] = polar.get(pm['node'], 0.0) + pm['inertia'][0]
        coupling = np.zeros((n, n))
        for i, node in enumerate(gyro['nodes']):
            ip = polar.get(node, 0.0)
            if ip <= 0.0:
                raise SceneError(f"scene key 'rotor.gyroscopic.nodes[{i}]': node {node} has no "
                                 'point-mass polar inertia (inertia about X) > 0', self.source)
            try:
                rows = self.basis.rows([self.system.index(node, 'ry'),
                                        self.system.index(node, 'rz')])
            except KeyError as exc:
                raise SceneError(f"scene key 'rotor.gyroscopic.nodes[{i}]': {exc.args[0]}",
                                 self.source) from None
            # G[ry, rz] = +Ip, G[rz, ry] = -Ip
            coupling += ip * (np.outer(rows[0], rows[1]) - np.outer(rows[1], rows[0]))
        return float(self.speed_profile.speed(0.0)) * coupling

    @property
    def input_names(self):
        """tuple of str: Name of every force input (``force<k>``, ``unbalance<i>_uy/_uz``)."""
        return (tuple(f'force{k}' for k in range(len(self.force_dofs)))
                + tuple(f'unbalance{i}_{d}' for i in range(len(self.unbalance_dofs))
                        for d in ('uy', 'uz')))

    # -- public -------------------------------------------------------------------------------
    @property
    def name(self):
        """str: The scene's name."""
        return self.scene['name']

    @property
    def impactors(self):
        """tuple of Impactor: The modal model's impactors (empty for a linear scene)."""
        return self.model.impactors

    @functools.cached_property
    def physical_model(self):
        """LinearModel: Physical-coordinate model for ``method='direct'``, built on first use.

        The condensed physical matrices with the structure's dashpots, plus the scene's tare
        damping turned into a physical matrix over *all* modes of the condensed system
        (``modal.damping.default`` on every mode, ``modal.damping.modes`` on those given),
        which equals the modal model's damping on the retained modes.
        """
        from ..integrate.direct import physical_model
        damping = self.scene['modal']['damping']
        zeta = np.full(self.basis.condensation.master.size, damping['default'])
        for mode, ratio in damping['modes'].items():
            zeta[mode - 1] = ratio
        return physical_model(
            self.system, force_indices=list(self.input_dofs),
            sensor_indices=list(self.sensor_dofs),
            impactors=[(imp, dofs) for imp, dofs in zip(self.model.impactors,
                                                          self.impactor_dofs)],
            tare_zeta=zeta if np.any(zeta) else None, sensor_names=self.model.sensor_names,
            input_names=self.model.input_names)

    def make_simulation(self, method=None, dt=None, **options):
        """Return a :class:`~impact_damper_sim.integrate.simulation.Simulation` of this scene.

        Parameters
        ----------
        method : str, optional
            ``'exact'``, ``'newmark'``, ``'newmark_step_end'`` or ``'direct'``; default the
            scene's ``simulation.method``.
        dt : float, optional
            Output sample period (s); default the scene's ``simulation.dt``.
        **options
            Integrator options; ``law``, ``stick_rule`` and ``stick_fraction`` default to
            the scene's ``simulation`` values. ``stuck_model`` (``'mass_update'`` or
            ``'basis_switch'``, default the scene's ``simulation.stuck_model``) chooses how
            the exact method treats stuck impactors.
            ``outputs`` (``(names, rows)``: sensor names and modal rows, shape
            ``(n_out, n_modes)``, 1/sqrt(kg)) replaces the scene's sensors, e.g. all six
            DOFs of a node from ``basis.rows``; not with ``method='direct'`` nor
            ``stuck_model='basis_switch'``, whose sensor rows come from the scene's sensor
            DOFs.

        Returns
        -------
        Simulation
            Starting at rest at t = 0 s (impactors at their ``position``).

        Raises
        ------
        SceneError
            ``stuck_model='basis_switch'`` with a method other than ``'exact'``.
        """
        from ..integrate.simulation import Simulation
        cfg = self.scene['simulation']
        method = cfg['method'] if method is None else method
        dt = cfg['dt'] if dt is None else dt
        self._check_rotor_sampling(dt)
        opts = {k: cfg[k] for k in ('law', 'stick_rule', 'stick_fraction')}
        stuck_model = options.pop('stuck_model', cfg['stuck_model'])
        outputs = options.pop('outputs', None)
        model = self.model
        if outputs is not None:
            if method == 'direct' or stuck_model == 'basis_switch':
                raise SceneError(f"custom outputs need the modal model with stuck_model "
                                 f"mass_update, not method {method!r} with {stuck_model!r}",
                                 self.source)
            names, rows = outputs
            model = dataclasses.replace(model, sensors=np.asarray(rows, dtype=float),
                                        sensor_names=tuple(names))
        opts.update(options)
        if stuck_model not in STUCK_MODELS:
            raise SceneError(f"scene key 'simulation.stuck_model': must be one of "
                             f"{', '.join(STUCK_MODELS)}, got {stuck_model!r}", self.source)
        if stuck_model == 'basis_switch':
            if method != 'exact':
                # Newmark and direct integrate one fixed set of coordinates
                raise SceneError(f"scene key 'simulation.stuck_model': basis_switch is "
                                 f"available with method exact only, not {method!r}; use "
                                 f"mass_update", self.source)
            from ..integrate.basis_switch import BasisSwitch
            opts['configurations'] = BasisSwitch.from_scene(self)
        physical = self.physical_model if method == 'direct' else None
        if method == 'direct' and 'stick_time' not in opts:
            # the paper's rule uses the highest *retained* mode; the physical model's highest
            # mode (massless-ish DOFs) would make it never fire
            opts['stick_time'] = (opts['stick_fraction'] * 2 * np.pi
                                  / float(np.max(self.basis.omega)))
        return Simulation(model, self.forcing, method=method, dt=dt,
                          physical_model=physical, **opts)

    def _check_rotor_sampling(self, dt):
        """Refuse a sample period ``dt`` (s) too long for a sampled unbalance force.

        Off constant speed the unbalance is sampled every ``dt`` and held linearly in
        between; the hold of a rotation sampled ``N`` times per revolution keeps only
        ``sinc^2(pi/N)`` of its amplitude, so ``N >= 10`` (3.3 % low) is required. A
        ``commanded`` speed counts with its initial speed (later commands are not known).

        Raises
        ------
        SceneError
            Fewer than 10 samples per revolution at the highest rotor speed.
        """
        if self.scene['rotor'] is None or not self.forcing.has_sampled:
            return
        hz = [f for label, f in excitation_frequencies(self.scene) if 'rotor speed' in label]
        if hz and dt * max(hz) * MIN_SAMPLES_PER_REVOLUTION > 1.0:
            raise SceneError(
                f"scene key 'simulation.dt': {dt:.4g} s samples the unbalance force fewer "
                f'than {MIN_SAMPLES_PER_REVOLUTION} times per revolution at the highest rotor '
                f'speed ({max(hz):.5g} rev/s); it must be at most '
                f'{1.0 / (MIN_SAMPLES_PER_REVOLUTION * max(hz)):.4g} s', self.source)

    def dof_counts(self):
        """Return DOF counts: total (6 per node), active, clamped, condensed, after condensation.

        Returns
        -------
        dict of str to int
            Counts (dimensionless).
        """
        cond = self.basis.condensation
        total = 6 * self.n_nodes
        return {'total': total, 'active': self.system.n_dof,
                'clamped': total - self.system.n_dof, 'condensed': int(cond.slave.size),
                'after_condensation': int(cond.master.size)}

    def describe_modes(self):
        """Return what ``study modes`` prints, as JSON-ready data.

        Returns
        -------
        dict
            ``scene``, ``source``, ``dofs`` (see :meth:`dof_counts`), ``selection_reason``,
            ``modes`` (number from 1, frequency in Hz, omega in rad/s, tare and effective
            damping ratios), ``coupled`` (modal matrices not diagonal), ``shapes``
            (mass-normalized mode-shape values, 1/sqrt(kg), at each sensor, impactor and force
            DOF) and ``impactors`` (masses and effective mass, kg).
        """
        basis = self.basis
        damping = basis.damping_matrix()
        modes = [{'mode': k + 1, 'frequency_hz': float(basis.frequencies_hz[k]),
                  'omega_rad_s': float(basis.omega[k]),
                  'tare_damping_ratio': float(basis.zeta[k]),
                  'damping_ratio': float(damping[k, k] / (2.0 * basis.omega[k]))}
                 for k in range(basis.n_modes)]
        shapes = []

        def add(role, name, node, dof, index):
            shapes.append({'role': role, 'name': name, 'node': node, 'dof': dof,
                           'values': [float(v) for v in basis.rows([index])[0]]})

        for s, idx in zip(self.scene['sensors'], self.sensor_dofs):
            add('sensor', s['name'], s['node'], s['dof'], idx)
            shapes[-1]['lowpass_hz'] = s['lowpass']   # anti-alias cutoff, reported only
        for imp, dofs in zip(self.scene['impactors'], self.impactor_dofs):
            names = [imp['dof']] if imp['kind'] == 'sdof' else imp['plane']
            for dof, idx in zip(names, dofs):
                add('impactor', imp['name'], imp['node'], dof, idx)
        for k, (f, idx) in enumerate(zip(self.scene['forcing'], self.force_dofs)):
            add('force', f'force{k}', f['node'], f['dof'], idx)
        rotor = self.scene['rotor']
        for i, pair in enumerate(self.unbalance_dofs):
            for dof, idx in zip(('uy', 'uz'), pair):
                add('unbalance', f'unbalance{i}_{dof}', rotor['unbalance'][i]['node'], dof, idx)
        impactors = []
        for imp, dofs in zip(self.model.impactors, self.impactor_dofs):
            mob = basis.impulse_mobility(list(dofs))
            impactors.append({
                'name': imp.name, 'kind': imp.kind, 'mass_kg': float(imp.mass),
                'housing_mass_kg': float(imp.housing_mass),
                'effective_mass_kg': [float(1.0 / mob[k, k]) if mob[k, k] > 0 else None
                                      for k in range(len(dofs))]})
        return {'scene': self.name, 'source': self.source, 'dofs': self.dof_counts(),
                'selection_reason': basis.selection_reason, 'modes': modes,
                'coupled': not basis.coupling_is_diagonal(), 'shapes': shapes,
                'impactors': impactors}

    def __repr__(self):
        return (f'SceneModel({self.name!r}, {self.basis.n_modes} modes, '
                f'{len(self.model.impactors)} impactors, source={self.source!r})')


def build(scene, *, source=None, overrides=()):
    """Build a :class:`SceneModel` from a validated scene.

    Parameters
    ----------
    scene : dict
        Output of ``validate(SCHEMA, raw)`` (SI units).
    source : str, optional
        Scene file, for messages.
    overrides : sequence of str, optional
        Overrides already applied (recorded only).

    Returns
    -------
    SceneModel
        The built scene.

    Raises
    ------
    SceneError
        For model problems, each naming the scene key; before anything is built, for a model
        whose estimated memory (:func:`impact_damper_sim.integrate.divergence.model_estimate`: DOFs,
        modes, impactors, stuck configurations) is over the limit, in one line with the
        estimate and the limit.
    """
    from ..integrate.divergence import ModelTooLarge, check_model
    try:
        check_model(scene)
    except ModelTooLarge as exc:
        raise SceneError(str(exc), source=source) from None
    fe, system = _build_fe(scene['structure'], source)
    basis = _build_basis(system, scene['modal'], source, scene)
    return SceneModel(scene, source, overrides, fe, system, basis)
