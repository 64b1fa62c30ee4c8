"""All Numba kernels of the project.

Conventions: float64/complex128 arrays only, no Python objects, state arrays updated in
place, times in s. Each kernel ``name`` is compiled by :func:`kernel` (``numba.njit``, cached,
without reference counting) from a
plain Python/NumPy function ``name_py`` kept beside it: that twin is what the tests compare
the compiled kernel against (``test/test_kernels*.py``), so the JIT never hides an untested
path. Set ``NUMBA_CACHE_DIR`` to choose where compiled kernels are cached.

Modules: :mod:`.flow` (evaluating and bounding the exact modal flow), :mod:`.poly`
(polynomials: safe steps, Bernstein bounds, certified roots), :mod:`.scan` (the safe-step event
scan), :mod:`.ledger` (energy ledger quadrature), :mod:`.exact` (the exact propagator's event
loop), :mod:`.newmark` and :mod:`.filters`.

Numba keys a cached function on its own source file only, not on the files of the functions
it calls; the kernels here call across modules, so a stale cache could pair new code with an
old callee. :func:`guard_cache` clears this package's cache whenever any of its sources
changes (on import, before anything is compiled or loaded).
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path

from numba import njit

_STAMP = 'impact_damper_sim_kernels.fingerprint'

#: How every kernel is compiled. ``_nrt=False`` turns off Numba's reference counting (NRT):
#: the kernels allocate nothing (work arrays come from the caller), so counting references is
#: pure cost, and an opaque call at every array argument, view and variable death also keeps
#: LLVM from optimizing across them (hpotp 6 s, ledger off: 21-22 -> 26 x real time, side by
#: side in docs/impact-cost.md). A kernel that allocates fails to compile without it, so the
#: two that do (a test reference, and Newmark's step loop, once per call) say ``_nrt=True``.
KERNEL_OPTIONS = {'cache': True, '_nrt': False}


def kernel(**options):
    """The decorator of a kernel: ``numba.njit`` with :data:`KERNEL_OPTIONS` and ``options``
    (such as ``inline='always'``)."""
    return njit(**{**KERNEL_OPTIONS, **options})


def _cache_probe():  # pragma: no cover - never called, only located
    return 0


def sources_fingerprint():
    """SHA-256 (hex) of every kernel module's source, in name order."""
    digest = hashlib.sha256()
    for path in sorted(Path(__file__).parent.glob('*.py')):
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def guard_cache():
    """Delete this package's cached kernels when its sources changed since they were cached.

    Returns the cache directory (``Path``), or ``None`` when it cannot be written or there is
    no cache (``NUMBA_DISABLE_JIT=1`` runs the plain-Python twins).
    """
    cache = getattr(njit(cache=True)(_cache_probe), '_cache', None)
    if cache is None:
        return None
    cache_dir = Path(cache._cache_path)
    stamp = cache_dir / _STAMP
    fingerprint = sources_fingerprint()
    try:
        if stamp.read_text() == fingerprint:
            return cache_dir
    except OSError:
        pass
    try:
        cache_dir.mkdir(parents=True, exist_ok=True)
        modules = {p.stem for p in Path(__file__).parent.glob('*.py')}
        for entry in cache_dir.iterdir():
            if entry.suffix in ('.nbi', '.nbc') and entry.name.split('.')[0] in modules:
                entry.unlink(missing_ok=True)
        tmp = stamp.with_suffix(f'.{os.getpid()}.tmp')
        tmp.write_text(fingerprint)
        tmp.replace(stamp)
    except OSError:
        return None
    return cache_dir


guard_cache()
