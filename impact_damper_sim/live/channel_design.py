"""Designs of the accelerometer channel's stages (:mod:`.channel`): mounting, resonance, HP.

Pure functions of the stage's values and the integrator's step rate; they carry no state and no
random numbers. Everything is SI.

* :func:`mounting_matrix`: the 3 x 3 matrix ``S (I + T) R^T`` from the model frame to the
  sensor's output axes (orientation, transverse sensitivity, sensitivity error).
* :func:`design_resonance`: a digital section for the mounted resonance's in-band effect.
* :func:`highpass_sos`: the IEPE coupling high-pass, first order.
"""
from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np


def rotation_matrix(orientation):
    """Rotation ``R = Rz(yaw) Ry(pitch) Rx(roll)``: the sensor's axes in the model frame.

    Column ``i`` of ``R`` is the sensor's axis ``i`` in model coordinates, so a sensor at this
    orientation reads ``R.T @ a`` for a model-frame acceleration ``a``.

    Parameters
    ----------
    orientation : sequence of 3 float
        ``[roll, pitch, yaw]`` (rad), the intrinsic z-y'-x'' (aerospace) angles.

    Returns
    -------
    ndarray, shape (3, 3)
        Orthonormal, determinant +1.
    """
    roll, pitch, yaw = (float(v) for v in orientation)
    cr, sr = _cos_sin(roll)
    cp, sp = _cos_sin(pitch)
    cy, sy = _cos_sin(yaw)
    rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    return rz @ ry @ rx


def _cos_sin(angle):
    # exact at whole quarter turns, so a 90 deg yaw swaps the axes with no 6e-17 leak
    quarter = angle / (0.5 * math.pi)
    if abs(quarter - round(quarter)) < 1e-12:
        return ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))[round(quarter) % 4]
    return math.cos(angle), math.sin(angle)


def transverse_matrix(fraction, angle):
    """Transverse sensitivity ``T`` of a triaxial sensor (dimensionless, zero diagonal).

    Axis ``i`` senses along ``e_i + fraction * u_i``, where ``u_i`` is the unit vector of the
    plane normal to ``e_i`` at ``angle`` from the next axis, turning towards the one after
    (cyclic: x -> y -> z -> x)::

        u_x = cos(angle) e_y + sin(angle) e_z
        u_y = cos(angle) e_z + sin(angle) e_x
        u_z = cos(angle) e_x + sin(angle) e_y

    So ``fraction`` is the datasheet's (maximum) transverse sensitivity: an excitation along
    ``u_i`` reads ``fraction`` of itself on axis ``i``; a pure-axis excitation along y reads
    ``fraction cos(angle)`` on x and ``fraction sin(angle)`` on z (``angle = 0``: each axis
    picks up the next one only).

    Parameters
    ----------
    fraction : float
        Transverse sensitivity (dimensionless, 0.05 = 5 %), >= 0.
    angle : float
        Direction of the maximum in each axis' normal plane (rad).

    Returns
    -------
    ndarray, shape (3, 3)
        ``T[i, j]``: the share of the acceleration along sensor axis ``j`` read on axis ``i``
        (before the sensitivity error).
    """
    c, s = _cos_sin(float(angle))
    f = float(fraction)
    t = np.zeros((3, 3))
    for i in range(3):
        t[i, (i + 1) % 3] = f * c
        t[i, (i + 2) % 3] = f * s
    return t


def mounting_matrix(orientation=None, transverse=None, sensitivity_error=None):
    """The mounting stage ``M = S (I + T) R^T``: model-frame acceleration to sensor output.

    Parameters
    ----------
    orientation : sequence of 3 float or None
        ``[roll, pitch, yaw]`` (rad), see :func:`rotation_matrix`; None: aligned.
    transverse : dict or None
        ``{'fraction': f (dimensionless), 'angle': rad}``, see :func:`transverse_matrix`.
    sensitivity_error : sequence of 3 float or None
        Per-axis relative error (dimensionless): ``S = diag(1 + e)``.

    Returns
    -------
    ndarray, shape (3, 3) or None
        None when every part is off (the identity is skipped, not applied).
    """
    if orientation is None and transverse is None and sensitivity_error is None:
        return None
    m = np.eye(3)
    if orientation is not None:
        m = rotation_matrix(orientation).T
    if transverse is not None:
        m = (np.eye(3) + transverse_matrix(transverse['fraction'], transverse['angle'])) @ m
    if sensitivity_error is not None:
        m = np.diag(1.0 + np.asarray(sensitivity_error, dtype=float)) @ m
    return m


def analog_resonance(f, fn, q):
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


#: Design tolerances of the resonance section against the analog response over its band:
#: gain (relative) and phase (deg), a fifth of the 0.5 % / 0.5 deg the channel promises ...
RESONANCE_GAIN_TOLERANCE = 1e-3
RESONANCE_PHASE_TOLERANCE_DEG = 0.1
#: ... and this fraction of the effect itself (the largest lift ``| |H| - 1 |`` and phase in
#: the band), so a small lift is modelled, not left out ...
RESONANCE_EFFECT_FRACTION = 0.1
#: ... but no finer than these (an effect below them is not worth a step of latency).
RESONANCE_GAIN_FLOOR = 1e-4
RESONANCE_PHASE_FLOOR_DEG = 0.01
#: Longest look-ahead tried (integrator steps): the fits need 7 at most (fn at the Nyquist
#: frequency, Q 30); no design within it is refused.
RESONANCE_MAX_DELAY = 12
#: Top of the checked band: min(0.4 x step rate, 0.5 x fn) (covers 0.1-0.3 fn with margin, and
#: the whole band below 0.4 x step rate once fn >= 0.8 x step rate).
RESONANCE_BAND_OF_STEP_RATE = 0.4
#: fn / step rate below which a denominator (a biquad's poles) is tried as well as FIRs.
RESONANCE_IIR_BELOW = 0.6
RESONANCE_BAND_OF_FN = 0.5


@dataclasses.dataclass(frozen=True)
class ResonanceDesign:
    """A digital section ``z^-delay H(z) = B(z) / A(z)`` for the mounted resonance.

    Attributes
    ----------
    b : ndarray
        Numerator, ``b[0] + b[1] z^-1 + ...`` (dimensionless).
    a : ndarray
        Denominator, ``[1]`` (FIR) or ``[1, a1, a2]``.
    delay : int
        Look-ahead bought with latency (integrator steps): ``B/A`` matches the analog response
        times ``z^-delay``; the channel delays its ground truth by the same steps.
    band_hz : float
        Top of the band the match is checked over (Hz), from 0.
    gain_error : float
        Largest ``| |H_d| / |H| - 1 |`` over the band (dimensionless).
    phase_error_deg : float
        Largest ``|arg(H_d / H)|`` over the band, the delay removed (deg).
    """

    b: np.ndarray
    a: np.ndarray
    delay: int
    band_hz: float
    gain_error: float
    phase_error_deg: float

    @property
    def identity(self):
        """bool: The in-band effect is within the tolerances: nothing to apply."""
        return self.delay == 0 and len(self.b) == 1 and len(self.a) == 1

    def response(self, f, step_rate_hz):
        """Digital response with the delay removed, ``e^{j w delay} B/A`` (dimensionless)."""
        theta = 2.0 * np.pi * np.asarray(f, dtype=float) / float(step_rate_hz)
        return _freqz(self.b, self.a, theta) * np.exp(1j * self.delay * theta)


def _freqz(b, a, theta):
    n = max(len(a), len(b))
    e = np.exp(-1j * np.outer(theta, np.arange(n)))
    return (e[:, :len(b)] @ b) / (e[:, :len(a)] @ a)


def _fit(theta, target, weight, nb, na, iterations=12):
    """Weighted least squares ``B/A ~ target`` with ``B(1) = A(1)`` (unit DC gain).

    ``na = 0``: the FIR ``B`` minimising the weighted output error (one linear solve).
    ``na = 2``: Sanathanan-Koerner iterations of the equation error ``B - target A``
    weighted by ``1/|A|`` of the previous pass.
    """
    e = np.exp(-1j * np.outer(theta, np.arange(max(nb, na) + 1)))
    a = np.zeros(na + 1)
    a[0] = 1.0
    b = np.ones(1)
    for _ in range(iterations if na else 1):
        w = weight / np.abs(e[:, :na + 1] @ a)
        # unknowns b_0..b_{nb-1}, a_1..a_na; b_nb = A(1) - sum(b_0..b_{nb-1})
        cols = [e[:, i] - e[:, nb] for i in range(nb)]
        cols += [e[:, nb] - target * e[:, i] for i in range(1, na + 1)]
        if not cols:
            return np.ones(1), a
        m = np.stack(cols, axis=1) * w[:, None]
        rhs = (target - e[:, nb]) * w
        x = np.linalg.lstsq(np.vstack([m.real, m.imag]), np.concatenate([rhs.real, rhs.imag]),
                            rcond=None)[0]
        a = np.concatenate([[1.0], x[nb:]])
        b = np.append(x[:nb], a.sum() - x[:nb].sum())
    return b, a


@functools.lru_cache(maxsize=64)
def _design(ratio, q):
    # in units of the step rate: the design depends on fn / step rate and Q only
    band = min(RESONANCE_BAND_OF_STEP_RATE, RESONANCE_BAND_OF_FN * ratio)
    n = 400
    inside = np.linspace(0.0, 2.0 * np.pi * band, n)
    outside = np.linspace(2.0 * np.pi * band, np.pi, n // 4)[1:]
    theta = np.concatenate([inside, outside])
    h = analog_resonance(theta / (2.0 * np.pi), ratio, q)
    # relative error in the band; a light pull towards the analog response above it keeps
    # the gain there near the sensor's (no fitted peak between the band and Nyquist)
    weight = np.concatenate([np.ones(n), np.full(len(outside), 0.05)]) / np.abs(h)
    h_max = float(np.abs(h).max())
    tol_gain = min(RESONANCE_GAIN_TOLERANCE, max(
        RESONANCE_GAIN_FLOOR, RESONANCE_EFFECT_FRACTION * np.max(np.abs(np.abs(h[:n]) - 1))))
    tol_phase = min(RESONANCE_PHASE_TOLERANCE_DEG, max(
        RESONANCE_PHASE_FLOOR_DEG,
        RESONANCE_EFFECT_FRACTION * np.max(np.abs(np.angle(h[:n], deg=True)))))
    # poles may ring at most twice as long as the sensor's own (a Q of 1000 in the band sits
    # at radius 0.9992), never closer to the unit circle than 0.999 otherwise
    rho = math.exp(-math.pi * min(ratio, 0.5) / q)
    pole_limit = max(0.999, 1.0 - 0.5 * (1.0 - rho))
    for delay in range(RESONANCE_MAX_DELAY + 1):
        target = h * np.exp(-1j * delay * theta)
        shapes = ([(0, 0)] if delay == 0 else []) + [
            (2 * delay, 0), (2 * delay + 1, 0), (2 * delay + 2, 0)]
        if ratio < RESONANCE_IIR_BELOW:   # a peak in the band needs poles
            shapes.insert(0, (2 * delay + 2, 2))
        for nb, na in shapes:
            b, a = _fit(theta, target, weight, nb, na)
            if na and np.max(np.abs(np.roots(a))) >= pole_limit:
                continue   # unstable or ringing at the unit circle
            hd = _freqz(b, a, theta) * np.exp(1j * delay * theta)
            rel = hd[:n] / h[:n]
            gain = float(np.max(np.abs(np.abs(rel) - 1.0)))
            phase = float(np.max(np.abs(np.angle(rel, deg=True))))
            if gain <= tol_gain and phase <= tol_phase and np.abs(hd).max() <= 2.0 * h_max:
                return b, a, delay, band, gain, phase
    return None


def design_resonance(frequency, q, step_rate_hz):
    """Digital section for the mounted resonance ``H(s) = wn^2 / (s^2 + wn/Q s + wn^2)``.

    The in-band effect of a resonance above the band is a lift ``|H| ~ 1 + (f/fn)^2`` with a
    phase lag ``~ (f/fn)/Q``: nearly zero phase under a rising gain. A causal, stable digital
    filter cannot follow that to 0.5 % up to 0.4 x the step rate: the band-limited ideal,
    ``H(j w)`` on ``|w| < pi/dt``, has an impulse response as large before t = 0 as after
    (for ``|H| ~ 1 + c w^2``: ``h[n] = 2 c (-1)^n / (n dt)^2`` on both sides), and causal fits
    stall at 1-4 % (fn 30 kHz, Q 30, 20 kHz) unless their gain above the band grows several
    fold or their poles reach the unit circle. So the section buys a look-ahead with
    latency: it is the least-squares fit of ``z^-L H`` (an FIR of ``2L + 1`` or ``2L + 2``
    taps, or that over a stable second-order denominator when the resonance lies in the band),
    with the smallest ``L`` whose match over the band ``0 .. min(0.4 fs, 0.5 fn)`` (the delay
    removed) is within 0.1 % in gain and 0.1 deg in phase and within 10 % of the effect itself
    (the largest ``| |H| - 1 |`` and phase in the band; floors 0.01 % and 0.01 deg), and whose
    gain above the band stays below twice the analog peak. The fit weighs the relative error
    in the band fully and, at 1/20, the gain above it towards the analog response, so the
    section does not invent a peak between the band and Nyquist. The channel delays its
    ground truth by the same ``L`` steps, so the two stay aligned; the latency is in its
    labels. Measured (``test/test_channel.py`` checks a sample): L is 0 when the whole effect
    is below the floors (identity); 1-3 for a resonance inside the band (fn 0.2-0.35 x the
    step rate, Q 10-300: a biquad over a short FIR); 2-5 for fn 1.5-25 x the step rate at
    Q 10-50 (4 at fn 30 kHz, Q 30 and a 20 kHz step: 0.2 ms); 4-12 with fn 0.45-1.25 x the
    step rate, about the Nyquist frequency.

    Parameters
    ----------
    frequency : float
        Mounted natural frequency fn (Hz), > 0.
    q : float
        Quality factor Q (dimensionless), > 0.
    step_rate_hz : float
        Integrator step rate (Hz).

    Returns
    -------
    ResonanceDesign

    Raises
    ------
    ValueError
        No design within :data:`RESONANCE_MAX_DELAY` steps (met for Q 2-1000 with fn from
        0.2 x the step rate up; not for Q <= 1 with fn 0.7-2 x the step rate).
    """
    fn, q, fs = float(frequency), float(q), float(step_rate_hz)
    if not (math.isfinite(fn) and fn > 0):
        raise ValueError(f"spec key 'resonance.frequency': must be a finite frequency > 0 Hz, "
                         f'got {frequency!r}')
    if not (math.isfinite(q) and q > 0):
        raise ValueError(f"spec key 'resonance.q': must be finite and > 0, got {q!r}")
    found = _design(fn / fs, q)
    if found is None:
        raise ValueError(f"spec key 'resonance': no digital section matches fn = {fn:g} Hz, "
                         f'Q = {q:g} at the step rate {fs:g} Hz within '
                         f'{RESONANCE_MAX_DELAY} steps of latency')
    b, a, delay, band, gain, phase = found
    return ResonanceDesign(b.copy(), a.copy(), delay, band * fs, gain, phase)


def highpass_sos(corner_hz, step_rate_hz):
    """First-order high-pass (IEPE coupling), bilinear, prewarped: -3 dB exactly at the corner.

    The analog ``s / (s + wc)`` mapped with ``s -> (wc / k) (1 - z^-1)/(1 + z^-1)``,
    ``k = tan(pi fc / fs)``: the digital response equals the analog one at the corner; its
    phase matches below (the warping is ``(f / fs)^2``-small at an IEPE corner).

    Parameters
    ----------
    corner_hz : float
        -3 dB corner fc (Hz), in ``(0, step_rate_hz / 2)``.
    step_rate_hz : float
        Step rate fs (Hz).

    Returns
    -------
    ndarray, shape (1, 6)
        One section ``[b0, b1, 0, 1, a1, 0]``.
    """
    fc, fs = float(corner_hz), float(step_rate_hz)
    if not (math.isfinite(fc) and 0.0 < fc < 0.5 * fs):
        raise ValueError(f"spec key 'highpass.corner': must lie in (0, {0.5 * fs:g}) Hz, the "
                         f'Nyquist frequency of the step rate, got {corner_hz!r}')
    k = math.tan(math.pi * fc / fs)
    g = 1.0 / (1.0 + k)
    return np.array([[g, -g, 0.0, 1.0, -(1.0 - k) * g, 0.0]])


__all__ = ['ResonanceDesign', 'analog_resonance', 'design_resonance', 'highpass_sos',
           'mounting_matrix', 'rotation_matrix', 'transverse_matrix']
