"""One triaxial accelerometer's measurement chain, streamed chunk by chunk (issue 36).

:class:`SensorChannel` turns the model's mean acceleration per integrator step (m/s^2, model
frame, at the step rate ``fs = 1/dt``) into what a real channel publishes at the output rate
``fs / decimation``, in this order (each stage off when its spec entry is None)::

    step rate:   mounting M = S (I + T) R^T  ->  resonance  ->  IEPE high-pass
                 -> + sensor noise and bias  ->  anti-alias low-pass (4th-order Butterworth)
    output rate: pick every decimation-th step -> + live white noise -> range clip
                 -> + ADC noise, ADC clip, round to the ADC grid

and, beside it, the ground truth: the model acceleration through the same low-pass and pick and
no other stage. No stage looks ahead, so neither is delayed beyond the low-pass. With every
stage off (``spec=None``, the *ideal* channel) the samples are the ground truth plus the live
white noise, bit for bit what ``LiveSimulation.step`` computed before (``StreamingLowpass``
then the pick). The state of every stage is kept between calls, so any split of a run into
chunks gives the same bytes as one call.

The ADC's grid step is ``LSB = 2 full_scale / 2^bits / sensitivity`` (m/s^2) and its codes
run from ``-2^(bits-1)`` to ``2^(bits-1) - 1`` (two's complement): it reads
``-full_scale/sensitivity`` to ``full_scale/sensitivity - LSB``, and a value more than half an
LSB beyond either end is clipped (and counted), so every unclipped value is within ``LSB/2``
of its published sample. The range clips the output-rate samples, after the anti-alias filter:
a real sensor's amplifier clips before the DAQ's filter, whose ringing can then overshoot the
range a little; here the sensor's output never passes it (the count is of published values),
and only the DAQ noise added after it can put a published value beyond it (by a few of its
standard deviations).

Conventions (the stage's own docstrings say more):

* **mounting**: ``R = Rz(yaw) Ry(pitch) Rx(roll)`` holds the sensor's axes in the model frame,
  a tilted sensor reads ``R.T a``; the transverse sensitivity ``T`` is defined in
  :func:`.channel_design.transverse_matrix`; ``S = diag(1 + sensitivity_error)``.
* **resonance**: ``H(s) = wn^2/(s^2 + wn/Q s + wn^2)`` as 1 to 3 causal, stable biquads with
  zero latency, fitted over the published band ``0 .. min(lowpass, 0.45 fs)``: gain within
  0.5 %, phase within 0.5 deg, the lift within 10 % of itself (where it is at least 1e-4);
  a resonance that no such cascade matches is refused (why and how in
  :func:`.resonance_design.design_resonance`). :attr:`SensorChannel.delay_steps` is 0.
* **noise density** (one-sided, ``(m/s^2)/sqrt(Hz)``, as datasheets give it): white noise of
  ``sigma = density sqrt(fs / 2)`` per step, so a Welch (one-sided) PSD of the noise is
  ``density^2``. PX4 and Kalibr write ``sigma = n / sqrt(dt) = n sqrt(fs)`` with ``n`` the
  density of a continuous white noise whose two-sided PSD is ``n^2`` (``E[w(t) w(t+s)] =
  n^2 delta(s)``); that is our density ``/ sqrt(2)``: a datasheet's one-sided figure put into
  their formula gives sqrt(2) (3 dB) more noise than the datasheet states.
* **bias**: turn-on (a constant per axis, N(0, turn_on) drawn once from the seed);
  Gauss-Markov in Gazebo's convention (driving strength sigma, steady spread
  ``sigma sqrt(tau/2)``, started from its steady distribution); random walk (Allan deviation
  ``rw sqrt(tau/3)``), started at 0. All three are in the sensor frame, added after the
  high-pass (a MEMS part has no high-pass; an IEPE part's bias is usually left off).
* **seeds**: every random stream comes from ``SeedSequence([seed, crc32(name)])`` spawned into
  one child per stage, in a fixed order, so switching one stage on or off moves no other
  stage's numbers, and two channels of one seed but different names are independent. The live
  white noise is the exception: :meth:`SensorChannel.set_white_noise` with a seed restarts it
  as ``default_rng(seed)``, today's node noise (``noise_std``/``noise_seed``); until then it
  draws from its own child.

Everything is SI; no ROS.
"""
from __future__ import annotations

import dataclasses
import math
import zlib
from collections.abc import Callable, Mapping
from typing import Any, cast

import numpy as np
import numpy.typing as npt

from .channel_design import highpass_sos, mounting_matrix
from .channel_keys import resolve_spec
from .filters import butter_lowpass_sos
from .resonance_design import design_resonance

#: The compiled ``sosfilt(sos, x, zi, y)`` kernel: filters ``x`` into ``y``, state ``zi``
_SosFilt = Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray], object]

#: Order of the anti-alias Butterworth (as ``StreamingLowpass``'s default, which it replaces).
LOWPASS_ORDER = 4
#: Random streams, one SeedSequence child each, in this fixed order (append, never reorder).
STREAMS = ('sensor_noise', 'turn_on', 'gauss_markov', 'random_walk', 'adc_noise', 'white_noise')


@dataclasses.dataclass
class ChannelOutput:
    """What :meth:`SensorChannel.process` returns for one chunk.

    Attributes
    ----------
    samples : ndarray, shape (k, 3)
        Published acceleration (m/s^2, sensor frame), output rate.
    truth : ndarray, shape (k, 3)
        Model acceleration (m/s^2, model frame) through the same low-pass and pick and no
        other stage.
    clipped : int
        Sample values (one per axis) this chunk clipped at the range or the ADC's full scale.
    """

    samples: np.ndarray
    truth: np.ndarray
    clipped: int


class SensorChannel:
    """One triaxial accelerometer's measurement chain, ROS-free, streamed chunk by chunk.

    Parameters
    ----------
    spec : dict or None
        The resolved sensor spec (SI; every key of :data:`.channel_keys.SPEC_KEYS`, None =
        stage off), or None for the ideal channel. Keys: ``preset`` (str), ``sensitivity``
        (V/(m/s^2)), ``sensitivity_error`` (3 x dimensionless), ``orientation`` ([roll, pitch,
        yaw] rad), ``transverse`` ({fraction: dimensionless, angle: rad}), ``resonance``
        ({frequency: Hz, q: dimensionless}), ``highpass`` ({corner: Hz}), ``noise_density``
        ((m/s^2)/sqrt(Hz), one-sided), ``bias`` ({turn_on: m/s^2, gauss_markov: {sigma:
        (m/s^2)/sqrt(s), tau: s}, random_walk: (m/s^2)/sqrt(s)}, each may be None),
        ``range`` (m/s^2, peak), ``adc`` ({bits: int, full_scale: V peak, noise: V rms};
        needs ``sensitivity``).
    step_rate_hz : float
        Integrator step rate ``1/dt`` (Hz), the rate of :meth:`process`'s input.
    decimation : int
        Steps per output sample (dimensionless), >= 1.
    lowpass_hz : float
        Anti-alias cutoff (Hz), below ``step_rate_hz / 2``.
    seed : int
        Seed of the stage streams (dimensionless, >= 0).
    name : str
        Accelerometer name: in error messages, labels and the seed.

    Raises
    ------
    ValueError
        A bad rate, cutoff or spec value; the message names the key.
    """

    def __init__(self, spec: Mapping[str, Any] | None, *, step_rate_hz: float, decimation: int,
                 lowpass_hz: float, seed: int = 0, name: str = '') -> None:
        self.name = str(name)
        self.step_rate_hz = float(step_rate_hz)
        self.decimation = int(decimation)
        self.lowpass_hz = float(lowpass_hz)
        self.seed = int(seed)
        fs = self.step_rate_hz
        if not (math.isfinite(fs) and fs > 0):
            raise ValueError(self._msg(f'step rate must be finite and > 0 Hz, got {fs!r}'))
        if self.decimation < 1 or self.decimation != decimation:
            raise ValueError(self._msg(f'decimation must be a whole number >= 1, '
                                       f'got {decimation!r}'))
        if not 0.0 < self.lowpass_hz < 0.5 * fs:
            raise ValueError(self._msg(f'low-pass cutoff {self.lowpass_hz:g} Hz must lie in '
                                       f'(0, {0.5 * fs:g}) Hz, the Nyquist frequency of the '
                                       f'step rate'))
        if self.seed < 0:
            raise ValueError(self._msg(f'seed must be >= 0, got {seed!r}'))
        self.spec = resolve_spec(spec, self._msg)
        s = self.spec
        self._lp_sos = butter_lowpass_sos(LOWPASS_ORDER, self.lowpass_hz, fs)
        self._pick = slice(self.decimation - 1, None, self.decimation)
        children = np.random.SeedSequence([self.seed, zlib.crc32(self.name.encode())]).spawn(
            len(STREAMS))
        rng = {k: np.random.default_rng(c) for k, c in zip(STREAMS, children)}
        # 1. mounting
        self.mounting = mounting_matrix(s['orientation'], s['transverse'],
                                        s['sensitivity_error'])
        # 2. resonance: its biquads (none when the in-band effect is below the tolerances),
        # ahead of the high-pass in one sos cascade
        self.resonance = None
        pre: list[np.ndarray] = []
        if s['resonance'] is not None:
            try:
                self.resonance = design_resonance(s['resonance']['frequency'],
                                                  s['resonance']['q'], fs, self.lowpass_hz)
            except ValueError as exc:
                raise ValueError(self._msg(str(exc))) from None
            pre.extend(self.resonance.sos)
        # 3. high-pass
        if s['highpass'] is not None:
            pre.append(highpass_sos(s['highpass']['corner'], fs)[0])
        self._pre_sos = np.array(pre) if pre else None
        # 4. noise and bias (sensor frame, step rate)
        density = s['noise_density']
        self.noise_std_per_step = 0.0 if density is None else density * math.sqrt(0.5 * fs)
        self._rng_noise = rng['sensor_noise']
        bias = s['bias'] or {}
        self.turn_on_bias = None
        if bias.get('turn_on') is not None:
            self.turn_on_bias = rng['turn_on'].normal(0.0, bias['turn_on'], 3)
        self._gm = self._rw = None
        gm = bias.get('gauss_markov')
        if gm is not None:
            phi = math.exp(-1.0 / (fs * gm['tau']))
            drive = gm['sigma'] * math.sqrt(0.5 * gm['tau'] * -math.expm1(-2.0 / (fs * gm['tau'])))
            steady = gm['sigma'] * math.sqrt(0.5 * gm['tau'])
            zi = np.zeros((1, 2, 3))
            zi[0, 0] = phi * rng['gauss_markov'].normal(0.0, steady, 3)   # b[-1] ~ steady
            self._gm = (np.array([[1.0, 0.0, 0.0, 1.0, -phi, 0.0]]), zi, drive,
                        rng['gauss_markov'])
        if bias.get('random_walk') is not None:
            self._rw = (np.array([[1.0, 0.0, 0.0, 1.0, -1.0, 0.0]]), np.zeros((1, 2, 3)),
                        bias['random_walk'] / math.sqrt(fs), rng['random_walk'])
        # 6. output rate: range and ADC
        self.range = s['range']
        self._adc = None
        if s['adc'] is not None:
            adc, sens = s['adc'], s['sensitivity']
            lsb = 2.0 * adc['full_scale'] / 2.0 ** adc['bits'] / sens
            half = 2.0 ** (adc['bits'] - 1)
            self._adc = (lsb, -half, half - 1.0, adc['noise'] / sens, rng['adc_noise'])
        self.white_noise_std = 0.0
        self.white_noise_seed: int | None = None
        self._rng_white = rng['white_noise']
        self._step_ideal = (self.mounting is None and self._pre_sos is None
                            and not self._has_sensor_noise)
        # state
        self._zi_lp = np.zeros((self._lp_sos.shape[0], 2, 3 if self._step_ideal else 6))
        self._zi_pre = (None if self._pre_sos is None
                        else np.zeros((self._pre_sos.shape[0], 2, 3)))
        self._lp_energy: np.ndarray | None = None
        self._sosfilt: _SosFilt | None = None
        # scratch arrays per chunk length (steps) and per limited shape: see _step_work
        self._work: dict[int, tuple[np.ndarray, ...]] = {}
        self._limit_work: dict[tuple[int, ...], tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        # the range's and the ADC's constants as 0-d arrays for _limit: (r, -r); (lsb, lo, hi)
        self._range_0d = (None if self.range is None
                          else (np.array(float(self.range)), np.array(-float(self.range))))
        self._adc_0d = None if self._adc is None else tuple(np.array(v) for v in self._adc[:3])
        # the compiled chain (kernels/channel_chunk.py) covers every channel whose ADC has a
        # code above 0 (bits >= 2): NumPy's minimum and maximum may order a tie of -0.0 and
        # 0.0 either way, a compiled comparison keeps the code's sign
        self._compiled = self._adc is None or self._adc[2] >= 1.0
        # its constant arguments; a stage that is off is an array with no rows
        none2, none3 = np.empty((0, 6)), np.empty((0, 2, 3))
        self._limits = np.array(
            [0.0 if self.range is None else 1.0, self.range or 0.0, -(self.range or 0.0),
             0.0 if self._adc is None else 1.0, *(self._adc[:3] if self._adc else (1, 0, 1))])
        self._no_rows = np.empty((0, 3))
        self._chain_consts = (
            none2 if self._pre_sos is None else self._pre_sos,
            none3 if self._zi_pre is None else self._zi_pre,
            np.empty(0) if self.turn_on_bias is None else self.turn_on_bias,
            *((none2, none3) if self._gm is None else self._gm[:2]),
            *((none2, none3) if self._rw is None else self._rw[:2]))
        self._mount_t = None if self.mounting is None else self.mounting.T
        self._kernels: tuple[Any, Any] | None = None

    def _load_kernel(self) -> _SosFilt:
        # imported on first use, as StreamingLowpass does: importing this module loads no Numba
        from ..integrate.kernels.filters import sosfilt
        self._sosfilt = sosfilt
        return sosfilt

    def _load_chain(self) -> tuple[Any, Any]:
        from ..integrate.kernels.channel_chunk import channel_chunk, limit
        # the limit a fault's chunk calls from here, compiled (or loaded) now, where the node
        # warms up, not in the paced tick of the first fault
        limit(np.empty((0, 1, 3)), 0, self._no_rows, self._limits)
        self._kernels = (channel_chunk, limit)
        return self._kernels

    # -- properties ----------------------------------------------------------------------
    @property
    def output_rate_hz(self) -> float:
        """float: Output sample rate ``step_rate_hz / decimation`` (Hz)."""
        return self.step_rate_hz / self.decimation

    #: int: Latency of the chain beyond the anti-alias filter's own (integrator steps): 0,
    #: always (the resonance is realised without a look-ahead); kept for its readers.
    delay_steps = 0

    @property
    def ideal(self) -> bool:
        """bool: No stage changes the numbers: samples = the ground truth (+ white noise)."""
        return self._step_ideal and self.range is None and self._adc is None

    @property
    def delay_s(self) -> float:
        """float: :attr:`delay_steps` in seconds: 0."""
        return self.delay_steps / self.step_rate_hz

    @property
    def lsb(self) -> float | None:
        """float or None: The ADC grid's step in acceleration (m/s^2); None without an ADC."""
        return None if self._adc is None else self._adc[0]

    @property
    def _has_sensor_noise(self) -> bool:
        return (self.noise_std_per_step > 0 or self.turn_on_bias is not None
                or self._gm is not None or self._rw is not None)

    def _msg(self, text: str) -> str:
        return f'accelerometer {self.name!r}: {text}' if self.name else text

    # -- set-up --------------------------------------------------------------------------
    def set_white_noise(self, std: float, seed: int | None = None) -> None:
        """Set the live white noise added to each output sample; optionally restart it.

        Parameters
        ----------
        std : float
            Standard deviation per output sample and axis (m/s^2), finite, >= 0.
        seed : int, optional
            Restart this stream (only this one) as ``numpy.random.default_rng(seed)``
            (dimensionless); None keeps its position.

        Raises
        ------
        ValueError
            A negative or non-finite ``std``; nothing changes.
        """
        std = float(std)
        if not (math.isfinite(std) and std >= 0):
            raise ValueError(self._msg(f'noise std: must be finite and >= 0 '
                                       f'm/s^2, got {std}'))
        self.white_noise_std = std
        if seed is not None:
            self.white_noise_seed = int(seed)
            self._rng_white = np.random.default_rng(int(seed))

    # -- streaming -----------------------------------------------------------------------
    def process(self, mean_acc: npt.ArrayLike,
                before_limit: Callable[[np.ndarray], object] | None = None) -> ChannelOutput:
        """Run the next chunk through the chain.

        Parameters
        ----------
        mean_acc : array_like, shape (k * decimation, 3)
            Mean acceleration over each integrator step (m/s^2, model frame).
        before_limit : callable, optional
            Called with the ``(k, 3)`` output-rate samples (m/s^2, sensor frame) after the
            live white noise and before the range and ADC, to change them in place: a
            sensor fault (:meth:`.faults.FaultInjector.hook`) then reaches the clipping,
            the clip count and the ADC grid as the real one would.

        Returns
        -------
        ChannelOutput
            ``k`` output samples (sensor frame), the ground truth (model frame), the clip
            count; every value in m/s^2. Neither is delayed beyond the anti-alias filter.
        """
        a = np.ascontiguousarray(mean_acc, dtype=float)
        if a.ndim != 2 or a.shape[1] != 3 or a.shape[0] % self.decimation:
            raise ValueError(self._msg(f'expected shape (k * {self.decimation}, 3), '
                                       f'got {a.shape}'))
        k = a.shape[0] // self.decimation
        samples, truth = np.empty((k, 1, 3)), np.empty((k, 1, 3))
        clipped = self._process_chunk(a, before_limit, samples, truth, 0)
        return ChannelOutput(samples[:, 0], truth[:, 0], clipped)

    def _process_chunk(self, a: np.ndarray, before_limit: Callable[[np.ndarray], object] | None,
                       samples: np.ndarray, truth: np.ndarray, acc: int) -> int:
        """:meth:`process` of a checked C-contiguous ``(k * decimation, 3)`` float chunk
        ``a`` (m/s^2) into ``samples[:, acc, :]`` and ``truth[:, acc, :]`` (each C-contiguous
        ``(k, n, 3)``, m/s^2; ``LiveSimulation.step`` passes its batch's arrays); returns the
        clip count. The compiled chain (:mod:`~impact_damper_sim.integrate.kernels.
        channel_chunk`) with the same draws from the same generators, in the same order, as
        :meth:`_process_into` (its NumPy twin, which a 1-bit ADC still takes): the same
        bytes."""
        if not self._compiled:
            return self._process_into(a, before_limit, samples[:, acc], truth[:, acc])
        chain, limit = self._kernels or self._load_chain()
        n = a.shape[0]
        work = self._work.get(n)
        if work is None:
            work = self._step_work(n)
        x, y, s, mounted, b = work
        # the mounting's product stays NumPy's (BLAS: a loop would not round alike)
        m = a if self._mount_t is None else np.matmul(a, self._mount_t, out=mounted)
        none = self._no_rows
        noise = (self._rng_noise.normal(0.0, self.noise_std_per_step, (n, 3))
                 if self.noise_std_per_step > 0 else none)
        gm_w = none if self._gm is None else self._gm[3].normal(0.0, self._gm[2], (n, 3))
        rw_w = none if self._rw is None else self._rw[3].normal(0.0, self._rw[2], (n, 3))
        k = n // self.decimation
        white = (self._rng_white.normal(0.0, self.white_noise_std, (k, 3))
                 if self.white_noise_std > 0 else none)
        adc = self._adc
        adc_noise = adc[4].normal(0.0, adc[3], (k, 3)) if adc is not None and adc[3] > 0 \
            else none
        pre_sos, zi_pre, bias, gm_sos, gm_zi, rw_sos, rw_zi = self._chain_consts
        # no early return for k = 0: that call compiles the kernels where the node warms up
        clipped = chain(a, m, pre_sos, zi_pre, noise, bias, gm_sos, gm_zi, gm_w, rw_sos, rw_zi,
                        rw_w, self._lp_sos, self._zi_lp, x, y, s, b, self.decimation, white,
                        samples, truth, acc, self._limits, adc_noise, before_limit is None)
        if before_limit is None:
            return int(clipped)
        before_limit(samples[:, acc])   # a fault acts before the range and ADC
        return int(limit(samples, acc, adc_noise, self._limits))

    def _process_into(self, a: np.ndarray, before_limit: Callable[[np.ndarray], object] | None,
                      samples: np.ndarray, truth: np.ndarray) -> int:
        """:meth:`process` of a checked C-contiguous ``(k * decimation, 3)`` float chunk
        ``a`` (m/s^2) into ``samples`` and ``truth`` (each ``(k, 3)``, any strides, m/s^2);
        returns the clip count. The same operations in the same order, without the checks,
        the output allocations or the :class:`ChannelOutput`: the NumPy twin of
        :meth:`_process_chunk` (``test/test_channel_chunk.py``)."""
        sosfilt = self._sosfilt or self._load_kernel()
        work = self._work.get(a.shape[0])
        if work is None:
            work = self._step_work(a.shape[0])
        # no early return for k = 0: that call compiles the kernel where the node warms up
        if self._step_ideal:
            y = work[1]
            sosfilt(self._lp_sos, a, self._zi_lp, y)
            picked = y[self._pick]
            truth[...] = picked
            samples[...] = picked
        else:
            x, y = work[0], work[1]
            x[:, :3] = a
            x[:, 3:] = self._step_chain(a, sosfilt, work[2])
            sosfilt(self._lp_sos, x, self._zi_lp, y)
            picked = y[self._pick]
            truth[...] = picked[:, :3]
            samples[...] = picked[:, 3:]
        if self.white_noise_std > 0:
            samples += self._rng_white.normal(0.0, self.white_noise_std, samples.shape)
        if before_limit is not None:
            before_limit(samples)
        return self._limit(samples, self._adc is not None and self._adc[3] > 0)

    def _step_work(self, n: int) -> tuple[np.ndarray, ...]:
        """Scratch arrays of an ``n``-step chunk, made once per chunk length (a live run
        steps one length): the low-pass's input and output, the sensor-frame signal, the
        mounted signal and a bias process's output."""
        if len(self._work) >= 8:   # chunk lengths vary (a paced run catching up): keep few
            self._work.clear()
        width = 3 if self._step_ideal else 6
        work = (np.empty((n, width)), np.empty((n, width)), np.empty((n, 3)), np.empty((n, 3)),
                np.empty((n, 3)))
        self._work[n] = work
        return work

    def _step_chain(self, a: np.ndarray, sosfilt: _SosFilt,
                    scratch: np.ndarray | None = None) -> np.ndarray:
        """Stages 1-4 at the step rate: (n, 3) model frame -> (n, 3) sensor, before the LP.

        ``scratch``, an (n, 3) array, receives the result when given (it may be returned)."""
        x = a if self.mounting is None else a @ self.mounting.T
        if self._pre_sos is not None:
            assert self._zi_pre is not None   # made with _pre_sos
            y = np.empty_like(x) if scratch is None else scratch
            sosfilt(self._pre_sos, np.ascontiguousarray(x), self._zi_pre, y)
            x = y
        elif x is a:
            if scratch is None:
                x = a.copy()
            else:
                scratch[...] = a
                x = scratch
        n = len(x)
        if self.noise_std_per_step > 0:
            x += self._rng_noise.normal(0.0, self.noise_std_per_step, (n, 3))
        if self.turn_on_bias is not None:
            x += self.turn_on_bias
        for proc in (self._gm, self._rw):
            if proc is not None:
                sos, zi, drive, rng = proc
                w = rng.normal(0.0, drive, (n, 3))
                b = np.empty_like(w)
                sosfilt(sos, w, zi, b)
                x += b
        return x

    def _limit(self, x: np.ndarray, adc_noise: bool) -> int:
        """Range clip and ADC (noise, clip, grid) in place; the number of clipped values."""
        work = self._limit_work.get(x.shape)
        if work is None:
            if len(self._limit_work) >= 8:
                self._limit_work.clear()
            work = self._limit_work[x.shape] = (np.empty(x.shape), np.empty(x.shape, bool),
                                                np.empty(x.shape, bool))
        scratch, over, high = work
        # ufuncs into scratch arrays, not np.clip nor new arrays, and the constants as 0-d
        # arrays (a Python float operand costs a ufunc call twice as much): the same values
        clips = False
        if self._range_0d is not None:
            r, minus_r = self._range_0d
            np.greater(np.abs(x, out=scratch), r, out=over)
            np.minimum(x, r, out=x)
            np.maximum(x, minus_r, out=x)
            clips = True
        if self._adc is not None:
            assert self._adc_0d is not None   # made with _adc
            lsb, lo, hi = self._adc_0d
            if adc_noise:
                x += self._adc[4].normal(0.0, self._adc[3], x.shape)
            codes = np.rint(np.divide(x, lsb, out=scratch), out=scratch)
            # the ADC's codes run -2^(b-1) .. 2^(b-1) - 1: a value past half an LSB beyond
            # the end codes is clipped (so every unclipped value is within LSB/2 of its code)
            if clips:
                np.logical_or(over, np.less(codes, lo, out=high), out=over)
            else:
                np.less(codes, lo, out=over)
            np.logical_or(over, np.greater(codes, hi, out=high), out=over)
            np.minimum(codes, hi, out=codes)
            np.maximum(codes, lo, out=codes)
            np.multiply(codes, lsb, out=x)
            clips = True
        return int(np.count_nonzero(over)) if clips else 0

    def process_decimated(self, imu: npt.ArrayLike) -> tuple[npt.NDArray[np.float64], int]:
        """Range clip and re-quantize samples decimated from this channel's output.

        ``LiveSimulation`` decimates the output-rate samples through its FIR
        (``StreamingDecimator``) into the per-sample Imu stream; its averages leave the range
        and the ADC grid, so they are clipped and rounded to the grid again (no ADC noise:
        the decimation is digital).

        Parameters
        ----------
        imu : array_like, shape (j, 3)
            Decimated samples (m/s^2, sensor frame).

        Returns
        -------
        imu_out : ndarray, shape (j, 3)
            In range and on the grid (m/s^2).
        clipped : int
            Values clipped here (counted apart from :meth:`process`'s).
        """
        x = np.array(imu, dtype=float)
        if x.ndim != 2 or x.shape[1] != 3:
            raise ValueError(self._msg(f'expected shape (j, 3), got {x.shape}'))
        return x, self._limit(x, False)

    # -- noise bookkeeping ---------------------------------------------------------------
    def _lp_impulse(self) -> np.ndarray:
        """Impulse response of the anti-alias low-pass at the step rate, to its last 1e-18."""
        if self._lp_energy is None:
            sosfilt = self._sosfilt or self._load_kernel()
            n = int(64 * self.step_rate_hz / self.lowpass_hz) + 64
            while True:
                x = np.zeros((n, 1))
                x[0] = 1.0
                h = np.empty_like(x)
                sosfilt(self._lp_sos, x, np.zeros((self._lp_sos.shape[0], 2, 1)), h)
                h = h[:, 0]
                if np.sum(h[-n // 4:] ** 2) < 1e-18 * np.sum(h ** 2):
                    break
                n *= 2
            self._lp_energy = h
        return self._lp_energy

    def _output_white_variance(self) -> float:
        lsb_var = 0.0 if self._adc is None else self._adc[0] ** 2 / 12.0
        adc_var = 0.0 if self._adc is None else self._adc[3] ** 2
        return self.white_noise_std ** 2 + adc_var + lsb_var

    def output_noise_variance(self) -> float:
        """Variance of the white noise in each output sample, per axis ((m/s^2)^2).

        The sensor noise (``noise_density``) through the low-pass (its impulse response's
        energy at the step rate), the live white noise, the ADC noise and the quantization
        (``LSB^2 / 12``). Not the biases (turn-on, Gauss-Markov, random walk: not white) and
        not clipping.

        Returns
        -------
        float
        """
        sensor = 0.0
        if self.noise_std_per_step > 0:
            sensor = self.noise_std_per_step ** 2 * float(np.sum(self._lp_impulse() ** 2))
        return sensor + self._output_white_variance()

    def decimated_noise_variance(self, taps: npt.ArrayLike) -> float:
        """:meth:`output_noise_variance` for a sample of an FIR decimator of this output.

        The sensor noise is coloured by the low-pass before the pick: its share is exact,
        ``noise_std_per_step^2 sum(g^2)`` with ``g`` the low-pass impulse response (step rate)
        convolved with the taps spread ``decimation`` steps apart; the output-rate white
        terms keep ``sum(taps^2)``; :meth:`process_decimated`'s rounding adds ``LSB^2/12``.

        Parameters
        ----------
        taps : array_like, shape (n,)
            The decimator's FIR taps at the output rate (dimensionless).

        Returns
        -------
        float
            (m/s^2)^2 per axis.
        """
        taps = np.asarray(taps, dtype=float).ravel()
        var = self._output_white_variance() * float(np.sum(taps ** 2))
        if self._adc is not None:
            var += self._adc[0] ** 2 / 12.0
        if self.noise_std_per_step > 0:
            spread = np.zeros((len(taps) - 1) * self.decimation + 1)
            spread[::self.decimation] = taps
            g = np.convolve(self._lp_impulse(), spread)
            var += self.noise_std_per_step ** 2 * float(np.sum(g ** 2))
        return var

    # -- labels --------------------------------------------------------------------------
    def labels(self) -> dict[str, Any]:
        """Every stage's values (SI, JSON-able) for a log's metadata.

        Returns
        -------
        dict
            The spec as given (None = off) plus what the channel derived: the mounting matrix,
            the resonance section (its biquads and errors), the per-step noise, the drawn
            turn-on bias, the ADC's LSB, the white noise, the rates, the latency (0) and the
            output noise variance.
        """
        s = self.spec
        res = None
        if self.resonance is not None:
            d = self.resonance
            res = {**s['resonance'], 'band_hz': float(d.band_hz),
                   'gain_error': float(d.gain_error),
                   'phase_error_deg': float(d.phase_error_deg),
                   'lift_error': float(d.lift_error), 'sos': d.sos.tolist(),
                   'b': [float(v) for v in d.b], 'a': [float(v) for v in d.a]}
        adc = None
        if s['adc'] is not None and self._adc is not None:
            adc = {**s['adc'], 'lsb': float(self._adc[0])}
        bias = None
        if s['bias'] is not None:
            bias = {**s['bias'], 'turn_on_values': (None if self.turn_on_bias is None else
                                                    [float(v) for v in self.turn_on_bias])}
        return cast(dict[str, Any], _jsonable({
            'name': self.name, 'preset': s['preset'], 'seed': self.seed,
            'ideal': self.ideal,
            'step_rate_hz': self.step_rate_hz, 'decimation': self.decimation,
            'output_rate_hz': self.output_rate_hz,
            'lowpass': {'cutoff_hz': self.lowpass_hz, 'order': LOWPASS_ORDER,
                        'kind': 'butterworth'},
            'sensitivity': s['sensitivity'], 'sensitivity_error': s['sensitivity_error'],
            'orientation': s['orientation'], 'transverse': s['transverse'],
            'mounting_matrix': None if self.mounting is None else self.mounting.tolist(),
            'resonance': res, 'highpass': s['highpass'],
            'noise_density': s['noise_density'], 'noise_std_per_step': self.noise_std_per_step,
            'bias': bias, 'range': s['range'], 'adc': adc,
            'white_noise': {'std': self.white_noise_std, 'seed': self.white_noise_seed},
            'delay_steps': self.delay_steps, 'delay_s': self.delay_s,
            'output_noise_variance': self.output_noise_variance(),
        }))


def _jsonable(v: object) -> object:
    if isinstance(v, dict):
        return {str(k): _jsonable(x) for k, x in v.items()}
    if isinstance(v, (list, tuple, np.ndarray)):
        return [_jsonable(x) for x in v]
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, (int, np.integer)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        return float(v)
    return v


__all__ = ['ChannelOutput', 'LOWPASS_ORDER', 'STREAMS', 'SensorChannel']
