"""The worker processes of ``study dataset``: none outlives the command, whatever ends it.

A data set may run for hours on a pool of processes. If the command is killed, its workers
must not go on recording runs into files no manifest lists (issue 35: with the study
runner's ``forkserver`` pool a SIGKILL left the fork server, the resource tracker and the
workers running, parent 1, until they had finished every queued run). So:

* :func:`process_pool` starts the workers with ``spawn``, as direct children of the command
  (a fork server would be their parent, and it lives as long as they do: they hold its
  liveness pipe);
* each worker asks the kernel for SIGKILL when its parent dies
  (``prctl(PR_SET_PDEATHSIG)``, Linux; elsewhere a thread polls ``os.getppid()`` every
  0.2 s), and checks that the parent is still the command after asking, so a parent that
  died in between is not missed. The resource tracker exits by itself once the command and
  its workers are gone (its pipe reaches end of file);
* :func:`catch_signals` turns SIGTERM and SIGHUP (and SIGINT's ``KeyboardInterrupt``) into
  :class:`Interrupted`, so that the command stops its workers at once
  (:func:`stop_workers`), removes their unfinished logs and says what is kept. Workers
  ignore SIGINT: a Ctrl-C reaches the whole process group, and the command decides.

Measured (``test/test_abuse_disk.py``, 2 workers recording): no process of the command's
session is left about 0.1 s after a SIGKILL of the command, and none after SIGTERM or SIGINT
once the command has exited.
"""
from __future__ import annotations

import concurrent.futures as cf
import contextlib
import multiprocessing
import os
import signal
import sys
import threading

#: ``prctl`` option: the signal a process gets when its parent dies (linux/prctl.h)
PR_SET_PDEATHSIG = 1
#: How often (s) a worker without ``prctl`` looks whether its parent is still there.
PARENT_POLL = 0.2


class Interrupted(BaseException):
    """The command got SIGINT, SIGTERM or SIGHUP (a ``BaseException``, as
    ``KeyboardInterrupt``: no ``except Exception`` of a run swallows it).

    Parameters
    ----------
    signum : int
        The signal.
    detail : str, optional
        What is kept, one line (``str()`` is ``interrupted by SIGTERM: <detail>``).
    """

    def __init__(self, signum, detail=''):
        super().__init__(signum, detail)
        self.signum, self.detail = signum, detail

    @property
    def name(self):
        """str: ``SIGTERM``, ..."""
        return signal.Signals(self.signum).name

    @property
    def exit_status(self):
        """int: The shell's status of a command ended by the signal (128 + its number)."""
        return 128 + int(self.signum)

    def __str__(self):
        return f'interrupted by {self.name}' + (f': {self.detail}' if self.detail else '')


@contextlib.contextmanager
def catch_signals():
    """Raise :class:`Interrupted` in the main thread on SIGTERM, SIGHUP and SIGINT.

    Outside the main thread (where Python cannot set handlers) it does nothing. The old
    handlers come back on exit.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum, frame):
        raise Interrupted(signum)

    old = {}
    for sig in (signal.SIGTERM, signal.SIGHUP, signal.SIGINT):
        with contextlib.suppress(ValueError, OSError):
            old[sig] = signal.signal(sig, interrupt)
    try:
        yield
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)


@contextlib.contextmanager
def ignoring_signals():
    """Ignore SIGTERM, SIGHUP and SIGINT for a while (the clean-up after the first one)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = {}
    for sig in (signal.SIGTERM, signal.SIGHUP, signal.SIGINT):
        with contextlib.suppress(ValueError, OSError):
            old[sig] = signal.signal(sig, signal.SIG_IGN)
    try:
        yield
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)


def die_with_parent(parent):
    """Make this process end when ``parent`` (its parent's pid) does.

    Parameters
    ----------
    parent : int
        The pid of the process that started this one.
    """
    if sys.platform.startswith('linux'):
        try:
            import ctypes
            libc = ctypes.CDLL(None, use_errno=True)
            if libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0) == 0:
                if os.getppid() != parent:   # it died before the request
                    os.kill(os.getpid(), signal.SIGKILL)
                return
        except (OSError, AttributeError):   # no libc prctl: poll below
            pass
    threading.Thread(target=_watch_parent, args=(parent,), name='parent-watch',
                     daemon=True).start()


def _watch_parent(parent):
    import time
    while os.getppid() == parent:
        time.sleep(PARENT_POLL)
    os.kill(os.getpid(), signal.SIGKILL)


def _worker_start(parent):
    """Pool initializer: SIGINT is the command's to handle; die with the command."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    die_with_parent(parent)


def process_pool(workers, n_tasks):
    """A process pool whose workers end with this process (see the module docstring).

    Parameters
    ----------
    workers : int or None
        Worker processes; default the CPU count.
    n_tasks : int
        Runs to do (no more workers than that are started).

    Returns
    -------
    tuple of (concurrent.futures.ProcessPoolExecutor, int)
        The pool and its number of workers.
    """
    n = int(workers) if workers else (os.cpu_count() or 1)
    n = max(1, min(n, int(n_tasks)))
    pool = cf.ProcessPoolExecutor(max_workers=n, mp_context=multiprocessing.get_context('spawn'),
                                  initializer=_worker_start, initargs=(os.getpid(),))
    return pool, n


def stop_workers(pool):
    """Kill a process pool's workers now and shut it down (runs in progress are lost).

    Parameters
    ----------
    pool : concurrent.futures.Executor
        A :func:`process_pool` (another executor is shut down without waiting, its queued
        calls cancelled).
    """
    # ProcessPoolExecutor has no public way to end running calls before Python 3.14
    processes = list((getattr(pool, '_processes', None) or {}).values())
    for process in processes:
        with contextlib.suppress(OSError, ValueError, AttributeError):
            process.kill()
    for process in processes:
        with contextlib.suppress(OSError, ValueError, AttributeError):
            process.join(5.0)
    try:
        pool.shutdown(wait=False, cancel_futures=True)
    except TypeError:   # an executor without cancel_futures
        pool.shutdown(wait=False)


def run_all(task, out_dir, runs, state, *, executor='process', workers=None,
            dask_address=None):
    """Run ``task(run, out_dir)`` for each run, a few at a time, until done or stopped.

    Parameters
    ----------
    task : callable
        A top-level function (it is pickled to the workers) returning a run's row.
    out_dir : str
        Its second argument (absolute).
    runs : list of dict
        The runs to do, in order.
    state : object
        ``add(run, row)`` after each run; ``stopped`` (not None: start no new run);
        ``not_started`` (set here); ``discard(run)`` for a run stopped by a signal;
        ``save()``; ``interrupted(signum, n_in_progress)``, the exception to raise then.
    executor : {'process', 'serial', 'dask'}
        ``process``: :func:`process_pool`; the others from :func:`.runner.make_executor`.
    workers : int, optional
        Worker processes.
    dask_address : str, optional
        A Dask scheduler.

    Raises
    ------
    Interrupted
        From ``state.interrupted`` on SIGINT, SIGTERM, SIGHUP (under :func:`catch_signals`),
        after the workers were killed and ``state`` saved.
    """
    from .runner import make_executor
    if executor == 'process':
        if workers is not None and int(workers) < 1:
            raise ValueError(f'workers must be >= 1, got {workers}')
        pool, window = process_pool(workers, len(runs))
        context = pool   # shut down (waiting for its workers) on leaving
    else:   # serial runs each call in submit: one at a time; dask: the cluster queues them
        window = 1 if executor == 'serial' else len(runs)
        context = make_executor(executor, workers, dask_address, n_tasks=len(runs))
    pending = {}   # future -> run
    queue = iter(runs)
    cancelled = 0
    with context as pool:
        # inside the with: leaving it waits for the workers, so they are killed first
        try:
            while True:
                # no new run after a disk error: it would fail the same way
                while state.stopped is None and len(pending) < window:
                    run = next(queue, None)
                    if run is None:
                        break
                    pending[pool.submit(task, run, out_dir)] = run
                if not pending:
                    break
                done, _ = cf.wait(list(pending), timeout=0.5, return_when=cf.FIRST_COMPLETED)
                for future in done:
                    run = pending.pop(future)
                    if future.cancelled():
                        cancelled += 1
                        continue
                    try:
                        row = future.result()
                    except Exception as exc:   # a worker that died: this run failed
                        row = {'id': run['id'], 'status': 'failed',
                               'error': f'{type(exc).__name__}: {exc}'.splitlines()[0]}
                    state.add(run, row)
                    if state.stopped is not None:   # queued, not started: not to start
                        for other in pending:
                            other.cancel()
            state.not_started = cancelled + sum(1 for _ in queue)
        except (Interrupted, KeyboardInterrupt) as exc:
            with ignoring_signals():   # a second Ctrl-C must not cut the clean-up short
                stop_workers(pool)
                for run in pending.values():
                    state.discard(run)
                state.save()
            raise state.interrupted(getattr(exc, 'signum', signal.SIGINT),
                                    len(pending)) from None


__all__ = ['Interrupted', 'PARENT_POLL', 'PR_SET_PDEATHSIG', 'catch_signals', 'die_with_parent',
           'ignoring_signals', 'process_pool', 'run_all', 'stop_workers']
