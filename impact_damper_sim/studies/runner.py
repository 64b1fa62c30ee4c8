"""Run independent study points in parallel through a ``concurrent.futures`` executor.

A :class:`Point` is a scene name, its ``key=value`` overrides, a seed and the parameters of
a *task*: a top-level function ``task(point) -> dict`` that builds the scene, simulates it and
measures what the study needs. Points share nothing, so they run in any order on any worker:

* ``'process'`` (default): :class:`~concurrent.futures.ProcessPoolExecutor`, one worker per
  CPU. Workers are started by ``forkserver`` (``spawn`` where unavailable), never ``fork``,
  so that threads of the parent (Dask, BLAS) cannot deadlock them.
* ``'serial'``: in this process, in order; for debugging (tracebacks, pdb).
* ``'dask'``: ``dask.distributed.Client(address).get_executor()``; without an address a local
  cluster is started. Dask is imported only then.

Results are deterministic: a point's result depends only on the point (its seed included),
never on the executor, the number of workers or the order of completion. A point that raises
is reported with its error message and the others are kept.
"""
from __future__ import annotations

import concurrent.futures as cf
import contextlib
import multiprocessing
import os
import sys
import time
import zlib
from dataclasses import dataclass, field

EXECUTORS = ('process', 'serial', 'dask')

__all__ = ['EXECUTORS', 'Point', 'PointResult', 'Progress', 'SerialExecutor', 'make_executor',
           'point_seed', 'run_points']


@dataclass(frozen=True)
class Point:
    """One independent run of a study.

    Attributes
    ----------
    task : callable
        Top-level (picklable) function ``task(point) -> dict`` of JSON-ready values.
    scene : str
        Scene name or path to a YAML file.
    overrides : tuple of str
        ``key=value`` scene overrides, applied in order (units allowed in values).
    seed : int
        Seed of the point's own random generator (``numpy.random.default_rng(seed)``), e.g.
        for an initial perturbation; tasks use no global random state.
    params : dict
        Task parameters (SI units).
    labels : dict
        What the study needs to place the result (e.g. ``{'frequency_ratio': 1.0}``); not
        used by the task.
    """

    task: object
    scene: str
    overrides: tuple = ()
    seed: int = 0
    params: dict = field(default_factory=dict)
    labels: dict = field(default_factory=dict)


@dataclass
class PointResult:
    """Outcome of one point.

    Attributes
    ----------
    point : Point
        The point.
    value : dict or None
        The task's result, None if it failed.
    error : str or None
        ``'<ExceptionType>: message'`` if the task failed.
    wall_time : float
        Wall-clock time of the task on its worker (s).
    """

    point: Point
    value: dict = None
    error: str = None
    wall_time: float = 0.0

    @property
    def ok(self):
        """bool: The task succeeded."""
        return self.error is None

    @property
    def diverged(self):
        """bool: The task failed because its run diverged (``Divergence``)."""
        return self.error is not None and self.error.startswith('Divergence:')


def point_seed(base_seed, key):
    """Return a seed derived from a base seed and a point's identity.

    The seed depends on the point's content, not on its position in the list, so adding or
    reordering points does not change the others' results.

    Parameters
    ----------
    base_seed : int
        The study's seed (``--seed``).
    key : str
        Identity of the point, e.g. its scene and overrides joined.

    Returns
    -------
    int
        Seed in ``[0, 2**63)``.
    """
    import numpy as np
    ss = np.random.SeedSequence([int(base_seed) & 0xFFFFFFFF, zlib.crc32(key.encode())])
    return int(ss.generate_state(1, dtype=np.uint64)[0] >> np.uint64(1))


def _execute(point):
    """Run one point on a worker; never raises (the error becomes the result).

    A :class:`~impact_damper_sim.integrate.divergence.Divergence` gets the point scene's advice
    (which setting to change) and its message starts with ``Divergence:``.
    """
    from ..integrate.divergence import Divergence
    start = time.perf_counter()
    try:
        value = point.task(point)
        error = None
    except Divergence as exc:
        value, error = None, _message(_advised(exc, point))
    except Exception as exc:   # a failing point must not take the study down
        value, error = None, _message(exc)
    return value, error, time.perf_counter() - start


def _advised(exc, point):
    if exc.setting:
        return exc
    from ..scene.advice import scene_advice
    try:
        from .measure import load_point
        return exc.with_setting(scene_advice(load_point(point), exc))
    except Exception:   # advice only
        return exc


def _message(exc):
    text = str(exc).strip() or repr(exc)
    return f'{type(exc).__name__}: {text}'


class SerialExecutor(cf.Executor):
    """Executor that runs each call at once, in this process (debugging, tiny studies)."""

    def submit(self, fn, /, *args, **kwargs):
        future = cf.Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except BaseException as exc:   # delivered through the future, like other executors
            future.set_exception(exc)
        return future


def _mp_context():
    methods = multiprocessing.get_all_start_methods()
    return multiprocessing.get_context('forkserver' if 'forkserver' in methods else 'spawn')


@contextlib.contextmanager
def make_executor(kind='process', workers=None, dask_address=None, n_tasks=None):
    """Open an executor for study points.

    Parameters
    ----------
    kind : {'process', 'serial', 'dask'}
        Executor kind (see the module docstring).
    workers : int, optional
        Worker processes (``'process'``; default the CPU count, at most ``n_tasks``) or
        workers of a local Dask cluster started when ``dask_address`` is None.
    dask_address : str, optional
        Scheduler address of a running Dask cluster (``'tcp://host:8786'``).
    n_tasks : int, optional
        Number of points, to avoid starting idle processes.

    Yields
    ------
    concurrent.futures.Executor
        Shut down (and its Dask client closed) on exit.
    """
    if kind not in EXECUTORS:
        raise ValueError(f"executor must be one of {', '.join(EXECUTORS)}, got {kind!r}")
    if workers is not None and int(workers) < 1:
        raise ValueError(f'workers must be >= 1, got {workers}')
    if kind == 'serial':
        yield SerialExecutor()
        return
    if kind == 'process':
        n = int(workers) if workers else (os.cpu_count() or 1)
        if n_tasks:
            n = max(1, min(n, int(n_tasks)))
        with cf.ProcessPoolExecutor(max_workers=n, mp_context=_mp_context()) as pool:
            yield pool
        return
    try:
        from dask.distributed import Client
    except ImportError as exc:
        raise ValueError(f'executor dask needs dask.distributed ({exc}); install '
                         "'dask[distributed]' or use --executor process") from None
    if dask_address:
        client = Client(dask_address)
    else:
        client = Client(n_workers=int(workers) if workers else None)
    try:
        with client.get_executor() as pool:
            yield pool
    finally:
        client.close()


class Progress:
    """A one-line progress bar on a text stream (no dependency).

    Parameters
    ----------
    total : int
        Number of points.
    stream : file, optional
        Default ``sys.stderr``.
    enabled : bool, optional
        Default: when the stream is a terminal.
    width : int
        Bar width (characters).
    """

    def __init__(self, total, stream=None, enabled=None, width=30):
        self.total = int(total)
        self.stream = sys.stderr if stream is None else stream
        if enabled is None:
            enabled = bool(getattr(self.stream, 'isatty', lambda: False)())
        self.enabled = enabled and self.total > 0
        self.width = width
        self.done = 0
        self.failed = 0
        self.start = time.perf_counter()

    def update(self, ok=True):
        """Count one finished point and redraw."""
        self.done += 1
        self.failed += 0 if ok else 1
        if not self.enabled:
            return
        frac = self.done / self.total
        fill = int(round(frac * self.width))
        elapsed = time.perf_counter() - self.start
        left = elapsed * (self.total - self.done) / self.done
        failed = f', {self.failed} failed' if self.failed else ''
        self.stream.write(f"\r[{'#' * fill}{'.' * (self.width - fill)}] {self.done}/"
                          f'{self.total}{failed}  {elapsed:5.0f} s, ~{left:.0f} s left ')
        if self.done == self.total:
            self.stream.write('\n')
        self.stream.flush()


def run_points(points, executor='process', *, workers=None, dask_address=None, progress=None):
    """Run study points and return their results in the points' order.

    Parameters
    ----------
    points : sequence of Point
        Independent points.
    executor : {'process', 'serial', 'dask'} or concurrent.futures.Executor
        Where to run them; an executor instance is used as is (and not shut down).
    workers : int, optional
        See :func:`make_executor`.
    dask_address : str, optional
        See :func:`make_executor`.
    progress : bool, optional
        Draw a progress bar on stderr; default when stderr is a terminal.

    Returns
    -------
    list of PointResult
        One per point, same order. A failed point has ``error`` set and ``value`` None; a
        worker that dies (e.g. out of memory) fails the points it had not returned.
    """
    points = list(points)
    results = [PointResult(p) for p in points]
    bar = Progress(len(points), enabled=progress)
    if isinstance(executor, cf.Executor):
        ctx = contextlib.nullcontext(executor)
    else:
        ctx = make_executor(executor, workers, dask_address, n_tasks=len(points))
    with ctx as pool:
        futures = {pool.submit(_execute, p): i for i, p in enumerate(points)}
        for future in cf.as_completed(futures):
            i = futures[future]
            try:
                value, error, wall = future.result()
            except Exception as exc:   # the worker itself failed (died, unpicklable, ...)
                value, error, wall = None, _message(exc), 0.0
            results[i].value, results[i].error, results[i].wall_time = value, error, wall
            bar.update(error is None)
    return results
