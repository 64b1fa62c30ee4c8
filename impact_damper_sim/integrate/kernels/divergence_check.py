"""Numba kernels of the divergence checks (:mod:`impact_damper_sim.integrate.divergence`).

The rule a clean chunk passes, in one pass over its arrays and one call: every sample finite
and every displacement within its bound. A chunk of a live run is small (hpotp: 100 x 12
values a field), so NumPy's ten calls per chunk (an ``abs`` and a ``max`` per array) cost
more than the reading; one compiled call does all of it. Conventions as in
:mod:`impact_damper_sim.integrate.kernels`; ``samples_clean_py`` and ``state_finite_py`` are
the plain twins (``test/test_divergence_check.py``).
"""
from __future__ import annotations

import math

from . import kernel


def samples_clean_py(disp, vel, acc, bound):
    """Return True if ``|disp| <= bound`` everywhere and ``vel`` and ``acc`` are finite.

    ``disp``, ``vel``, ``acc`` are 2-D float64 arrays (m, m/s, m/s^2), ``bound`` in m. A NaN
    fails the bound (the comparison is false) as an inf exceeds it.
    """
    for i in range(disp.shape[0]):
        for j in range(disp.shape[1]):
            if not abs(disp[i, j]) <= bound:
                return False
    for i in range(vel.shape[0]):
        for j in range(vel.shape[1]):
            if not math.isfinite(vel[i, j]):
                return False
    for i in range(acc.shape[0]):
        for j in range(acc.shape[1]):
            if not math.isfinite(acc[i, j]):
                return False
    return True


def state_finite_py(q, qd):
    """Return True if the 1-D float64 arrays ``q`` and ``qd`` are finite."""
    for i in range(q.shape[0]):
        if not math.isfinite(q[i]):
            return False
    for i in range(qd.shape[0]):
        if not math.isfinite(qd[i]):
            return False
    return True


samples_clean = kernel()(samples_clean_py)
state_finite = kernel()(state_finite_py)
