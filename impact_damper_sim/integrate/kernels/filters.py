"""Numba kernel of the streaming low-pass (second-order sections, direct form II transposed).

Conventions as in :mod:`impact_damper_sim.integrate.kernels`: float64 arrays only, the filter
state updated in place. ``sosfilt_py`` is the plain NumPy twin of ``sosfilt``; both compute
what ``scipy.signal.sosfilt(sos, x, axis=0, zi=zi)`` computes (``test/test_filters.py``).
"""
from __future__ import annotations

from . import kernel


def sosfilt_py(sos, x, zi, y):
    """Filter ``x`` (k, n_channels) through ``sos`` (n_sections, 6) into ``y``.

    ``zi`` (n_sections, 2, n_channels) is the direct-form-II-transposed state, carried from
    the previous chunk and left ready for the next; ``y`` has the shape of ``x`` (same unit).
    """
    n_sections = sos.shape[0]
    for c in range(x.shape[1]):
        for k in range(x.shape[0]):
            v = x[k, c]
            for s in range(n_sections):
                b0, b1, b2 = sos[s, 0], sos[s, 1], sos[s, 2]
                a1, a2 = sos[s, 4], sos[s, 5]   # sos[s, 3] = a0 = 1
                out = b0 * v + zi[s, 0, c]
                zi[s, 0, c] = b1 * v - a1 * out + zi[s, 1, c]
                zi[s, 1, c] = b2 * v - a2 * out
                v = out
            y[k, c] = v


sosfilt = kernel()(sosfilt_py)
