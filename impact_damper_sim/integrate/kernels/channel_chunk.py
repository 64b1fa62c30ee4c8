"""Numba kernels of the live accelerometer chain, one call per stage group and chunk (issue 39).

``LiveSimulation.step`` turned each chunk of a live run into published samples with some
sixty small NumPy calls per accelerometer (ufuncs of 100 x 3 values, copies, ``sosfilt``
calls, the decimator's gather): hpotp's chunk spent ~160 us there, most of it in calls, not
arithmetic. These kernels do the same float operations in the same order in a few calls:

* :func:`step_inputs`: one accelerometer's mean acceleration per integrator step (the
  difference of the step-end velocities over ``dt``) and its angular velocity at the output
  steps;
* :func:`channel_chunk`: :class:`~impact_damper_sim.live.channel.SensorChannel`'s stages
  from the mounted signal to the range and ADC (resonance and high-pass sections, sensor
  noise, biases, the anti-alias low-pass, the pick, the live white noise) and, unless a fault
  must act first, :func:`limit`;
* :func:`limit`: the range clip and the ADC (noise, clip, grid) with the clip count;
* :func:`decimator_gather`: the DAQ decimator's windows and its history.

What stays in NumPy, because a compiled loop would not round alike: the mounting matrix's
product and the decimator's dot products (BLAS), and every random draw (each is the same
``Generator.normal`` call as before, made before the kernel and passed in). A stage that is
off is passed as an array with no rows. No kernel uses fast-math, so none contracts a
product and a sum into one rounding: the bytes are those of the NumPy path
(``test/test_channel_chunk.py``, and the live stream's fingerprint).

Conventions as in :mod:`impact_damper_sim.integrate.kernels`; ``name_py`` is each kernel's
plain twin. The filters are the :func:`.filters.sosfilt` kernel, called by symbol.
"""
from __future__ import annotations

import math

import numpy as np

from . import kernel


def sosfilt_sections_py(sos, x, zi, y):
    """:func:`.filters.sosfilt`, a section at a time over the whole chunk, channels inner.

    Each value goes through the sections in the same order, by the same operations, as in
    ``sosfilt`` (a section's output is kept in ``y`` between sections, as a float64 like the
    local it was), so the bytes are the same (``test/test_channel_chunk.py``); the channels'
    recursions are independent, so the processor overlaps them instead of waiting on one
    (hpotp's six low-pass channels of a chunk: 1.6 us instead of 3.7). ``y`` may be ``x``.
    """
    n_sections = sos.shape[0]
    if n_sections == 0:
        for k in range(x.shape[0]):
            for c in range(x.shape[1]):
                y[k, c] = x[k, c]
    for s in range(n_sections):
        b0, b1, b2 = sos[s, 0], sos[s, 1], sos[s, 2]
        a1, a2 = sos[s, 4], sos[s, 5]   # sos[s, 3] = a0 = 1
        src = x if s == 0 else y
        for k in range(x.shape[0]):
            for c in range(x.shape[1]):
                v = src[k, c]
                out = b0 * v + zi[s, 0, c]
                zi[s, 0, c] = b1 * v - a1 * out + zi[s, 1, c]
                zi[s, 1, c] = b2 * v - a2 * out
                y[k, c] = out


def step_inputs_py(vel, v_prev, c, dt, decimation, mean, ang, acc):
    """One accelerometer's inputs of a chunk, from the sensor velocities at the step ends.

    ``vel`` (n, 6 n_acc) m/s and rad/s, ``v_prev`` (6 n_acc,) the last chunk's end, ``c``
    the accelerometer's first column; writes ``mean`` (n, 3), ``(vel[i] - vel[i-1]) / dt``
    (m/s^2, ``dt`` in s) of columns ``c .. c+2``, and ``ang[:, acc, :]`` (rad/s) from columns
    ``c+3 .. c+5`` at every ``decimation``-th step end (``ang`` is (n / decimation, n_acc, 3)).
    Returns True if the six columns are finite (else the outputs are of no use).
    """
    n = mean.shape[0]
    for i in range(n):
        for j in range(6):
            if not math.isfinite(vel[i, c + j]):
                return False
    if n > 0:
        for j in range(3):
            mean[0, j] = (vel[0, c + j] - v_prev[c + j]) / dt
    for i in range(1, n):
        for j in range(3):
            mean[i, j] = (vel[i, c + j] - vel[i - 1, c + j]) / dt
    for r in range(n // decimation):
        row = (r + 1) * decimation - 1
        for j in range(3):
            ang[r, acc, j] = vel[row, c + 3 + j]
    return True


def limit_py(x, acc, noise, limits):
    """Range clip and ADC of ``x[:, acc, :]`` (m/s^2) in place; return the values clipped.

    ``limits`` = ``[has_range, range, -range, has_adc, lsb, lowest code, highest code]``
    (flags 0 or 1; m/s^2; codes as floats, the highest >= 1): with a range, a value beyond it
    is clipped and counted; with an ADC, ``noise`` (k, 3) m/s^2 (no rows: none) is added,
    the value divided by the LSB and rounded half to even to a code, a code beyond the ends
    clipped and counted, and the code times the LSB is the sample. A NaN stays NaN and is
    not counted, as with NumPy's ``minimum`` and ``maximum``.
    """
    has_range = limits[0] != 0.0
    r, minus_r = limits[1], limits[2]
    has_adc = limits[3] != 0.0
    lsb, lo, hi = limits[4], limits[5], limits[6]
    add_noise = noise.shape[0] > 0
    count = 0
    for i in range(x.shape[0]):
        for j in range(3):
            v = x[i, acc, j]
            over = False
            if has_range:
                over = abs(v) > r
                if v > r:          # np.minimum(v, r): r > 0, so no tie of signed zeros
                    v = r
                if v < minus_r:
                    v = minus_r
            if has_adc:
                if add_noise:
                    v = v + noise[i, j]
                code = np.rint(v / lsb)
                if code < lo or code > hi:
                    over = True
                if code > hi:      # hi >= 1 and lo <= -1: no tie of signed zeros
                    code = hi
                if code < lo:
                    code = lo
                v = code * lsb
            x[i, acc, j] = v
            if over:
                count += 1
    return count


def channel_chunk_py(a, m, pre_sos, zi_pre, noise, bias, gm_sos, gm_zi, gm_w, rw_sos, rw_zi,
                     rw_w, lp_sos, zi_lp, x, y, s, b, decimation, white, samples, truth, acc,
                     limits, adc_noise, do_limit):
    """One accelerometer's chain over a chunk of ``n = k decimation`` integrator steps.

    ``a`` (n, 3) is the model-frame mean acceleration (m/s^2), ``m`` (n, 3) the same through
    the mounting matrix (``a`` itself without one). Sensor frame, step rate: ``pre_sos``
    (resonance and high-pass sections, state ``zi_pre``) from ``m`` into ``s``, then
    ``+ noise`` (n, 3), ``+ bias`` (3,), ``+`` the Gauss-Markov and random-walk biases
    (``gm_w``/``rw_w`` (n, 3) drives through ``gm_sos``/``rw_sos``, via ``b``). Then the
    anti-alias low-pass ``lp_sos`` (state ``zi_lp``) of ``x = [a | s]`` into ``y`` (n, 6),
    or, when ``zi_lp`` has 3 columns (the ideal channel: no stage before it), of ``a`` into
    ``y`` (n, 3). At every ``decimation``-th step: ``truth[:, acc, :]`` = the model columns,
    ``samples[:, acc, :]`` = the sensor columns ``+ white`` (k, 3). With ``do_limit``,
    :func:`limit` of ``samples`` with ``limits`` and ``adc_noise``; returns its count (0
    without). A stage that is off has no rows (``pre_sos``, ``noise``, ``bias``, ``gm_sos``,
    ``rw_sos``, ``white``, ``adc_noise``); every state array is updated in place.
    """
    n = a.shape[0]
    sensor = 0
    if zi_lp.shape[2] == 3:
        sosfilt_sections(lp_sos, a, zi_lp, y)
    else:
        sensor = 3
        if pre_sos.shape[0] > 0:
            sosfilt_sections(pre_sos, m, zi_pre, s)
        else:
            for i in range(n):
                for j in range(3):
                    s[i, j] = m[i, j]
        if noise.shape[0] > 0:
            for i in range(n):
                for j in range(3):
                    s[i, j] = s[i, j] + noise[i, j]
        if bias.shape[0] > 0:
            for i in range(n):
                for j in range(3):
                    s[i, j] = s[i, j] + bias[j]
        if gm_sos.shape[0] > 0:
            sosfilt_sections(gm_sos, gm_w, gm_zi, b)
            for i in range(n):
                for j in range(3):
                    s[i, j] = s[i, j] + b[i, j]
        if rw_sos.shape[0] > 0:
            sosfilt_sections(rw_sos, rw_w, rw_zi, b)
            for i in range(n):
                for j in range(3):
                    s[i, j] = s[i, j] + b[i, j]
        for i in range(n):
            for j in range(3):
                x[i, j] = a[i, j]
                x[i, 3 + j] = s[i, j]
        sosfilt_sections(lp_sos, x, zi_lp, y)
    add_white = white.shape[0] > 0
    for r in range(n // decimation):
        row = (r + 1) * decimation - 1
        for j in range(3):
            truth[r, acc, j] = y[row, j]
            v = y[row, sensor + j]
            if add_white:
                v = v + white[r, j]
            samples[r, acc, j] = v
    if do_limit:
        return limit(samples, acc, adc_noise, limits)
    return 0


def decimator_gather_py(history, a, b, lo0, factor, buf, windows):
    """The decimator's windows of a chunk, and its history moved on past the chunk.

    The signal is ``history`` (n_channels, h) followed by the chunk, whose channel
    ``w i + j`` (``w`` = the widths of ``a`` and ``b`` together) is ``a[:, i, j]`` for
    ``j`` below ``a``'s width, else ``b[:, i, j - width]`` (``a``, ``b`` (k, n_groups, width)).
    It is laid out channel-major in ``buf`` (n_channels, h + k); then ``windows[o, ch, :]``
    (``windows`` (n_out, n_channels, taps)) = the signal of channel ``ch`` from position
    ``lo0 + factor o`` on, and ``history`` becomes the signal's last ``h`` positions.
    """
    hist = history.shape[1]
    k = a.shape[0]
    wa = a.shape[2]
    w = wa + b.shape[2]
    n_out, n_ch, n = windows.shape
    for ch in range(n_ch):
        i = ch // w
        j = ch - w * i
        for q in range(hist):
            buf[ch, q] = history[ch, q]
        if j < wa:
            for p in range(k):
                buf[ch, hist + p] = a[p, i, j]
        else:
            for p in range(k):
                buf[ch, hist + p] = b[p, i, j - wa]
    for o in range(n_out):
        start = lo0 + factor * o
        for ch in range(n_ch):
            for t in range(n):
                windows[o, ch, t] = buf[ch, start + t]
    for ch in range(n_ch):
        for q in range(hist):
            history[ch, q] = buf[ch, k + q]


def split_decimated_py(r, lin, ang, limits, clipped):
    """The decimator's outputs into the Imu arrays, the linear ones through :func:`limit`.

    ``r`` (6 n_acc, j): channel ``6 a + c`` goes to ``lin[:, a, c]`` (``c`` < 3) and
    ``ang[:, a, c - 3]`` (each (j, n_acc, 3)); then each accelerometer's ``lin[:, a, :]``
    through :func:`limit` with its row of ``limits`` (n_acc, 7) and no noise, its count into
    ``clipped[a]``.
    """
    for o in range(lin.shape[0]):
        for a in range(lin.shape[1]):
            for c in range(3):
                lin[o, a, c] = r[6 * a + c, o]
                ang[o, a, c] = r[6 * a + 3 + c, o]
    no_noise = r[:0, :3]   # (0, 3): a stage that is off
    for a in range(lin.shape[1]):
        clipped[a] = limit(lin, a, no_noise, limits[a])


sosfilt_sections = kernel()(sosfilt_sections_py)
step_inputs = kernel()(step_inputs_py)
limit = kernel()(limit_py)
channel_chunk = kernel()(channel_chunk_py)
decimator_gather = kernel()(decimator_gather_py)
split_decimated = kernel()(split_decimated_py)
