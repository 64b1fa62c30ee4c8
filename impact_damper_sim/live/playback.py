"""Replay pacing without ROS: a log's wall-clock deadlines and the loop that keeps them.

:class:`Schedule` maps each message's log time to the wall time it is due (rate, start
offset, loop passes) and gives the ``/clock`` value at any wall time; :class:`Player` waits
for each deadline, calls a publish function and ticks a clock between messages, and
reports the lateness it achieved (:class:`PlaybackStats`). This is the ROS-free core of the
``replay`` node (:mod:`impact_damper_sim.ros.replay`), kept apart from it as the stepping
core of ``vibration_node`` is: it is tested with a fake clock and plain callables, and it
imports nothing of ROS.
"""
from __future__ import annotations

import collections
import itertools
import math
import statistics
import threading
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

#: lateness statistics are kept over this many recent messages (bounded memory with --loop)
LATENESS_WINDOW = 100_000


class Schedule:
    """Wall-clock deadlines of a log's messages.

    Parameters
    ----------
    start_ns : int
        log_time of the log's first message (ns).
    end_ns : int
        log_time of its last message (ns).
    count : int
        Number of messages in the log (sets the gap between loop passes).
    rate : float
        Playback speed factor (-); 2 plays twice as fast. Must be > 0.
    start_offset : float
        Log time skipped at the start (s), >= 0 and not past the end.
    loop : bool
        Play again and again.

    Raises
    ------
    ValueError
        A rate that is not a positive number, or an offset outside the log.
    """

    def __init__(self, start_ns: int, end_ns: int, count: int = 2, rate: float = 1.0,
                 start_offset: float = 0.0, loop: bool = False) -> None:
        if not (isinstance(rate, (int, float)) and math.isfinite(rate) and rate > 0):
            raise ValueError(f'--rate must be a number > 0, got {rate}')
        span = int(end_ns) - int(start_ns)
        if span < 0:
            raise ValueError('the log ends before it starts')
        if not (math.isfinite(start_offset) and start_offset >= 0):
            raise ValueError(f'--start-offset must be >= 0 s, got {start_offset}')
        if start_offset * 1e9 > span:
            raise ValueError(f'--start-offset {start_offset:g} s is past the end of the log '
                             f'({span * 1e-9:g} s long)')
        self.rate = float(rate)
        self.loop = bool(loop)
        self.begin_ns = int(start_ns) + round(start_offset * 1e9)
        self.end_ns = int(end_ns)
        # a pass restarts one mean message interval after the last message (1 s for one)
        gap = span / (count - 1) if count > 1 and span > 0 else 1e9
        self.period_ns = (self.end_ns - self.begin_ns) + gap

    def selects(self, log_time_ns: int) -> bool:
        """True if a message at ``log_time_ns`` (ns) is played (not before the offset)."""
        return log_time_ns >= self.begin_ns

    def deadline(self, log_time_ns: int, iteration: int = 0) -> float:
        """Wall time (s after playback start) at which to publish a message.

        Parameters
        ----------
        log_time_ns : int
            The message's log_time (ns).
        iteration : int
            Loop pass, from 0.

        Returns
        -------
        float
        """
        return ((log_time_ns - self.begin_ns) + iteration * self.period_ns) / (self.rate * 1e9)

    def log_time_at(self, wall_s: float) -> int:
        """Log time (ns) that playback has reached ``wall_s`` s after its start: the /clock.

        Parameters
        ----------
        wall_s : float
            Wall time since playback start (s).

        Returns
        -------
        int
        """
        elapsed = wall_s * self.rate * 1e9
        if self.loop:
            elapsed = math.fmod(elapsed, self.period_ns)
        return self.begin_ns + int(min(elapsed, self.end_ns - self.begin_ns))

    def iterations(self) -> Iterable[int]:
        """Return the pass numbers: 0 only, or 0, 1, 2, ... with ``loop``."""
        return itertools.count() if self.loop else range(1)

    @property
    def pass_s(self) -> float:
        """float: wall duration of one pass, first to last message (s)."""
        return (self.end_ns - self.begin_ns) / (self.rate * 1e9)


def deadlines(log_times_ns: Sequence[int], rate: float = 1.0, start_offset: float = 0.0,
              passes: int = 1) -> list[tuple[int, int, float]]:
    """Wall deadlines of a list of log times, over a number of passes.

    Parameters
    ----------
    log_times_ns : sequence of int
        log_time of each message (ns), sorted, at least one.
    rate : float
        Playback speed factor (-).
    start_offset : float
        Log time skipped at the start (s).
    passes : int
        Number of passes (more than 1 loops).

    Returns
    -------
    list of tuple
        ``(pass, index, deadline_s)`` for every message played, in publishing order.
    """
    times = list(log_times_ns)
    if not times:
        raise ValueError('no log times')
    s = Schedule(times[0], times[-1], len(times), rate, start_offset, loop=passes > 1)
    return [(k, i, s.deadline(t, k)) for k in range(passes) for i, t in enumerate(times)
            if s.selects(t)]


@dataclass
class PlaybackStats:
    """What a playback achieved (wall times in s)."""

    messages: int = 0
    passes: int = 0
    clock_ticks: int = 0
    wall_s: float = 0.0
    median_lateness_s: float = math.nan
    max_lateness_s: float = math.nan
    stopped: bool = False


class _Stopped(Exception):
    pass


class Player:
    """Publish a schedule's messages at their deadlines, with /clock ticks in between.

    Parameters
    ----------
    schedule : Schedule
        Deadlines.
    source : callable
        ``source()`` returns an iterable of ``(key, log_time_ns, data)`` in log_time order;
        called once per pass.
    publish : callable
        ``publish(key, data)``.
    clock : callable, optional
        ``clock(log_time_ns)`` publishes the clock; None for no clock.
    clock_period : float
        Wall time between clock ticks (s).
    stop : threading.Event, optional
        Set to end playback early.
    now : callable
        Monotonic wall clock (s).
    """

    def __init__(self, schedule: Schedule,
                 source: Callable[[], Iterable[tuple[object, int, object]]],
                 publish: Callable[[object, object], object],
                 clock: Callable[[int], object] | None = None, clock_period: float = 0.01,
                 stop: threading.Event | None = None,
                 now: Callable[[], float] = time.monotonic) -> None:
        if not clock_period > 0:
            raise ValueError(f'clock period must be > 0 s, got {clock_period}')
        self.schedule, self._source, self._publish = schedule, source, publish
        self._clock, self._period = clock, clock_period
        self._stop = stop if stop is not None else threading.Event()
        self._now = now

    def _wait(self, t: float) -> None:
        remaining = t - self._now()
        if remaining > 0 and self._stop.wait(remaining):
            raise _Stopped
        if self._stop.is_set():
            raise _Stopped

    def run(self) -> PlaybackStats:
        """Play to the end (or until stopped).

        Returns
        -------
        PlaybackStats
        """
        s, stats = self.schedule, PlaybackStats()
        late: collections.deque[float] = collections.deque(maxlen=LATENESS_WINDOW)
        worst, tick, last_log = -math.inf, 0, None
        t0 = self._now()
        try:
            for iteration in s.iterations():
                for key, log_time, data in self._source():
                    if not s.selects(log_time):
                        continue
                    due = s.deadline(log_time, iteration)
                    while self._clock is not None and tick * self._period <= due:
                        self._wait(t0 + tick * self._period)
                        # behind by whole ticks: skip them rather than send a burst
                        behind = int((self._now() - t0) / self._period)
                        if behind > tick and behind * self._period <= due:
                            tick = behind
                        self._clock(s.log_time_at(tick * self._period))
                        tick += 1
                        stats.clock_ticks += 1
                    self._wait(t0 + due)
                    self._publish(key, data)
                    lateness = self._now() - t0 - due
                    late.append(lateness)
                    worst = max(worst, lateness)
                    stats.messages += 1
                    last_log = log_time
                stats.passes += 1
            if self._clock is not None and last_log is not None:
                self._clock(last_log)   # the clock ends where the log's content ends
                stats.clock_ticks += 1
        except _Stopped:
            stats.stopped = True
        stats.wall_s = self._now() - t0
        if late:
            stats.median_lateness_s = statistics.median(late)
            stats.max_lateness_s = worst
        return stats


__all__ = ['LATENESS_WINDOW', 'PlaybackStats', 'Player', 'Schedule', 'deadlines']
