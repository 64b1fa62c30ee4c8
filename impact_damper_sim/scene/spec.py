"""THE scene schema: every key a scene file may hold, its unit, default, range and meaning.

This module is the single source of truth for scene files. :mod:`.build` turns a scene
validated against :data:`SCHEMA` into a model, ``study keys`` prints it and the README's key
table is generated from it (``test/test_readme.py`` keeps the two equal).

Layout
------
``name``, ``description``, ``offline_only``
    Identification, and whether the live node may run the scene.
``structure``
    ``kind: sdof`` (one mass on a spring, built as a one-node finite-element model so that it
    runs through exactly the same machinery as a beam model) or ``kind: beam`` (3D beam
    elements and lumped items). Keys marked *(sdof)* or *(beam)* belong to one kind only;
    giving one to the other kind is an error.
``modal``
    Mode selection and per-mode "tare" damping.
``sensors``, ``channel``, ``forcing``, ``impactors``
    What is read and through which accelerometer channel (:mod:`.channel_spec`), what drives
    the structure and the impact dampers.
``rotor``
    Optional: the rotor speed profile and its unbalance, whose forces enter as extra force
    inputs (uy, uz) at each unbalance node.
``simulation``
    Defaults of ``study simulate`` (method, step, duration, ...).

New structure kinds and sections (rotor unbalance, speed profiles, bearings, gyroscopics)
are added here as new keys with ``None`` defaults and a kind check, so existing scenes stay
valid.

This module imports only the schema engine and NumPy-level constants, so ``study keys``
stays fast.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from ..dampers.law import IMPACT_LAWS
from ..integrate.events import STICK_RULES
from ..integrate.simulation import METHODS
from .channel_spec import CHANNEL, SENSOR_CHANNEL
from .containers import ListOf, MapOf, Optional, Section, Vector
from .schema import Boolean, Choice, Integer, Quantity, String
from .units import UNITS

__all__ = ['SCHEMA', 'DOF_NAMES', 'TRANSLATIONS', 'ROTATIONS', 'SDOF_KEYS', 'BEAM_KEYS',
           'SECTION_SHAPES', 'SDOF_NODE', 'SPEED_KINDS', 'STUCK_MODELS']

#: Node DOF names in node order (same as :data:`impact_damper_sim.fem.DOF_NAMES`; kept here
#: so that the schema does not import SciPy).
DOF_NAMES = ('ux', 'uy', 'uz', 'rx', 'ry', 'rz')
TRANSLATIONS = DOF_NAMES[:3]
ROTATIONS = DOF_NAMES[3:]

#: Node id of the single node of an SDOF structure.
SDOF_NODE = 0

#: Values of ``simulation.stuck_model`` (see :mod:`impact_damper_sim.integrate.basis_switch`).
STUCK_MODELS = ('mass_update', 'basis_switch')

_IDENT = r'[A-Za-z][A-Za-z0-9_]*'   # ROS-friendly names (topics, frames)


def _node(doc: str) -> Integer:
    return Integer(min=0, doc=doc)


# --- structure ------------------------------------------------------------------------------

#: Keys of each section shape; the first list is required, the second optional.
SECTION_SHAPES = {
    'solid_circular': (('diameter',), ()),
    'hollow_circular': (('outer_diameter', 'inner_diameter'), ()),
    'general': (('A', 'Iy', 'Iz', 'J'), ('Ip', 'kappa_y', 'kappa_z')),
}


def _check_section(values: dict[str, Any]) -> list[str]:
    required, optional = SECTION_SHAPES[values['shape']]
    problems = [f"shape {values['shape']} needs key '{k}'" for k in required
                if values[k] is None]
    allowed = set(required) | set(optional) | {'shape'}
    problems += [f"key '{k}' does not apply to shape {values['shape']} "
                 f"(it takes {', '.join(required + optional)})"
                 for k, v in values.items() if v is not None and k not in allowed]
    if (values['shape'] == 'hollow_circular' and not problems
            and not values['inner_diameter'] < values['outer_diameter']):
        problems.append('inner_diameter must be smaller than outer_diameter')
    return problems


_SECTION = Section({
    'shape': Choice(tuple(SECTION_SHAPES), doc='cross-section kind'),
    'diameter': Optional(Quantity('length', min=0, min_inclusive=False),
                         doc='(solid_circular) diameter'),
    'outer_diameter': Optional(Quantity('length', min=0, min_inclusive=False),
                               doc='(hollow_circular) outer diameter'),
    'inner_diameter': Optional(Quantity('length', min=0),
                               doc='(hollow_circular) inner diameter, < outer_diameter'),
    'A': Optional(Quantity('area', min=0, min_inclusive=False), doc='(general) area'),
    'Iy': Optional(Quantity('second_moment', min=0, min_inclusive=False),
                   doc='(general) second moment of area about local y (bending in local x-z)'),
    'Iz': Optional(Quantity('second_moment', min=0, min_inclusive=False),
                   doc='(general) second moment of area about local z (bending in local x-y)'),
    'J': Optional(Quantity('second_moment', min=0, min_inclusive=False),
                  doc='(general) torsion constant'),
    'Ip': Optional(Quantity('second_moment', min=0, min_inclusive=False),
                   doc='(general) polar moment for torsional rotary inertia; none = Iy + Iz'),
    'kappa_y': Optional(Quantity('dimensionless', min=0, min_inclusive=False),
                        doc='(general) shear coefficient along local y; none = no shear '
                            'deformation'),
    'kappa_z': Optional(Quantity('dimensionless', min=0, min_inclusive=False),
                        doc='(general) shear coefficient along local z; none = no shear '
                            'deformation'),
}, checks=[_check_section])

_BEAM_OPTIONS = {
    'shear': Boolean(default=True,
                     doc='(beam) Timoshenko shear deformation (false: Euler-Bernoulli)'),
    'rotary_inertia': Boolean(default=False,
                              doc='(beam) lump the section rotary inertia on the end rotations '
                                  '(false: rotations are massless and condensed)'),
    'orientation': Optional(Vector('dimensionless', 3),
                            doc='(beam) reference vector setting local y (direction only); '
                                'none = global Z (global Y for an element along Z), so a beam '
                                'along X bends in global uy with Iy. Iz resists bending '
                                'towards local y'),
}


def _check_clamp_dofs(values: dict[str, Any]) -> str | None:
    dofs = values.get('dofs')
    if dofs is not None and len(set(dofs)) != len(dofs):
        return 'dofs must be distinct'
    return None


def _check_spring(kind_key: str, rot_key: str) -> Callable[[dict[str, Any]], list[str]]:
    def check(values: dict[str, Any]) -> list[str]:
        rotational = values['dof'] in ROTATIONS
        want, other = (rot_key, kind_key) if rotational else (kind_key, rot_key)
        problems = []
        if values[want] is None:
            problems.append(f"dof {values['dof']} needs '{want}'")
        if values[other] is not None:
            problems.append(f"'{other}' does not apply to dof {values['dof']} (use '{want}')")
        return problems
    return check


def _check_square(values: dict[str, Any]) -> list[str]:
    n = len(values['dofs'])
    problems = []
    for key in ('stiffness', 'damping'):
        matrix = values[key]
        if matrix is not None and (len(matrix) != n or any(len(r) != n for r in matrix)):
            problems.append(f'{key} must be a {n}x{n} matrix (one row and column per dofs '
                            f'entry)')
    pairs = [(d['node'], d['dof']) for d in values['dofs']]
    if len(set(pairs)) != len(pairs):
        problems.append('dofs must be distinct (node, dof) pairs')
    return problems


_ROW = ListOf(Quantity('dimensionless', doc='(beam) one matrix entry'), min_len=1,
              doc='(beam) one matrix row')


def _check_line(values: dict[str, Any]) -> str | None:
    if max(abs(a - b) for a, b in zip(values['from'], values['to'])) == 0.0:
        return "'from' and 'to' coincide"
    return None


#: Keys of ``structure`` that belong to one kind only.
SDOF_KEYS = ('mass', 'natural_frequency', 'stiffness', 'damping_ratio', 'dof')
BEAM_KEYS = ('material', 'sections', 'nodes', 'lines', 'elements', 'point_masses', 'springs',
             'dampers', 'super_elements', 'clamps', 'cross_couplings')


def _check_structure(values: dict[str, Any]) -> list[str]:
    kind = values['kind']
    own, foreign = (SDOF_KEYS, BEAM_KEYS) if kind == 'sdof' else (BEAM_KEYS, SDOF_KEYS)
    problems = [f"key '{k}' does not apply to kind {kind} (keys of kind {kind}: "
                f"kind, {', '.join(own)})" for k in foreign if values[k] is not None]
    if kind == 'sdof':
        if values['mass'] is None:
            problems.append("kind sdof needs 'mass'")
        given = [k for k in ('natural_frequency', 'stiffness') if values[k] is not None]
        if len(given) != 1:
            problems.append("kind sdof needs exactly one of 'natural_frequency' and "
                            f"'stiffness' (got {', '.join(given) or 'neither'})")
    else:
        if values['material'] is None and (values['elements'] or values['lines']):
            problems.append("beam elements need 'material'")
        if not (values['nodes'] or values['lines']):
            problems.append("kind beam needs 'nodes' or 'lines'")
    return problems


_STRUCTURE = Section(doc='the linear structure', fields={
    'kind': Choice(('sdof', 'beam'),
                   doc='sdof: one mass on a grounded spring (node 0); beam: 3D beam '
                       'finite-element model'),
    # -- sdof
    'mass': Optional(Quantity('mass', min=0, min_inclusive=False),
                     doc='(sdof) primary mass, a point mass at node 0'),
    'natural_frequency': Optional(Quantity('frequency', min=0, min_inclusive=False),
                                  doc='(sdof) undamped natural frequency; sets the spring '
                                      'stiffness = mass (2 pi f)^2. Give this or stiffness'),
    'stiffness': Optional(Quantity('stiffness', min=0, min_inclusive=False),
                          doc='(sdof) spring stiffness; give this or natural_frequency'),
    'damping_ratio': Optional(Quantity('dimensionless', min=0, max=1, max_inclusive=False),
                              doc='(sdof) viscous damping ratio of the primary system, a '
                                  'grounded dashpot 2 zeta sqrt(K M); none = undamped'),
    'dof': Optional(Choice(TRANSLATIONS),
                    doc='(sdof) direction of the spring; all other DOFs of node 0 are '
                        'clamped; none = uy'),
    # -- beam
    'material': Optional(Section({
        'E': Quantity('modulus', min=0, min_inclusive=False, doc="(beam) Young's modulus"),
        'nu': Quantity('dimensionless', min=-1, max=0.5, min_inclusive=False,
                       max_inclusive=False, doc="(beam) Poisson's ratio, G = E/(2(1+nu))"),
        'rho': Quantity('density', min=0, min_inclusive=False,
                        doc='(beam) density (lumped at the element ends); use a tiny value '
                            'for members of negligible inertia'),
    }), doc='(beam) isotropic material of every element'),
    'sections': Optional(MapOf(String(pattern=_IDENT), _SECTION, min_len=1),
                         doc='(beam) named cross-sections'),
    'nodes': Optional(ListOf(Section({
        'id': _node('(beam) node id, unique'),
        'xyz': Vector('length', 3, doc='(beam) global coordinates'),
    })), doc='(beam) explicit nodes'),
    'lines': Optional(ListOf(Section({
        'from': Vector('length', 3, doc='(beam) start point'),
        'to': Vector('length', 3, doc='(beam) end point'),
        'n_elements': Integer(min=1, max=100000, doc='(beam) number of equal elements'),
        'section': String(pattern=_IDENT, doc='(beam) name of a section in sections'),
        'first_node': Optional(Integer(min=0),
                               doc='(beam) id of the node at from; the others follow '
                                   'consecutively. An existing node with that id must sit at '
                                   'from (joins lines). none = one past the largest id so far '
                                   '(0 for the first)'),
        **_BEAM_OPTIONS,
    }, checks=[_check_line])), doc='(beam) straight beams generated as n_elements equal '
                                   'elements and n_elements + 1 nodes'),
    'elements': Optional(ListOf(Section({
        'nodes': ListOf(Integer(min=0, doc='(beam) node id'), min_len=2, max_len=2,
                        doc='(beam) end node ids [i, j]; local x runs from i to j'),
        'section': String(pattern=_IDENT, doc='(beam) name of a section in sections'),
        **_BEAM_OPTIONS,
    })), doc='(beam) explicit two-node beam elements'),
    'point_masses': Optional(ListOf(Section({
        'node': _node('(beam) node id'),
        'mass': Quantity('mass', min=0, doc='(beam) mass on ux, uy, uz'),
        'inertia': Optional(Vector('mass_moment', 3, min=0),
                            doc='(beam) principal rotary inertia on rx, ry, rz (global)'),
    })), doc='(beam) rigid lumped masses'),
    'springs': Optional(ListOf(Section({
        'node': _node('(beam) node id'),
        'dof': Choice(DOF_NAMES, doc='(beam) DOF the spring acts on'),
        'stiffness': Optional(Quantity('stiffness', min=0),
                              doc='(beam) stiffness, for a translation'),
        'rotational_stiffness': Optional(Quantity('rotational_stiffness', min=0),
                                         doc='(beam) stiffness, for a rotation'),
    }, checks=[_check_spring('stiffness', 'rotational_stiffness')])),
        doc='(beam) grounded springs'),
    'dampers': Optional(ListOf(Section({
        'node': _node('(beam) node id'),
        'dof': Choice(DOF_NAMES, doc='(beam) DOF the dashpot acts on'),
        'damping': Optional(Quantity('damping', min=0), doc='(beam) damping, for a translation'),
        'rotational_damping': Optional(Quantity('rotational_damping', min=0),
                                       doc='(beam) damping, for a rotation'),
    }, checks=[_check_spring('damping', 'rotational_damping')])),
        doc='(beam) grounded viscous dampers (physical damping, besides modal tare damping)'),
    'super_elements': Optional(ListOf(Section({
        'dofs': ListOf(Section({
            'node': _node('(beam) node id'),
            'dof': Choice(DOF_NAMES, doc='(beam) DOF of this row and column'),
        }), min_len=1, doc='(beam) the DOFs the matrices act on, in row order'),
        'stiffness': ListOf(_ROW, min_len=1,
                            doc='(beam) symmetric stiffness matrix, plain numbers in '
                                'force_unit and length_unit (rad for rotations): N/m, N/rad, '
                                'N m/rad in SI'),
        'damping': Optional(ListOf(_ROW, min_len=1),
                            doc='(beam) symmetric damping matrix, as stiffness times s'),
        'force_unit': Choice(tuple(u for u in UNITS['force']), default='N',
                             doc='(beam) force unit of the matrix entries'),
        'length_unit': Choice(tuple(u for u in UNITS['length']), default='m',
                              doc='(beam) length unit of the matrix entries'),
    }, checks=[_check_square])), doc='(beam) general symmetric stiffness (and damping) '
                                     'matrices, e.g. a boundary super element'),
    'clamps': Optional(ListOf(Section({
        'node': _node('(beam) node id'),
        'dofs': Optional(ListOf(Choice(DOF_NAMES, doc='(beam) a DOF name'), min_len=1),
                         doc='(beam) DOFs fixed to zero; none = all six'),
    }, checks=[_check_clamp_dofs])), doc='(beam) boundary conditions'),
    'cross_couplings': Optional(ListOf(Section({
        'node': _node('(beam) node id'),
        'kcc': Quantity('stiffness', doc='(beam) cross-coupled stiffness, any sign: '
                                         'K[a,b] += kcc, K[b,a] -= kcc'),
        'dofs': ListOf(Choice(TRANSLATIONS, doc='(beam) a DOF name'), min_len=2, max_len=2,
                       default=['uy', 'uz'],
                       doc='(beam) the two DOFs (a, b)'),
    }, checks=[lambda v: None if v['dofs'][0] != v['dofs'][1] else 'dofs must differ'])),
        doc='(beam) circulatory (destabilizing) stiffness, e.g. seals'),
}, checks=[_check_structure])


# --- modal ----------------------------------------------------------------------------------

_RATIO: dict[str, Any] = dict(min=0, max=1, max_inclusive=False)

#: Default margin of ``modal.cutoff: auto`` over the highest frequency of interest.
CUTOFF_FACTOR = 1.5


def _check_modal(values: dict[str, Any]) -> str | None:
    if values['cutoff'] == 'auto' and values['f_max'] is not None:
        return "give f_max or cutoff: auto, not both (cutoff: auto derives f_max)"
    return None


_MODAL = Section(doc='mode selection and tare damping', checks=[_check_modal], fields={
    'n_modes': Optional(Integer(min=1),
                        doc='keep the lowest n_modes modes; with f_max (or cutoff: auto) '
                            'too, the smaller set; neither = all modes'),
    'f_max': Optional(Quantity('frequency', min=0, min_inclusive=False),
                      doc='keep every mode with frequency <= f_max'),
    'cutoff': Choice(('none', 'auto'), default='none',
                     doc='auto: f_max = cutoff_factor x the highest frequency of interest, '
                         'the largest of the sensor low-pass cutoffs, the forcing frequencies '
                         'and the highest rotor speed / 2 pi (commanded: its initial speed); '
                         'none: f_max as given'),
    'cutoff_factor': Quantity('dimensionless', default=CUTOFF_FACTOR, min=1,
                              doc='(cutoff: auto) margin over the highest frequency of '
                                  'interest'),
    'solver': Choice(('auto', 'dense', 'sparse'), default='auto',
                     doc='eigen solver: dense LAPACK, sparse shift-invert Lanczos (accurate '
                         'lowest modes of badly scaled models), auto = dense up to 2000 DOFs'),
    'damping': Section(doc='tare (modal) damping', fields={
        'default': Quantity('dimensionless', default=0, **_RATIO,
                            doc="tare damping ratio of every retained mode (the paper's "
                                'per-mode damping)'),
        'modes': MapOf(Integer(min=1), Quantity('dimensionless', **_RATIO,
                                                doc='tare damping ratio of that mode'),
                       default={},
                       doc='tare damping ratio by mode number (1 = lowest), overriding '
                           'default'),
    }),
})


# --- sensors, forcing, impactors ---------------------------------------------------------

_SENSOR = Section({
    'name': String(pattern=_IDENT, doc='sensor name (unique), used in outputs'),
    'node': _node('node id'),
    'dof': Choice(DOF_NAMES, doc='DOF read (m for translations, rad for rotations)'),
    'frame_id': Optional(String(), doc='frame_id for ROS messages; none = derived from the name'),
    'lowpass': Optional(Quantity('frequency', min=0, min_inclusive=False),
                        doc='cutoff of the anti-alias low-pass filter of the accelerometer '
                            'output: a 4th-order Butterworth on the mean acceleration per '
                            'sample period, below the Nyquist frequency; none = no filter'),
    'channel': SENSOR_CHANNEL,
})


def _check_force(values: dict[str, Any]) -> str | None:
    given = [k for k in ('frequency', 'frequency_ratio') if values[k] is not None]
    if len(given) != 1:
        return ("give exactly one of 'frequency' and 'frequency_ratio' "
                f"(got {', '.join(given) or 'neither'})")
    return None


_FORCE = Section({
    'node': _node('node id'),
    'dof': Choice(TRANSLATIONS, doc='direction of the force'),
    'amplitude': Quantity('force', min=0, doc='amplitude F0 of F0 cos(2 pi f t + phase)'),
    'frequency': Optional(Quantity('frequency', min=0, min_inclusive=False),
                          doc='forcing frequency f; give this or frequency_ratio'),
    'frequency_ratio': Optional(Quantity('dimensionless', min=0, min_inclusive=False),
                                doc='forcing frequency over the first natural frequency of '
                                    'the structure (retained modes, without impactors)'),
    'phase': Quantity('angle', default=0, doc='phase of the cosine'),
}, checks=[_check_force])


def _check_impactor(values: dict[str, Any]) -> list[str]:
    problems = []
    if values['kind'] == 'sdof':
        if values['dof'] is None:
            problems.append("kind sdof needs 'dof'")
        if values['plane'] is not None:
            problems.append("'plane' applies to kind planar only (kind sdof uses 'dof')")
        dim, limit = 1, values['clearance'] / 2
    else:
        if values['plane'] is None:
            problems.append("kind planar needs 'plane'")
        elif values['plane'][0] == values['plane'][1]:
            problems.append('plane must name two different DOFs')
        if values['dof'] is not None:
            problems.append("'dof' applies to kind sdof only (kind planar uses 'plane')")
        dim, limit = 2, values['clearance']
    given = [k for k in ('mass', 'mass_ratio') if values[k] is not None]
    if len(given) != 1:
        problems.append("give exactly one of 'mass' and 'mass_ratio' "
                        f"(got {', '.join(given) or 'neither'})")
    pos = values['position']
    if pos is not None:
        if len(pos) != dim:
            problems.append(f"position of a {values['kind']} impactor has {dim} "
                            f'component(s), got {len(pos)}')
        elif math.hypot(*pos) > limit:
            problems.append(f'position {pos} m lies outside the clearance '
                            f'(|position| <= {limit:.6g} m)')
    return problems


_IMPACTOR = Section({
    'name': String(pattern=_IDENT, doc='impactor name (unique), used in outputs'),
    'kind': Choice(('sdof', 'planar'), default='sdof',
                   doc='sdof: particle in a slot along one DOF; planar: cylinder in a '
                       'cylindrical housing moving in a plane'),
    'node': _node('node id of the housing'),
    'dof': Optional(Choice(TRANSLATIONS), doc='(sdof) direction of the slot'),
    'plane': Optional(ListOf(Choice(TRANSLATIONS, doc='(planar) a DOF name'), min_len=2,
                             max_len=2),
                      doc='(planar) the two DOFs spanning the plane'),
    'mass': Optional(Quantity('mass', min=0, min_inclusive=False),
                     doc='impactor mass (a weight in lb is read as lbm); give this or '
                         'mass_ratio'),
    'mass_ratio': Optional(Quantity('dimensionless', min=0, max=10, min_inclusive=False),
                           doc='impactor mass over the housing mass (housing_mass, whose '
                               'default for an SDOF structure is its primary mass)'),
    'housing_mass': Optional(Quantity('mass', min=0, min_inclusive=False),
                             doc='lumped housing mass, the reference of mass_ratio and the '
                                 'mass of the lumped_mass impact law; none = the lumped '
                                 'mass of the model at the housing DOF'),
    'cor': Quantity('dimensionless', min=0, max=1, doc='coefficient of restitution e'),
    'clearance': Quantity('length', min='1e-8 m', max='0.1 m',
                          doc='sdof: total free travel D (|z - x| <= D/2); planar: radial '
                              'clearance c'),
    'position': Optional(ListOf(Quantity('length', doc='one component'), min_len=1,
                                max_len=2),
                         doc='initial position relative to the housing centre: [r] (sdof) '
                             'or [r_a, r_b] (planar); none = centred. Starts at rest'),
}, checks=[_check_impactor])


# --- rotor ------------------------------------------------------------------------------------

#: Keys of ``rotor.speed`` by kind: (required, optional).
SPEED_KINDS = {
    'constant': (('speed',), ()),
    'paper_ramp': ((), ('final_speed', 'ramp_time')),
    'piecewise': (('times', 'speeds'), ()),
    'commanded': (('speed', 'max_rate'), ()),
}


def _check_speed(values: dict[str, Any]) -> list[str]:
    kind = values['kind']
    required, optional = SPEED_KINDS[kind]
    allowed = set(required) | set(optional) | {'kind'}
    problems = [f"kind {kind} needs key '{k}'" for k in required if values[k] is None]
    problems += [f"key '{k}' does not apply to kind {kind} (keys of kind {kind}: kind"
                 f"{''.join(', ' + a for a in required + optional)})"
                 for k, v in values.items() if v is not None and k not in allowed]
    if kind == 'piecewise' and values['times'] is not None and values['speeds'] is not None:
        times, speeds = values['times'], values['speeds']
        if len(times) != len(speeds):
            problems.append(f'times and speeds must have the same length (got {len(times)} '
                            f'and {len(speeds)})')
        if any(b <= a for a, b in zip(times, times[1:])):
            problems.append('times must be strictly increasing')
    return problems


_SPEED = Section(doc='rotor speed profile', checks=[_check_speed], fields={
    'kind': Choice(tuple(SPEED_KINDS), default='constant',
                   doc='constant: fixed speed; paper_ramp: linear ramp from rest to '
                       'final_speed in ramp_time, then held (Eq. 4.3.1); piecewise: linear '
                       'between (times, speeds) points, held outside; commanded: starts at '
                       'speed and follows run-time commands under the rate limit max_rate'),
    'speed': Optional(Quantity('angular_speed', min=0),
                      doc='(constant) rotor speed; (commanded) initial speed'),
    'final_speed': Optional(Quantity('angular_speed', min=0, min_inclusive=False),
                            doc="(paper_ramp) running speed; none = the paper's 2400 rad/s"),
    'ramp_time': Optional(Quantity('time', min=0, min_inclusive=False),
                          doc="(paper_ramp) ramp duration; none = the paper's 5 s"),
    'times': Optional(ListOf(Quantity('time', min=0, doc='(piecewise) a time'), min_len=1),
                      doc='(piecewise) strictly increasing times'),
    'speeds': Optional(ListOf(Quantity('angular_speed', min=0, doc='(piecewise) a speed'),
                              min_len=1),
                       doc='(piecewise) speeds at times'),
    'max_rate': Optional(Quantity('angular_acceleration', min=0, min_inclusive=False),
                         doc='(commanded) magnitude of the speed change rate'),
})


_ROTOR = Section(doc='rotating shaft: speed profile and unbalance (rotor axis along global '
                     'X; unbalance forces act in uy and uz)', fields={
    'speed': _SPEED,
    'unbalance': ListOf(Section({
        'node': _node('node id of the unbalance (uy and uz must be active)'),
        'amount': Quantity('unbalance', min=0, doc='base unbalance m e (mass x eccentricity)'),
        'phase': Quantity('angle', default=0,
                          doc='angle of the unbalance relative to the rotor angle'),
    }), default=[], doc='base unbalance distribution; F_y = X m e (phi\'^2 cos(phi + p) + '
                        "phi'' sin(phi + p)), F_z = X m e (phi'^2 sin(phi + p) - phi'' "
                        'cos(phi + p))'),
    'multiplier': Quantity('dimensionless', default=1, min=0,
                           doc="unbalance multiplier X of the paper (Sec. 4.3)"),
    'gyroscopic': Optional(Section({
        'nodes': ListOf(_node('node id of a spinning disk'), min_len=1,
                        doc='nodes whose point-mass polar inertia (inertia about X) spins with '
                            'the rotor'),
    }), doc='speed-dependent gyroscopic coupling Omega G of the spinning disks, entering as a '
            'dense modal damping-like coupling; needs a constant speed; none = off'),
})


# --- simulation -------------------------------------------------------------------------------

def _check_simulation(values: dict[str, Any]) -> list[str]:
    problems = []
    if values['window'] > values['duration']:
        problems.append(f"window {values['window']:g} s exceeds duration "
                        f"{values['duration']:g} s")
    if values['dt'] > values['duration']:
        problems.append(f"dt {values['dt']:g} s exceeds duration {values['duration']:g} s")
    if values['stuck_model'] == 'basis_switch' and values['method'] != 'exact':
        problems.append(f"stuck_model basis_switch needs method exact (got method "
                        f"{values['method']}); use stuck_model mass_update")
    return problems


_SIMULATION = Section(doc='defaults of study simulate and make_simulation', fields={
    'method': Choice(METHODS, default='exact',
                     doc='exact: exact modal flow with located impacts; newmark: modal '
                         'Newmark with located impacts; newmark_step_end: impacts at step ends '
                         "(the paper's); direct: Newmark in physical coordinates"),
    'dt': Quantity('time', default='0.1 ms', min=1e-9, max=1,
                   doc='output sample period (and Newmark step); 1 ns at least (a 1e-308 s '
                       'step overflowed the step count)'),
    'duration': Quantity('time', default='2 s', min=0, max=1e6, min_inclusive=False,
                         doc='simulated time of study simulate'),
    'window': Quantity('time', default='0.5 s', min=0, min_inclusive=False,
                       doc='trailing window of the steady-state amplitude'),
    'law': Choice(IMPACT_LAWS, default='effective_mass',
                  doc='impact law: effective_mass (exact restitution and momentum of the '
                      "simulated model) or lumped_mass (the paper's, uses housing_mass)"),
    'stick_rule': Choice(STICK_RULES, default='paper',
                         doc='when a bounce-down becomes the stuck state'),
    'stick_fraction': Quantity('dimensionless', default=0.002, min=0, max=1,
                               min_inclusive=False, max_inclusive=False,
                               doc='paper rule: second impact on one wall within this fraction '
                                   'of the period of the highest retained mode'),
    'stuck_model': Choice(STUCK_MODELS, default='mass_update',
                          doc='how a stuck impactor enters the modal model (method exact '
                              'only): mass_update adds its mass to the free modal '
                              'coordinates (no switching loss); basis_switch is the '
                              "paper's second modal basis with the mass added, whose "
                              'switches lose a little energy on truncated bases'),
}, checks=[_check_simulation])


# --- the scene --------------------------------------------------------------------------------

def _unique(values: dict[str, Any], key: str) -> list[str]:
    names = [item['name'] for item in values[key]]
    dup = sorted({n for n in names if names.count(n) > 1})
    return [f"{key}: name '{n}' is used more than once" for n in dup]


def _check_scene(values: dict[str, Any]) -> list[str]:
    return _unique(values, 'sensors') + _unique(values, 'impactors')


SCHEMA = Section({
    'name': String(pattern=r'[A-Za-z0-9][A-Za-z0-9_.-]*', doc='scene name'),
    'description': String(default='', allow_empty=True, doc='free text'),
    'offline_only': String(default='', allow_empty=True,
                           doc='why the scene is meant only for offline studies (the live '
                               'node refuses it with this reason); empty = live too'),
    'structure': _STRUCTURE,
    'modal': _MODAL,
    'sensors': ListOf(_SENSOR, default=[], doc='displacement outputs'),
    'channel': CHANNEL,
    'forcing': ListOf(_FORCE, default=[], doc='harmonic forces'),
    'impactors': ListOf(_IMPACTOR, default=[], doc='impact dampers; none = linear structure'),
    'rotor': Optional(_ROTOR, doc='rotor speed and unbalance; none = no rotor (no unbalance '
                                  'forces)'),
    'simulation': _SIMULATION,
}, checks=[_check_scene])
"""The scene schema (:class:`~.containers.Section`); validate with :func:`~.schema.validate`."""
