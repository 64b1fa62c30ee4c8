"""A node process's life: guarded spinning, the start-up heap, interrupts and shutdown.

:class:`SignalStop` turns SIGINT, SIGTERM and SIGHUP into a flag and a shut-down context,
never into an exception in the middle of a callback; :func:`spin_guarded`,
:func:`settle_interrupt` and :func:`shutdown_quietly` spin and end a ``main`` without racing
rclpy's own handler, which shuts the context down on another thread;
:func:`ignore_further_interrupts` keeps a second SIGINT from interrupting the clean-up;
:func:`thread_stack` and :func:`report_a_stuck_clean_up` say where a thread that will not
stop is; :func:`freeze_start_up_heap` keeps the collector off the start-up objects.
"""
from __future__ import annotations

import signal
import sys
import time


def spin_guarded(executor, report):
    """Spin ``executor`` until shutdown; a callback that raises is reported, not fatal.

    Any process on the domain can send a malformed message or request, so no exception from a
    callback may stop the node; Ctrl-C and an external shutdown still end the loop (raised to
    the caller).

    Parameters
    ----------
    executor : rclpy.executors.Executor
        With the node added.
    report : callable
        Called with the exception (e.g. a throttled error log).
    """
    from rclpy.executors import ExternalShutdownException
    while executor.context.ok():
        try:
            executor.spin_once(timeout_sec=0.5)
        except (KeyboardInterrupt, ExternalShutdownException):
            raise
        except Exception as exc:   # a malformed message or request must not stop the node
            if not executor.context.ok():
                # Ctrl-C shut the context down under the wait ("context is not valid")
                raise ExternalShutdownException() from exc
            report(exc)


class SignalStop:
    """Ends a node process's ``main`` on SIGINT, SIGTERM or SIGHUP without raising in the
    middle of a running node's callback.

    Python's default SIGINT handler raises ``KeyboardInterrupt`` at whatever bytecode the
    main thread runs next. Raised just after a callback took the node's lock and before the
    ``try`` that releases it, it leaked the lock: the stepping thread waited for it for ever,
    ``destroy_node`` waited for the stepping thread, and ``ros2 launch`` had to SIGKILL the
    node 15 s later (once in CI, a two-machine plant). It happens when the signal reaches
    another thread while the main thread waits for the lock, so the wait goes on, succeeds,
    and the pending interrupt is raised one bytecode later.

    Construct it before ``rclpy.init``: rclpy's handlers (SIGINT and SIGTERM: they shut the
    context down and wake the executor's wait) then chain to these. While the node is being
    built SIGINT still raises ``KeyboardInterrupt``, so Ctrl-C cuts a long start-up (a cold
    kernel cache) short; no lock is shared yet. Call :meth:`begin_running` before the
    stepping thread starts: from then on a signal is only noted, and the spin ends with
    ``ExternalShutdownException``, as it always did on SIGTERM. SIGHUP (a closed terminal) is
    raised again as SIGTERM, so it ends the node the same way.

    Attributes
    ----------
    signum : int or None
        The first signal received (SIGINT, SIGTERM), or None.
    """

    def __init__(self):
        self.signum = None
        self._interrupt = True
        signal.signal(signal.SIGINT, self._note)
        signal.signal(signal.SIGTERM, self._note)
        signal.signal(signal.SIGHUP, lambda *_: signal.raise_signal(signal.SIGTERM))

    def _note(self, signum, frame):
        if self.signum is None:
            self.signum = signum
        if self._interrupt and signum == signal.SIGINT:
            raise KeyboardInterrupt

    def begin_running(self):
        """From now on only note a signal (the node's threads and callbacks start next);
        raise ``ExternalShutdownException`` if one came while the node was built (SIGTERM,
        or a SIGINT caught by start-up code): the spin that follows would not see it."""
        from rclpy.executors import ExternalShutdownException
        self._interrupt = False
        if self.received:
            raise ExternalShutdownException()

    @property
    def received(self):
        """True once a stop signal arrived."""
        return self.signum is not None

    def begin_clean_up(self):
        """Start a ``main``'s clean-up (its ``finally``): report it if it hangs
        (:func:`report_a_stuck_clean_up`, cancelled by :func:`shutdown_quietly`); after a
        signal, ignore further SIGINTs and let rclpy's handler finish its shutdown first."""
        report_a_stuck_clean_up()
        if self.received:
            ignore_further_interrupts()
            settle_interrupt()


def report_a_stuck_clean_up(timeout_s=4.0):
    """Print every thread's stack to stderr if the clean-up that begins now still runs after
    ``timeout_s`` (s); :func:`shutdown_quietly` cancels it.

    ``ros2 launch`` sends SIGTERM 5 s after SIGINT and SIGKILL 10 s later, and a killed
    process says nothing about where it hung. ``faulthandler`` writes from a thread of its
    own, without the GIL, so it reports a deadlocked process too.
    """
    import faulthandler
    try:
        faulthandler.dump_traceback_later(timeout_s, exit=False, file=sys.__stderr__)
    except (AttributeError, OSError, ValueError):   # no stderr file (an embedding host)
        pass


def thread_stack(thread, limit=8):
    """The innermost ``limit`` frames of a running ``thread``, formatted (str), for a log
    that must say where a thread is stuck."""
    import traceback
    frame = sys._current_frames().get(thread.ident)
    if frame is None:
        return '  (no stack: the thread has ended)'
    return ''.join(traceback.format_stack(frame)[-limit:]).rstrip()


def freeze_start_up_heap():
    """Collect once, then move every object alive after start-up out of the garbage
    collector's reach (``gc.freeze``), before a node's paced work begins.

    A node's start-up leaves some 136,000 container objects (rclpy, NumPy, Numba, the
    model) that live as long as the process. Python's collector walks all of them in each
    full collection, and a full collection holds the GIL for about 150 ms on this 2-core
    machine: the stepping thread stood still for it and a 1 s window fell to 0.90 x real
    time. Frozen, they are never walked again; objects made afterwards are collected as
    usual. Call it from a ``main`` (a process entry point), not from a node's constructor:
    tests build many nodes in one process.

    Returns
    -------
    int
        Objects frozen (the permanent generation's count, dimensionless).
    """
    import gc
    gc.collect()
    gc.freeze()
    return gc.get_freeze_count()


def ignore_further_interrupts():
    """After the first Ctrl-C of a ``main``, ignore SIGINT while it cleans up.

    ``ros2 launch`` without a terminal signals the whole process group, so a node gets the
    launch's SIGINT and the group's: the second one interrupted ``destroy_node`` with a
    traceback (launch reported exit code -2); the first one already asked to stop.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def settle_interrupt(context=None, timeout_s=1.0):
    """After Ctrl-C, wait up to ``timeout_s`` (s) for rclpy's SIGINT handler to shut down.

    That handler shuts the context down on a thread of its own while the main thread gets
    ``KeyboardInterrupt``: tearing the nodes down, or calling ``try_shutdown``, at the same
    moment raced it (``rcl_shutdown already called``, 3 of 60 SIGINTs to ``replay`` with the
    cores loaded). Call this at the start of a ``main``'s clean-up when it was interrupted.
    """
    import rclpy
    context = context or rclpy.get_default_context()
    end = time.monotonic() + timeout_s
    while context.ok() and time.monotonic() < end:
        time.sleep(0.005)


def shutdown_quietly(context=None):
    """``rclpy.try_shutdown``, taking "already shut down" by the SIGINT handler as done."""
    import faulthandler

    import rclpy
    from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
    faulthandler.cancel_dump_traceback_later()   # the clean-up got this far
    try:
        rclpy.try_shutdown(context=context)
    except _rclpy.RCLError:
        if (context or rclpy.get_default_context()).ok():
            raise   # a failure of our own, not the handler's shutdown


__all__ = ['SignalStop', 'freeze_start_up_heap', 'ignore_further_interrupts',
           'report_a_stuck_clean_up', 'settle_interrupt', 'shutdown_quietly', 'spin_guarded',
           'thread_stack']
