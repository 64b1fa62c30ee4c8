"""Scene files to models: finite-element system, modal basis, linear model and forcing.

>>> from impact_damper_sim.scene.build import load
>>> scene = load('sdof', overrides=['impactors.0.cor=0.6'])   # doctest: +SKIP
>>> sim = scene.make_simulation()                              # doctest: +SKIP
>>> samples = sim.advance_to(1.0)                              # doctest: +SKIP

Every problem a scene can have is reported as a :class:`~.schema.SceneError` naming the key:
schema problems by :func:`~.schema.validate`, model problems (an undefined node, a clamped
sensor DOF, too many modes) here, in :mod:`.structure` and in :mod:`.modes`, with the same
``scene key 'path': message`` format. Everything is SI.

This module holds :class:`SceneModel` and the two calls that make one, :func:`load` and
:func:`build`; finding and validating scene files is :mod:`.catalog`, the finite elements
:mod:`.structure`, the retained modes :mod:`.modes`.
"""
from __future__ import annotations

import dataclasses
import functools
import os
from collections.abc import Iterable
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from .accelerometers import accelerometer_problems
from .catalog import validated
from .modes import MIN_SAMPLES_PER_REVOLUTION, _build_basis, excitation_frequencies
from .schema import SceneError, _Errors
from .spec import STUCK_MODELS
from .structure import _build_fe, _has_node

if TYPE_CHECKING:
    from ..dampers.impactors import Impactor
    from ..fem import AssembledSystem, FEModel
    from ..integrate.basis_switch import BasisSwitch
    from ..integrate.forcing import Forcing
    from ..integrate.model import LinearModel
    from ..integrate.simulation import Simulation
    from ..modal.basis import ModalBasis
    from .excitation import SpeedProfile, UnbalanceForce

__all__ = ['SceneModel', 'build', 'load']

_ROW_ZERO_RTOL = 1e-12   # a mode-shape row this small (relative) does not move the DOF


def load(scene_name_or_path: str | os.PathLike[str], overrides: Iterable[str] = ()
         ) -> SceneModel:
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
        The rotor speed profile (rad/s); a
        :class:`~impact_damper_sim.scene.excitation.CommandedSpeed` takes run-time commands.
        None without ``rotor``.
    unbalance : UnbalanceForce or None
        The unbalance forces (N), None without unbalance.
    impactor_dofs : tuple of tuple of int
        Active DOF indices of each impactor housing (one for sdof, two for planar).
    """

    def __init__(self, scene: dict[str, Any], source: str | None, overrides: Iterable[str],
                 fe: FEModel, system: AssembledSystem, basis: ModalBasis) -> None:
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
        for path, message in accelerometer_problems(scene):   # one channel per node
            errors.add(path, message)
        errors.raise_if_any(source)
        self.speed_profile, self.unbalance = self._make_rotor()
        self.forcing = self._make_forcing()
        impactors = self._make_impactors(errors)
        errors.raise_if_any(source)
        self.model = self._make_model(impactors)

    # -- construction helpers --------------------------------------------------------------
    def _dof(self, fe: FEModel, node: int, dof: str, path: str, errors: _Errors,
             dof_key: str = 'dof') -> int:
        if not _has_node(fe, node, f'{path}.node', errors):
            return -1
        try:
            return self.system.index(node, dof)
        except KeyError:
            errors.add(f'{path}.{dof_key}', f'DOF {dof} at node {node} is clamped')
            return -1

    @property
    def input_dofs(self) -> tuple[int, ...]:
        """tuple of int: Active DOF of every force input: forcing entries, then (uy, uz) of
        each unbalance."""
        return self.force_dofs + tuple(d for pair in self.unbalance_dofs for d in pair)

    def _make_rotor(self) -> tuple[SpeedProfile | None, UnbalanceForce | None]:
        """The speed profile and the unbalance force (None, None without a rotor)."""
        from .excitation import UnbalanceForce, speed_profile
        rotor = self.scene['rotor']
        if rotor is None:
            return None, None
        profile = speed_profile(rotor['speed'])
        if not self.unbalance_dofs:
            return profile, None
        first = len(self.force_dofs)
        pairs = [(first + 2 * i, first + 2 * i + 1) for i in range(len(self.unbalance_dofs))]
        unbalances = [(u['amount'], u['phase']) for u in rotor['unbalance']]
        force = UnbalanceForce(profile, unbalances, pairs, rotor['multiplier'],
                               n_inputs=len(self.input_dofs))
        return profile, force

    def _make_forcing(self) -> Forcing:
        from ..integrate.forcing import Forcing, Harmonic
        from .excitation import unbalance_forcing
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

    def _housing_mass(self, i: int, imp: dict[str, Any], errors: _Errors) -> float:
        if imp['housing_mass'] is not None:
            return imp['housing_mass']
        lumped = float(self.system.M[self.impactor_dofs[i][0], self.impactor_dofs[i][0]])
        if lumped <= 0.0 and imp['mass_ratio'] is not None:
            errors.add(f'impactors[{i}].mass_ratio', 'the housing DOF carries no lumped mass, '
                       'so mass_ratio has no reference; give housing_mass or mass')
        return lumped

    def _make_impactors(self, errors: _Errors) -> tuple[Impactor, ...]:
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

    def _make_model(self, impactors: tuple[Impactor, ...]) -> LinearModel:
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

    def polar_inertia(self) -> dict[int, float]:
        """Polar inertia of each ``rotor.gyroscopic`` node (the Campbell study's too).

        Returns
        -------
        dict of int to float
            Node id to the sum of its point masses' inertia about X (kg m^2), 0.0 for a node
            without one, in ``rotor.gyroscopic.nodes`` order; empty without
            ``rotor.gyroscopic``.
        """
        rotor = self.scene['rotor']
        gyro = rotor['gyroscopic'] if rotor else None
        if gyro is None:
            return {}
        polar: dict[int, float] = {}
        for pm in self.scene['structure']['point_masses'] or ():
            if pm['inertia'] is not None:
                polar[pm['node']] = polar.get(pm['node'], 0.0) + pm['inertia'][0]
        return {node: polar.get(node, 0.0) for node in gyro['nodes']}

    def _gyroscopic_disks(self) -> tuple[tuple[int, int, float], ...]:
        """``(ry, rz, Ip)`` of each ``rotor.gyroscopic`` node: active DOF indices of its tilts
        and its point-mass polar inertia (kg m^2); empty without ``rotor.gyroscopic``.

        Raises
        ------
        SceneError
            A speed that is not constant, a node without polar inertia or a clamped tilt.
        """
        rotor = self.scene['rotor']
        gyro = rotor['gyroscopic'] if rotor else None
        if gyro is None:
            return ()
        from .excitation import ConstantSpeed
        if not isinstance(self.speed_profile, ConstantSpeed):
            raise SceneError("scene key 'rotor.gyroscopic': needs rotor.speed.kind constant "
                             '(the flow is linear time-invariant per configuration)',
                             self.source)
        disks: list[tuple[int, int, float]] = []
        for i, (node, ip) in enumerate(self.polar_inertia().items()):
            if ip <= 0.0:
                raise SceneError(f"scene key 'rotor.gyroscopic.nodes[{i}]': node {node} has no "
                                 'point-mass polar inertia (inertia about X) > 0', self.source)
            try:
                disks.append((self.system.index(node, 'ry'), self.system.index(node, 'rz'),
                              ip))
            except KeyError as exc:
                raise SceneError(f"scene key 'rotor.gyroscopic.nodes[{i}]': {exc.args[0]}",
                                 self.source) from None
        return tuple(disks)

    def gyroscopic_terms(self) -> tuple[tuple[int, int, float], ...]:
        """The physical gyroscopic matrix: ``(ry, rz, Ip Omega)`` per ``rotor.gyroscopic`` node.

        Returns
        -------
        tuple of (int, int, float)
            Active DOF indices of the disk's tilts (dimensionless) and its polar inertia
            times the constant spin speed (kg m^2/s): ``G[ry, rz] = +Ip Omega``,
            ``G[rz, ry] = -Ip Omega``. Empty without ``rotor.gyroscopic``.
        """
        disks = self._gyroscopic_disks()
        if not disks or self.speed_profile is None:   # disks: a constant-speed rotor
            return ()
        omega = float(self.speed_profile.speed(0.0))
        return tuple((ry, rz, ip * omega) for ry, rz, ip in disks)

    def _gyroscopic_coupling(self) -> npt.NDArray[np.float64]:
        """Modal gyroscopic coupling ``Omega Phi^T G Phi`` (1/s); zero without ``rotor.gyroscopic``.

        A disk of polar inertia ``Ip`` spinning at ``Omega`` about global X adds
        ``Ip Omega theta_z'`` to the ``ry`` equation and ``-Ip Omega theta_y'`` to the ``rz``
        one (the small-tilt change of its angular momentum): a skew-symmetric matrix that does
        no work and splits each whirl pair into forward and backward modes.
        """
        n = self.basis.n_modes
        disks = self._gyroscopic_disks()
        if not disks or self.speed_profile is None:   # disks: a constant-speed rotor
            return np.zeros((n, n))

        coupling = np.zeros((n, n))
        for ry, rz, ip in disks:
            rows = self.basis.rows([ry, rz])
            # G[ry, rz] = +Ip, G[rz, ry] = -Ip
            coupling += ip * (np.outer(rows[0], rows[1]) - np.outer(rows[1], rows[0]))
        return float(self.speed_profile.speed(0.0)) * coupling

    @property
    def input_names(self) -> tuple[str, ...]:
        """tuple of str: Name of every force input (``force<k>``, ``unbalance<i>_uy/_uz``)."""
        return (tuple(f'force{k}' for k in range(len(self.force_dofs)))
                + tuple(f'unbalance{i}_{d}' for i in range(len(self.unbalance_dofs))
                        for d in ('uy', 'uz')))

    # -- public -------------------------------------------------------------------------------
    @property
    def name(self) -> str:
        """str: The scene's name."""
        return self.scene['name']

    @property
    def impactors(self) -> tuple[Impactor, ...]:
        """tuple of Impactor: The modal model's impactors (empty for a linear scene)."""
        return self.model.impactors

    @functools.cached_property
    def physical_model(self) -> LinearModel:
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

    def basis_switch(self) -> BasisSwitch:
        """The stuck-state configurations of the ``basis_switch`` model for this scene.

        Returns
        -------
        BasisSwitch
            Built from the scene's system, basis, modal model and DOF indices (its stuck
            bases use ``modal.solver``); no stuck basis built yet.
        """
        from ..integrate.basis_switch import BasisSwitch
        return BasisSwitch(self.system, self.basis, self.model, self.impactor_dofs,
                           sensor_indices=self.sensor_dofs, force_indices=self.input_dofs,
                           method=self.scene['modal']['solver'],
                           gyroscopic=self.gyroscopic_terms())

    def make_simulation(self, method: str | None = None, dt: float | None = None,
                        **options: Any) -> Simulation:
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
            opts['configurations'] = self.basis_switch()
        physical = self.physical_model if method == 'direct' else None
        if method == 'direct' and 'stick_time' not in opts:
            # the paper's rule uses the highest *retained* mode; the physical model's highest
            # mode (massless-ish DOFs) would make it never fire
            opts['stick_time'] = (opts['stick_fraction'] * 2 * np.pi
                                  / float(np.max(self.basis.omega)))
        from ..integrate.newmark import StepTooLarge
        try:
            return Simulation(model, self.forcing, method=method, dt=dt,
                              physical_model=physical, **opts)
        except StepTooLarge as exc:   # said with the scene key that sets the step
            raise ValueError(exc.text('simulation.dt')) from None

    def _check_rotor_sampling(self, dt: float) -> None:
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

    def dof_counts(self) -> dict[str, int]:
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

    def describe_modes(self) -> dict[str, Any]:
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
        shapes: list[dict[str, Any]] = []

        def add(role: str, name: str, node: int, dof: str, index: int) -> None:
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
        impactors: list[dict[str, Any]] = []
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

    def __repr__(self) -> str:
        return (f'SceneModel({self.name!r}, {self.basis.n_modes} modes, '
                f'{len(self.model.impactors)} impactors, source={self.source!r})')


def build(scene: dict[str, Any], *, source: str | None = None,
          overrides: Iterable[str] = ()) -> SceneModel:

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
        whose estimated memory (:func:`impact_damper_sim.scene.model_budget.model_estimate`: DOFs,
        modes, impactors, stuck configurations) is over the limit, in one line with the
        estimate and the limit.
    """
    from .model_budget import ModelTooLarge, check_model
    try:
        check_model(scene)
    except ModelTooLarge as exc:
        raise SceneError(str(exc), source=source) from None
    fe, system = _build_fe(scene['structure'], source)
    basis = _build_basis(system, scene['modal'], source, scene)
    return SceneModel(scene, source, overrides, fe, system, basis)
