"""Blow-up detection: a run that diverges ends in one typed error, never in inf/NaN results.

A run *diverges* when its state leaves what floating point and the physics can carry: a
non-finite modal state or sensor sample, a sensor displacement beyond
:data:`MAX_DISPLACEMENT` (no structure this package models moves a kilometre; beyond it the
energies overflow long before the state does), or an engine failure that only such states
cause (unresolved chatter, a floating-point error). :class:`Divergence` says what diverged,
when, and which setting to change; :func:`scene_advice` finds that setting in a scene.

Also here, the memory budget of a run, in one place: :func:`model_estimate`, what a scene's
model will allocate (DOFs, modes, impactors, stuck configurations), computed from the
validated scene before anything is built and refused by :func:`check_model`
(:class:`ModelTooLarge`, with the estimate and the limit); and :func:`check_allocation`,
which refuses up front a run whose sample arrays, with the model, would not fit
(:class:`TooLarge`). Both use :func:`memory_limit`.

Pure NumPy, no rclpy: :class:`~impact_damper_sim.integrate.simulation.Simulation` checks every chunk
it advances, the ``study`` command turns :class:`Divergence` into exit status
:data:`EXIT_DIVERGED`, and a node reports ``str(exc)`` in its diagnostics.
"""
from __future__ import annotations

import math
import os

import numpy as np

#: Exit status of ``study`` when a run diverged.
EXIT_DIVERGED = 3

#: Sensor displacement beyond which a run has diverged (m).
MAX_DISPLACEMENT = 1.0e3

#: Largest memory one run may allocate (bytes): its model (:func:`model_estimate`) plus the
#: sample arrays of one advance: 4 GiB, or half the physical memory if that is less
#: (:func:`memory_limit`). The interpreter with NumPy, SciPy and the compiled kernels, about
#: 190 MB, comes on top.
MAX_SAMPLE_BYTES = 4 * 2 ** 30

#: Engine messages that only a diverging state produces (``RuntimeError`` text).
_ENGINE_BLOW_UPS = ('chatter not resolved', 'non-finite')


class Divergence(RuntimeError):
    """A run diverged: what, when, and which setting to change.

    Parameters
    ----------
    what : str
        What diverged, e.g. ``"sensor 'primary' displacement 1.4e+295 m (bound 1000 m)"``.
    t : float
        Simulated time at which it was detected (s): the end of the first sample period
        that shows it, or the engine's time for an engine failure.
    setting : str, optional
        Which setting to change (scene keys), e.g. from :func:`scene_advice`.

    Attributes
    ----------
    what, t, setting
        As given.
    code : int
        :data:`EXIT_DIVERGED`.
    """

    code = EXIT_DIVERGED

    def __init__(self, what, t, setting=None):
        self.what = str(what)
        self.t = float(t)
        self.setting = setting
        super().__init__(self.message())

    def message(self):
        """Return the one-line message: ``diverged at t = ... s: what; change ...``."""
        text = f'diverged at t = {self.t:.6g} s: {self.what}'
        return f'{text}; {self.setting}' if self.setting else text

    def __str__(self):
        return self.message()

    def __reduce__(self):   # picklable across process pools, with its fields
        return (Divergence, (self.what, self.t, self.setting))

    def with_setting(self, setting):
        """Return a copy whose advice is ``setting`` (str)."""
        return Divergence(self.what, self.t, setting)


class StudyDiverged(RuntimeError):
    """A study cannot go on because a run it depends on diverged (e.g. its reference).

    The message is the run's one-line :class:`Divergence` text; ``code`` is
    :data:`EXIT_DIVERGED`.
    """

    code = EXIT_DIVERGED


class TooLarge(ValueError):
    """A run refused up front: its sample arrays would not fit in memory.

    Parameters
    ----------
    n_steps : int
        Samples asked for (dimensionless).
    n_bytes : int
        Estimated size of their arrays (bytes).
    limit : int
        The limit (bytes).
    context : str, optional
        What asked for them, e.g. ``'simulation.dt = 1e-09 s over ...'``.
    """

    def __init__(self, n_steps, n_bytes, limit, context=None, model_bytes=0):
        self.n_steps, self.n_bytes, self.limit = int(n_steps), int(n_bytes), int(limit)
        self.model_bytes = int(model_bytes)
        lead = f'{context}: ' if context else ''
        model = (f", with the model's {_gib(self.model_bytes)}" if self.model_bytes else '')
        super().__init__(
            f'{lead}{self.n_steps:.4g} samples would need about {_gib(self.n_bytes)} of memory '
            f'(limit {_gib(self.limit)}{model}): raise simulation.dt (--dt) or shorten '
            'simulation.duration (--duration)')


def _gib(n_bytes):
    return f'{n_bytes / 2 ** 30:.3g} GiB'


def sample_bytes(n_steps, n_outputs):
    """Size of the sample arrays of ``n_steps`` samples of ``n_outputs`` sensors (bytes).

    Time plus displacement, velocity and acceleration per sensor, float64, and as much again
    for the mean acceleration and filtering done on them afterwards.
    """
    return 2 * 8 * int(n_steps) * (1 + 3 * int(n_outputs))


def memory_limit():
    """The allocation limit: :data:`MAX_SAMPLE_BYTES` or half the physical memory (bytes)."""
    try:
        physical = os.sysconf('SC_PAGE_SIZE') * os.sysconf('SC_PHYS_PAGES')
    except (AttributeError, ValueError, OSError):
        physical = 0
    return min(MAX_SAMPLE_BYTES, physical // 2) if physical > 0 else MAX_SAMPLE_BYTES


# --- the model-size estimate ------------------------------------------------------------

#: Largest number of stuck configurations the exact propagator keeps as one table inside
#: its kernel (a table for every stuck count of every group of interchangeable impactors,
#: allocated at once); a scene with more switches through Python
#: (:mod:`impact_damper_sim.integrate.exact`).
MAX_TABLE_SLOTS = 4096
#: ... and the largest such table (bytes, flows included, :func:`configuration_bytes` per
#: slot): 2,000 interchangeable impactors on one mode (2,001 slots of 0.96 MB) switch
#: through Python instead of allocating 1.8 GB.
MAX_TABLE_BYTES = 2 ** 30
#: Stuck configurations kept when switching through Python (a flow and a one-slot table
#: each): as many as fit in :data:`MAX_CACHE_BYTES`, at least this many (and at most
#: :data:`MAX_TABLE_SLOTS`), see :func:`cache_limit`; the least recently used is dropped
#: beyond and built again if reached again. With ``stuck_model: basis_switch`` (a modal
#: basis each) this many. Without a bound 5,000 interchangeable impactors passed 2.4 GB in
#: 1.2 simulated s (1,300 configurations of 1.7 MB).
MAX_CACHED_CONFIGURATIONS = 64
#: Memory of the configurations kept when switching through Python (bytes). 5,000
#: impactors over 0.8 simulated s (625 configurations): 121 s and 1.29 GB peak without a
#: bound, 189 s and 0.38 GB with 64 kept (rebuilt when reached again), 0.5 GiB about 300.
MAX_CACHE_BYTES = 2 ** 29

#: Most impactors in a scene. Every step scans each impactor and every change of the stuck
#: set costs time and memory in proportion to their number: interchangeable impactors on
#: one mode took 3.2 s (100), 9.9 s (1,000), 14.5 s (2,000) and 47 s (5,000) for 0.5
#: simulated s on a 2-core machine (10,000: 64 s and 4.5 GB for the probe); the shipped
#: scenes have at most 12.
MAX_IMPACTORS = 1000
#: Bytes per DOF pair of the structure's dense matrices: static condensation (the n x m
#: recovery and its product with K, the condensed M, C, K), the dense eigen solver's copies
#: and workspace, at most 12 dense n x n float64 arrays. See :func:`model_estimate`.
DENSE_BYTES_PER_DOF2 = 12 * 8
#: Bytes per impactor kept by the scene and its model outside the configurations: the
#: validated scene entry, the Impactor, its housing rows, the propagator's state (measured:
#: 5,000 impactors on one mode add 39 MB to the built scene, 8 kB each, mostly the YAML
#: and validated entries).
IMPACTOR_BYTES = 8 * 1024


class ModelTooLarge(ValueError):
    """A scene refused before it is built: its model would not fit in memory.

    The message is one line: the fields that size the model (impactors, modes, DOFs, stuck
    configurations), the estimate and the limit, and the keys to change.

    Attributes
    ----------
    estimate : ModelEstimate
        The estimate.
    limit : int
        The limit (bytes).
    """

    def __init__(self, estimate, limit):
        self.estimate, self.limit = estimate, int(limit)
        if estimate.n_impactors > MAX_IMPACTORS:
            text = (f"scene key 'impactors': {estimate.n_impactors:,} impactors, over the "
                    f'limit of {MAX_IMPACTORS:,} (each costs time every step and memory in '
                    f'every stuck configuration; model estimate {_gib(estimate.total)}): '
                    'use fewer impactors')
        else:
            text = (f'model too large: {estimate.describe()} would need about '
                    f'{_gib(estimate.total)} of memory (limit {_gib(self.limit)}): '
                    f'{estimate.advice()}')
        super().__init__(text)


def configuration_bytes(n_modes, n_impactors, n_sensors=0, n_inputs=0, n_harmonics=1):
    """Bytes of one stuck configuration of the exact propagator: its flow and table slot.

    Per configuration the flow (:func:`~impact_damper_sim.integrate.flow.build_flow`) and
    its copy in the kernel's table hold the complex eigenvectors and their inverse
    (``2n x 2n`` each), the ledger's rows and patterns, and per impactor its housing rows,
    impulse response and 2 x 2 mobilities (``house_q``, ``kick``, ``house_abs``,
    ``mobility``, ``house_mobility``, ``release_map``).

    Parameters
    ----------
    n_modes, n_impactors, n_sensors, n_inputs, n_harmonics : int
        Model sizes (dimensionless).

    Returns
    -------
    int
        Bytes (an upper bound: 480 bytes per impactor on one mode, where 5,000 impactors
        measured 350 per configuration).
    """
    n, ni = int(n_modes), int(n_impactors)
    n2 = 2 * n
    per_impactor = 2 * (2 * 2 * n2 * 16 + 3 * 4 * 8) + 2 * n2 * 8   # flow and table
    modal = (2 * 2 * n2 * n2 * 16                       # V, Vinv in flow and table
             + 2 * n2 * (int(n_inputs) + 2 * int(n_harmonics) + 2 * int(n_sensors)) * 16
             + 4 * n2 * n * 8 + 2 * n * n2 * 8           # ledger rows, row patterns
             + 8 * n2 * 16)                              # eigenvalues, step factors
    return per_impactor * ni + modal


def cache_limit(per_configuration):
    """How many configurations of ``per_configuration`` bytes are kept when switching
    through Python: :data:`MAX_CACHE_BYTES` worth, between
    :data:`MAX_CACHED_CONFIGURATIONS` and :data:`MAX_TABLE_SLOTS` (int)."""
    fit = MAX_CACHE_BYTES // max(int(per_configuration), 1)
    return int(max(MAX_CACHED_CONFIGURATIONS, min(MAX_TABLE_SLOTS, fit)))


class ModelEstimate:
    """What a scene's model allocates, estimated from the validated scene (bytes).

    Build it with :func:`model_estimate`. Attributes: ``n_nodes``, ``n_dof`` (6 per node,
    an upper bound on the active DOFs), ``n_modes`` (``modal.n_modes``, or ``n_dof`` when
    the modes are chosen by frequency), ``n_impactors``, ``n_configurations`` (stuck
    configurations the run may hold at once), ``stuck_model`` and ``terms`` (bytes by
    kind: ``dofs``, ``modes``, ``impactors``, ``configurations``); ``total`` their sum.
    """

    def __init__(self, **fields):
        self.__dict__.update(fields)
        self.total = int(sum(self.terms.values()))

    def describe(self):
        """The sizes, largest term first, e.g. ``'10,000 impactors, 4,096 stuck ...'``."""
        def count(n, what):
            return f'{n:,} {what}' + ('' if n == 1 else 's')

        parts = {
            'impactors': count(self.n_impactors, 'impactor'),
            'configurations': count(self.n_configurations, 'stuck configuration')
            + f' ({self.stuck_model})',
            'modes': count(self.n_modes, 'mode'),
            'dofs': f"{count(self.n_dof, 'DOF')} ({count(self.n_nodes, 'node')})",
        }
        order = sorted(parts, key=lambda k: -self.terms[k])
        return ', '.join(parts[k] for k in order)

    def advice(self):
        """Which keys to change, for the largest term."""
        top = max(self.terms, key=self.terms.get)
        if top == 'dofs':
            return ('use fewer nodes (structure.lines[].n_elements, structure.nodes)')
        if top == 'modes':
            return 'retain fewer modes (modal.n_modes, modal.f_max, modal.cutoff)'
        return 'use fewer impactors (impactors) or fewer modes (modal.n_modes)'

    def __repr__(self):
        return f'ModelEstimate({self.describe()}: {self.total} bytes)'


def _impactor_groups(impactors):
    """Sizes of the groups of interchangeable impactors (same housing and mass), as
    :func:`impact_damper_sim.integrate.exact._interchangeable_groups` finds them in the
    built model, approximated from the scene entries."""
    sizes = {}
    for imp in impactors:
        where = (imp.get('node'), imp.get('kind'), imp.get('dof'),
                 tuple(imp.get('plane') or ()))
        mass = (imp.get('mass'), imp.get('mass_ratio'), imp.get('housing_mass'))
        sizes[(where, mass)] = sizes.get((where, mass), 0) + 1
    return list(sizes.values())


def model_estimate(scene):
    """Estimate the memory a scene's model allocates, before building it.

    Calibrated against the peak resident memory (``ru_maxrss``, ``/usr/bin/time -v``) of
    ``study simulate``, over the 186 to 189 MiB of ``sdof`` (interpreter, NumPy, SciPy,
    compiled kernels): the shipped scenes add 0 to 5.3 MiB (estimates 0.01 to 8.2 MiB); a
    100-element beam with rotary inertia (606 DOFs, 20 modes) 15 MiB (estimate 35 MiB);
    interchangeable impactors on one mode: 100 add nothing measurable (estimate 5.5 MiB),
    1,000 over 0.5 s 4 MiB (estimate 467 MiB: the table is allocated for every stuck count,
    touched only for those reached), 2,000 over 5 s 129 MiB (estimate 0.51 GiB), 5,000
    over 0.8 s 430 MiB with 223 configurations kept (estimate 0.54 GiB; 1.1 GiB and growing
    without the bound). An upper bound, then, by design.

    Parameters
    ----------
    scene : dict
        A validated scene (SI units), see :mod:`impact_damper_sim.scene.spec`.

    Returns
    -------
    ModelEstimate
        The sizes and the bytes by kind (an upper bound).
    """
    st = scene['structure']
    if st['kind'] == 'sdof':
        n_nodes = 1
    else:
        n_nodes = len(st.get('nodes') or ()) + sum(line['n_elements'] + 1
                                                   for line in st.get('lines') or ())
    n_dof = 6 * n_nodes
    modal = scene['modal']
    n_modes = min(modal['n_modes'], n_dof) if modal.get('n_modes') else n_dof
    impactors = scene.get('impactors') or []
    ni = len(impactors)
    rotor = scene.get('rotor') or {}
    n_inputs = len(scene.get('forcing') or ()) + 2 * len(rotor.get('unbalance') or ())
    stuck_model = (scene.get('simulation') or {}).get('stuck_model') or 'mass_update'
    n_keys = 1
    for size in _impactor_groups(impactors):
        n_keys *= size + 1
        if n_keys > MAX_TABLE_SLOTS:
            break
    per_config = configuration_bytes(n_modes, ni, len(scene.get('sensors') or ()), n_inputs,
                                     len(scene.get('forcing') or ()) + 1)
    if (stuck_model == 'mass_update' and n_keys <= MAX_TABLE_SLOTS
            and n_keys * per_config <= MAX_TABLE_BYTES):
        n_configs = n_keys   # one table of every stuck count per group, allocated at once
    elif stuck_model == 'mass_update':
        n_configs = min(2 ** min(ni, 62), cache_limit(per_config))
    else:
        n_configs = min(2 ** min(ni, 62), MAX_CACHED_CONFIGURATIONS)
    if stuck_model == 'basis_switch':
        # each stuck set's own modal basis: its dense condensation and mode shapes
        per_config += 3 * 8 * n_dof ** 2 + 2 * 8 * n_dof * n_modes + 8 * n_modes ** 2
    terms = {'dofs': DENSE_BYTES_PER_DOF2 * n_dof ** 2,
             'modes': 8 * n_dof * n_modes * 4,   # shapes, rows, basis and solver copies
             'impactors': IMPACTOR_BYTES * ni,
             'configurations': n_configs * per_config}
    return ModelEstimate(n_nodes=n_nodes, n_dof=n_dof, n_modes=n_modes, n_impactors=ni,
                         n_configurations=n_configs, stuck_model=stuck_model, terms=terms)


def check_model(scene, limit=None):
    """Refuse a scene whose model would not fit in memory, before building it.

    Parameters
    ----------
    scene : dict
        A validated scene (SI units).
    limit : int, optional
        Bytes; default :func:`memory_limit`.

    Returns
    -------
    ModelEstimate
        The estimate, when it fits.

    Raises
    ------
    ModelTooLarge
        With the estimate and the limit, in one line; also for more than
        :data:`MAX_IMPACTORS` impactors.
    """
    limit = memory_limit() if limit is None else int(limit)
    estimate = model_estimate(scene)
    if estimate.total > limit or estimate.n_impactors > MAX_IMPACTORS:
        raise ModelTooLarge(estimate, limit)
    return estimate


def check_allocation(n_steps, n_outputs, limit=None, model_bytes=0):
    """Refuse a run whose samples would not fit in memory.

    Parameters
    ----------
    n_steps : int
        Samples (dimensionless).
    n_outputs : int
        Sensor outputs per sample (dimensionless).
    limit : int, optional
        Bytes; default :func:`memory_limit`.
    model_bytes : int, optional
        The model's estimate (bytes, :func:`model_estimate`), which shares the limit.

    Raises
    ------
    TooLarge
        With the estimate.
    """
    limit = memory_limit() if limit is None else int(limit)
    need = sample_bytes(n_steps, n_outputs)
    if need + int(model_bytes) > limit:
        raise TooLarge(n_steps, need, limit, model_bytes=model_bytes)


def check_state(q, qd, t):
    """Raise :class:`Divergence` if the modal state is not finite.

    Parameters
    ----------
    q, qd : ndarray
        Modal coordinates (m sqrt(kg)) and their velocities (m sqrt(kg)/s).
    t : float
        Time of the state (s).
    """
    for name, v in (('modal coordinates', q), ('modal velocities', qd)):
        v = np.asarray(v)
        if not np.all(np.isfinite(v)):
            bad = np.flatnonzero(~np.isfinite(v.ravel()))
            raise Divergence(f'{name} not finite (mode {int(bad[0]) + 1} of {v.size})', t)


def check_samples(samples, names=(), max_displacement=MAX_DISPLACEMENT):
    """Raise :class:`Divergence` at the first sample that is not finite or too large.

    Parameters
    ----------
    samples : Samples
        Sensor samples (``t`` in s; displacement m; velocity m/s; acceleration m/s^2).
    names : sequence of str
        Sensor names, in column order (for the message).
    max_displacement : float
        Largest acceptable ``|displacement|`` (m).
    """
    if samples.t.size == 0:
        return
    # a clean chunk, the rule, in three reductions (a NaN or inf fails each test)
    disp = np.asarray(samples.displacement)
    with np.errstate(over='ignore', invalid='ignore'):   # a sum may overflow: then look
        if ((disp.size == 0 or np.abs(disp).max() <= max_displacement)
                and np.isfinite(np.sum(samples.velocity))
                and np.isfinite(np.sum(samples.acceleration))):
            return
    bad_rows = None
    for field in ('displacement', 'velocity', 'acceleration'):
        values = getattr(samples, field)
        bad = ~np.isfinite(values)
        if field == 'displacement':
            with np.errstate(invalid='ignore'):
                bad |= np.abs(values) > max_displacement
        rows = np.flatnonzero(bad.any(axis=1)) if bad.ndim == 2 else np.flatnonzero(bad)
        if rows.size and (bad_rows is None or rows[0] < bad_rows[0]):
            bad_rows = (int(rows[0]), field, bad)
    if bad_rows is None:
        return
    k, field, bad = bad_rows
    col = int(np.flatnonzero(bad[k])[0]) if bad.ndim == 2 else 0
    value = float(np.asarray(getattr(samples, field))[k].ravel()[col])
    name = names[col] if col < len(names) else f'#{col}'
    unit = {'displacement': 'm', 'velocity': 'm/s', 'acceleration': 'm/s^2'}[field]
    if math.isfinite(value):
        what = (f'sensor {name!r} displacement {value:.3g} m exceeds {max_displacement:g} m')
    else:
        what = f'sensor {name!r} {field} is {value} {unit}'
    raise Divergence(what, float(samples.t[k]))


def from_engine_error(exc, t):
    """Return the :class:`Divergence` an engine error stands for, or None.

    ``FloatingPointError`` and the engine's ``RuntimeError`` for unresolved chatter or a
    non-finite state only happen on a diverging state.

    Parameters
    ----------
    exc : BaseException
        The engine's error.
    t : float
        Simulated time when it was raised (s).
    """
    if isinstance(exc, Divergence):
        return exc
    text = str(exc).strip()
    if isinstance(exc, FloatingPointError) or (
            isinstance(exc, RuntimeError) and any(k in text for k in _ENGINE_BLOW_UPS)):
        return Divergence(f'the integrator stopped: {text or type(exc).__name__}', t)
    return None


def scene_advice(scene, cause=None):
    """Which settings to change when ``scene`` diverges (one line).

    Parameters
    ----------
    scene : SceneModel
        The built scene (its ``scene`` dict, SI units, and modal matrices are read).
    cause : Divergence, optional
        The divergence (chatter gets its own advice).

    Returns
    -------
    str
        E.g. ``"change forcing.0.amplitude (1e+300 N)"``; the linearly unstable case names
        the cross-coupled stiffness and its growth rate.
    """
    cfg = scene.scene
    hints = []
    couplings = (cfg.get('structure') or {}).get('cross_couplings') or []
    if couplings:
        growth = _linear_growth(scene)
        if growth is not None and growth > 0:
            keys = ', '.join(f'structure.cross_couplings.{i}.kcc ({c["kcc"]:.4g} N/m)'
                             for i, c in enumerate(couplings))
            # the cause, whatever else the scene has
            return (f'the structure is linearly unstable (growth rate {growth:.3g} 1/s): '
                    f'lower {keys}')
    forcing = cfg.get('forcing') or []
    if forcing:
        j = max(range(len(forcing)), key=lambda i: forcing[i]['amplitude'])
        hints.append(f'forcing.{j}.amplitude ({forcing[j]["amplitude"]:.4g} N)')
    rotor = cfg.get('rotor') or {}
    if rotor.get('unbalance'):
        mult = rotor.get('multiplier', 1.0)
        hints.append(f'rotor.multiplier ({mult:.4g}) or rotor.unbalance[].amount')
    if cause is not None and 'chatter' in cause.what and cfg.get('impactors'):
        hints.append('impactors[].cor or simulation.dt (bounce-down chatter)')
    if not hints:
        hints.append('the stiffness and damping values (structure.*) and simulation.dt')
    return 'change ' + ', '.join(hints)


def _linear_growth(scene):
    """Largest real part of the scene's linear eigenvalues without impactors (1/s)."""
    try:
        from ..modal.stability import least_damped_eigenvalue
        return float(least_damped_eigenvalue(scene.basis.stiffness_matrix(),
                                             scene.basis.damping_matrix()).real)
    except Exception:   # advice only: a failure here must not hide the divergence
        return None


__all__ = ['Divergence', 'EXIT_DIVERGED', 'MAX_CACHE_BYTES', 'MAX_CACHED_CONFIGURATIONS',
           'MAX_DISPLACEMENT', 'MAX_IMPACTORS', 'MAX_SAMPLE_BYTES', 'MAX_TABLE_BYTES',
           'MAX_TABLE_SLOTS', 'ModelEstimate', 'ModelTooLarge', 'StudyDiverged', 'TooLarge',
           'cache_limit', 'check_allocation', 'check_model', 'check_samples', 'check_state',
           'configuration_bytes', 'from_engine_error', 'memory_limit', 'model_estimate',
           'sample_bytes', 'scene_advice']
