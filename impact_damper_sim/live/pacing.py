"""Pacing and delivery: when to step, what to send per wake-up, catch-up and deficits.

ROS-free, on an injected wall clock, so the rules are tested with plain Python
(test/test_pacing.py) and the node only carries them out.

* :class:`Pacer` maps wall time to sim time for a real-time factor and drops a deficit
  longer than ``max_lag``.
* :class:`Outbox` holds the items stepped ahead of their time, in time order, and decides
  which leave at a wake-up (at most ``early`` before their time, in small groups when a
  backlog built up), when the next chunk is stepped and how long the thread sleeps.

Items are ``(ns, key, payload, wire)``: sim time (ns), an opaque key (the node's outlet),
the payload and whether anybody receives it (an item nobody receives does not wait for its
time). The outbox never looks inside a key or payload; the caller's ``send`` does.
"""
from __future__ import annotations

import collections
import math
import time
from collections.abc import Callable, Hashable, Iterable
from typing import NamedTuple


class PacingError(ValueError):
    """A pacing setting out of range; the message names the quantity and its range."""


class Pacer:
    """Maps wall time to the sim time the simulation should have reached.

    Sim time advances with wall time x ``real_time_factor``; 0 means as fast as possible.
    When the simulation falls more than ``max_lag`` (wall s) behind, the deficit is dropped
    from the schedule (the physics is not skipped: the simulation just runs slower than
    asked, and the node reports it), so it does not race afterwards.

    Parameters
    ----------
    real_time_factor : float
        Sim seconds per wall second (dimensionless), >= 0.
    t_sim : float
        Sim time now (s).
    max_lag : float
        Largest schedule deficit kept (wall s).
    clock : callable
        Wall clock (s), ``time.monotonic`` by default.
    """

    def __init__(self, real_time_factor: float, t_sim: float, *, max_lag: float = 0.25,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self._clock = clock
        self.max_lag = float(max_lag)
        self.deficits = 0
        self.reset(real_time_factor, t_sim)

    def reset(self, real_time_factor: float, t_sim: float) -> None:
        """Restart the schedule at sim time ``t_sim`` (s) with a new factor.

        Raises
        ------
        PacingError
            The factor is not finite or is negative; nothing changes.
        """
        rtf = float(real_time_factor)
        if not (math.isfinite(rtf) and rtf >= 0):
            raise PacingError(f'real-time factor: must be finite and >= 0, got {rtf}')
        self.real_time_factor = rtf
        self._wall0 = self._clock()
        self._sim0 = float(t_sim)

    def wall_at(self, t_sim: float) -> float:
        """Wall time (s) at which sim time ``t_sim`` (s) is due; -inf as fast as possible."""
        if self.real_time_factor == 0:
            return -math.inf
        return self._wall0 + (t_sim - self._sim0) / self.real_time_factor

    def sim_at(self, wall: float) -> float:
        """Sim time (s) due at wall time ``wall`` (s), the inverse of :meth:`wall_at`; inf as
        fast as possible (no deficit is dropped here)."""
        if self.real_time_factor == 0:
            return math.inf
        return self._sim0 + (wall - self._wall0) * self.real_time_factor

    def target(self, t_sim: float) -> tuple[float, float]:
        """Sim time to reach now (s), given the current sim time ``t_sim`` (s); inf if 0.

        Returns
        -------
        target : float
            Sim time (s).
        lag : float
            How far the simulation is behind the schedule (wall s), before any deficit is
            dropped.
        """
        if self.real_time_factor == 0:
            return math.inf, 0.0
        now = self._clock()
        target = self._sim0 + (now - self._wall0) * self.real_time_factor
        lag = (target - t_sim) / self.real_time_factor
        if lag > self.max_lag:
            # drop the deficit: re-anchor so the schedule is max_lag ahead of the simulation
            self.deficits += 1
            self._sim0 = t_sim + self.max_lag * self.real_time_factor
            self._wall0 = now
            target = self._sim0
        return target, lag


class Plan(NamedTuple):
    """What :meth:`Outbox.plan` decided."""

    #: chunks to step now, back to back (0: none)
    chunks: int
    #: the first of them is a whole chunk behind schedule
    late: bool
    #: the stream's lag before any deficit was dropped (wall s)
    lag: float

    @property
    def step(self) -> bool:
        """bool: Step now (``chunks`` > 0)."""
        return self.chunks > 0

#: ``send(ns, key, payload, wire)``: publishes one queued item
SendFn = Callable[[int, Hashable, object, bool], object]



class Outbox:
    """Items stepped ahead of their time, and the rules for sending them and stepping more.

    Parameters
    ----------
    pacer : Pacer
        The schedule (its clock is the outbox's).
    imu_rate : float
        Rate of the per-sample stream (Hz): bursts are counted in its samples.
    lookahead : float
        How far stepping runs ahead of the schedule (wall s at factor 1).
    chunk : float
        Sim time of one stepped chunk (s).
    t_sim : float
        Sim time now (s): nothing is published before it.
    limited : iterable
        Keys of the per-sample streams whose sends per wake-up are limited (one
        accelerometer each).
    group : int
        Imu samples per accelerometer a paced wake-up sends (dimensionless), 1 to
        :attr:`MAX_BURST`; default :attr:`GROUP`.

    Raises
    ------
    PacingError
        ``group`` out of range.
    """

    #: Imu samples per accelerometer one paced wake-up sends, by default (the node's
    #: ``imu_group``): 4 every 4 ms at 1 kHz. Each wake-up costs the node its loop, a sleep
    #: and cold caches: groups of 4 instead of pairs (GROUP 2) halve the wake-ups and cut
    #: the node on hpotp by about 1.5-2 points of a core (bench/node_cost.py, paired),
    #: every stamp unchanged; up to MAX_BURST, so a keep-last-5 reader holds a whole group
    GROUP = 4
    #: how early (wall s) an item may leave with the one due before it, at most, beyond
    #: ``group - 1`` ms: 0.2 ms for single samples, 1.2 ms for pairs, 3.2 ms for groups of 4
    EARLY_MARGIN = 2e-4
    #: wall time (s) between the wake-ups that send a backlog (twice the sample rate or more)
    #: wall time (s) between the wake-ups that send a backlog (twice the sample rate or more)
    CATCH_UP = 5e-4
    #: a backlog leaves at up to this many times the Imu rate, counted over the wall time
    #: since the previous wake-up: on a busy core a wake-up takes 1-3 ms, not CATCH_UP, and a
    #: fixed group per wake-up then drained a 35 ms backlog in 0.6 s (measured)
    CATCH_UP_RATE = 4.0
    #: ... in groups of at most this many samples per accelerometer (keep-last-5 readers);
    #: also the largest ``group``
    MAX_BURST = 4
    #: chunks stepped beyond ``lookahead`` once stepping starts, back to back in one
    #: wake-up: the Python of each chunk after the first then runs warm. On this 2-core VM
    #: code idle for 10 ms costs several times its warm cost when it wakes (bench/
    #: wake_cost.py; bench/node_cost.py: the node on hpotp 24 -> 19 % of a core, paired
    #: runs); the stream is unchanged, samples due during the refill (a few ms) leave
    #: after it as a backlog, and a command
    #: waits up to this many chunks more to reach the stream
    REFILL = 4

    def __init__(self, pacer: Pacer, *, imu_rate: float, lookahead: float, chunk: float,
                 t_sim: float = 0.0, limited: Iterable[Hashable] = (),
                 group: int = GROUP) -> None:
        if isinstance(group, bool) or not (isinstance(group, int) and 1 <= group <= self.MAX_BURST):
            raise PacingError(f'Imu group: must be a whole number of samples in '
                              f'[1, {self.MAX_BURST}], got {group!r}')
        self.pacer = pacer
        #: samples per limited stream a paced wake-up sends (or 1 ms of them, if more)
        self.burst = group
        #: how early an item may leave, at most: in Imu periods (each sample goes with the
        #: ``group - 1`` before it) and in wall s
        self.early_samples = group - 0.9
        self.early = (group - 1) * 1e-3 + self.EARLY_MARGIN
        self.imu_period = 1.0 / float(imu_rate)
        self.lookahead = float(lookahead)
        self.chunk = float(chunk)
        self.limited = frozenset(limited)
        # (sim ns, key, payload, wire), in time order
        self.pending: collections.deque[tuple[int, Hashable, object, bool]] = \
            collections.deque()
        self.t_published = float(t_sim)      # sim time up to which items are out (s)
        self._last_wake = 0.0                # wall time (s) of the last paced wake-up

    def put(self, ns: int, key: Hashable, payload: object, wire: bool) -> None:
        """Queue an item for sim time ``ns`` (ns); items must come in time order."""
        self.pending.append((ns, key, payload, wire))

    def reset(self, real_time_factor: float, t_sim: float | None = None) -> None:
        """Restart the schedule with a new factor at the published time (or ``t_sim``, s):
        what ran before is no deficit to catch up."""
        self.pacer.reset(real_time_factor, self.t_published if t_sim is None else t_sim)

    # -- sending --------------------------------------------------------------------------
    def allowance(self, now: float) -> tuple[float, int]:
        """Wall horizon (s) and samples per limited stream that a paced wake-up at ``now``
        (wall s) may send, at a factor > 0.

        Groups of ``group`` Imu samples (see :attr:`GROUP`), within a keep-last-5 reader's
        depth; a backlog (the thread was descheduled) leaves in small groups, not in one
        burst, at :attr:`CATCH_UP_RATE` x the stream's rate over the time since the last
        wake-up. Counted in Imu samples, not in the full-rate batch's: at 20 kHz 1 ms of the
        latter would be 20 Imu messages at once.
        """
        rtf = self.pacer.real_time_factor
        period = self.imu_period
        per_ms = max(self.burst, math.ceil(1e-3 * rtf / period - 1e-9))
        earned = self.CATCH_UP_RATE * rtf * (now - self._last_wake) / period
        # (+1e-9: 4 x 0.5 ms of a 2 kHz stream can round to 3.999...)
        burst = max(per_ms, math.floor(min(earned, self.MAX_BURST) + 1e-9))
        return now + min(self.early, self.early_samples * period / rtf), burst

    def send_due(self, now: float, t_stepped: float, send: SendFn) -> bool:
        """One wake-up at wall time ``now`` (s): send what the pacing allows through
        ``send(ns, key, payload, wire)``; True when due samples were held back (a backlog to
        send at the next wake-up, :attr:`CATCH_UP` from now). ``t_stepped``: the stepped
        sim time (s). At factor 0 everything queued leaves."""
        if self.pacer.real_time_factor > 0:
            horizon, burst = self.allowance(now)
            held = self.flush(horizon, t_stepped, send, burst)
            self._last_wake = now
            return held
        self.flush(math.inf, t_stepped, send)
        return False

    def flush(self, now: float, t_stepped: float, send: SendFn,
              burst: int | None = None) -> bool:
        """Send every queued item due by wall time ``now`` (s; ``math.inf``: all).

        An item nobody receives (``wire`` false) does not wait for its time, so a topic
        nobody reads costs no wake-ups; items still leave in time order.

        Parameters
        ----------
        now : float
            Wall time (s).
        t_stepped : float
            Sim time stepped so far (s).
        send : callable
            ``send(ns, key, payload, wire)``.
        burst : int, optional
            Most samples sent per limited stream (None: no limit).

        Returns
        -------
        bool
            True when due samples were held back by ``burst``.
        """
        pending = self.pending
        if not pending:
            # nothing queued (a scene without outputs): all that was stepped is out, up to
            # the schedule, or pacing would wait forever for an item
            self.t_published = max(self.t_published, min(t_stepped, self.pacer.sim_at(now)))
            return False
        horizon = self.pacer.sim_at(now) * 1e9   # ns (a float; inf for now = inf)
        left = dict.fromkeys(self.limited, burst) if burst else None
        while pending:
            ns, key, payload, wire = pending[0]
            if wire:
                if ns > horizon:
                    break
                if left is not None and key in left:
                    if not left[key]:
                        return True
                    left[key] -= 1
            pending.popleft()
            send(ns, key, payload, wire)
            self.t_published = min(ns, horizon) * 1e-9
        return False

    # -- stepping -------------------------------------------------------------------------
    def plan(self, now: float, t_stepped: float) -> Plan:
        """Whether to step a chunk at wall time ``now`` (s) with ``t_stepped`` (s) stepped.

        The lag is the stream's (the delivered time's), not the last item's: at a tiny
        factor that stands still between items (500 s at 1e-6) and every wake-up dropped a
        deficit. Stepping starts when less than ``lookahead`` is stepped ahead of the
        schedule, and then steps 1 + :attr:`REFILL` chunks at once (one at factor 0).

        Returns
        -------
        Plan
        """
        target, lag = self.pacer.target(self.delivered_t(now, t_stepped))
        ahead = self.lookahead * self.pacer.real_time_factor
        step = t_stepped < target + ahead - 1e-12 or math.isinf(target)
        chunks = (1 if math.isinf(target) else 1 + self.REFILL) if step else 0
        late = step and t_stepped < target - self.chunk < math.inf
        return Plan(chunks, late, lag)

    def wait(self, held: bool, now: float, t_stepped: float, longest: float) -> float:
        """How long (wall s) to sleep after a wake-up that stepped nothing: until the next
        queued item is due, or :attr:`CATCH_UP` with a backlog held back, at most
        ``longest``."""
        if held:
            return self.CATCH_UP
        if self.pending:
            return self.pacer.wall_at(self.pending[0][0] * 1e-9) - now
        return min(longest, self.pacer.wall_at(t_stepped) - now)

    def delivered_t(self, wall: float, t_stepped: float) -> float:
        """Sim time (s) whose items are all out by wall time ``wall`` (s): the schedule's,
        up to the first item still queued (the queue is in time order: all before it are
        out) and the stepped time ``t_stepped`` (s); never before the published time (an
        item may leave up to ``early`` before its time). Never decreases between resets of
        the pacer, so an achieved factor is never negative."""
        pending = self.pending
        first = pending[0][0] * 1e-9 if pending else math.inf
        return max(self.t_published, min(t_stepped, self.pacer.sim_at(wall), first))


__all__ = ['Outbox', 'Pacer', 'PacingError', 'Plan']
