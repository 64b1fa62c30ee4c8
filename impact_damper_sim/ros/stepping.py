"""The stepping loop of ``vibration_node``: one thread that steps one machine, or several.

A :class:`~.vibration_node.VibrationNode` steps its simulation and sends what is due in its
``_cycle``, which returns how long it may wait. On its own, a node runs that cycle in a
thread of its own (``vibration_stepping``). In ``plant_host`` one :class:`SharedStepping`
thread runs the cycles of all the process's machines in turn and sleeps once for all of
them: the machines' sends and chunks then share its wake-ups and run on warm caches, where
threads of their own would each wake on their own and wait for the interpreter lock. A send
after a sleep costs several times one sent back to back (a raw ``Imu`` send on a 2-core VM:
3 us back to back and 16 us after a 4 ms sleep with no reader, 10 and 34 us with two;
docs/bench/send-cost.md).
"""
from __future__ import annotations

import math
import threading
import time

from ..live.pacing import Outbox

#: a wait longer than this (s) is an Event wait that a parameter change can end; a shorter
#: one a plain sleep (cheaper than Event.wait at a few kHz)
LONG_WAIT = 0.05
#: cycles between two checks that the ROS context is still up (a C call: not every cycle)
CONTEXT_EVERY = 64


def wait_for(delay, wake, longest):
    """Wait ``delay`` s (at most ``longest``); a wait over :data:`LONG_WAIT` ends early when
    ``wake`` (threading.Event) is set, and clears it. ``delay`` <= 0 or NaN: no wait."""
    if not delay > 0:   # 0, or NaN from a degenerate schedule
        return
    if delay > LONG_WAIT:
        if wake.wait(min(delay, longest)):
            wake.clear()
    else:
        time.sleep(delay)


class SharedStepping:
    """One stepping thread for several machines of one process.

    Each turn of the loop runs every member's cycle once (its sends due now, and a refill
    of chunks when its buffer runs short), then waits the shortest wait any member asked
    for. A member's stop (:meth:`remove`) takes effect between turns; the thread ends when
    the last member has left.

    Parameters
    ----------
    longest : float
        Longest single wait (s): members re-read their schedules at least this often.

    Attributes
    ----------
    wake : threading.Event
        Ends a long wait: each member's ``_wake`` (a parameter change, a stop).
    thread : threading.Thread
        The stepping thread (named ``vibration_stepping``, as a node's own).
    """

    def __init__(self, longest=0.5):
        self.longest = float(longest)
        self.wake = threading.Event()
        self._members = ()
        # held while the loop is inside its members' cycles: remove() waits for it, so a
        # removed member is never cycled again
        self._turns = threading.Lock()
        self.thread = threading.Thread(target=self._run, name='vibration_stepping',
                                       daemon=True)

    @property
    def members(self):
        """tuple: The machines stepped now."""
        return self._members

    def add(self, node):
        """Step ``node`` (a VibrationNode) from the next turn on (from :meth:`start` on, if
        the thread has not started); the chunks it should step at once to take its
        refill phase (:meth:`phase`), int."""
        with self._turns:
            if node not in self._members:
                self._members += (node,)
            phase = self.phase(node)
        self.wake.set()
        return phase

    def phase(self, node):
        """Chunks (0 to ``Outbox.REFILL``) member ``node`` steps ahead at its start, so
        that the members refill in turn, not all in one turn.

        A member refills ``Outbox.REFILL`` + 1 chunks back to back when its stepped time
        comes within a chunk of its schedule. Machines started together would refill in
        the same turn, and the last one's sends would wait for all their chunks (five
        hpotp machines: some 40 ms, a 1 s window of 0.96 followed by one of 1.04). Each
        chunk stepped ahead at the start moves a member's refills a chunk later, for
        good: member ``k`` gets ``k`` modulo ``Outbox.REFILL`` + 1."""
        return self._members.index(node) % (Outbox.REFILL + 1)

    def start(self):
        """Start the thread (idempotent): each member's schedule began at its own start,
        so start this once every member of the first batch is added."""
        if self.thread.ident is None:
            self.thread.start()

    def remove(self, node, timeout):
        """Stop stepping ``node``, waiting at most ``timeout`` s for the turn under way.

        Returns
        -------
        bool
            True once the loop will not cycle ``node`` again; False when the turn under
            way did not end in time (a member stuck inside its cycle).
        """
        if not self._turns.acquire(timeout=timeout):
            return False
        try:
            self._members = tuple(m for m in self._members if m is not node)
        finally:
            self._turns.release()
        self.wake.set()
        return True

    def send_others(self, node):
        """Between two chunks of ``node``'s refill: every other member sends what is due
        now, so that no machine's samples wait for another's whole refill (some 15-20 ms
        for hpotp's five chunks on this 2-core VM: a 1 s window of 0.98 followed by one of
        1.02). A member whose send fails is left to its own turn, which meets the same
        failure and reports it as that member's."""
        for other in self._members:
            if other is not node:
                try:
                    other._send_due(other._wall())
                except Exception:   # reported by its own turn, not by this one
                    continue

    def _run(self):
        turns = 0
        while True:
            with self._turns:
                members = self._members
                if not members:
                    return
                turns += 1
                check_context = turns % CONTEXT_EVERY == 0
                delay = math.inf
                for node in members:
                    wait = node._turn(check_context)
                    if wait is None:   # stopped, or its context is gone
                        self._members = tuple(m for m in self._members if m is not node)
                    elif wait < delay or not wait == wait:
                        delay = wait
            wait_for(delay, self.wake, self.longest)


__all__ = ['CONTEXT_EVERY', 'LONG_WAIT', 'SharedStepping', 'wait_for']
