"""A node process's life: guarded spinning, the start-up heap, interrupts and shutdown.

:func:`spin_guarded`, :func:`settle_interrupt` and :func:`shutdown_quietly` spin and end a
``main`` without racing rclpy's own SIGINT handler, which shuts the context down on another
thread; :func:`ignore_further_interrupts` keeps a second SIGINT from interrupting the
clean-up; :func:`freeze_start_up_heap` keeps the collector off the start-up objects.
"""
from __future__ import annotations

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
    import signal
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
    import rclpy
    from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
    try:
        rclpy.try_shutdown(context=context)
    except _rclpy.RCLError:
        if (context or rclpy.get_default_context()).ok():
            raise   # a failure of our own, not the handler's shutdown


__all__ = ['freeze_start_up_heap', 'ignore_further_interrupts', 'settle_interrupt',
           'shutdown_quietly', 'spin_guarded']
