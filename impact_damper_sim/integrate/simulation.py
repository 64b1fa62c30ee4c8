"""The simulation object: a model, its forcing and an integrator, advanced in time.

Everything is in SI units. Typical use::

    sim = Simulation(model, forcing, method='exact', dt=5e-4)
    samples = sim.advance_to(1.0)        # sensor outputs every dt up to t = 1 s
    events = sim.take_events()           # impacts, sticks and releases since the last call
    sim.impactor_states()                # stuck/free, relative position and velocity
    sim.energy()                         # energy ledger (J)

:meth:`Simulation.advance` checks every chunk of :data:`CHECK_EVERY` samples: a run that
diverges raises :class:`~impact_damper_sim.integrate.divergence.Divergence` at once (what,
when), and a request whose samples would not fit in memory raises
:class:`~impact_damper_sim.integrate.memory.TooLarge` before anything is allocated.
"""
from __future__ import annotations

import math
import sys
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from .base import IntegratorBase
from .divergence import check_samples, check_state, from_engine_error
from .events import EVENT_KINDS, Samples
from .memory import check_allocation

if TYPE_CHECKING:
    from .events import EnergyLedger
    from .forcing import Forcing
    from .model import LinearModel

#: The integration methods of a run (:func:`make_integrator`), defined here only.
METHODS = ('exact', 'newmark', 'newmark_step_end', 'direct')

#: Samples per divergence check: a blow-up is caught within this many samples of its start
#: (a chunk costs a call of the engine, a state read and a finiteness test: 0.2 to 1 ms measured
#: on sdof and hpotp, 6 to 12 % of the exact engine's time at 1024 samples, within run-to-run
#: noise at 8192).
CHECK_EVERY = 8192


def _spacing(x: float) -> float:
    """``np.spacing(abs(x))`` of a float ``x`` (its unit in the last place), without a NumPy
    call: ``math.ulp`` is the same below the largest float."""
    return math.ulp(x) if abs(x) < _FLOAT_MAX else float(np.spacing(abs(x)))


_FLOAT_MAX = sys.float_info.max


def make_integrator(method: str, model: LinearModel, forcing: Forcing, dt: float,
                    physical_model: LinearModel | None = None,
                    **options: Any) -> IntegratorBase:
    """Build the integrator for ``method``.

    Parameters
    ----------
    method : {'exact', 'newmark', 'newmark_step_end', 'direct'}
        Exact modal propagator; Newmark on the modal model with impacts located inside the
        step or applied at step ends (the paper's baseline); Newmark in physical coordinates.
    model : LinearModel
        The modal model.
    forcing : Forcing
        Forcing on the model's inputs (N).
    dt : float
        Output step (s).
    physical_model : LinearModel, optional
        Physical-coordinate model, required by ``'direct'``.
    **options
        Passed to the integrator (``law``, ``stick_rule``, ``stick_fraction``, ``ledger``,
        ``q0``, ``qd0``, ...). Unknown options raise ``TypeError``.
    """
    if method == 'exact':
        from .exact import ExactPropagator
        return ExactPropagator(model, forcing, dt, **options)
    if method in ('newmark', 'newmark_step_end', 'direct'):
        from .newmark import NewmarkIntegrator
        impacts = 'step_end' if method == 'newmark_step_end' else 'located'
        target = model
        if method == 'direct':
            if physical_model is None:
                raise ValueError("method 'direct' needs the physical model")
            target = physical_model
        return NewmarkIntegrator(target, forcing, dt, impacts=impacts, **options)
    raise ValueError(f'method must be one of {METHODS}, got {method!r}')


class Simulation:
    """A model with impactors, advanced to given times.

    Parameters
    ----------
    model : LinearModel
        Modal model with its sensors and impactors.
    forcing : Forcing
        External forcing (N).
    method : str
        One of :data:`METHODS`.
    dt : float
        Output sample period (s).
    physical_model : LinearModel, optional
        Physical model for ``method='direct'``.
    **options
        Integrator options (see :func:`make_integrator`).
    """

    def __init__(self, model: LinearModel, forcing: Forcing, *, method: str = 'exact',
                 dt: float, physical_model: LinearModel | None = None,
                 **options: Any) -> None:
        self.model = model
        self.forcing = forcing
        self.method = method
        self.dt = float(dt)
        self.integrator = make_integrator(method, model, forcing, dt, physical_model, **options)
        self._last_velocity = self._sensor_velocity_now()
        self._velocity_before_advance = self._last_velocity

    @property
    def t(self) -> float:
        """float: Current simulated time (s)."""
        return self.integrator.t

    @property
    def sensor_names(self) -> tuple[str, ...]:
        """tuple of str: Names of the sensor outputs."""
        return self.model.sensor_names

    @property
    def impactor_names(self) -> tuple[str, ...]:
        """tuple of str: Names of the impactors."""
        return tuple(imp.name for imp in self.integrator.model.impactors)

    def _sensor_velocity_now(self) -> npt.NDArray[np.float64]:
        _, qd = self.integrator.state()
        return self.integrator.model.sensors @ qd

    def advance(self, n_steps: int) -> Samples:
        """Advance ``n_steps`` sample periods and return their :class:`Samples`.

        Raises
        ------
        TooLarge
            Before anything runs, if the samples would not fit in memory.
        Divergence
            If the run diverges (non-finite or absurd state, unresolved chatter); raised at
            the first chunk of :data:`CHECK_EVERY` samples that shows it. The simulation
            stays at the end of that chunk.
        """
        n_steps = int(n_steps)
        integrator = self.integrator
        check_allocation(n_steps, integrator.model.sensors.shape[0])
        self._velocity_before_advance = self._last_velocity
        chunks: list[Samples] = []
        done = 0
        t_start, dt = integrator.t, getattr(integrator, 'dt', self.dt)
        while True:
            n = min(CHECK_EVERY, n_steps - done)
            chunks.append(self._checked_advance(n))
            done += n
            # the engines stamp time as chunk start + k dt: put the time base back on
            # t_start + done dt, where one call would have left it (no drift of an ulp a chunk)
            t_exact = t_start + dt * done
            if abs(integrator.t - t_exact) <= 8 * _spacing(t_exact):
                integrator.t = t_exact
            if done >= n_steps:
                break
        samples = chunks[0] if len(chunks) == 1 else Samples(
            *(np.concatenate([getattr(c, f) for c in chunks])
              for f in ('t', 'displacement', 'velocity', 'acceleration')))
        if samples.t.size:
            self._last_velocity = samples.velocity[-1].copy()
        return samples

    def _checked_advance(self, n: int) -> Samples:
        integrator = self.integrator
        try:
            with np.errstate(over='ignore', invalid='ignore'):
                samples = integrator.advance(n)
        except (FloatingPointError, RuntimeError) as exc:
            div = from_engine_error(exc, integrator.t)
            if div is None:
                raise
            raise div from exc
        check_samples(samples, self.sensor_names)
        q, qd = integrator.state()
        check_state(q, qd, integrator.t)
        return samples

    def advance_to(self, t_end: float) -> Samples:
        """Advance to ``t_end`` (s), rounded to whole sample periods.

        Returns
        -------
        Samples
            Sensor displacement (m), velocity (m/s) and smooth acceleration (m/s^2) at each
            sample time.
        """
        n = int(round((float(t_end) - self.t) / self.dt))
        if n < 0:
            raise ValueError(f'cannot advance backwards from t = {self.t} s to {t_end} s')
        return self.advance(n)

    def mean_acceleration(self, samples: Samples, v_before: npt.ArrayLike | None = None
                          ) -> npt.NDArray[np.float64]:
        """Mean acceleration over each sample period (m/s^2), impacts included.

        An impact is an instantaneous velocity jump; its acceleration is a Dirac impulse that
        no sample can hold. ``(v_k - v_{k-1})/dt`` is the acceleration averaged over each
        period, what an ideal accelerometer integrating over the period reads, and it keeps
        the impulse's effect on the signal. ``v_before`` is the sensor velocity at the start
        of the first period (m/s); by default, the one before the last :meth:`advance`.
        """
        if v_before is None:
            v_before = self._velocity_before_advance
        v = np.vstack([np.asarray(v_before, dtype=float)[None, :], samples.velocity])
        return np.diff(v, axis=0) / self.dt

    def take_events(self) -> np.ndarray:
        """Events since the last call: structured array of ``EVENT_DTYPE``."""
        return self.integrator.take_events()

    def impactor_states(self) -> list[dict[str, Any]]:
        """List of dicts: name, stuck flag, relative position (m) and velocity (m/s)."""
        rel, vel, stuck = self.integrator.impactor_states()
        return [{'name': imp.name, 'stuck': bool(s), 'position': rel[j, :imp.dim].copy(),
                 'velocity': vel[j, :imp.dim].copy()}
                for j, (imp, s) in enumerate(zip(self.integrator.model.impactors, stuck))]

    @property
    def impacts_enabled(self) -> bool:
        """bool: Whether the impact dampers act (see :meth:`set_impacts_enabled`)."""
        return self.integrator.impacts_enabled

    def set_impacts_enabled(self, enabled: bool) -> None:
        """Switch the impact dampers on or off from now on (True = on).

        Off releases stuck impactors and lets every impactor fly free without walls; on puts
        each back at its housing centre, moving with it. The structure's state is untouched.
        """
        self.integrator.set_impacts_enabled(enabled)

    def energy(self) -> EnergyLedger:
        """The :class:`~.integrate.events.EnergyLedger` now (J)."""
        return self.integrator.energy()


def event_kind_name(code: int) -> str:

    """Return the name of an event kind code."""
    return EVENT_KINDS[int(code)]


__all__ = ['METHODS', 'Samples', 'Simulation', 'event_kind_name', 'make_integrator']
