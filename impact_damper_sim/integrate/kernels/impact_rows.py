"""Numba kernel of the live impact batch's rows (:mod:`impact_damper_sim.recording.node_messages`).

A chunk's impact batch (``impacts``, ``sensor_msgs/PointCloud2``) has one row per impact among
the chunk's events, in time order: t, impactor, jx jy jz, v_approach, v_separation, energy. A
live chunk holds a few dozen impacts (hpotp: ~35 per 10 ms, 70 in its run-up), and NumPy's
forty-odd calls per chunk (a mask, a sort, a scatter per impulse component, one per field)
cost several times the writing: 17 us a chunk warm against 3.5 us for this one call, 30
against 10 us the first time after a chunk is stepped (hpotp, one core). Conventions as in
:mod:`impact_damper_sim.integrate.kernels`, except that the event fields come as the integer
and float arrays they are; ``impact_rows_py`` is the plain twin (``test/test_impact_rows.py``
holds both to the NumPy statement of the rows, byte for byte).
"""
from __future__ import annotations

import numpy as np

from . import kernel


def impact_rows_py(t, kind, impactor, impulse, normal, v_n, v_n_after, loss, impact_kind,
                   start_ns, columns, order, rows, rows_u4):
    """Write the impact rows of a chunk's events; return how many (int).

    Parameters
    ----------
    t, kind, impactor, impulse, normal, v_n, v_n_after, loss : ndarray
        The events' fields (``EVENT_DTYPE``: s, kind, index, N s, ``(m, 2)`` unit normal,
        m/s, m/s, J); views of the structured array are fine.
    impact_kind : int
        ``kind`` of an impact (``events.IMPACT``).
    start_ns : int
        Start of the interval the batch covers (ns): each row's t is relative to it (s).
    columns : ndarray of int64, shape (2, n_impactors)
        Per normal component, each impactor's column of its impulse in a row (2, 3, 4: jx jy
        jz; 5, v_approach, written after it, where an impactor has no second component).
    order : ndarray of int64, shape (>= m,)
        Work array: the impacts' event indices, sorted by time.
    rows : ndarray of float64, shape (>= m, 8), zeros
        The rows, written in place (the first ``n``); the impactor goes in the low four
        bytes of the second slot through ``rows_u4``, the high four stay zero.
    rows_u4 : ndarray of uint32, shape (>= m, 16)
        ``rows`` viewed as little-endian uint32.
    """
    n = 0
    for i in range(t.shape[0]):
        if kind[i] == impact_kind:
            order[n] = i
            n += 1
    # by stamp (ns, rounded as the samples are), equal stamps in event order: a stable
    # insertion sort, as the events come nearly sorted
    for a in range(1, n):
        j = order[a]
        stamp = np.rint(t[j] * 1e9)
        b = a - 1
        while b >= 0 and np.rint(t[order[b]] * 1e9) > stamp:
            order[b + 1] = order[b]
            b -= 1
        order[b + 1] = j
    for r in range(n):
        i = order[r]
        t_ns = np.int64(np.rint(t[i] * 1e9))
        rows[r, 0] = float(t_ns - start_ns) * 1e-9
        which = impactor[i]
        rows_u4[r, 2] = which
        rows[r, columns[0, which]] = impulse[i] * normal[i, 0]
        rows[r, columns[1, which]] = impulse[i] * normal[i, 1]
        rows[r, 5] = abs(v_n[i])   # after the impulses: a second component lands here
        rows[r, 6] = abs(v_n_after[i])
        rows[r, 7] = loss[i]
    return n


impact_rows = kernel()(impact_rows_py)
