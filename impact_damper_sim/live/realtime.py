"""A scene stepped in chunks for a live stream: accelerometers, events, commands, pacing.

This is the core that ``vibration_node`` owns; it imports no ROS, so callbacks' logic is
tested here with plain NumPy. Everything is SI.

* :class:`LiveSimulation` steps a scene's modal model and turns its output into what the
  node publishes: per accelerometer, the node's acceleration on three axes (m/s^2, mean over
  each integrator step, through the anti-alias low-pass, decimated to the output rate, plus
  optional noise) and angular velocity (rad/s); impact events; impactor states; the applied
  rotor speed and unbalance multiplier; the tachometer (the rotor angle the unbalance force
  uses, at every output sample, and the once-per-revolution keyphasor times). Speed and
  unbalance commands are validated here.

When to step and what to send is :mod:`.pacing`'s. Messages name quantities (``speed``,
``sample rate``), never the topics or parameters an adapter sets them with.

The scene it steps is loaded, and its accelerometers and output rates are chosen, in
:mod:`.streams`.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ..integrate.divergence import Divergence
from ..scene.advice import scene_advice
from ..scene.excitation import CommandedSpeed
from ..scene.schema import SceneError
from .batch import Batch
from .fault_spec import FaultError
from .faults import FaultInjector
from .streams import accelerometers, default_imu_rate, default_sample_rate

if TYPE_CHECKING:
    from ..scene.build import SceneModel
    from .channel import SensorChannel
    from .fault_spec import FaultSpec

_TRANSLATIONS = ('ux', 'uy', 'uz')
_ROTATIONS = ('rx', 'ry', 'rz')
_TWO_PI = 2.0 * math.pi

#: One keyphasor event: the time (s) the rotor angle reached 2 pi ``revolution`` (the shaft's
#: zero mark passing the probe; revolution 1 first) and the speed then (rad/s).
KEYPHASOR_DTYPE = np.dtype([('t', '<f8'), ('revolution', '<i8'), ('speed', '<f8')])


#: Growth rates below this fraction of the largest eigenvalue modulus are rounding, not
#: instability (dimensionless): the eigensolver's error is ~1e-16 of it, and at the largest
#: modulus of the shipped scenes (~1e4 rad/s) the threshold is a time constant of hours.
GROWTH_RATE_NOISE = 1e-8


class CommandError(ValueError):
    """A rejected command; the message (``'<quantity>: ...'``) names the quantity and its
    allowed range."""


class LiveSimulation:
    """A scene stepped chunk by chunk into accelerometer streams and events.

    Parameters
    ----------
    scene_model : SceneModel
        Built scene; its rotor, if any, must be commanded (see :func:`~.streams.live_scene`).
    sample_rate : float, optional
        Output sample rate (Hz), > 2 x every anti-alias cutoff; default
        :func:`default_sample_rate`. The integrator step is the largest step not above the
        scene's ``simulation.dt`` that divides the output period.
    imu_rate : float, optional
        Rate of the decimated per-sample stream (Hz), ``sample_rate / k`` for a whole
        number k; default :func:`default_imu_rate`. Decimated through a linear-phase
        anti-alias FIR (flat to 0.4 x ``imu_rate``, 80 dB from 0.5 x ``imu_rate`` on).
        k is at most :data:`~.filters.MAX_DECIMATION_FACTOR` (2000): the FIR has ~52 k taps.
    initial_target : float, optional
        Rotor speed commanded at t = 0 (rad/s).
    max_speed : float, optional
        Largest accepted speed command (rad/s); default twice ``initial_target`` (or
        twice the initial speed, or 1e4 rad/s when both are zero).
    max_unbalance : float
        Largest accepted unbalance multiplier (dimensionless).
    noise_std : float
        Standard deviation of white noise added to each acceleration sample (m/s^2), in the
        channel before its range and ADC.
    seed : int
        Seed of the noise generator, of every random stage of the channels and of the
        sensor faults' default seeds (dimensionless).
    dampers_enabled : bool
        Whether the impact dampers act.
    method : str, optional
        Integration method; default the scene's.
    ledger : bool
        Keep the integrator's energy ledger (off by default: it costs CPU every step and a
        live stream does not report it).
    """

    def __init__(self, scene_model: SceneModel, *, sample_rate: float | None = None,
                 imu_rate: float | None = None, initial_target: float | None = None,
                 max_speed: float | None = None, max_unbalance: float = 100.0,
                 noise_std: float = 0.0, seed: int = 0, dampers_enabled: bool = True,
                 method: str | None = None, ledger: bool = False) -> None:
        from .filters import MAX_DECIMATION_FACTOR, StreamingDecimator
        sample_rate = (default_sample_rate(scene_model) if sample_rate is None
                       else float(sample_rate))
        if not (math.isfinite(sample_rate) and sample_rate > 0):
            raise SceneError(f"sample rate: must be a finite rate > 0 Hz, "
                             f'got {sample_rate}')
        self.scene = scene_model
        self.sample_rate = sample_rate
        self.accelerometers = accelerometers(scene_model, sample_rate)
        for acc in self.accelerometers:
            if not acc.lowpass_hz < 0.5 * sample_rate:
                raise SceneError(f"sample rate: {sample_rate:g} Hz must exceed "
                                 f'twice the anti-alias cutoff {acc.lowpass_hz:g} Hz of '
                                 f'accelerometer {acc.name!r} (> {2 * acc.lowpass_hz:g} Hz)')
        dt_scene = float(scene_model.scene['simulation']['dt'])
        self.decimation = max(1, math.ceil(1.0 / (dt_scene * sample_rate) - 1e-9))
        self.dt = 1.0 / (sample_rate * self.decimation)
        method = method or scene_model.scene['simulation']['method']
        if method == 'direct':
            raise SceneError("scene key 'simulation.method': the live node steps the modal "
                             "model; use exact, newmark or newmark_step_end")
        names, rows = self._output_rows()
        self.sim = scene_model.make_simulation(method=method, dt=self.dt,
                                               outputs=(names, rows), ledger=ledger)
        # each impactor's DOF count, and which (impactor, column) cells of the integrator's
        # (n_i, 2) state arrays hold them, row-major: impactor_state_arrays' flat order
        self._impactor_dims = [imp.dim for imp in self.sim.integrator.model.impactors]
        self._impactor_cells = (np.arange(2) < np.asarray(self._impactor_dims,
                                                          dtype=int).reshape(-1, 1))
        n_acc = len(self.accelerometers)
        self.channels = self._channels(seed)
        # each channel's range and ADC for the compiled Imu limit (kernels/channel_chunk.py),
        # none for the channels it does not cover: those NumPy's (SensorChannel._limit)
        self._imu_numpy = [a for a, ch in enumerate(self.channels) if not ch._compiled]
        self._imu_limits = np.array([ch._limits if ch._compiled else np.zeros(7)
                                     for ch in self.channels]).reshape(n_acc, 7)
        imu_rate = default_imu_rate(sample_rate) if imu_rate is None else float(imu_rate)
        factor = sample_rate / imu_rate if math.isfinite(imu_rate) and imu_rate > 0 else 0.0
        if factor > MAX_DECIMATION_FACTOR + 0.5:   # the anti-alias FIR is ~52 x k taps
            raise SceneError(f'imu rate: must be in [{sample_rate / MAX_DECIMATION_FACTOR:g}, '
                             f'{sample_rate:g}] Hz (sample rate / k, k at most '
                             f'{MAX_DECIMATION_FACTOR}), got {imu_rate:g} Hz')
        if not (factor >= 1 - 1e-9 and abs(factor - round(factor)) < 1e-6 * factor):
            raise SceneError(f"imu rate: must be the sample rate "
                             f'{sample_rate:g} Hz divided by a whole number (e.g. '
                             f'{default_imu_rate(sample_rate):g} Hz), got {imu_rate:g} Hz')
        self.imu_rate = sample_rate / round(factor)
        self._decimator = StreamingDecimator(round(factor), sample_rate, 6 * n_acc)
        self._t_first: float | None = None       # time of the first one (s)
        self._v_prev = np.zeros(6 * n_acc)
        self._pick = slice(self.decimation - 1, None, self.decimation)   # the output steps
        self._mean_work: dict[int, list[np.ndarray]] = {}   # step's scratch per chunk length
        self._kernels: tuple[Any, Any] | None = None   # see _load_kernels
        # a 0-d operand: a cheaper ufunc call than with a Python float, the same values
        self._sample_rate_0d = np.array(sample_rate)
        self.max_unbalance = float(max_unbalance)
        self.profile = scene_model.speed_profile
        self.unbalance = scene_model.unbalance
        #: the rate limit at start (rad/s^2): a speed rate limit of 0 restores it
        self.start_speed_rate = (self.profile.max_rate
                                 if isinstance(self.profile, CommandedSpeed) else None)
        if self.profile is not None:
            w0 = float(self.profile.speed(np.asarray(0.0)))
            reference = max(initial_target or 0.0, w0)
            self.max_speed = float(max_speed) if max_speed else (
                2.0 * reference if reference > 0 else 1e4)
            if initial_target is not None:
                self.command_speed(initial_target)
        else:
            self.max_speed = 0.0
        self.noise_std = 0.0
        self.noise_seed = int(seed)
        self.set_noise(noise_std, seed)
        # sensor faults on the channels' output streams (none until commanded)
        self.faults = FaultInjector.for_channels(self.channels, self.sample_rate,
                                                 seed=self.noise_seed)
        self.sim.set_impacts_enabled(dampers_enabled)
        self._stuck = self._stuck_flags()
        self._stuck_raw: bytes | None = None   # the integrator's flags' bytes _stuck is of
        self.failure: str | None = None
        self.steps = 0
        # the time (s) and rotor angle (rad) at the end of the last chunk
        self._t_end = float(self.sim.t)
        self._phi_end = (float(self.profile.angle(np.asarray(self._t_end)))
                         if self.profile is not None else 0.0)

    def imu_noise_variances(self) -> list[float]:
        """Variance of the white noise in each decimated (per-sample Imu) acceleration, per
        accelerometer ((m/s^2)^2 per axis): the channel's sensor noise (coloured by the
        anti-alias filter), the live ``noise_std`` noise, ADC noise and quantization, through
        the decimation filter (which keeps ``sum(taps^2)`` of a white signal's variance, not
        all of it). Biases are not in it (they are not white).

        Returns
        -------
        list of float
        """
        return [ch.decimated_noise_variance(self._decimator.taps) for ch in self.channels]

    def _channels(self, seed: int) -> list[SensorChannel]:
        """One measurement chain per accelerometer, from the scene's resolved channels."""
        from ..scene.accelerometers import channel_of, resonance_problem
        from .channel import SensorChannel
        out: list[SensorChannel] = []
        for acc in self.accelerometers:
            spec = channel_of(self.scene, acc.node)
            # a default cutoff is known only now (from the sample rate)
            problem = resonance_problem(spec, acc.lowpass_hz, f'accelerometer {acc.name!r}')
            if problem:
                raise SceneError(f"scene key 'channel.resonance.frequency': {problem}",
                                 self.scene.source)
            try:
                out.append(SensorChannel(spec, step_rate_hz=1.0 / self.dt,
                                         decimation=self.decimation,
                                         lowpass_hz=acc.lowpass_hz, seed=seed,
                                         name=acc.name))
            except ValueError as exc:
                raise SceneError(f"scene key 'channel': {exc}", self.scene.source) from None
        return out

    @property
    def imu_delay(self) -> float:
        """float: Delay of the decimation filter (s): a per-sample reading is complete this
        long after the time it stands for (0 without decimation)."""
        return self._decimator.delay / self.sample_rate

    # -- set-up ---------------------------------------------------------------------------
    def _output_rows(self) -> tuple[tuple[str, ...], npt.NDArray[np.float64]]:
        """Sensor names and rows: per accelerometer ux, uy, uz, rx, ry, rz (zero if clamped)."""
        scene = self.scene
        names: list[str] = []
        rows: list[npt.NDArray[np.float64]] = []
        for acc in self.accelerometers:
            for dof in _TRANSLATIONS + _ROTATIONS:
                names.append(f'{acc.name}/{dof}')
                try:
                    index = scene.system.index(acc.node, dof)
                except KeyError:   # clamped DOF: it does not move
                    rows.append(np.zeros(scene.basis.n_modes))
                    continue
                rows.append(scene.basis.rows([index])[0])
        return tuple(names), np.array(rows)

    # -- commands -------------------------------------------------------------------------
    @property
    def has_rotor(self) -> bool:
        """bool: The scene has a rotor (speed commands apply)."""
        return self.profile is not None

    @property
    def speed_commanded(self) -> bool:
        """bool: The rotor's speed follows commands (a gyroscopic scene's does not)."""
        return self.profile is not None and self.profile.commanded

    def command_speed(self, target: float) -> None:
        """Command a rotor speed from now on, reached under the rate limit.

        Parameters
        ----------
        target : float
            Target speed (rad/s), finite, in ``[0, max_speed]``.

        Raises
        ------
        CommandError
            No rotor, or the target is out of range; nothing changes.
        """
        if not self.has_rotor:
            raise CommandError(f'speed: scene {self.scene.name!r} has no rotor')
        if not isinstance(self.profile, CommandedSpeed):   # speed_commanded, for mypy
            raise CommandError(f'speed: scene {self.scene.name!r} has a gyroscopic coupling '
                               'built for its constant speed')
        target = _checked(target, 'speed', 0.0, self.max_speed, 'rad/s')
        self.profile.command(self.sim.t, target)

    def set_speed_rate(self, rate: float) -> None:
        """Set the rate limit of speed changes from now on; a ramp under way goes on at it.

        Parameters
        ----------
        rate : float
            Rate limit (rad/s^2), finite, in ``[0, 1e6]``; 0 restores the rate at start
            (:attr:`start_speed_rate`).

        Raises
        ------
        CommandError
            No commanded rotor, or the rate is out of range; nothing changes.
        """
        if not isinstance(self.profile, CommandedSpeed):   # speed_commanded, for mypy
            raise CommandError(f'speed rate limit: scene {self.scene.name!r} has no commanded '
                               'rotor')
        rate = _checked(rate, 'speed rate limit', 0.0, 1.0e6, 'rad/s^2')
        assert self.start_speed_rate is not None   # set at start for a commanded rotor
        self.profile.max_rate = rate if rate > 0 else self.start_speed_rate

        # re-command the target now: the remaining ramp is rebuilt at the new rate
        self.profile.command(self.sim.t, self.profile.target)

    def command_unbalance(self, multiplier: float) -> None:
        """Set the unbalance multiplier X from now on.

        Parameters
        ----------
        multiplier : float
            X (dimensionless), finite, in ``[0, max_unbalance]``.

        Raises
        ------
        CommandError
            No unbalance in the scene, or X out of range; nothing changes.
        """
        if self.unbalance is None:
            raise CommandError(f'unbalance multiplier: scene {self.scene.name!r} has no rotor '
                               'unbalance')
        self.unbalance.multiplier = _checked(multiplier, 'unbalance multiplier', 0.0,
                                             self.max_unbalance, '')

    def set_noise(self, std: float, seed: int | None = None) -> None:
        """Set the accelerometer noise (m/s^2 standard deviation) and optionally reseed it.

        A seed restarts the white noise of every accelerometer; the first one's is
        ``default_rng(seed)``, the others' are drawn from ``seed`` and their index, so that no
        two accelerometers carry the same noise.
        """
        std = float(std)
        if not (math.isfinite(std) and std >= 0):
            raise CommandError(f"noise std: must be finite and >= 0 m/s^2, "
                               f'got {std}')
        self.noise_std = std
        for k, channel in enumerate(self.channels):
            own = None if seed is None else int(seed) if k == 0 else int(
                np.random.SeedSequence([int(seed), k]).generate_state(1)[0])
            channel.set_white_noise(std, own)

    def add_fault(self, spec: FaultSpec | Mapping[str, Any], key: str = 'fault') -> str:
        """Add a sensor fault from now on (:mod:`.faults`): it acts from the next output
        sample, or from its ``onset`` when that is later.

        Parameters
        ----------
        spec : FaultSpec or dict
            The fault (a mapping is read by :func:`~.fault_spec.parse_fault`: units allowed).
        key : str
            The command's name in messages (the node gives its topic; ``schedule[2].fault``).

        Returns
        -------
        str
            The fault's name (given, or ``<kind>-<n>``).

        Raises
        ------
        CommandError
            One line naming the key: an unknown accelerometer (naming the ones there are), a
            value out of range, a name in use, a window that has passed; nothing changes.
        """
        try:
            return self.faults.add(spec, now=float(self.sim.t), key=key)
        except FaultError as exc:
            raise CommandError(_one_line(exc)) from None

    def clear_faults(self, name: str | None = None, key: str = 'clear') -> list[str]:
        """End the sensor fault ``name`` (None: every fault) after the last stepped sample.

        Parameters
        ----------
        name : str, optional
            The fault's name; None clears every fault.
        key : str
            The command's name in messages.

        Returns
        -------
        list of str
            The faults this cut short.

        Raises
        ------
        CommandError
            No fault of that name (naming the ones there are); nothing changes.
        """
        try:
            return self.faults.clear(name, key=key)
        except FaultError as exc:
            raise CommandError(_one_line(exc)) from None

    def fault_command(self, command: str | Mapping[str, Any], key: str = 'fault command'
                      ) -> tuple[str, list[str]]:
        """Apply a fault command as the node receives it (:func:`~.fault_spec.parse_command`).

        Parameters
        ----------
        command : str or dict
            YAML or JSON text (or its mapping): a fault to add (``{kind: ..., accelerometer:
            ..., ...}``), ``{clear: <name>}`` or ``{clear: all}``.
        key : str
            The command's name in messages (the node passes its topic).

        Returns
        -------
        action : str
            ``'add'`` or ``'clear'``.
        names : list of str
            The fault added, or the faults cleared.

        Raises
        ------
        CommandError
            One line naming the key (bad YAML, a bad value, an unknown accelerometer naming
            the ones there are, an unknown fault to clear); nothing changes.
        """
        from .fault_spec import parse_command
        try:
            cmd = parse_command(command, [acc.name for acc in self.accelerometers], key=key)
        except FaultError as exc:
            raise CommandError(_one_line(exc)) from None
        if cmd.action == 'clear':
            return 'clear', self.clear_faults(cmd.name, key=f'{key}.clear')
        assert cmd.spec is not None   # parse_command gives an 'add' its spec
        return 'add', [self.add_fault(cmd.spec, key=key)]

    def set_dampers_enabled(self, enabled: bool) -> None:
        """Switch the impact dampers on or off (see ``Simulation.set_impacts_enabled``)."""
        self.sim.set_impacts_enabled(bool(enabled))
        self._stuck = self._stuck_flags()
        self._stuck_raw = None

    @property
    def dampers_enabled(self) -> bool:
        """bool: Whether the impact dampers act."""
        return self.sim.impacts_enabled

    # -- state ----------------------------------------------------------------------------
    @property
    def t(self) -> float:
        """float: Simulated time (s)."""
        return self.sim.t

    def rotor_state(self) -> tuple[float, float, float]:
        """Applied speed (rad/s), speed rate (rad/s^2) and multiplier X now (NaN/0 if none)."""
        if self.profile is None:
            return 0.0, 0.0, 0.0
        x = self.unbalance.multiplier if self.unbalance is not None else 0.0
        _, speed, rate = self.profile.state(np.asarray(self.sim.t))   # one search of the knots
        return (float(speed), float(rate), float(x))

    def stuck_count(self) -> int:
        """int: Impactors stuck to their housing at the end of the last chunk."""
        return sum(self._stuck)

    def _stuck_flags(self) -> tuple[bool, ...]:
        return tuple(bool(s) for s in self.sim.integrator._stuck)

    def impactor_states(self) -> list[dict[str, Any]]:
        """The impactors' states: list of dicts (name, stuck, position m, velocity m/s).

        Position and velocity are relative to the housing. Disabled dampers report zeros.
        """
        out: list[dict[str, Any]] = []
        _, qd = self.sim.integrator.state()
        rows = self.sim.integrator._housing_rows()
        for s, R in zip(self.sim.impactor_states(), rows):
            position, velocity = s['position'], s['velocity'] - R @ qd
            if not self.dampers_enabled:
                position, velocity = np.zeros_like(position), np.zeros_like(velocity)
            out.append({'name': s['name'], 'stuck': s['stuck'], 'position': position,
                        'velocity': velocity})
        return out

    def impactor_state_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`impactor_states` as flat arrays, one entry per impactor DOF in the
        impactors' order (their ``position`` and ``velocity`` concatenated): the same
        numbers without a dict per impactor.

        Returns
        -------
        position : ndarray, shape (n_dof,)
            Relative to the housing (m).
        velocity : ndarray, shape (n_dof,)
            Relative to the housing (m/s).
        stuck : ndarray of bool, shape (n_dof,)
            The DOF's impactor rides its housing.
        """
        integrator, dims = self.sim.integrator, self._impactor_dims
        if not dims:
            empty = np.zeros(0)
            return empty, empty, np.zeros(0, bool)
        rel, vel, stuck = integrator.impactor_states()
        if not self.dampers_enabled:
            zeros = np.zeros(sum(dims))
            return zeros, zeros.copy(), np.repeat(stuck, dims)
        _, qd = integrator.state()
        housing = np.concatenate([R @ qd for R in integrator._housing_rows()])
        cells = self._impactor_cells
        return rel[cells], vel[cells] - housing, np.repeat(stuck, dims)

    # -- stepping -------------------------------------------------------------------------
    def _load_kernels(self) -> tuple[Any, Any]:
        # imported on the first step (the node's warm-up), as the channels' kernels are
        from ..integrate.kernels.channel_chunk import split_decimated, step_inputs
        self._kernels = (step_inputs, split_decimated)
        return self._kernels

    def step(self, n_samples: int) -> Batch | None:
        """Advance ``n_samples`` output samples.

        Parameters
        ----------
        n_samples : int
            Number of output samples (dimensionless).

        Returns
        -------
        Batch or None
            None once the simulation has failed (see :attr:`failure`).
        """
        if self.failure is not None:
            return None
        n_steps = int(n_samples) * self.decimation
        try:
            samples = self.sim.advance(n_steps)
        except Divergence as exc:   # the core's blow-up check: what, when, what to change
            self.failure = str(exc.with_setting(scene_advice(self.scene, exc)))
            return None
        except (FloatingPointError, RuntimeError) as exc:
            self.failure = f'{type(exc).__name__}: {exc}'
            return None
        vel = samples.velocity
        # the chain's kernels (kernels/channel_chunk.py), imported on the first step
        step_inputs, split_decimated = self._kernels or self._load_kernels()
        k = int(n_samples)
        n_acc = len(self.channels)
        ang = np.empty((k, n_acc, 3))
        # each accelerometer's mean acceleration over each step, made in these buffers per
        # chunk length: its channel reads it and keeps nothing of it
        means = self._mean_work.get(n_steps)
        if means is None:
            if len(self._mean_work) >= 8:   # chunk lengths vary (a paced run catching up)
                self._mean_work.clear()
            means = self._mean_work[n_steps] = [np.empty((n_steps, 3)) for _ in range(n_acc)]
        v_prev, dt, decimation = self._v_prev, self.dt, self.decimation
        finite = True
        for a in range(n_acc):
            # mean acceleration over each step, translations only (rotations give rates):
            # the difference of the velocities at the steps' ends (the first from the last
            # chunk's end) over dt, as np.diff of them stacked, / dt; the angular velocity
            # at the output steps into ang; whether the six columns are finite
            finite = step_inputs(vel, v_prev, 6 * a, dt, decimation, means[a], ang, a) \
                and finite
        if not finite:
            self.failure = f'non-finite sensor velocity before t = {self.sim.t:.6g} s'
            return None
        pick = self._pick
        t = samples.t[pick]
        lin = np.empty((k, n_acc, 3))
        truth = np.empty((k, n_acc, 3))
        clipped = np.zeros(n_acc, dtype=np.int64)
        valid = np.empty((k, n_acc), bool)
        valid.fill(True)   # np.ones costs a copyto call more
        faults = self.faults
        for a, channel in enumerate(self.channels):
            # the faults that change values act before the range and ADC (a gain clips, and
            # the clip count counts it), the rest after them (stuck, missing samples)
            if faults.has_faults(a):
                clipped[a] = channel._process_chunk(means[a], faults.hook(t, a), lin, truth, a)
                valid[:, a] = faults.after_limit(t, lin[:, a, :], a)[1]
            else:   # no fault: every sample valid; the injector keeps the last one read
                clipped[a] = channel._process_chunk(means[a], None, lin, truth, a)
                faults.follow(t[0] if k else t, lin[:, a, :], a)
        if n_steps:
            self._v_prev = vel[-1].copy()
        if self._t_first is None and k:
            self._t_first = float(t[0])
        # the sensor's noise passes through the DAQ's decimation filter, as in hardware;
        # channel 6 a + j is lin[:, a, j] (j < 3), else ang[:, a, j - 3]
        index, dec = self._decimator._apply_groups(lin, ang)
        imu_lin = np.empty((index.size, n_acc, 3))
        imu_ang = np.empty((index.size, n_acc, 3))
        imu_clipped = np.zeros(n_acc, dtype=np.int64)
        # the Imu is on the ADC's grid too: each channel's range and ADC (process_decimated
        # without its copy and checks), compiled, or NumPy's where the kernel does not cover it
        split_decimated(np.ascontiguousarray(dec.T), imu_lin, imu_ang, self._imu_limits,
                        imu_clipped)
        for a in self._imu_numpy:
            imu_clipped[a] = self.channels[a]._limit(imu_lin[:, a], False)
        imu_t = (self._t_first or 0.0) + index / self._sample_rate_0d
        imu_valid = np.empty((imu_t.size, n_acc), bool)
        imu_valid.fill(True)
        if len(faults):   # a missing sample is missing in both streams
            for a in range(n_acc):
                imu_valid[:, a] = faults.valid_at(imu_t, a)
        events = self.sim.take_events()
        raw = self.sim.integrator._stuck.tobytes()   # the flags change rarely: compare bytes
        changed = False
        if raw != self._stuck_raw:
            stuck = self._stuck_flags()
            changed = stuck != self._stuck
            self._stuck, self._stuck_raw = stuck, raw
        self.steps += n_steps
        angle, speed, keyphasor = self._tachometer(t)
        return Batch(t, lin, ang, events, changed, imu_t, imu_lin, imu_ang, truth,
                     clipped, imu_clipped, angle, speed, keyphasor, valid, imu_valid)

    def _tachometer(self, t: npt.NDArray[np.float64]
                    ) -> tuple[np.ndarray | None, np.ndarray | None, np.ndarray | None]:
        """The rotor angle and speed at the output times ``t`` (s) of the chunk just stepped,
        and its keyphasor events; (None, None, None) without a rotor.

        Read from the speed profile before any later command rewrites its future, so the
        angle is the ``phi(t)`` that :class:`~impact_damper_sim.scene.excitation.
        UnbalanceForce` evaluated at the same times. A turn k is in the chunk when
        ``2 pi k`` is above the angle at the previous chunk's end and not above the angle at
        this one's: each turn in exactly one chunk.
        """
        if self.profile is None:
            return None, None, None
        if not t.size:
            return np.empty(0), np.empty(0), np.empty(0, KEYPHASOR_DTYPE)
        # t is 1-D: state(t) without the acceleration; lists for the chunk's few turns
        angle, speed = self.profile.angle_speed(t)
        phi_end, t_end = float(angle[-1]), float(t[-1])
        first, last = _turns(self._phi_end) + 1, _turns(phi_end)
        if last >= first:
            at, at_speed = self.profile.keyphasor(first, last, self._t_end, t_end)
            keyphasor = np.fromiter(zip(at, range(first, last + 1), at_speed),
                                    KEYPHASOR_DTYPE, last - first + 1)
        else:
            keyphasor = np.empty(0, KEYPHASOR_DTYPE)
        self._phi_end, self._t_end = phi_end, t_end
        return angle, speed, keyphasor

    def linear_growth_rate(self) -> float:
        """Largest real part of the free structure's eigenvalues now (1/s); > 0 = unstable.

        Impactors can bound an unstable linear system's response, which is why the paper
        used them; this is the rate the response grows at without them. A real part within
        :data:`GROWTH_RATE_NOISE` x the largest eigenvalue modulus is rounding in the
        eigensolver (a conservative rotor, ``ross_rotor``, gave 1.1e-13 1/s at modes of
        1e3 rad/s), not growth: it is reported as 0.
        """
        from scipy.linalg import eigvals
        model = self.sim.integrator.model
        n = model.n
        A = np.block([[np.zeros((n, n)), np.eye(n)],
                      [-np.linalg.solve(model.M, model.K), -np.linalg.solve(model.M, model.C)]])
        lam = eigvals(A)
        rate = float(np.max(lam.real))
        return rate if rate > GROWTH_RATE_NOISE * float(np.max(np.abs(lam))) else 0.0


def _turns(angle: float) -> int:
    """The largest whole number of turns k with ``2 pi k <= angle`` (angle in rad, >= 0),
    compared as the float products the keyphasor uses."""
    k = math.floor(angle / _TWO_PI)
    while _TWO_PI * k > angle:
        k -= 1
    while _TWO_PI * (k + 1) <= angle:
        k += 1
    return k


def _one_line(exc: SceneError) -> str:
    """A refusal's problems (a ``SceneError``'s ``errors``) on one line."""
    return '; '.join(' '.join(str(e).splitlines()) for e in exc.errors)


def _checked(value: float | str, name: str, low: float, high: float, unit: str) -> float:
    try:
        number = float(value)

    except (TypeError, ValueError):
        raise CommandError(f'{name}: must be a number, got {value!r}') from None
    if not math.isfinite(number) or not low <= number <= high:
        unit = f' {unit}' if unit else ''
        raise CommandError(f'{name}: {number!r} is outside the allowed range '
                           f'[{low:g}, {high:g}]{unit}; the last good command stays in force')
    return number



__all__ = ['CommandError', 'KEYPHASOR_DTYPE', 'LiveSimulation']
