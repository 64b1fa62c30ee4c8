"""The mounted resonance of the accelerometer channel (:mod:`.channel`) as causal biquads.

:func:`design_resonance` fits a cascade of up to :data:`RESONANCE_MAX_SECTIONS` biquads, with
zero latency, to the analog ``wn^2 / (s^2 + wn/Q s + wn^2)`` (:func:`analog_resonance`) over
the band below the anti-alias cutoff, and refuses a resonance no cascade meets within the
tolerances below. A pure function of the stage's values and the integrator's step rate: no
state, no random numbers. Everything is SI.

The fit costs about 0.3 s of CPU, so each design is kept in the process and in a per-user
cache on disk (:func:`impact_damper_sim._cache_dir.design_cache_dir`): one JSON file per
design holding its floats bit for bit, keyed by the inputs' bits, this module's source text
(a change of the algorithm or its tolerances misses every entry), numpy's version and the
machine. A missing, corrupt or unwritable cache costs the fit again, never an error.
"""
from __future__ import annotations

import contextlib
import dataclasses
import functools
import hashlib
import json
import logging
import math
import os
import platform
import tempfile
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from .._cache_dir import design_cache_dir

#: What :func:`_check` measures of a cascade: (score, gain error, phase error (deg), lift
#: error, gain above band, error above band, largest pole radius)
_Checked = tuple[float, float, float, float, float, float, float]
#: One fit of :meth:`_Fit.run`: (score on the grid, numerator b, denominator a, parameters p)
_FitRun = tuple[float, np.ndarray, np.ndarray, np.ndarray]
#: A design: the sections (None when refused) and what :func:`_check` measured of them
_Designed = tuple[npt.NDArray[np.float64] | None, _Checked]


def analog_resonance(f: npt.ArrayLike, fn: float, q: float) -> np.ndarray:
    """Closed form ``H(j 2 pi f)`` of ``wn^2 / (s^2 + wn/Q s + wn^2)`` (dimensionless).

    Parameters
    ----------
    f : array_like
        Frequency (Hz).
    fn : float
        Natural frequency (Hz).
    q : float
        Quality factor (dimensionless).
    """
    r = np.asarray(f, dtype=float) / float(fn)
    return 1.0 / (1.0 - r * r + 1j * r / float(q))


#: Tolerances of the resonance section against the analog response over its band: gain
#: (relative) and phase (deg) ...
RESONANCE_GAIN_TOLERANCE = 5e-3
RESONANCE_PHASE_TOLERANCE_DEG = 0.5
#: ... and the lift ``| |H| - 1 |`` within this fraction of itself where it is at least
#: :data:`RESONANCE_LIFT_FLOOR`; where it is below, the section's lift stays below the floor
#: times ``1 + fraction`` (so the gain tolerance, ``max(0.1 lift, 1.1e-4 - lift)`` capped at
#: 0.5 %, is continuous in the lift).
RESONANCE_LIFT_FRACTION = 0.1
RESONANCE_LIFT_FLOOR = 1e-4
#: Top of the band: min(lowpass, this x the step rate). Above the anti-alias cutoff the
#: 4th-order Butterworth removes the signal; the last 10 % below Nyquist is left free.
RESONANCE_BAND_OF_STEP_RATE = 0.45
#: A section count is taken when its fit meets this fraction of the tolerances; else the best
#: count within the tolerances themselves; else the resonance is refused.
RESONANCE_DESIGN_MARGIN = 0.5
#: Most biquads tried (each one section of ``sosfilt``, a few ns per sample and axis).
RESONANCE_MAX_SECTIONS = 3
#: Above the band, up to Nyquist, the gain stays below this times ``max(1, |H|)`` (no invented
#: peak) ...
RESONANCE_GAIN_ABOVE_BAND = 1.5
#: ... and within this fraction of the analog gain once through the anti-alias filter,
#: ``| |H_d|/|H| - 1 | |LP|`` (``|LP| = 1/sqrt(1 + (f/lowpass)^8)``), so the published
#: spectrum just above the cutoff, where the Butterworth has not yet removed it, is the
#: sensor's too.
RESONANCE_ABOVE_TOLERANCE = 0.05
#: Largest pole radius of a section (a Q of 1000 at 0.2 x the step rate has 0.99937): the
#: denominator is ``1 + rho k1 (1 + k2) z^-1 + rho^2 k2 z^-2`` with ``|k1|, |k2| < 1``.
_POLE_RADIUS = 0.9998
_K_MAX = 0.9999
#: Fit grid: points in the band and above it (the reported errors use 2001 in each).
_N_BAND, _N_ABOVE, _N_CHECK = 120, 120, 2001


@dataclasses.dataclass(frozen=True)
class ResonanceDesign:
    """The mounted resonance as a cascade of stable biquads, causal and with zero latency.

    Attributes
    ----------
    sos : ndarray, shape (m, 6)
        Second-order sections ``[b0, b1, b2, 1, a1, a2]``, each of unit DC gain; ``m = 0``
        when the in-band effect is within the tolerances unmodelled (identity).
    band_hz : float
        Top of the band the match holds over (Hz), from 0: ``min(lowpass, 0.45 x step rate)``.
    gain_error : float
        Largest ``| |H_d| / |H| - 1 |`` over the band (dimensionless).
    phase_error_deg : float
        Largest ``|arg(H_d / H)|`` over the band (deg).
    lift_error : float
        Largest ``| |H_d| - |H| | / | |H| - 1 |`` where the lift is at least
        :data:`RESONANCE_LIFT_FLOOR` (dimensionless; 0 when it is nowhere).
    gain_above_band : float
        Largest ``|H_d|`` from the band to Nyquist over ``max(1, |H|)`` there
        (dimensionless).
    error_above_band : float
        Largest ``| |H_d|/|H| - 1 |`` from the band to Nyquist times the anti-alias filter's
        gain (dimensionless).
    pole_radius : float
        Largest pole radius (dimensionless, < 1; 0 without poles).
    """

    sos: np.ndarray
    band_hz: float
    gain_error: float
    phase_error_deg: float
    lift_error: float
    gain_above_band: float
    error_above_band: float
    pole_radius: float

    @property
    def identity(self) -> bool:
        """bool: The in-band effect is within the tolerances: nothing to apply."""
        return len(self.sos) == 0

    @property
    def b(self) -> npt.NDArray[np.float64]:
        """ndarray: Numerator of the whole cascade, ``b[0] + b[1] z^-1 + ...``."""
        return functools.reduce(np.convolve, self.sos[:, :3], np.ones(1))

    @property
    def a(self) -> npt.NDArray[np.float64]:
        """ndarray: Denominator of the whole cascade, ``1 + a[1] z^-1 + ...``."""
        return functools.reduce(np.convolve, self.sos[:, 3:], np.ones(1))

    def response(self, f: npt.ArrayLike, step_rate_hz: float) -> npt.NDArray[np.complex128]:
        """Digital response ``H_d(e^{j 2 pi f / fs})`` (dimensionless), nothing removed."""
        theta = 2.0 * np.pi * np.asarray(f, dtype=float) / float(step_rate_hz)
        return _sos_response(self.sos, theta)


def _sos_response(sos: np.ndarray, theta: np.ndarray) -> npt.NDArray[np.complex128]:
    e = np.exp(-1j * np.multiply.outer(theta, np.arange(3)))
    out = np.ones(np.shape(theta), dtype=complex)
    for row in sos:
        out *= (e @ row[:3]) / (e @ row[3:])
    return out


def _tolerances(h: np.ndarray) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Gain (relative) and phase (rad) tolerance at each point of the analog response ``h``."""
    lift = np.abs(np.abs(h) - 1.0)
    floor = RESONANCE_LIFT_FLOOR * (1.0 + RESONANCE_LIFT_FRACTION)
    gain = np.minimum(RESONANCE_GAIN_TOLERANCE,
                      np.maximum(RESONANCE_LIFT_FRACTION * lift, floor - lift))
    return gain, np.full(np.shape(h), math.radians(RESONANCE_PHASE_TOLERANCE_DEG))


def _denominator(p: Sequence[float] | np.ndarray) -> npt.NDArray[np.float64]:
    """Stable denominator, two parameters per section: reflection coefficients
    ``k = K_MAX tanh(p)`` of a polynomial stable in the unit disk, its poles scaled by
    ``_POLE_RADIUS`` (so every pole lies inside that radius)."""
    a = np.ones(1)
    rho = _POLE_RADIUS
    for i in range(0, len(p), 2):
        k1, k2 = _K_MAX * math.tanh(p[i]), _K_MAX * math.tanh(p[i + 1])
        a = np.convolve(a, [1.0, rho * k1 * (1.0 + k2), rho * rho * k2])
    return a


def _params(a1: float, a2: float) -> list[float]:
    """Inverse of :func:`_denominator` for one section ``1 + a1 z^-1 + a2 z^-2``."""
    rho = _POLE_RADIUS
    k2 = a2 / (rho * rho)
    k = (a1 / rho / (1.0 + k2), k2)
    return [math.atanh(min(max(v / _K_MAX, -0.999), 0.999)) for v in k]


def _section_starts(ratio: float, q: float) -> list[list[float]]:
    """Starting denominators of one section: none (an FIR); a real pole near Nyquist and one
    near 0 (the shape the fits take for fn above the band); the analog poles mapped by
    ``z = e^{s dt}`` when fn is below Nyquist, a pair at 0.75 pi otherwise."""
    starts = [[0.0, 0.0], _params(0.95 - 0.1, -0.095)]
    wn, zeta = 2.0 * math.pi * ratio, 0.5 / q
    if ratio < 0.5 and zeta < 1.0:
        r = math.exp(-zeta * wn)
        starts.append(_params(-2.0 * r * math.cos(wn * math.sqrt(1.0 - zeta * zeta)), r * r))
    elif ratio < 0.5:
        root = math.sqrt(zeta * zeta - 1.0)
        p1, p2 = math.exp(-wn * (zeta - root)), math.exp(-wn * (zeta + root))
        starts.append(_params(-(p1 + p2), p1 * p2))
    else:
        starts.append(_params(-1.8 * math.cos(0.75 * math.pi), 0.81))
    return starts


class _Fit:
    """Weighted least squares of ``B/A ~ H``, ``A`` stable, ``B(1) = A(1)``.

    Variable projection: for a denominator the numerator is one linear solve; the
    denominator's reflection coefficients are found by Levenberg-Marquardt. The residuals are
    ``Re`` and ``Im`` of ``H_d/H - 1`` (gain and phase errors) over their tolerances in the
    band; above it, the gain error through the anti-alias filter over its tolerance (and the
    phase, at a tenth of that weight), and a penalty on the gain beyond 0.95 x its cap.
    Lawson's reweighting pushes the least-squares fit towards the minimax one.
    """

    def __init__(self, ratio: float, q: float, band: float, lowpass: float,
                 sections: int) -> None:
        self.theta = np.linspace(0.0, 2.0 * np.pi * band, _N_BAND)
        above = _above_grid(band, _N_ABOVE, ratio, q)
        self.h = analog_resonance(self.theta / (2.0 * np.pi), ratio, q)
        self.tol_gain, self.tol_phase = _tolerances(self.h)
        self.h_above = analog_resonance(above / (2.0 * np.pi), ratio, q)
        self.cap = RESONANCE_GAIN_ABOVE_BAND * np.maximum(1.0, np.abs(self.h_above))
        # Re(H_d/H - 1) |LP| ~ (|H_d|/|H| - 1) |LP|: the error above the band, per tolerance
        self.w_above = _lowpass_gain(above, lowpass) / RESONANCE_ABOVE_TOLERANCE
        k = np.arange(2 * sections + 1)
        self.e = np.exp(-1j * np.outer(self.theta, k))
        self.e_above = np.exp(-1j * np.outer(above, k))
        self.e_all = np.vstack([self.e, self.e_above])
        self.h_all = np.concatenate([self.h, self.h_above])

    def numerator(self, a: np.ndarray, nb: int, w_re: np.ndarray,
                  w_im: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The numerator for the denominator ``a`` and the weighted residuals. ``w_re`` and
        ``w_im`` weigh the band's points, then those above it (only lightly in phase)."""
        # unknowns b_0 .. b_{nb-1}; b_nb = A(1) - sum(b_0 .. b_{nb-1})
        e = self.e_all
        ah = (e[:, :len(a)] @ a) * self.h_all
        cols = (e[:, :nb] - e[:, [nb]]) / ah[:, None]
        base = a.sum() * e[:, nb] / ah - 1.0
        m = np.vstack([cols.real * w_re[:, None], cols.imag * w_im[:, None]])
        rhs = -np.concatenate([base.real * w_re, base.imag * w_im])
        x = np.linalg.lstsq(m, rhs, rcond=None)[0]
        return np.append(x, a.sum() - x.sum()), m @ x - rhs

    def above(self, b: np.ndarray, a: np.ndarray) -> npt.NDArray[np.float64]:
        """|H_d| above the band over its cap."""
        return np.abs((self.e_above[:, :len(b)] @ b) / (self.e_above[:, :len(a)] @ a)) / self.cap

    def residuals(self, p: np.ndarray, nb: int, w_re: np.ndarray,
                  w_im: np.ndarray) -> npt.NDArray[np.float64]:
        a = _denominator(p)
        b, res = self.numerator(a, nb, w_re, w_im)
        return np.concatenate([res, 100.0 * np.maximum(self.above(b, a) - 0.95, 0.0)])

    def run(self, p0: Sequence[float], nb: int, lawson: int = 4) -> _FitRun | None:
        """The fit from the start ``p0``: (score on the grid, b, a, p), or None."""
        w_re = np.concatenate([1.0 / self.tol_gain, self.w_above])
        w_im = np.concatenate([1.0 / self.tol_phase, 0.1 * self.w_above])
        p, best = np.array(p0, dtype=float), None

        def residuals(v: np.ndarray) -> npt.NDArray[np.float64]:
            return self.residuals(v, nb, w_re, w_im)

        for _ in range(lawson):
            p = _levenberg_marquardt(residuals, p)
            a = _denominator(p)
            b = self.numerator(a, nb, w_re, w_im)[0]
            rel = (self.e[:, :len(b)] @ b) / (self.e[:, :len(a)] @ a) / self.h
            err_gain = np.abs(np.abs(rel) - 1.0) / self.tol_gain
            err_phase = np.abs(np.angle(rel)) / self.tol_phase
            hd_above = np.abs((self.e_above[:, :len(b)] @ b) / (self.e_above[:, :len(a)] @ a))
            h_above = np.abs(self.h_above)
            err_above = np.abs(hd_above / h_above - 1.0) * self.w_above
            score = max(err_gain.max(), err_phase.max(), err_above.max())
            if np.all(hd_above <= self.cap) and (best is None or score < best[0]):
                best = (score, b, a, p.copy())
            # Lawson: raise the weights where the error is largest (towards the minimax fit)
            w_re = w_re * np.sqrt(1.0 + np.concatenate([err_gain, err_above]) / score)
            w_im = w_im * np.sqrt(1.0 + np.concatenate([err_phase, err_above]) / score)
        return best


def _levenberg_marquardt(fun: Callable[[np.ndarray], np.ndarray], p: np.ndarray,
                         iterations: int = 30) -> np.ndarray:
    """Minimise ``|fun(p)|^2`` (a few parameters; forward-difference Jacobian)."""
    r = fun(p)
    cost, lam = float(r @ r), 1e-3
    for _ in range(iterations):
        jac = np.empty((len(r), len(p)))
        for i in range(len(p)):
            step = 1e-6 * max(1.0, abs(p[i]))
            q = p.copy()
            q[i] += step
            jac[:, i] = (fun(q) - r) / step
        g, jtj = jac.T @ r, jac.T @ jac
        diag = np.diag(jtj).copy() + 1e-12
        for _ in range(8):
            dp = np.linalg.solve(jtj + lam * np.diag(diag), -g)
            r_new = fun(p + dp)
            cost_new = float(r_new @ r_new)
            if cost_new < cost:
                break
            lam *= 4.0
        else:
            return p
        gain = cost - cost_new
        p, r, cost, lam = p + dp, r_new, cost_new, max(lam / 3.0, 1e-9)
        if gain <= 1e-9 * cost:
            break
    return p


def _to_sos(b: np.ndarray, p: np.ndarray) -> npt.NDArray[np.float64]:
    """The cascade ``B/A`` as unit-DC-gain sections: the fit's own denominator sections, and
    B's roots paired into real quadratics (conjugate pairs; real roots by size)."""
    den = np.array([_denominator(p[i:i + 2]) for i in range(0, len(p), 2)])
    lead = len(b) - len(np.trim_zeros(b, 'f'))
    sos = np.hstack([_quadratics(np.roots(b[lead:]), len(den), lead), den])
    for row in sos:
        row[:3] *= row[3:].sum() / row[:3].sum()   # unit DC gain per section
    return sos


def _quadratics(roots: Iterable[complex], m: int, lead_zeros: int = 0) -> npt.NDArray[np.float64]:
    """``m`` real factors ``[c0, c1, c2]`` (in ``z^-1``) of a polynomial with these roots.

    ``lead_zeros`` leading zero coefficients (roots at infinity) become ``z^-1`` factors.
    """
    roots = list(roots)
    cplx = sorted((z for z in roots if z.imag > 1e-12 * max(1.0, abs(z))),
                  key=lambda z: -abs(z))
    real = sorted((z.real for z in roots if abs(z.imag) <= 1e-12 * max(1.0, abs(z))),
                  key=lambda x: -abs(x))
    factors = [[1.0, -2.0 * z.real, abs(z) ** 2] for z in cplx]
    linear = [[1.0, -x] for x in real] + [[0.0, 1.0]] * lead_zeros
    for i in range(0, len(linear) - 1, 2):
        factors.append(list(np.convolve(linear[i], linear[i + 1])))
    if len(linear) % 2:
        factors.append(linear[-1] + [0.0])
    while len(factors) < m:
        factors.append([1.0, 0.0, 0.0])
    return np.array(factors[:m], dtype=float)


def _above_grid(band: float, n: int, ratio: float | None = None,
                q: float | None = None) -> npt.NDArray[np.float64]:
    """``n`` points from the band's top (excluded) to Nyquist, denser near the top; with
    ``ratio`` and ``q``, plus 13 across the resonance's peak when it lies there."""
    u = np.linspace(0.0, 1.0, n + 1)[1:]
    theta = 2.0 * np.pi * band + (np.pi - 2.0 * np.pi * band) * u * u
    if ratio is not None and q is not None and band < ratio < 0.5:
        peak = 2.0 * np.pi * ratio * (1.0 + np.linspace(-3.0, 3.0, 13) / (2.0 * q))
        theta = np.sort(np.concatenate([theta, peak[(peak > 2.0 * np.pi * band)
                                                    & (peak <= np.pi)]]))
    return theta


def _lowpass_gain(theta: np.ndarray, lowpass: float) -> npt.NDArray[np.float64]:
    """The anti-alias Butterworth's gain (4th order, analog form) at ``theta`` (rad/step)."""
    return 1.0 / np.sqrt(1.0 + (theta / (2.0 * np.pi * lowpass)) ** 8)


def _check(sos: np.ndarray, ratio: float, q: float, band: float, lowpass: float) -> _Checked:
    """(score, gain error, phase error deg, lift error, gain above band, error above band,
    pole radius) on dense grids; the score is the largest error over its tolerance, in the
    band and above it."""
    theta = np.linspace(0.0, 2.0 * np.pi * band, _N_CHECK)
    h = analog_resonance(theta / (2.0 * np.pi), ratio, q)
    hd = _sos_response(sos, theta)
    tol_gain, tol_phase = _tolerances(h)
    rel = hd / h
    err_gain = np.abs(np.abs(rel) - 1.0)
    err_phase = np.abs(np.angle(rel))
    lift = np.abs(np.abs(h) - 1.0)
    lifted = lift >= RESONANCE_LIFT_FLOOR
    lift_error = (float(np.max(np.abs(np.abs(hd) - np.abs(h))[lifted] / lift[lifted]))
                  if lifted.any() else 0.0)
    above = _above_grid(band, _N_CHECK, ratio, q)
    h_above = np.abs(analog_resonance(above / (2.0 * np.pi), ratio, q))
    hd_above = np.abs(_sos_response(sos, above))
    gain_above = float(np.max(hd_above / np.maximum(1.0, h_above)))
    error_above = float(np.max(np.abs(hd_above / h_above - 1.0) * _lowpass_gain(above, lowpass)))
    score = max(float(np.max(err_gain / tol_gain)), float(np.max(err_phase / tol_phase)),
                error_above / RESONANCE_ABOVE_TOLERANCE,
                # the cap is a bound, not a tolerance: beyond it nothing is taken
                0.0 if gain_above <= RESONANCE_GAIN_ABOVE_BAND else math.inf)
    radius = max((float(np.max(np.abs(np.roots(row[3:])))) for row in sos if row[4] or row[5]),
                 default=0.0)
    return (score, float(err_gain.max()), float(np.degrees(err_phase.max())), lift_error,
            gain_above, error_above, radius)


def _fit_design(ratio: float, q: float, band: float, lowpass: float) -> _Designed:
    """Fit the design (the cost :func:`_design` caches): ``(sos or None when refused, the
    checked errors)``. The arguments are fn, band and lowpass in units of the step rate and Q:
    the design depends on nothing else."""
    identity = np.zeros((0, 6))
    checked = _check(identity, ratio, q, band, lowpass)
    if checked[0] <= RESONANCE_DESIGN_MARGIN:
        return identity, checked
    best, found = None, [(checked[0], 0, identity, checked)]
    for sections in range(1, RESONANCE_MAX_SECTIONS + 1):
        fit = _Fit(ratio, q, band, lowpass, sections)
        starts = [([] if best is None else list(best[3])) + s
                  for s in _section_starts(ratio, q)]
        runs = []
        for p0 in starts:
            try:
                run = fit.run(p0, 2 * sections)
            except np.linalg.LinAlgError:
                run = None
            if run is not None:
                runs.append(run)
        if not runs:
            break
        best = min(runs, key=lambda r: r[0])
        sos = _to_sos(best[1], best[3])
        checked = _check(sos, ratio, q, band, lowpass)
        found.append((checked[0], sections, sos, checked))
        if checked[0] <= RESONANCE_DESIGN_MARGIN:
            return sos, checked
    score, _, sos, checked = min(found, key=lambda f: (f[0], f[1]))
    return (sos if score <= 1.0 else None), checked


_log = logging.getLogger(__name__)
#: Layout of the cache's entries; a change of it (or of anything in this file) misses them all.
_CACHE_FORMAT = 1


def _source_digest() -> str | None:
    """SHA-256 (hex) of this module's source file now; None when it cannot be read."""
    try:
        return hashlib.sha256(Path(__file__).read_bytes()).hexdigest()
    except OSError:
        return None


#: The digest of the source as this process imported it: the code that runs
_SOURCE_DIGEST = _source_digest()


def _cache_entry_place(ratio: float, q: float, band: float,
                       lowpass: float) -> tuple[Path, dict[str, Any]] | None:
    """The cache file of a design and the key it must hold, or None without a cache: off,
    or the source unreadable or edited since the import (the running code is not the file's,
    so its designs must not be stored under the file's digest)."""
    directory, digest = design_cache_dir(), _SOURCE_DIGEST
    if directory is None or digest is None or _source_digest() != digest:
        return None
    key = {'format': _CACHE_FORMAT,
           'inputs': [float(v).hex() for v in (ratio, q, band, lowpass)],
           'source_sha256': digest, 'numpy': np.__version__, 'machine': platform.machine()}
    name = hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()
    return directory / f'{name}.json', key


def _encode_entry(key: dict[str, Any], designed: _Designed) -> dict[str, Any]:
    """A design as JSON, each float as ``float.hex`` (exact, also for -0, inf and nan)."""
    sos, checked = designed
    return {'key': key,
            'sos': None if sos is None else {'shape': list(sos.shape),
                                             'values': [v.hex() for v in sos.ravel().tolist()]},
            'checked': [float(v).hex() for v in checked]}


def _decode_entry(entry: Any, key: dict[str, Any]) -> _Designed:
    """The design an entry holds; ValueError when it is not one of ``key``."""
    if not isinstance(entry, dict) or entry.get('key') != key:
        raise ValueError('the entry holds another key')
    if not isinstance(entry['checked'], list):
        raise ValueError('the checked values are not a list')
    # unpacking raises ValueError unless there are exactly 7
    score, gain, phase, lift, above, error_above, radius = map(float.fromhex, entry['checked'])
    checked = (score, gain, phase, lift, above, error_above, radius)
    stored = entry['sos']
    if stored is None:
        return None, checked
    rows, columns = stored['shape']
    if not isinstance(stored['values'], list):
        raise ValueError('the sections are not a list')
    values = [float.fromhex(v) for v in stored['values']]
    if (type(rows) is not int or not 0 <= rows <= RESONANCE_MAX_SECTIONS or columns != 6
            or len(values) != 6 * rows):
        raise ValueError(f'sections of shape {stored["shape"]} with {len(values)} values')
    sos = np.array(values, dtype=np.float64).reshape(rows, 6)
    return sos, checked


def _read_cached(path: Path, key: dict[str, Any]) -> _Designed | None:
    """The design cached at ``path``, or None when it is missing or unusable."""
    try:
        with open(path, encoding='ascii') as f:
            return _decode_entry(json.load(f), key)
    except FileNotFoundError:
        return None
    except Exception as exc:   # whatever a damaged entry raises: fit again
        _log.debug('resonance design cache: %s unusable (%s), fitting again', path, exc)
        return None


def _write_cached(path: Path, entry: dict[str, Any]) -> None:
    """Store ``entry`` at ``path`` atomically (a temporary file in the same directory, then
    renamed), so a concurrent reader sees the whole entry or none; failing quietly."""
    tmp = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix='.', suffix='.tmp', dir=path.parent)
        with os.fdopen(fd, 'w', encoding='ascii') as f:
            json.dump(entry, f)
        os.replace(tmp, path)
        tmp = None
    except Exception as exc:   # read-only, full disk, ...: the design stands
        _log.debug('resonance design cache: cannot write %s (%s)', path, exc)
    finally:
        if tmp is not None:
            with contextlib.suppress(OSError):
                os.unlink(tmp)


@functools.lru_cache(maxsize=64)
def _design(ratio: float, q: float, band: float, lowpass: float) -> _Designed:
    """:func:`_fit_design`, from the disk cache when it holds the design, else fitted and
    stored there. The arrays returned are shared: callers copy them."""
    try:
        place = _cache_entry_place(ratio, q, band, lowpass)
    except Exception as exc:   # e.g. no home directory: no disk cache
        _log.debug('resonance design cache: none (%s)', exc)
        place = None
    if place is not None:
        cached = _read_cached(*place)
        if cached is not None:
            return cached
    designed = _fit_design(ratio, q, band, lowpass)
    if place is not None:
        _write_cached(place[0], _encode_entry(place[1], designed))
    return designed


def design_resonance(frequency: float, q: float, step_rate_hz: float,
                     lowpass_hz: float) -> ResonanceDesign:
    """Digital section for the mounted resonance ``H(s) = wn^2 / (s^2 + wn/Q s + wn^2)``.

    Causal, stable and with **zero latency**: the channel's samples carry the model's motion
    of their own time, so a 1X phase read against a tachometer or an impact time is the
    sensor's, not the simulator's (a look-ahead of L steps would shift 1X by ``L dt`` x the
    speed: 0.72 rad at 2400 rad/s for 3 steps at 10 kHz, against the resonance's own
    ``(f/fn)/Q`` = 3e-4 rad there on hpotp).

    The section matches the analog response over the published band, ``0 .. min(lowpass,
    0.45 x step rate)`` (above the anti-alias cutoff its 4th-order Butterworth removes the
    signal): gain within 0.5 % and phase within 0.5 deg, and the lift ``| |H| - 1 |``
    within 10 % of itself where it is at least 1e-4 (below, the section's lift stays below
    1.1e-4). Above the band, up to Nyquist, its gain stays below 1.5 x ``max(1, |H|)`` and,
    once through the anti-alias filter, within 5 % of the analog gain.

    Why a fit, and not a closed form: a resonance above the band lifts the gain as
    ``(f/fn)^2`` with almost no phase, which no causal filter does exactly (zero phase under a
    rising gain is a symmetric, two-sided impulse response). The bilinear transform maps
    ``f`` to ``(fs/pi) tan(pi f/fs)``, so its lift is ``(tan(pi f/fs) / (pi f/fs))^2`` times
    too large: +62 % of the lift at 0.25 x the step rate (rbs: 2.1 % read as 3.4 %); one
    prewarped at the band's top is exact there and 38 % short of the lift below it. The
    low-frequency expansion ``1 - s/(wn Q) - s^2/wn^2`` needs ``s^2`` causally, and a backward
    second difference lags it by a step (1.6 rad at the rbs band edge). Causal FIRs fitted by
    least squares need 8 taps for 0.1 % over a quarter of the step rate and stay near 1 %
    over 0.4 x with 12. What meets the tolerances is a rational fit whose poles and zeros sit
    above the band, where the response is free: they bend the phase in the band back to the
    analog one. So the section is a least-squares fit, with zero look-ahead, of a cascade of
    1 to 3 biquads ``B/A ~ H`` (weights: the tolerances above, reweighted towards the
    minimax fit), with ``B(1) = A(1)`` (unit DC gain) and each biquad's denominator stable by
    construction (its poles inside radius 0.9998). The fewest biquads whose errors are
    within half the tolerances are taken; failing that, the most accurate within them;
    failing that, the resonance is refused. It runs as sections of ``sosfilt``, ahead of the
    high-pass.

    Measured (``test/test_channel.py`` checks them through the channel): the presets (fn 35
    and 50 kHz, Q 25) take 1 biquad at a 10 kHz step with an 800 Hz low-pass (errors below
    2e-8 in gain and 0.003 deg), 2 at 20 kHz with 5 kHz (rbs: 7e-4 in gain, 0.14 deg,
    3.5 % of the 2.1 % lift) or 1 (rbs_kcc, fn 50 kHz: 1.4e-4, 0.16 deg), 3 at 10 kHz with
    4 kHz (6e-4, 0.27 deg, 5 % of the lift); fn 5 kHz at a 50 kHz step with a 2 kHz
    low-pass, Q 5-200, 1 biquad within 5e-6 and 3e-4 deg. Every combination is met with
    the low-pass at up to 0.2 x the step rate and fn from 1.1 x it, Q 0.51-1000. Refused:
    fn not far enough above a band near Nyquist (with the low-pass at 0.4 x the step rate,
    fn below 2.5 x the step rate at Q 25, 3 x at Q 10, 10 x at Q 2, 30 x at Q 0.7; at
    0.3 x: 1.5 x at Q 10 and up, 2.5 x at Q 2). The fit takes 0.05 to about 1 s, once per
    combination: the design is kept in the process and in the per-user cache on disk (see the
    module's docstring), which a later process reads in about a millisecond.

    Parameters
    ----------
    frequency : float
        Mounted natural frequency fn (Hz), > 0.
    q : float
        Quality factor Q (dimensionless), > 0.
    step_rate_hz : float
        Integrator step rate fs (Hz), > 0.
    lowpass_hz : float
        The accelerometer's anti-alias cutoff (Hz), in ``(0, fs/2)``: the top of the band
        (capped at 0.45 fs).

    Returns
    -------
    ResonanceDesign

    Raises
    ------
    ValueError
        A bad value, or no causal section within the tolerances (the message names the key
        ``resonance``, the band and the best errors reached).
    """
    fn, q, fs, lp = float(frequency), float(q), float(step_rate_hz), float(lowpass_hz)
    if not (math.isfinite(fn) and fn > 0):
        raise ValueError(f"spec key 'resonance.frequency': must be a finite frequency > 0 Hz, "
                         f'got {frequency!r}')
    if not (math.isfinite(q) and q > 0):
        raise ValueError(f"spec key 'resonance.q': must be finite and > 0, got {q!r}")
    if not (math.isfinite(fs) and fs > 0 and 0.0 < lp < 0.5 * fs):
        raise ValueError(f'resonance: the low-pass cutoff {lowpass_hz!r} Hz must lie in '
                         f'(0, {0.5 * fs:g}) Hz at the step rate {step_rate_hz!r} Hz')
    band = min(lp / fs, RESONANCE_BAND_OF_STEP_RATE)
    sos, checked = _design(fn / fs, q, band, lp / fs)
    if sos is None:
        best = f' (best reached: {checked[1]:.2g} in gain, {checked[2]:.2g} deg)'
        raise ValueError(
            f"spec key 'resonance': fn = {fn:g} Hz, Q = {q:g} cannot be realised causally "
            f'with zero latency at the step rate {fs:g} Hz: no cascade of up to '
            f'{RESONANCE_MAX_SECTIONS} biquads matches the analog response within '
            f'{100 * RESONANCE_GAIN_TOLERANCE:g} % and {RESONANCE_PHASE_TOLERANCE_DEG:g} deg '
            f'over 0 .. {band * fs:g} Hz, the band min(lowpass, '
            f'{RESONANCE_BAND_OF_STEP_RATE:g} x step rate){best}: a causal filter cannot '
            f'follow it over a band this close to Nyquist; raise the step rate or lower the '
            f'lowpass')
    _, gain, phase, lift, above, error_above, radius = checked
    return ResonanceDesign(sos.copy(), band * fs, gain, phase, lift, above, error_above,
                           radius)


__all__ = ['ResonanceDesign', 'analog_resonance', 'design_resonance']
