"""The kernels a run compiles in helper processes from its very start, with their argument types.

On a cold cache the event search (``search``, 26 kernels with its callees) was the longest job
and started only when the main process, typing ``advance``, reached its call: 2-3 s after the
warm-up began, and its fallback scan (``scan_multi``) 10 s later still. :func:`prefetch` has
helper processes compile both (:func:`~impact_damper_sim.integrate.kernels._farm`) as soon as a
run is certain (:func:`~impact_damper_sim.live.streams.live_scene`, an exact propagator being
built), while the scene is built and ``advance`` is typed; the caller later finds them farmed
and waits only to link them. A warm cache makes this a no-op (each entry is looked up first).

The argument types must be exactly those of the calls (``test/test_warm_up.py`` checks that
every live scene calls each entry with them): a stale entry would compile a signature nobody
calls. Types are written as Numba's signature strings: ``float64``, ``int64``, ``boolean``,
``complex128[::1]`` (C-contiguous 1-D), ``complex128[:, ::1]`` (2-D), ...
"""
from __future__ import annotations

import importlib

from numba import types

#: ``(module, kernel, argument types)`` of each kernel to compile at a run's start.
ENTRIES = (
    ('impact_damper_sim.integrate.kernels.search', 'search',
     'float64, float64, complex128[::1], complex128[::1], float64, complex128[:, ::1], '
     'complex128[::1], complex128[::1], complex128[:, ::1], complex128[:, ::1], '
     'float64[::1], complex128[:, ::1], float64[::1], float64[::1], complex128[:, :, ::1], '
     'float64[:, :, ::1], int64[::1], int64[::1], float64[:, ::1], float64[:, ::1], '
     'float64[::1], int64[::1], int64[::1], float64[:, ::1], int64, complex128[::1], '
     'complex128[::1], float64[:, ::1], complex128[:, ::1], float64[:, :, ::1], '
     'float64[:, ::1], float64[::1], float64[::1], float64[:, ::1], float64[::1], '
     'float64[::1], float64[:, ::1], float64[::1], float64[::1], int64[::1], int64[::1], '
     'float64[::1], float64[::1], int64[::1], float64[:, ::1], bool[::1], float64[::1], '
     'float64[:, ::1], float64[::1], float64[::1], float64[::1], float64[::1], int64[::1], '
     'float64[::1]'),
    ('impact_damper_sim.integrate.kernels.scan', 'scan_multi',
     'int64, int64[::1], int64[::1], float64, float64, complex128[::1], complex128[::1], '
     'complex128[:, ::1], complex128[::1], complex128[::1], complex128[:, ::1], '
     'complex128[:, ::1], float64[::1], complex128[:, ::1], float64[::1], float64[::1], '
     'complex128[:, :, ::1], int64[::1], float64[:, ::1], float64[:, ::1], float64[::1], '
     'float64[:, ::1], int64[::1], complex128[::1], complex128[::1], float64[:, ::1], '
     'complex128[:, ::1], float64[:, ::1], float64[:, ::1], float64[::1], float64[::1], '
     'float64[:, ::1], float64[::1], bool[::1], float64[::1], float64[::1]'),
)


def parse_types(spec):
    """Numba types (tuple) of a comma-separated list such as ``'float64, complex128[:, ::1]'``.

    Parameters
    ----------
    spec : str
        Scalars by Numba name; arrays as ``dtype[...]`` with the last axis ``::1``
        (C-contiguous), ``:`` for each other axis.

    Returns
    -------
    tuple of numba.types.Type
    """
    parsed, depth, token = [], 0, ''
    for char in spec + ',':
        if char == ',' and depth == 0:
            token = token.strip()
            name, _, dims = token.partition('[')
            dtype = types.boolean if name == 'bool' else getattr(types, name)
            if dims:
                axes = dims.rstrip(']').split(',')
                if axes[-1].strip() != '::1' or any(a.strip() != ':' for a in axes[:-1]):
                    raise ValueError(f'only C-contiguous arrays: {token!r}')
                dtype = types.Array(dtype, len(axes), 'C')
            parsed.append(dtype)
            token = ''
            continue
        depth += (char == '[') - (char == ']')
        token += char
    return tuple(parsed)


def prefetch(entries=ENTRIES):
    """Have helper processes compile ``entries`` now (none when cached or no helper may start).

    Parameters
    ----------
    entries : sequence of (str, str, str)
        Module, kernel name and argument types (:func:`parse_types`).

    Returns
    -------
    list of str
        The kernels sent to helper processes by this call.
    """
    from . import _FARMED, _farm
    started = []
    for module, name, spec in entries:
        dispatcher = getattr(importlib.import_module(module), name)
        if not hasattr(dispatcher, 'internal'):   # NUMBA_DISABLE_JIT: plain Python
            continue
        twin, args = dispatcher.internal(), parse_types(spec)
        if args in twin.overloads or (twin, args) in _FARMED:   # loaded here, or farmed
            continue
        if _farm(twin, args):
            started.append(name)
    return started
