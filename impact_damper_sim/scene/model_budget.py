"""The model-size budget of a scene: what its model will allocate, before anything is built.

:func:`model_estimate` counts, from the validated scene, what the model will allocate (DOFs,
modes, impactors, stuck configurations); :func:`check_model` refuses a scene over
:func:`~impact_damper_sim.integrate.memory.memory_limit` or with more than
:data:`MAX_IMPACTORS` impactors (:class:`ModelTooLarge`: the estimate, the limit and the scene
keys to change, in one line). The engine's own budgets (sample arrays, the stuck
configurations it keeps) are :mod:`impact_damper_sim.integrate.memory`.
"""
from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

from ..integrate import memory
from ..integrate.memory import (
    MAX_CACHED_CONFIGURATIONS,
    MAX_TABLE_BYTES,
    MAX_TABLE_SLOTS,
    cache_limit,
    configuration_bytes,
    gib,
)

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

    def __init__(self, estimate: ModelEstimate, limit: int) -> None:
        self.estimate, self.limit = estimate, int(limit)
        if estimate.n_impactors > MAX_IMPACTORS:
            text = (f"scene key 'impactors': {estimate.n_impactors:,} impactors, over the "
                    f'limit of {MAX_IMPACTORS:,} (each costs time every step and memory in '
                    f'every stuck configuration; model estimate {gib(estimate.total)}): '
                    'use fewer impactors')
        else:
            text = (f'model too large: {estimate.describe()} would need about '
                    f'{gib(estimate.total)} of memory (limit {gib(self.limit)}): '
                    f'{estimate.advice()}')
        super().__init__(text)


class ModelEstimate:
    """What a scene's model allocates, estimated from the validated scene (bytes).

    Build it with :func:`model_estimate`. Attributes: ``n_nodes``, ``n_dof`` (6 per node,
    an upper bound on the active DOFs), ``n_modes`` (``modal.n_modes``, or ``n_dof`` when
    the modes are chosen by frequency), ``n_impactors``, ``n_configurations`` (stuck
    configurations the run may hold at once), ``stuck_model`` and ``terms`` (bytes by
    kind: ``dofs``, ``modes``, ``impactors``, ``configurations``); ``total`` their sum.
    """

    # set from the keyword arguments of __init__ (see the class docstring)
    n_nodes: int
    n_dof: int
    n_modes: int
    n_impactors: int
    n_configurations: int
    stuck_model: str
    terms: dict[str, int]

    def __init__(self, **fields: object) -> None:
        self.__dict__.update(fields)
        self.total = int(sum(self.terms.values()))

    def describe(self) -> str:
        """The sizes, largest term first, e.g. ``'10,000 impactors, 4,096 stuck ...'``."""
        def count(n: int, what: str) -> str:
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

    def advice(self) -> str:
        """Which keys to change, for the largest term."""
        top = max(self.terms, key=self.terms.__getitem__)
        if top == 'dofs':
            return ('use fewer nodes (structure.lines[].n_elements, structure.nodes)')
        if top == 'modes':
            return 'retain fewer modes (modal.n_modes, modal.f_max, modal.cutoff)'
        return 'use fewer impactors (impactors) or fewer modes (modal.n_modes)'

    def __repr__(self) -> str:
        return f'ModelEstimate({self.describe()}: {self.total} bytes)'


def _impactor_groups(impactors: Iterable[Mapping[str, Any]]) -> list[int]:
    """Sizes of the groups of interchangeable impactors (same housing and mass), as
    :func:`impact_damper_sim.integrate.exact._interchangeable_groups` finds them in the
    built model, approximated from the scene entries."""
    sizes: dict[tuple[object, ...], int] = {}
    for imp in impactors:
        where = (imp.get('node'), imp.get('kind'), imp.get('dof'),
                 tuple(imp.get('plane') or ()))
        mass = (imp.get('mass'), imp.get('mass_ratio'), imp.get('housing_mass'))
        sizes[(where, mass)] = sizes.get((where, mass), 0) + 1
    return list(sizes.values())


def model_estimate(scene: Mapping[str, Any]) -> ModelEstimate:
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


def check_model(scene: Mapping[str, Any], limit: int | None = None) -> ModelEstimate:

    """Refuse a scene whose model would not fit in memory, before building it.

    Parameters
    ----------
    scene : dict
        A validated scene (SI units).
    limit : int, optional
        Bytes; default :func:`~impact_damper_sim.integrate.memory.memory_limit`.

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
    limit = memory.memory_limit() if limit is None else int(limit)
    estimate = model_estimate(scene)
    if estimate.total > limit or estimate.n_impactors > MAX_IMPACTORS:
        raise ModelTooLarge(estimate, limit)
    return estimate


__all__ = ['DENSE_BYTES_PER_DOF2', 'IMPACTOR_BYTES', 'MAX_IMPACTORS', 'ModelEstimate',
           'ModelTooLarge', 'check_model', 'model_estimate']
