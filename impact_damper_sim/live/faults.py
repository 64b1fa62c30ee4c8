"""Sensor faults injected into an accelerometer's output stream, chunk by chunk (issue 36).

:class:`FaultInjector` holds the faults of every accelerometer of a run (specs:
:mod:`.fault_spec`) and changes the channel's output-rate samples (m/s^2, sensor frame) in two
stages around the channel's range and ADC (``SensorChannel._limit``)::

    channel chain -> + live white noise -> [before_limit] -> range, ADC -> [after_limit]
                     gain, bias, spikes,                                  stuck, dropout,
                     intermittent (rail)                                  intermittent (dropout)

* **before the limit** (:meth:`FaultInjector.before_limit`): the faults that change values.
  A gain drives the range into clipping, a spike or a bias beyond the range is clipped, and
  every published sample stays on the ADC's grid; the channel counts what its limit clips (a
  real DAQ's overrange counter counts these too). ``intermittent`` with ``off: rail`` sets
  the open periods to its ``level``: by default twice the channel's rail, which the limit
  clips to the rail (an IEPE sensor's open connection lets its constant-current supply drive
  the input to the supply's compliance voltage, ~24 V against a +-5 V DAQ input: a
  positive full-scale reading, not missing samples; the DAQ keeps sampling).
* **after the limit** (:meth:`FaultInjector.after_limit`): ``stuck`` holds, on its axes,
  the value the channel read (after the first stage and the limit) at the sample before its
  onset (at a run's first sample: that sample's); ``dropout`` and ``intermittent`` with
  ``off: dropout`` clear the returned validity mask: those samples are missing from the
  batch and the Imu stream (:meth:`FaultInjector.valid_at` answers for any sample time, e.g.
  the Imu's). The values under a false mask are left as the channel made them, so a filter
  downstream sees a continuous signal.

Within a stage the faults act in the order of :data:`~.fault_spec.KINDS` (gain before bias
before spikes ...), then in the order they were added; each kind's code is in
:mod:`.fault_kinds`.

Time: sample ``n`` is at ``t = n / fs`` (``LiveSimulation``'s first sample is n = 1, at the
end of the first output period) and stands for the period ending there. A fault of onset
``t0`` and duration ``d`` acts on the samples with ``t0 < t <= t0 + d``: a fault added at sim
time ``t0`` (a schedule entry applied there, a command arriving then) starts with the next
sample, and one given ahead starts with the same sample. Times are rounded to the sample grid
(within 1e-6 of a sample period). Everything is kept as sample indices, and a random kind
draws its events in fixed blocks from its own generator, so any split of a run into chunks
gives the same bytes as one pass, and the same seeds the same bytes.

Labels (:meth:`FaultInjector.labels`) give every fault's kind, values, seed and actual window
(and each spike and open period) for a log's metadata: the node's diagnostics must not show
them (a real sensor does not), the log's labels do. No ROS, no per-sample Python loops.
"""
from __future__ import annotations

import functools
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from .fault_kinds import CLASSES, after_index
from .fault_spec import (
    KINDS,
    MAX_SEED,
    RANDOM_KINDS,
    FaultError,
    FaultSpec,
    accelerometer_problem,
    parse_fault,
)

if TYPE_CHECKING:
    from .channel import SensorChannel
    from .fault_kinds import _Fault

#: An open connection's default reading, in units of the channel's rail (dimensionless):
#: anything beyond 1 is clipped to the rail by the limit; 2 says "beyond" plainly.
OPEN_OVERDRIVE = 2.0


def channel_rail(channel: SensorChannel) -> float | None:
    """The largest value a channel publishes: its range or its ADC's top code, the lower.

    Parameters
    ----------
    channel : SensorChannel
        The accelerometer's channel (:mod:`.channel`).

    Returns
    -------
    float or None
        m/s^2; None when it has neither a range nor an ADC (an ideal channel).
    """
    rails = []
    if channel.range is not None:
        rails.append(float(channel.range))
    if channel.lsb is not None:
        rails.append((2.0 ** (channel.spec['adc']['bits'] - 1) - 1.0) * channel.lsb)
    return min(rails) if rails else None


class FaultInjector:
    """The sensor faults of a run's accelerometers, applied to their output streams.

    Parameters
    ----------
    accelerometer_names : sequence of str
        The accelerometers, in the order of ``acc_index`` (``LiveSimulation.accelerometers``).
    sample_rate_hz : float
        Output sample rate (Hz) of the samples given to :meth:`apply`.
    seed : int
        Seed of the random kinds' default seeds (dimensionless, [0, 2^32 - 1]).
    rails : sequence of (float or None), optional
        Per accelerometer, the largest value its channel publishes (m/s^2; None = no range
        or ADC): the default open reading of ``intermittent`` (rail) is ``OPEN_OVERDRIVE``
        times it. :meth:`for_channels` takes them from the channels.

    Raises
    ------
    ValueError
        A bad rate, seed, rails list or repeated name.
    """

    def __init__(self, accelerometer_names: Iterable[str], sample_rate_hz: float, seed: int = 0,
                 *, rails: Sequence[float | None] | None = None) -> None:
        self.names = [str(n) for n in accelerometer_names]
        if len(set(self.names)) != len(self.names):
            raise ValueError(f'accelerometer names repeat: {self.names}')
        self.sample_rate_hz = float(sample_rate_hz)
        if not (math.isfinite(self.sample_rate_hz) and self.sample_rate_hz > 0):
            raise ValueError(f'sample rate must be finite and > 0 Hz, got {sample_rate_hz!r}')
        if isinstance(seed, bool) or int(seed) != seed or not 0 <= int(seed) <= MAX_SEED:
            raise ValueError(f'seed must be a whole number in [0, {MAX_SEED}], got {seed!r}')
        self.seed = int(seed)
        self.rails: list[float | None] = [None] * len(self.names) if rails is None else [
            None if r is None else float(r) for r in rails]
        if len(self.rails) != len(self.names):
            raise ValueError(f'{len(self.rails)} rails for {len(self.names)} accelerometers')
        if not all(r is None or (math.isfinite(r) and r > 0) for r in self.rails):
            raise ValueError(f'rails must be finite and > 0 m/s^2 (or None), got {rails!r}')
        self._faults: list[_Fault] = []                # every fault, in the order added
        self._by_acc: list[list[_Fault]] = [[] for _ in self.names]   # per accelerometer
        self._done: list[int | None] = [None] * len(self.names)   # next sample index
        self._last: list[np.ndarray | None] = [None] * len(self.names)   # last value read

    @classmethod
    def for_channels(cls, channels: Iterable[SensorChannel], sample_rate_hz: float | None = None,
                     seed: int = 0) -> FaultInjector:
        """An injector for ``SensorChannel`` s: their names, output rate and rails.

        Parameters
        ----------
        channels : sequence of SensorChannel
            The run's channels, in accelerometer order (``LiveSimulation.channels``).
        sample_rate_hz : float, optional
            Output rate (Hz); default the first channel's ``output_rate_hz``.
        seed : int
            As the constructor's (dimensionless).
        """
        channels = list(channels)
        rate = channels[0].output_rate_hz if sample_rate_hz is None else sample_rate_hz
        return cls([c.name for c in channels], rate, seed,
                   rails=[channel_rail(c) for c in channels])

    def __len__(self) -> int:
        """Faults added so far (over or not; dimensionless)."""
        return len(self._faults)

    # -- faults ------------------------------------------------------------------------------
    def add(self, spec: FaultSpec | Mapping[str, Any], now: float | None = None, *,
            key: str = 'fault') -> str:
        """Add a fault.

        Parameters
        ----------
        spec : FaultSpec or dict
            The fault (a mapping is read by :func:`~.fault_spec.parse_fault`).
        now : float, optional
            Sim time it arrives (s): its onset when the spec gives none. Default: the time
            of the last sample this accelerometer's stream has been through (0 before any).
        key : str
            The spec's key in messages.

        Returns
        -------
        str
            The fault's name (given, or ``<kind>-<n>``).

        Raises
        ------
        FaultError
            In one line naming the key: an unknown accelerometer (naming the ones there
            are), a name in use, a window that has passed or holds no sample, an
            ``intermittent`` rail without a rail or ``level``.
        """
        if not isinstance(spec, FaultSpec):
            spec = parse_fault(spec, self.names, key=key)
        problem = accelerometer_problem(spec.accelerometer, self.names)
        if problem:
            raise FaultError(f"key '{key}.accelerometer': {problem}")
        acc = self.names.index(spec.accelerometer)
        taken = {f.name for f in self._faults}
        name = spec.name
        if name in taken:
            raise FaultError(f"key '{key}.name': {name!r} names an earlier fault of this run; "
                             'give another name')
        count = len(self._faults)
        while name is None or name in taken:
            count += 1
            name = f'{spec.kind}-{count}'
        fs = self.sample_rate_hz
        nxt = self._done[acc] or 0
        onset = spec.onset
        if onset is None:
            onset = float(now) if now is not None else max(nxt - 1, 0) / fs
        lo = after_index(onset, fs)
        hi = None if spec.duration is None else after_index(onset + spec.duration, fs)
        if hi is not None and hi <= lo:
            raise FaultError(f"key '{key}.duration': {spec.duration:g} s holds no output "
                             f'sample at {fs:g} Hz (one every {1 / fs:g} s)')
        if hi is not None and hi <= nxt:
            raise FaultError(f"key '{key}.onset': the window {onset:g} s + {spec.duration:g} s "
                             f'has passed: the stream is at {(nxt - 1) / fs:g} s')
        seed = None
        if spec.kind in RANDOM_KINDS:
            seed = spec.seed if spec.seed is not None else int(
                np.random.SeedSequence([self.seed, len(self._faults)]).generate_state(1)[0])
        fault = CLASSES[spec.kind](spec, name, acc, max(lo, nxt), hi, fs, seed)
        if spec.kind == 'intermittent' and fault.params['off'] == 'rail':
            if fault.params['level'] is None:
                rail = self.rails[acc]
                if rail is None:
                    raise FaultError(f"key '{key}.level': accelerometer {spec.accelerometer!r}"
                                     ' has no range or ADC to rail at; give level (the '
                                     'reading while open, m/s^2) or off: dropout')
                fault.params['level'] = OPEN_OVERDRIVE * rail
        self._faults.append(fault)
        order = [KINDS.index(f.spec.kind) for f in self._by_acc[acc]]
        self._by_acc[acc].insert(int(np.searchsorted(order, KINDS.index(spec.kind),
                                                     side='right')), fault)
        return name

    def clear(self, name: str | None = None, at: float | None = None, *,
              key: str = 'clear') -> list[str]:
        """End a fault (or every fault) now, or at sim time ``at``.

        Parameters
        ----------
        name : str, optional
            The fault; None = every fault.
        at : float, optional
            Sim time it ends (s): it acts on no sample after ``at``. Default (and at the
            earliest): after the last sample its accelerometer's stream has been through.
        key : str
            The command's key in messages.

        Returns
        -------
        list of str
            The faults this cut short (those already over are left as they were).

        Raises
        ------
        FaultError
            No fault of that name, naming the ones there are.
        """
        targets = [f for f in self._faults if name is None or f.name == name]
        if name is not None and not targets:
            known = ', '.join(f.name for f in self._faults) or 'none'
            raise FaultError(f"key '{key}': no fault named {name!r}; the faults: {known}")
        cut = []
        for f in targets:
            nxt = self._done[f.acc] or 0
            end = nxt if at is None else max(after_index(at, self.sample_rate_hz), nxt)
            if f.hi is None or end < f.hi:
                f.hi = max(end, f.lo)
                f.cleared_at = (end - 1) / self.sample_rate_hz
                cut.append(f.name)
        return cut

    def active(self, acc_index: int | None = None) -> list[str]:
        """The faults not over yet (running or to come). Not for diagnostics: a real sensor
        does not say it is faulty.

        Parameters
        ----------
        acc_index : int, optional
            One accelerometer's (dimensionless); None = every accelerometer's.

        Returns
        -------
        list of str
            Their names, in the order added.
        """
        return [f.name for f in self._faults
                if (acc_index is None or f.acc == acc_index)
                and (f.hi is None or f.hi > (self._done[f.acc] or 0)) and
                (f.hi is None or f.hi > f.lo)]

    def has_faults(self, acc_index: int) -> bool:
        """Whether any fault was ever added to accelerometer ``acc_index`` (over or not): one
        without can skip :meth:`hook` and needs :meth:`after_limit` only for its bookkeeping."""
        return bool(self._by_acc[acc_index])

    # -- streams -----------------------------------------------------------------------------
    def _start(self, t: npt.ArrayLike, k: int) -> int:
        """Index of a chunk's first sample from its times ``t`` (s; array, or the first)."""
        t = np.asarray(t, dtype=float)
        fs = self.sample_rate_hz
        if t.ndim == 0:
            return int(np.rint(t * fs))
        if t.shape != (k,):
            raise ValueError(f'sample times of shape {t.shape} for {k} samples')
        if k == 0:
            return 0
        n0 = int(np.rint(t[0] * fs))
        if k > 1 and int(np.rint(t[-1] * fs)) - n0 != k - 1:
            raise ValueError(f'sample times {t[0]:g} .. {t[-1]:g} s are not {k} consecutive '
                             f'samples at {fs:g} Hz')
        return n0

    def before_limit(self, t: npt.ArrayLike, samples: np.ndarray, acc_index: int) -> np.ndarray:
        """First stage, in place: gain, bias, spikes, intermittent rail.

        Parameters
        ----------
        t : array_like, shape (k,), or float
            Sample times (s), or the first one's.
        samples : ndarray, shape (k, 3)
            One accelerometer's output-rate samples before the range and ADC (m/s^2, sensor
            frame), changed in place.
        acc_index : int
            The accelerometer (dimensionless).

        Returns
        -------
        ndarray
            ``samples``.
        """
        n0 = self._start(t, len(samples))
        for f in self._by_acc[acc_index]:
            if f.stage == 'before':
                f.before(samples, n0)
        return samples

    def hook(self, t: npt.ArrayLike, acc_index: int) -> Callable[[np.ndarray], np.ndarray] | None:
        """``before_limit`` for one chunk as ``f(samples)``, or None when no first-stage
        fault of the accelerometer touches it (the channel's ``before_limit`` argument).

        Parameters
        ----------
        t : array_like, shape (k,)
            The chunk's sample times (s).
        acc_index : int
            The accelerometer (dimensionless).

        Returns
        -------
        callable or None
            ``f(samples)``: :meth:`before_limit` of this chunk in place on the (k, 3) samples
            (m/s^2).
        """
        before = [f for f in self._by_acc[acc_index] if f.stage == 'before']
        if not before:   # the common case (no fault at all): nothing to place in the chunk
            return None
        t = np.asarray(t, dtype=float)
        n0 = self._start(t, len(t))
        if not any(a < b for a, b in (f.span(n0, len(t)) for f in before)):
            return None
        return functools.partial(self.before_limit, t, acc_index=acc_index)

    def after_limit(self, t: npt.ArrayLike, samples: np.ndarray,
                    acc_index: int) -> tuple[np.ndarray, npt.NDArray[np.bool_]]:
        """Second stage, in place: stuck, then the validity mask (dropout, intermittent).

        Call it for every chunk of every accelerometer, faults or none: it keeps the last
        value read (``stuck``'s hold) and where the stream is.

        Parameters
        ----------
        t : array_like, shape (k,), or float
            Sample times (s), or the first one's; chunks must follow each other.
        samples : ndarray, shape (k, 3)
            The samples after the range and ADC (m/s^2), changed in place.
        acc_index : int
            The accelerometer (dimensionless).

        Returns
        -------
        samples : ndarray, shape (k, 3)
        valid : ndarray of bool, shape (k,)
            False where a sample is missing: leave it out of the batch and the Imu stream.
        """
        k = len(samples)
        n0 = self._start(t, k)
        if k == 0:
            return samples, np.ones(0, bool)
        if self._done[acc_index] is not None and n0 != self._done[acc_index]:
            raise ValueError(f'chunk starts at sample {n0}; the last one ended before '
                             f'{self._done[acc_index]}: chunks must follow each other')
        valid = np.ones(k, bool)
        stage = [f for f in self._by_acc[acc_index] if f.stage == 'after']
        for f in stage:   # holds first, from the values read, before any fault changes them
            f.capture(samples, n0, self._last[acc_index])
        last = samples[-1].copy()
        for f in stage:
            f.after(samples, n0, valid)
        self._last[acc_index] = last
        self._done[acc_index] = n0 + k
        return samples, valid

    def follow(self, t0: npt.ArrayLike, samples: np.ndarray, acc_index: int) -> None:
        """:meth:`after_limit` for a caller that does not need the validity mask: the same
        state kept (the last value read, where the stream is) and the same errors.

        For an accelerometer that has never had a fault this is bookkeeping only (no
        fault acts), done on Python numbers: the live step calls it per channel and chunk.

        Parameters
        ----------
        t0 : float or array_like
            The chunk's first sample time (s), or its times as :meth:`after_limit` takes
            them; chunks must follow each other.
        samples : ndarray, shape (k, 3)
            The samples after the range and ADC (m/s^2), changed in place by any fault.
        acc_index : int
            The accelerometer (dimensionless).
        """
        k = len(samples)
        if self._by_acc[acc_index] or not k or not isinstance(t0, float):
            self.after_limit(t0, samples, acc_index)
            return
        # np.rint and round both round half to even (and raise alike on inf, nan)
        n0 = round(float(t0) * self.sample_rate_hz)
        done = self._done[acc_index]
        if done is not None and n0 != done:
            raise ValueError(f'chunk starts at sample {n0}; the last one ended before '
                             f'{done}: chunks must follow each other')
        self._last[acc_index] = samples[-1].copy()
        self._done[acc_index] = n0 + k

    def apply(self, t: npt.ArrayLike, samples: npt.ArrayLike, acc_index: int,
              limit: Callable[[np.ndarray], object] | None = None
              ) -> tuple[np.ndarray, npt.NDArray[np.bool_]]:
        """Both stages on a copy of ``samples``, with the channel's limit between them.

        Parameters
        ----------
        t : array_like, shape (k,), or float
            Sample times (s), or the first one's.
        samples : array_like, shape (k, 3)
            Output-rate samples (m/s^2), before the channel's range and ADC if ``limit`` is
            given.
        acc_index : int
            The accelerometer (dimensionless).
        limit : callable, optional
            ``limit(x)``: the range and ADC in place on the (k, 3) array (e.g.
            ``lambda x: channel._limit(x, True)``); its return value is not used. Without
            it a gain or a rail is not clipped.

        Returns
        -------
        samples : ndarray, shape (k, 3)
            m/s^2.
        valid : ndarray of bool, shape (k,)
        """
        x = np.array(samples, dtype=float)
        if x.ndim != 2 or x.shape[1] != 3:
            raise ValueError(f'expected samples of shape (k, 3), got {x.shape}')
        self.before_limit(t, x, acc_index)
        if limit is not None:
            limit(x)
        return self.after_limit(t, x, acc_index)

    def valid_at(self, t: npt.ArrayLike, acc_index: int) -> npt.NDArray[np.bool_]:
        """Whether the samples at times ``t`` are there (not dropped), for any sample times:
        e.g. an Imu stream's (the sample each decimated value stands for).

        Parameters
        ----------
        t : array_like
            Sample times (s), on the output grid.
        acc_index : int
            The accelerometer (dimensionless).

        Returns
        -------
        ndarray of bool, shape of ``t``
        """
        n = np.rint(np.asarray(t, dtype=float) * self.sample_rate_hz).astype(np.int64)
        valid = np.ones(n.shape, bool)
        for f in self._by_acc[acc_index]:
            gone = f.invalid(n)
            if gone is not None:
                valid &= ~gone
        return valid

    # -- labels ------------------------------------------------------------------------------
    def labels(self) -> list[dict[str, Any]]:
        """Every fault added, for a log's metadata and a data set's manifest (JSON-able, SI).

        Returns
        -------
        list of dict
            In the order added: ``name``, ``kind``, ``accelerometer``, ``axes``, ``stage``
            (``'before_limit'``/``'after_limit'``), ``seed`` (random kinds; else None),
            ``parameters`` (the kind's values, SI; an intermittent rail's ``level`` as used),
            ``requested`` (``onset_s``, ``duration_s`` as given; None = now / until
            cleared), ``onset_s`` and ``end_s`` (the window (onset, end]: the samples with
            onset < t <= end; ``end_s`` None while it lasts until cleared),
            ``cleared_at_s`` (None unless cleared), ``samples`` (samples in its window so
            far), and ``events``: a spike's start times ``t_s`` and ``sign``, an
            intermittent's open periods ``open_s`` ([t0, t1], as the window); None else.
        """
        fs = self.sample_rate_hz
        out = []
        for f in self._faults:
            done = self._done[f.acc] or 0
            end = done if f.hi is None else min(done, f.hi)
            out.append({
                'name': f.name, 'kind': f.spec.kind, 'accelerometer': f.spec.accelerometer,
                'axes': f.spec.axes, 'stage': f'{f.stage}_limit', 'seed': f.seed,
                'parameters': dict(f.params),
                'requested': {'onset_s': f.spec.onset, 'duration_s': f.spec.duration},
                'onset_s': (f.lo - 1) / fs,
                'end_s': None if f.hi is None else (max(f.hi, f.lo) - 1) / fs,
                'cleared_at_s': f.cleared_at,
                'samples': max(0, end - f.lo),
                'events': f.events(max(done, f.lo)),
            })
        return out


__all__ = ['FaultInjector', 'OPEN_OVERDRIVE', 'channel_rail']
