"""Memory budgets of a run: the limits and the bytes the engine allocates, in one place.

:func:`memory_limit` is the budget of one run (bytes). :func:`check_allocation` refuses up
front a run whose sample arrays, with its model, would not fit (:class:`TooLarge`).
:func:`configuration_bytes` and :func:`cache_limit` size the stuck configurations the exact
propagator keeps (:mod:`impact_damper_sim.integrate.exact`); the ``MAX_*`` limits bound them.
What a scene's model will allocate, estimated before anything is built, is
:mod:`impact_damper_sim.scene.model_budget` (it reads the scene).

Pure Python: no NumPy, no rclpy.
"""
from __future__ import annotations

import os

#: Largest memory one run may allocate (bytes): its model
#: (:func:`impact_damper_sim.scene.model_budget.model_estimate`) plus the sample arrays of
#: one advance: 4 GiB, or half the physical memory if that is less (:func:`memory_limit`).
#: The interpreter with NumPy, SciPy and the compiled kernels, about 190 MB, comes on top.
MAX_SAMPLE_BYTES = 4 * 2 ** 30

#: Largest number of stuck configurations the exact propagator keeps as one table inside
#: its kernel (a table for every stuck count of every group of interchangeable impactors,
#: allocated at once); a model with more switches through Python
#: (:mod:`impact_damper_sim.integrate.exact`).
MAX_TABLE_SLOTS = 4096
#: ... and the largest such table (bytes, flows included, :func:`configuration_bytes` per
#: slot): 2,000 interchangeable impactors on one mode (2,001 slots of 0.96 MB) switch
#: through Python instead of allocating 1.8 GB.
MAX_TABLE_BYTES = 2 ** 30
#: Stuck configurations kept when switching through Python (a flow and a one-slot table
#: each): as many as fit in :data:`MAX_CACHE_BYTES`, at least this many (and at most
#: :data:`MAX_TABLE_SLOTS`), see :func:`cache_limit`; the least recently used is dropped
#: beyond and built again if reached again. With the basis-switch provider (a modal basis
#: each) this many. Without a bound 5,000 interchangeable impactors passed 2.4 GB in 1.2
#: simulated s (1,300 configurations of 1.7 MB).
MAX_CACHED_CONFIGURATIONS = 64
#: Memory of the configurations kept when switching through Python (bytes). 5,000
#: impactors over 0.8 simulated s (625 configurations): 121 s and 1.29 GB peak without a
#: bound, 189 s and 0.38 GB with 64 kept (rebuilt when reached again), 0.5 GiB about 300.
MAX_CACHE_BYTES = 2 ** 29


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
        What asked for them, e.g. ``'dt = 1e-09 s over 1 s'``.
    model_bytes : int, optional
        The model's estimate that shares the limit (bytes).
    advice : str, optional
        What to change, in the caller's words (e.g. its scene keys and options).
    """

    def __init__(self, n_steps: int, n_bytes: int, limit: int, context: str | None = None,
                 model_bytes: int = 0,
                 advice: str = 'use a longer time step or a shorter run') -> None:
        self.n_steps, self.n_bytes, self.limit = int(n_steps), int(n_bytes), int(limit)
        self.model_bytes = int(model_bytes)
        lead = f'{context}: ' if context else ''
        model = (f", with the model's {gib(self.model_bytes)}" if self.model_bytes else '')
        super().__init__(
            f'{lead}{self.n_steps:.4g} samples would need about {gib(self.n_bytes)} of memory '
            f'(limit {gib(self.limit)}{model}): {advice}')


def gib(n_bytes: float) -> str:
    """``n_bytes`` (bytes) as text in GiB, three significant digits, e.g. ``'4 GiB'``."""
    return f'{n_bytes / 2 ** 30:.3g} GiB'


def sample_bytes(n_steps: int, n_outputs: int) -> int:
    """Size of the sample arrays of ``n_steps`` samples of ``n_outputs`` sensors (bytes).

    Time plus displacement, velocity and acceleration per sensor, float64, and as much again
    for the mean acceleration and filtering done on them afterwards.
    """
    return 2 * 8 * int(n_steps) * (1 + 3 * int(n_outputs))


def memory_limit() -> int:
    """The allocation limit: :data:`MAX_SAMPLE_BYTES` or half the physical memory (bytes)."""
    try:
        physical = os.sysconf('SC_PAGE_SIZE') * os.sysconf('SC_PHYS_PAGES')
    except (AttributeError, ValueError, OSError):
        physical = 0
    return min(MAX_SAMPLE_BYTES, physical // 2) if physical > 0 else MAX_SAMPLE_BYTES


def configuration_bytes(n_modes: int, n_impactors: int, n_sensors: int = 0, n_inputs: int = 0,
                        n_harmonics: int = 1) -> int:
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


def cache_limit(per_configuration: int) -> int:
    """How many configurations of ``per_configuration`` bytes are kept when switching
    through Python: :data:`MAX_CACHE_BYTES` worth, between
    :data:`MAX_CACHED_CONFIGURATIONS` and :data:`MAX_TABLE_SLOTS` (int)."""
    fit = MAX_CACHE_BYTES // max(int(per_configuration), 1)
    return int(max(MAX_CACHED_CONFIGURATIONS, min(MAX_TABLE_SLOTS, fit)))


def check_allocation(n_steps: int, n_outputs: int, limit: int | None = None,
                     model_bytes: int = 0) -> None:

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
        The model's estimate (bytes,
        :func:`impact_damper_sim.scene.model_budget.model_estimate`), which shares the limit.

    Raises
    ------
    TooLarge
        With the estimate.
    """
    limit = memory_limit() if limit is None else int(limit)
    need = sample_bytes(n_steps, n_outputs)
    if need + int(model_bytes) > limit:
        raise TooLarge(n_steps, need, limit, model_bytes=model_bytes)


__all__ = ['MAX_CACHE_BYTES', 'MAX_CACHED_CONFIGURATIONS', 'MAX_SAMPLE_BYTES',
           'MAX_TABLE_BYTES', 'MAX_TABLE_SLOTS', 'TooLarge', 'cache_limit', 'check_allocation',
           'configuration_bytes', 'gib', 'memory_limit', 'sample_bytes']
