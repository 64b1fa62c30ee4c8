"""The fault kinds of :mod:`.faults`: each one's window, state and action on a chunk.

Private to :class:`~.faults.FaultInjector`, which creates them (one per added fault) and calls
them in its two stages. A fault's window is ``[lo, hi)`` in sample indices (sample ``n`` at
``t = n / fs``; ``hi`` None = until cleared); every method takes a chunk as an array of ``k``
samples and the index ``n0`` of its first, and touches only rows inside the window. A random
kind draws its events in blocks of :data:`BLOCK` from its own generator, so the events do not
depend on how the run is chunked. No per-sample Python loops.
"""
from __future__ import annotations

import math
import zlib
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:
    from .fault_spec import FaultSpec

#: Events drawn per refill of a random fault (dimensionless): a fixed block, so that the
#: numbers never depend on how the run is chunked.
BLOCK = 256
_EPS = 1e-6   # a time within this many sample periods of a sample is on it
_AXIS = {'x': 0, 'y': 1, 'z': 2}


def after_index(t: float, fs: float) -> int:
    """Index of the first sample strictly after sim time ``t`` (s), on the grid within _EPS."""
    return int(math.floor(t * fs + _EPS)) + 1


class _Buffer:
    """A growing 1-D array with amortised O(1) appends (events of a long run)."""

    def __init__(self, dtype: npt.DTypeLike) -> None:
        self._a = np.empty(64, dtype)
        self.n = 0

    def extend(self, values: np.ndarray) -> None:
        need = self.n + len(values)
        if need > len(self._a):
            grown = np.empty(max(need, 2 * len(self._a)), self._a.dtype)
            grown[:self.n] = self._a[:self.n]
            self._a = grown
        self._a[self.n:need] = values
        self.n = need

    @property
    def values(self) -> np.ndarray:
        return self._a[:self.n]


class _Fault:
    """One added fault: its window ``[lo, hi)`` in sample indices (hi None = until cleared)."""

    stage = 'before'

    def __init__(self, spec: FaultSpec, name: str, acc: int, lo: int, hi: int | None,
                 fs: float, seed: int | None) -> None:
        self.spec, self.name, self.acc = spec, name, acc
        self.lo, self.hi, self.fs, self.seed = lo, hi, fs, seed
        self.cols = np.array([_AXIS[c] for c in spec.axes])
        self.all_axes = spec.axes == 'xyz'
        self.cleared_at: float | None = None
        self.params = dict(spec.params)
        self.rng: np.random.Generator | None = None
        if seed is not None:   # own stream: kind and accelerometer in it, so one seed on two
            self.rng = np.random.default_rng(np.random.SeedSequence(   # sensors is two streams
                [seed, zlib.crc32(spec.kind.encode()), zlib.crc32(spec.accelerometer.encode())]))

    def span(self, n0: int, k: int) -> tuple[int, int]:
        """The window's part in the chunk of samples n0 .. n0 + k - 1: (a, b), chunk-relative
        (empty when a >= b)."""
        b = n0 + k if self.hi is None else min(self.hi, n0 + k)
        return max(self.lo, n0) - n0, b - n0

    def _set(self, x: np.ndarray, a: int, b: int, value: np.ndarray) -> None:
        if self.all_axes:
            x[a:b] = value
        else:
            x[a:b, self.cols] = value

    def before(self, x: np.ndarray, n0: int) -> None:
        pass

    def capture(self, x: np.ndarray, n0: int, last: np.ndarray | None) -> None:
        pass

    def after(self, x: np.ndarray, n0: int, valid: npt.NDArray[np.bool_]) -> None:
        pass

    @property
    def random(self) -> np.random.Generator:
        """The fault's own generator (the random kinds: their spec or injector gives a seed)."""
        if self.rng is None:
            raise RuntimeError(f'fault kind {self.spec.kind!r} has no random stream')
        return self.rng

    def invalid(self, n: np.ndarray) -> npt.NDArray[np.bool_] | None:
        """Samples ``n`` (absolute indices) this fault leaves out; None if it leaves none."""
        return None

    def events(self, end: int) -> dict[str, list[Any]] | None:
        """Its random events before sample ``end`` for the labels; None for a fixed kind."""
        return None


class _Gain(_Fault):
    def before(self, x: np.ndarray, n0: int) -> None:
        a, b = self.span(n0, len(x))
        if a < b:
            if self.all_axes:
                x[a:b] *= self.params['gain']
            else:
                x[a:b, self.cols] *= self.params['gain']


class _Bias(_Fault):
    def before(self, x: np.ndarray, n0: int) -> None:
        a, b = self.span(n0, len(x))
        if a >= b:
            return
        step, drift = self.params['step'], self.params['drift']
        if drift == 0.0:
            value = step
        else:   # t - onset = (n - lo + 1) / fs: whole numbers first, the same in any chunking
            value = (step + drift * ((np.arange(a, b) + (n0 - self.lo + 1)) / self.fs))[:, None]
        if self.all_axes:
            x[a:b] += value
        else:
            x[a:b, self.cols] += value


class _Spikes(_Fault):
    def __init__(self, spec: FaultSpec, name: str, acc: int, lo: int, hi: int | None,
                 fs: float, seed: int | None) -> None:
        super().__init__(spec, name, acc, lo, hi, fs, seed)
        self.starts = _Buffer(np.int64)
        self.signs = _Buffer(np.int8)
        self._carry = 0.0   # position of the last arrival (samples after lo, continuous)
        self._scale = self.fs / self.params['rate']   # mean gap (samples)

    def _extend(self, end: int) -> None:
        """Draw arrivals until one starts at or after sample ``end``."""
        while self.lo + math.floor(self._carry) < end:
            gaps = self.random.exponential(self._scale, BLOCK)
            signs = self.random.integers(0, 2, BLOCK)
            pos = self._carry + np.cumsum(gaps)
            self._carry = float(pos[-1])
            # an arrival in [j, j + 1) samples after lo starts at sample lo + j
            self.starts.extend(self.lo + np.floor(pos).astype(np.int64))
            self.signs.extend((2 * signs - 1).astype(np.int8))

    def before(self, x: np.ndarray, n0: int) -> None:
        a, b = self.span(n0, len(x))
        if a >= b:
            return
        end, width = n0 + b, self.params['width']
        self._extend(end)
        starts = self.starts.values
        # spikes that started up to width - 1 samples before the chunk reach into it
        i0 = np.searchsorted(starts, max(self.lo, n0 - width + 1))
        i1 = np.searchsorted(starts, end)
        if i0 == i1:
            return
        rows = (starts[i0:i1, None] + np.arange(width)).ravel()
        vals = np.repeat(self.signs.values[i0:i1] * self.params['amplitude'], width)
        keep = (rows >= n0 + a) & (rows < end)
        # overlapping spikes add, summed in arrival order: the same bits in any chunking
        rows, inverse = np.unique(rows[keep] - n0, return_inverse=True)
        sums = np.bincount(inverse, weights=vals[keep], minlength=len(rows))
        x[rows[:, None], self.cols] += sums[:, None]

    def events(self, end: int) -> dict[str, list[Any]] | None:
        end = end if self.hi is None else min(end, self.hi)
        self._extend(end)
        i = np.searchsorted(self.starts.values, end)
        return {'t_s': (self.starts.values[:i] / self.fs).tolist(),
                'sign': self.signs.values[:i].astype(int).tolist()}


class _Intermittent(_Fault):
    def __init__(self, spec: FaultSpec, name: str, acc: int, lo: int, hi: int | None,
                 fs: float, seed: int | None) -> None:
        super().__init__(spec, name, acc, lo, hi, fs, seed)
        self.stage = 'before' if self.params['off'] == 'rail' else 'after'
        self.starts = _Buffer(np.int64)   # open periods [start, end), sample indices
        self.ends = _Buffer(np.int64)
        self._carry = 0.0   # where the next open period begins (samples after lo)
        self._means = np.array([self.params['mean_off'], self.params['mean_on']]) * self.fs

    def _extend(self, end: int) -> None:
        """Draw open/connected periods until the next open one starts at or after ``end``."""
        while self.lo + math.ceil(self._carry) < end:
            bounds = self._carry + np.cumsum(
                (self.random.exponential(1.0, (BLOCK, 2)) * self._means).ravel())
            begin = np.concatenate([[self._carry], bounds[1:-1:2]])
            self._carry = float(bounds[-1])
            # a sample is open when its index lies in an open period: [ceil(begin), ceil(end))
            s = self.lo + np.ceil(begin).astype(np.int64)
            e = self.lo + np.ceil(bounds[0::2]).astype(np.int64)
            keep = e > s   # a period between two samples is not seen
            self.starts.extend(s[keep])
            self.ends.extend(e[keep])

    def _open(self, n0: int, a: int, b: int) -> npt.NDArray[np.bool_]:
        """Chunk-relative mask of the open samples in a .. b - 1."""
        self._extend(n0 + b)
        starts, ends = self.starts.values, self.ends.values
        i0 = np.searchsorted(ends, n0 + a, side='right')
        i1 = np.searchsorted(starts, n0 + b)
        edges = np.zeros(b - a + 1, np.int64)
        edges[np.clip(starts[i0:i1], n0 + a, n0 + b) - n0 - a] += 1   # unique: periods
        edges[np.clip(ends[i0:i1], n0 + a, n0 + b) - n0 - a] -= 1     # do not overlap
        return np.cumsum(edges[:-1]) > 0

    def before(self, x: np.ndarray, n0: int) -> None:
        a, b = self.span(n0, len(x))
        if a < b:
            rows = np.flatnonzero(self._open(n0, a, b)) + a
            x[rows[:, None], self.cols] = self.params['level']

    def after(self, x: np.ndarray, n0: int, valid: npt.NDArray[np.bool_]) -> None:
        a, b = self.span(n0, len(x))
        if a < b:
            valid[a:b] &= ~self._open(n0, a, b)

    def invalid(self, n: np.ndarray) -> npt.NDArray[np.bool_] | None:
        if self.stage == 'before' or n.size == 0:
            return None
        self._extend(int(n.max()) + 1)
        starts, ends = self.starts.values, self.ends.values
        if not len(starts):
            return np.zeros(n.shape, bool)
        i = np.searchsorted(starts, n, side='right') - 1   # the last period starting at or before
        inside = (i >= 0) & (n < ends[np.maximum(i, 0)])
        return inside & (n >= self.lo) & (True if self.hi is None else n < self.hi)

    def events(self, end: int) -> dict[str, list[Any]] | None:
        end = end if self.hi is None else min(end, self.hi)
        self._extend(end)
        i = np.searchsorted(self.starts.values, end)
        s = self.starts.values[:i]
        e = np.minimum(self.ends.values[:i], end)
        # (t0, t1]: the samples after t0 up to t1, as a fault's window
        return {'open_s': np.stack([(s - 1) / self.fs, (e - 1) / self.fs], axis=1).tolist()}


class _Stuck(_Fault):
    stage = 'after'

    def __init__(self, spec: FaultSpec, name: str, acc: int, lo: int, hi: int | None,
                 fs: float, seed: int | None) -> None:
        super().__init__(spec, name, acc, lo, hi, fs, seed)
        self.hold: np.ndarray | None = None

    def capture(self, x: np.ndarray, n0: int, last: np.ndarray | None) -> None:
        if self.hold is not None:
            return
        p = self.lo - 1 - n0   # the sample before the onset, chunk-relative
        if 0 <= p < len(x):
            self.hold = x[p].copy()
        elif p == -1 and last is not None:
            self.hold = last.copy()
        elif p < 0 and len(x):   # the stream's first sample: nothing was read before it
            self.hold = x[0].copy()

    def after(self, x: np.ndarray, n0: int, valid: npt.NDArray[np.bool_]) -> None:
        a, b = self.span(n0, len(x))
        if a < b:
            hold = self.hold
            assert hold is not None   # capture() keeps the last reading before the span
            self._set(x, a, b, hold if self.all_axes else hold[self.cols])


class _Dropout(_Fault):
    stage = 'after'

    def after(self, x: np.ndarray, n0: int, valid: npt.NDArray[np.bool_]) -> None:
        a, b = self.span(n0, len(x))
        valid[a:max(a, b)] = False

    def invalid(self, n: np.ndarray) -> npt.NDArray[np.bool_] | None:
        return (n >= self.lo) & (True if self.hi is None else n < self.hi)


CLASSES = {'gain': _Gain, 'bias': _Bias, 'spikes': _Spikes, 'intermittent': _Intermittent,
            'stuck': _Stuck, 'dropout': _Dropout}


__all__ = ['BLOCK', 'CLASSES', 'after_index']
