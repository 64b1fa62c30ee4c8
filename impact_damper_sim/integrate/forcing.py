"""External forcing ``u(t)`` on a model's force inputs.

A forcing is the sum of *harmonic* terms, which the exact propagator integrates in closed
form, and *sampled* terms (ramps, tables, callables), which it integrates exactly under a
first-order hold between the samples of its time grid (Nigam & Jennings 1969).
Every value is in newtons (or N m on rotational inputs) and every time in seconds.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]


def _check_input(index: int, n_inputs: int, name: str) -> int:
    if not 0 <= int(index) < n_inputs:
        raise ValueError(f'{name}: force input index {index} out of range 0..{n_inputs - 1}')
    return int(index)


def _finite(value: float, name: str) -> float:
    number = float(value)
    if not np.isfinite(number):
        raise ValueError(f'{name} must be finite, got {number}')
    return number


@dataclass(frozen=True)
class Harmonic:
    """``u[input](t) += amplitude * cos(omega t + phase)``.

    Parameters
    ----------
    input_index : int
        Force input the term acts on (dimensionless).
    amplitude : float
        Amplitude (N).
    omega : float
        Angular frequency (rad/s), >= 0.
    phase : float
        Phase (rad).
    """

    input_index: int
    amplitude: float
    omega: float
    phase: float = 0.0

    def __post_init__(self) -> None:
        _finite(self.amplitude, 'Harmonic.amplitude')
        if not (np.isfinite(self.omega) and self.omega >= 0.0):
            raise ValueError(f'Harmonic.omega must be finite and >= 0 rad/s, got {self.omega}')
        _finite(self.phase, 'Harmonic.phase')


@dataclass(frozen=True)
class Ramp:
    """``u[input](t) += value0 + rate * (t - t0)`` for ``t >= t0`` (0 before).

    Parameters
    ----------
    input_index : int
        Force input (dimensionless).
    value0 : float
        Value at ``t0`` (N).
    rate : float
        Slope (N/s).
    t0 : float
        Start time (s).
    """

    input_index: int
    value0: float
    rate: float
    t0: float = 0.0

    def __post_init__(self) -> None:
        for name in ('value0', 'rate', 't0'):
            _finite(getattr(self, name), f'Ramp.{name}')

    def __call__(self, t: FloatArray) -> FloatArray:
        return np.where(t >= self.t0, self.value0 + self.rate * (t - self.t0), 0.0)


@dataclass(frozen=True)
class Tabulated:
    """Piecewise-linear table ``u[input](t)``, held at its end values outside the table.

    Parameters
    ----------
    input_index : int
        Force input (dimensionless).
    times : array_like
        Strictly increasing sample times (s).
    values : array_like
        Values at ``times`` (N).
    """

    input_index: int
    times: Sequence[float] | FloatArray
    values: Sequence[float] | FloatArray

    def __post_init__(self) -> None:
        t = np.asarray(self.times, dtype=float)
        v = np.asarray(self.values, dtype=float)
        if t.ndim != 1 or t.shape != v.shape or t.size < 2:
            raise ValueError('Tabulated: times and values must be 1-D of equal length >= 2')
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(v))):
            raise ValueError('Tabulated: times and values must be finite')
        if np.any(np.diff(t) <= 0):
            raise ValueError('Tabulated: times must be strictly increasing')

    def __call__(self, t: FloatArray) -> FloatArray:
        return np.interp(t, self.times, self.values)


@dataclass(frozen=True)
class CallableForce:
    """Any vectorized callable ``fn(t) -> array (len(t), n_inputs)`` of forces (N).

    Parameters
    ----------
    fn : callable
        Maps a 1-D array of times (s) to an array of shape ``(len(t), n_inputs)`` (N).
    """

    fn: Callable[[FloatArray], npt.ArrayLike]

    def __call__(self, t: FloatArray) -> npt.ArrayLike:
        return self.fn(t)


#: what :meth:`Forcing.add` takes: a term, or a callable that it wraps in a CallableForce
ForcingTerm = Harmonic | Ramp | Tabulated | CallableForce | Callable[[FloatArray], npt.ArrayLike]


class Forcing:

    """Sum of forcing terms on ``n_inputs`` force inputs.

    Parameters
    ----------
    n_inputs : int
        Number of force inputs of the model (dimensionless).
    terms : iterable
        :class:`Harmonic`, :class:`Ramp`, :class:`Tabulated` or :class:`CallableForce` objects.
    """

    def __init__(self, n_inputs: int, terms: Iterable[ForcingTerm] = ()) -> None:
        self.n_inputs = int(n_inputs)
        self.harmonics: list[Harmonic] = []
        self.sampled: list[Ramp | Tabulated | CallableForce] = []
        for term in terms:
            self.add(term)

    def add(self, term: ForcingTerm) -> Forcing:
        """Add one forcing term (see the class docstring)."""
        if isinstance(term, Harmonic):
            _check_input(term.input_index, self.n_inputs, 'Harmonic')
            self.harmonics.append(term)
        elif isinstance(term, (Ramp, Tabulated)):
            _check_input(term.input_index, self.n_inputs, type(term).__name__)
            self.sampled.append(term)
        elif isinstance(term, CallableForce) or callable(term):
            self.sampled.append(term if isinstance(term, CallableForce) else CallableForce(term))
        else:
            raise TypeError(f'unsupported forcing term {term!r}')
        return self

    @property
    def has_sampled(self) -> bool:
        """bool: True when some term needs first-order-hold sampling."""
        return bool(self.sampled)

    def harmonic_table(self) -> tuple[FloatArray, npt.NDArray[np.complex128]]:
        """Group harmonic terms by frequency.

        Returns
        -------
        omegas : ndarray, shape (n_h,)
            Distinct angular frequencies (rad/s).
        amplitudes : ndarray of complex, shape (n_h, n_inputs)
            ``U`` such that ``u_h(t) = Re(sum_h U[h] exp(i omega_h t))`` (N).
        """
        omegas = sorted({h.omega for h in self.harmonics})
        table = np.zeros((len(omegas), self.n_inputs), dtype=complex)
        for h in self.harmonics:
            table[omegas.index(h.omega), h.input_index] += h.amplitude * np.exp(1j * h.phase)
        return np.asarray(omegas, dtype=float), table

    def sample(self, t: npt.ArrayLike) -> FloatArray:
        """Return the sampled (non-harmonic) part at times ``t``.

        Parameters
        ----------
        t : array_like
            Times (s).

        Returns
        -------
        ndarray, shape (len(t), n_inputs)
            Forces (N). Raises ValueError if a callable returns a wrong shape or non-finite value.
        """
        if type(t) is np.ndarray and t.ndim == 1 and t.dtype == np.float64:
            times = t   # a propagator's grid: nothing to convert
        else:
            times = np.atleast_1d(np.asarray(t, dtype=float))
        sampled = self.sampled
        if len(sampled) == 1 and type(sampled[0]) is CallableForce:
            # one callable (an unbalance): its value added to zeros, in one operation
            value = np.asarray(sampled[0].fn(times), dtype=float)
            if value.shape != (times.size, self.n_inputs):
                raise ValueError(f'forcing callable returned shape {value.shape}, '
                                 f'expected {(times.size, self.n_inputs)}')
            out = np.add(value, 0.0, order='C')   # as 0 + value: -0 becomes +0
        else:
            out = np.zeros((times.size, self.n_inputs))
            for term in sampled:
                if isinstance(term, CallableForce):
                    value = np.asarray(term(times), dtype=float)
                    if value.shape != out.shape:
                        raise ValueError(f'forcing callable returned shape {value.shape}, '
                                         f'expected {out.shape}')
                    out += value
                else:
                    out[:, term.input_index] += term(times)
        if not np.isfinite(out).all():   # the method: np.all's dispatch costs more
            raise ValueError('forcing produced a non-finite value')
        return out

    def evaluate(self, t: npt.ArrayLike) -> FloatArray:
        """Return the total forcing (harmonic plus sampled) at times ``t`` (N)."""
        times = np.atleast_1d(np.asarray(t, dtype=float))
        out = self.sample(times)
        for h in self.harmonics:
            out[:, h.input_index] += h.amplitude * np.cos(h.omega * times + h.phase)

        return out
