"""The node's hand-off lock: the stepping thread yields it between chunks to waiters."""
from __future__ import annotations

import threading
import time


class HandoffLock:
    """A re-entrant lock that the stepping thread hands over when someone waits for it.

    Python locks are not fair: a thread that releases a lock and takes it again at once
    keeps winning, and stepping flat out (``real_time_factor`` 0) would starve commands and
    diagnostics. Waiters are counted; :meth:`hand_over`, called by the stepper between
    chunks, pauses 0.5 ms when anyone waits.

    Attributes
    ----------
    stepper : threading.RLock
        The same lock for the stepper itself, taken without counting it as a waiter (only
        others' waits make :meth:`hand_over` pause): ``with lock.stepper:`` runs no Python,
        a few microseconds less at each of its some 500 acquisitions a second.
    """

    def __init__(self):
        self._lock = threading.RLock()
        self.stepper = self._lock
        self.waiting = 0

    def __enter__(self):
        self.waiting += 1
        try:
            self._lock.acquire()
        finally:   # an interrupted wait leaves no waiter counted for ever
            self.waiting -= 1
        return self

    def __exit__(self, *exc_info):
        self._lock.release()

    def acquire(self, timeout):
        """Take the lock, waiting at most ``timeout`` s; True when taken (release it)."""
        self.waiting += 1
        try:
            return self._lock.acquire(timeout=timeout)
        finally:
            self.waiting -= 1

    def release(self):
        """Release a lock taken with :meth:`acquire`."""
        self._lock.release()

    def hand_over(self):
        """Let a waiting thread take the lock (call with the lock released)."""
        if self.waiting > 0:
            time.sleep(0.0005)


__all__ = ['HandoffLock']
