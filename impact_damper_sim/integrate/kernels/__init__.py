"""All Numba kernels of the project.

Conventions: float64/complex128 arrays only, no Python objects, state arrays updated in
place, times in s. Each kernel ``name`` is compiled by :func:`kernel` (``numba.njit``, cached,
without reference counting) from a
plain Python/NumPy function ``name_py`` kept beside it: that twin is what the tests compare
the compiled kernel against (``test/test_kernels*.py``), so the JIT never hides an untested
path. Compiled kernels are cached in ``NUMBA_CACHE_DIR``, a per-user directory unless set
(:mod:`impact_damper_sim._cache_dir`).

Modules: :mod:`.flow` (evaluating and bounding the exact modal flow), :mod:`.poly`
(polynomials: safe steps, Bernstein bounds, certified roots), :mod:`.scan` (the safe-step event
scan), :mod:`.ledger` (energy ledger quadrature), :mod:`.exact` (the exact propagator's event
loop), :mod:`.newmark` and :mod:`.filters`.

Compile time (an empty cache compiles the kernels a run calls, once): a kernel is compiled
for the first call that needs it, once per argument types (:class:`Kernel`), and Numba links
each callee's code into its caller and optimizes it there again, so the cost grows with the
depth of the calls (``advance`` holds them all). Small helpers of the hot loops are inlined
by LLVM (``forceinline=True``), not by Numba: ``inline='always'`` copies a helper's Numba IR
into every call site and types and lowers each copy (hpotp's node start: 58 s of compile
CPU that way, 46 s this way, the same speed after). What a run does not use is not compiled:
:func:`.exact.advance` leaves out the energy ledger, or the ledger form a model does not
need, by the types of its arguments.

Numba keys a cached function on its own source file only, not on the files of the functions
it calls; the kernels here call across modules, so a stale cache could pair new code with an
old callee. :func:`guard_cache` clears this package's cache whenever any of its sources
changes (on import, before anything is compiled or loaded).
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path

from numba import njit, types
from numba.core.registry import CPUDispatcher

_STAMP = 'impact_damper_sim_kernels.fingerprint'

#: How every kernel is compiled. ``_nrt=False`` turns off Numba's reference counting (NRT):
#: the kernels allocate nothing (work arrays come from the caller), so counting references is
#: pure cost, and an opaque call at every array argument, view and variable death also keeps
#: LLVM from optimizing across them (hpotp 6 s, ledger off: 21-22 -> 26 x real time, side by
#: side in docs/impact-cost.md). A kernel that allocates fails to compile without it, so the
#: two that do (a test reference, and Newmark's step loop, once per call) say ``_nrt=True``.
#: ``no_cfunc_wrapper``: the C-callable wrapper Numba adds for first-class function use is
#: never called here, and every caller's module carried a copy (8 % of the code compiled).
KERNEL_OPTIONS = {'cache': True, '_nrt': False, 'no_cfunc_wrapper': True}


class Kernel(CPUDispatcher):
    """Numba's CPU dispatcher, typing calls from other kernels without literal values.

    Inside a kernel a constant argument (``point_eval(..., 2, ...)``), or a variable that
    still holds its first constant while Numba infers types (``n_cand = 0`` before
    ``n_cand += 1``), has a literal type such as ``Literal[int](0)``, and Numba compiled a
    callee once for it and once for ``int64``: hpotp compiled 8 of its 33 kernels two or
    three times (``point_eval``, ``scan_multi``, ``ledger_modal``, ...; a tenth of its cold
    start). The kernels never branch on a literal's value, so a call is typed with the
    plain types.
    """

    def get_call_template(self, args, kws):
        return super().get_call_template(tuple(types.unliteral(a) for a in args),
                                         {k: types.unliteral(v) for k, v in kws.items()})


def kernel(**options):
    """The decorator of a kernel: ``numba.njit`` with :data:`KERNEL_OPTIONS` and ``options``
    (such as ``forceinline=True``), dispatched by :class:`Kernel`."""
    def compile_lazily(func):
        dispatcher = njit(**{**KERNEL_OPTIONS, **options})(func)
        if type(dispatcher) is CPUDispatcher:   # not the plain function of NUMBA_DISABLE_JIT
            dispatcher.__class__ = Kernel
        return dispatcher
    return compile_lazily


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
