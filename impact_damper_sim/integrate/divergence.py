"""Blow-up detection: a run that diverges ends in one typed error, never in inf/NaN results.

A run *diverges* when its state leaves what floating point and the physics can carry: a
non-finite modal state or sensor sample, a sensor displacement beyond
:data:`MAX_DISPLACEMENT` (no structure this package models moves a kilometre; beyond it the
energies overflow long before the state does), or an engine failure that only such states
cause (unresolved chatter, a floating-point error). :class:`Divergence` says what diverged,
when, and which setting to change; :func:`impact_damper_sim.scene.advice.scene_advice`
finds that setting in a scene. Memory budgets are :mod:`.memory`.

NumPy, no rclpy (a chunk's clean-chunk test is one compiled call,
:mod:`.kernels.divergence_check`, imported on the first check):
:class:`~impact_damper_sim.integrate.simulation.Simulation` checks every chunk it advances, the
``study`` command turns :class:`Divergence` into exit status ``EXIT_DIVERGED`` (3), and a node
reports ``str(exc)`` in its diagnostics.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from .._exit_status import EXIT_DIVERGED
from .events import Samples

#: Sensor displacement beyond which a run has diverged (m).
MAX_DISPLACEMENT = 1.0e3

#: Engine messages that only a diverging state produces (``RuntimeError`` text).
_ENGINE_BLOW_UPS = ('chatter not resolved', 'non-finite')


class Divergence(RuntimeError):
    """A run diverged: what, when, and which setting to change.

    Parameters
    ----------
    what : str
        What diverged, e.g. ``"sensor 'primary' displacement 1.4e+295 m (bound 1000 m)"``.
    t : float
        Simulated time at which it was detected (s): the end of the first sample period
        that shows it, or the engine's time for an engine failure.
    setting : str, optional
        Which setting to change, e.g. from
        :func:`impact_damper_sim.scene.advice.scene_advice`.

    Attributes
    ----------
    what, t, setting
        As given.
    code : int
        :data:`EXIT_DIVERGED`.
    """

    code = EXIT_DIVERGED

    def __init__(self, what: str, t: float, setting: str | None = None) -> None:
        self.what = str(what)
        self.t = float(t)
        self.setting = setting
        super().__init__(self.message())

    def message(self) -> str:
        """Return the one-line message: ``diverged at t = ... s: what; change ...``."""
        text = f'diverged at t = {self.t:.6g} s: {self.what}'
        return f'{text}; {self.setting}' if self.setting else text

    def __str__(self) -> str:
        return self.message()

    def __reduce__(self) -> tuple[type[Divergence], tuple[str, float, str | None]]:
        # picklable across process pools, with its fields
        return (Divergence, (self.what, self.t, self.setting))

    def with_setting(self, setting: str) -> Divergence:
        """Return a copy whose advice is ``setting`` (str)."""
        return Divergence(self.what, self.t, setting)


class StudyDiverged(RuntimeError):
    """A study cannot go on because a run it depends on diverged (e.g. its reference).

    The message is the run's one-line :class:`Divergence` text; ``code`` is
    :data:`EXIT_DIVERGED`.
    """

    code = EXIT_DIVERGED


def _abs_max(values: npt.ArrayLike) -> float:
    """Largest ``|value|`` of real floating-point ``values`` (0 for none): inf or NaN if one
    is not finite; NaN for other types, which the callers then examine entry by entry.

    One ``abs`` and one ``maximum`` reduction: neither overflows nor raises a floating-point
    error on NaN or inf, so no error state is needed (a sum would need one and may overflow),
    and the ufunc's own ``reduce`` skips NumPy's Python wrappers (a chunk checks five arrays).
    """
    a = np.asarray(values)
    if a.dtype.kind != 'f':
        return math.nan
    return float(_MAXIMUM(np.abs(a), axis=None)) if a.size else 0.0


_MAXIMUM = np.maximum.reduce
_F8 = np.dtype(np.float64)
#: The compiled checks (:mod:`.kernels.divergence_check`), imported on the first check (it
#: imports Numba, which importing this module does not); False when Numba's JIT is off.
_compiled: Any = None


def _kernels() -> Any:
    global _compiled
    if _compiled is None:
        from .kernels import divergence_check as compiled
        if hasattr(compiled.samples_clean, 'py_func'):
            # compiled (or loaded) now, for the array types a run passes, so that a node's
            # warm-up (an empty chunk: only the state is checked) leaves no compile for its
            # first chunk: samples are C arrays, the exact state a view of a complex product
            real = np.zeros(2, dtype=complex).real
            block = np.zeros((1, 1))
            compiled.samples_clean(block, block, block, 1.0)
            compiled.state_finite(real, real)
            compiled.state_finite(block[0], block[0])
        _compiled = compiled if hasattr(compiled.samples_clean, 'py_func') else False
    return _compiled


def _float_array(values: object, ndim: int) -> bool:
    """True for a float64 ndarray of ``ndim`` dimensions: what the compiled checks take."""
    return type(values) is np.ndarray and values.dtype is _F8 and values.ndim == ndim


def check_state(q: npt.ArrayLike, qd: npt.ArrayLike, t: float) -> None:
    """Raise :class:`Divergence` if the modal state is not finite.

    Parameters
    ----------
    q, qd : ndarray
        Modal coordinates (m sqrt(kg)) and their velocities (m sqrt(kg)/s).
    t : float
        Time of the state (s).
    """
    compiled = _compiled if _compiled is not None else _kernels()
    if compiled and _float_array(q, 1) and _float_array(qd, 1):
        if compiled.state_finite(q, qd):   # the rule, in one call
            return
    elif _abs_max(q) < math.inf and _abs_max(qd) < math.inf:   # the rule: all finite
        return
    for name, given in (('modal coordinates', q), ('modal velocities', qd)):
        v = np.asarray(given)
        if not np.all(np.isfinite(v)):
            bad = np.flatnonzero(~np.isfinite(v.ravel()))
            raise Divergence(f'{name} not finite (mode {int(bad[0]) + 1} of {v.size})', t)


def check_samples(samples: Samples, names: Sequence[str] = (),
                  max_displacement: float = MAX_DISPLACEMENT) -> None:
    """Raise :class:`Divergence` at the first sample that is not finite or too large.

    Parameters
    ----------
    samples : Samples
        Sensor samples (``t`` in s; displacement m; velocity m/s; acceleration m/s^2).
    names : sequence of str
        Sensor names, in column order (for the message).
    max_displacement : float
        Largest acceptable ``|displacement|`` (m).
    """
    if samples.t.size == 0:
        return
    # a clean chunk, the rule: in one compiled pass, or one largest |value| per field (a NaN
    # or inf fails each test)
    disp, vel, acc = samples.displacement, samples.velocity, samples.acceleration
    compiled = _compiled if _compiled is not None else _kernels()
    if compiled and _float_array(disp, 2) and _float_array(vel, 2) and _float_array(acc, 2):
        if compiled.samples_clean(disp, vel, acc, float(max_displacement)):
            return
    else:
        disp = np.asarray(disp)
        if ((disp.size == 0 or _abs_max(disp) <= max_displacement)
                and _abs_max(vel) < math.inf and _abs_max(acc) < math.inf):
            return
    bad_rows = None
    for field in ('displacement', 'velocity', 'acceleration'):
        values = getattr(samples, field)
        bad = ~np.isfinite(values)
        if field == 'displacement':
            with np.errstate(invalid='ignore'):
                bad |= np.abs(values) > max_displacement
        rows = np.flatnonzero(bad.any(axis=1)) if bad.ndim == 2 else np.flatnonzero(bad)
        if rows.size and (bad_rows is None or rows[0] < bad_rows[0]):
            bad_rows = (int(rows[0]), field, bad)
    if bad_rows is None:
        return
    k, field, bad = bad_rows
    col = int(np.flatnonzero(bad[k])[0]) if bad.ndim == 2 else 0
    value = float(np.asarray(getattr(samples, field))[k].ravel()[col])
    name = names[col] if col < len(names) else f'#{col}'
    unit = {'displacement': 'm', 'velocity': 'm/s', 'acceleration': 'm/s^2'}[field]
    if math.isfinite(value):
        what = (f'sensor {name!r} displacement {value:.3g} m exceeds {max_displacement:g} m')
    else:
        what = f'sensor {name!r} {field} is {value} {unit}'
    raise Divergence(what, float(samples.t[k]))


def from_engine_error(exc: BaseException, t: float) -> Divergence | None:

    """Return the :class:`Divergence` an engine error stands for, or None.

    ``FloatingPointError`` and the engine's ``RuntimeError`` for unresolved chatter or a
    non-finite state only happen on a diverging state.

    Parameters
    ----------
    exc : BaseException
        The engine's error.
    t : float
        Simulated time when it was raised (s).
    """
    if isinstance(exc, Divergence):
        return exc
    text = str(exc).strip()
    if isinstance(exc, FloatingPointError) or (
            isinstance(exc, RuntimeError) and any(k in text for k in _ENGINE_BLOW_UPS)):
        return Divergence(f'the integrator stopped: {text or type(exc).__name__}', t)
    return None


__all__ = ['Divergence', 'MAX_DISPLACEMENT', 'StudyDiverged', 'check_samples',
           'check_state', 'from_engine_error']
