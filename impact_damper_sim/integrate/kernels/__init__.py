"""All Numba kernels of the project.

Conventions: float64/complex128 arrays only, no Python objects, state arrays updated in
place, times in s. Each kernel ``name`` is compiled by :func:`kernel` (``numba.njit``, cached,
without reference counting) from a
plain Python/NumPy function ``name_py`` kept beside it: that twin is what the tests compare
the compiled kernel against (``test/test_kernels*.py``), so the JIT never hides an untested
path. Compiled kernels are cached in ``NUMBA_CACHE_DIR``, a per-user directory unless set
(:mod:`impact_damper_sim._cache_dir`).

Modules: :mod:`.flow_eval` (evaluating and bounding the exact modal flow), :mod:`.poly`
(polynomials: safe steps, Bernstein bounds, certified roots), :mod:`.scan` (the safe-step event
scan), :mod:`.search` (the event search and the quiet-window certificate), :mod:`.contact`
(impacts, sticks, releases and configuration switches), :mod:`.codes` (status codes, event
kinds, sticking rules, work counters), :mod:`.ledger` (energy ledger quadrature: its forms)
with :mod:`.quadrature` (the series, integrals and factors they share), :mod:`.event_loop` (the
exact propagator's event loop, and the entry point of :mod:`impact_damper_sim.integrate.exact`),
:mod:`.prefetch` (what a cold start compiles in helper processes first), :mod:`.newmark_step`
(the Newmark step), :mod:`.filters` (the streaming low-pass), :mod:`.divergence_check` (each
chunk's divergence check, one pass over its samples), :mod:`.channel_chunk` (the live
accelerometer chain of a chunk: its inputs, the channel's stages, range and ADC, the DAQ
decimator's gather) and :mod:`.impact_rows` (the rows of a chunk's impact batch).

Compile time (an empty cache compiles the kernels a run calls, once): a kernel is compiled
for the first call that needs it, once per argument types (:class:`Kernel`). Numba links a
callee's LLVM code into each caller and optimizes it there again, so the cost grew with the
depth of the calls (``advance`` re-optimized the whole event search); here a kernel calls
another through an exported symbol (:func:`_bind`), so each kernel's code is optimized once,
and kernels call a twin compiled without Numba's CPython wrapper, which only Python calls
need (:meth:`Kernel.internal`). Small helpers of the hot loops are linked and inlined by
LLVM (``forceinline=True``), not by Numba: ``inline='always'`` copies a helper's Numba IR into
every call site and types and lowers each copy (12 s more of hpotp's node start). hpotp's
node start, compile CPU in one process: 53 s with Numba's linking, 44 s by symbol, 37 s
without the wrappers, the same speed after (events and outputs bit for bit;
docs/impact-cost.md). A kernel with a declared return type (``kernel(returns=...)``: the
event search, its fallback scan and the ledger's two main forms) is compiled by a helper
process when a caller is typed on a cold start (:func:`_farm`), so a cold start uses the
machine's cores (``IMPACT_DAMPER_SIM_COMPILE_HELPERS=0``: none). What a run does not use is
not compiled: :func:`.event_loop.advance` leaves out the energy ledger, or the ledger form a model
does not need, by the types of its arguments.

Numba keys a cached function on its own source file only, not on the files of the functions
it calls; the kernels here call across modules, so a stale cache could pair new code with an
old callee. :func:`guard_cache` clears this package's cache whenever any of its sources
changes (on import, before anything is compiled or loaded).
"""
from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import importlib
import inspect
import os
import pickle
import subprocess
import sys
import types as pytypes
from pathlib import Path

try:
    import fcntl
except ImportError:   # not POSIX: processes may compile the same kernel side by side
    fcntl = None

from llvmlite import binding as llvm_binding
from numba import njit, types
from numba.core import cgutils, sigutils
from numba.core.imputils import fix_returning_optional, impl_ret_new_ref
from numba.core.registry import CPUDispatcher
from numba.core.typing.templates import make_concrete_template

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

    A kernel with a declared return type (``returns``) that is neither compiled nor cached
    when a caller is typed is compiled by a helper process (:func:`_farm`) while the caller
    goes on; the caller waits for it only when its own machine code is finalized.

    The dispatcher a module holds compiles what Python calls, with Numba's CPython wrapper
    (the unboxing of every argument). Calls from other kernels go to its twin without that
    wrapper (:meth:`internal`; a tenth of the compile time was wrappers never called).
    """

    #: Called by other kernels through its symbol (:func:`_bind`) instead of linked into them.
    by_symbol = False
    #: The declared return type (a Numba type), or ``None``.
    returns = None
    #: The twin that kernels call (the public dispatcher: ``None`` until first needed), or
    #: the public dispatcher itself (the twin)
    _twin = None
    _public = True

    def internal(self):
        """The twin of this kernel that other kernels call: same code and options, without
        the CPython wrapper, cached apart (its own name, ``NAME_py.internal``)."""
        if not self._public:
            return self
        if self._twin is None:
            py_func = self.py_func
            func = pytypes.FunctionType(py_func.__code__, py_func.__globals__,
                                        py_func.__name__, py_func.__defaults__,
                                        py_func.__closure__)
            func.__qualname__ = f'{py_func.__qualname__}.internal'
            func.__module__ = py_func.__module__
            func.__doc__ = py_func.__doc__
            cached = type(self._cache).__name__ != 'NullCache'
            options = {k: v for k, v in self.targetoptions.items() if k != 'nopython'}
            twin = njit(**options, no_cpython_wrapper=True, cache=cached)(func)
            twin.__class__ = Kernel
            twin.by_symbol = self.by_symbol
            twin.returns = self.returns
            twin._public = False
            twin._twin = self
            self._twin = twin
        return self._twin

    def get_call_template(self, args, kws):
        if self._public:
            return self.internal().get_call_template(args, kws)
        args = tuple(types.unliteral(a) for a in args)
        kws = {k: types.unliteral(v) for k, v in kws.items()}
        if self.returns is not None and not kws and args not in self.overloads and \
                _farm(self, args):
            pysig, args = self._compiler.fold_argument_types(args, kws)
            template = make_concrete_template(f'CallTemplate({self.py_func.__name__})',
                                              key=self.py_func.__name__,
                                              signatures=[self.returns(*args)])
            return template, pysig, args, {}
        return super().get_call_template(args, kws)

    def get_overload(self, args):
        if self._public:
            return self.internal().get_overload(args)
        args = tuple(args)
        if args not in self.overloads and (self, args) in _FARMED:
            return _FARMED[self, args]   # the key of its call by symbol (_farm)
        return super().get_overload(args)

    def compile(self, sig):
        """Load ``sig`` from the cache, or compile it one process at a time.

        The helper processes and this one share callees (``point_eval``, ``propagate``, ...
        are called from both the event search and ``advance``); without a lock each process
        compiled its own copy at about the same moment. With :func:`_compile_lock` the second
        one waits and then loads the first one's result from the cache.
        """
        args, _ = sigutils.normalize_signature(sig)
        if tuple(args) in self.overloads or _in_cache(self, sig):
            # a load needs no lock: the cache's files are replaced whole. Ten nodes starting
            # at once queued on these locks for every load (0 % CPU for seconds; issue 39)
            return super().compile(sig)
        with _compile_lock(self, args):
            return super().compile(sig)

    def add_overload(self, cres):
        super().add_overload(cres)
        if self.by_symbol and not cres.objectmode:
            _bind(self, cres)


@dataclasses.dataclass(frozen=True)
class _Load:
    """Load (or compile) kernel ``module.name`` for argument types ``args`` (numba types).

    Kept in the cache entry of every kernel that calls it by symbol: Numba runs it before it
    loads that caller's machine code, whose reference to the symbol must then resolve.
    """
    module: str
    name: str
    args: tuple

    def __call__(self):
        getattr(importlib.import_module(self.module), self.name).internal().compile(self.args)


@contextlib.contextmanager
def _compile_lock(dispatcher, args):
    """Hold an exclusive lock (``flock``) on a file named after the kernel and its argument
    types in the cache directory while it is compiled or loaded; no lock without a cache.

    Kernels call each other without cycles, so the locks are taken in call order and cannot
    deadlock; the lock goes with its file descriptor when a process dies.
    """
    if fcntl is None or _CACHE_DIR is None or type(dispatcher._cache).__name__ == 'NullCache':
        yield
        return
    func = dispatcher.py_func
    key = f'{func.__module__}.{func.__qualname__}({", ".join(str(a) for a in args)})'
    path = _CACHE_DIR / f'{hashlib.sha256(key.encode()).hexdigest()[:24]}.lock'
    try:
        fd = os.open(path, os.O_CREAT | os.O_RDWR, 0o644)
    except OSError:
        yield   # a cache directory we may read but not write: compile unlocked
        return
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)


def _symbol(load):
    """The process-wide symbol of a kernel's compiled function (stable across processes)."""
    key = f'{load.module}.{load.name}({", ".join(str(a) for a in load.args)})'
    return f'impact_damper_sim.{load.name}.{hashlib.sha256(key.encode()).hexdigest()[:20]}'


def _load_of(dispatcher, args):
    """The :class:`_Load` of a kernel's internal twin, or ``None`` when its module does not
    hold its public dispatcher under its name (a test's own dispatcher: callers link it as
    Numba does)."""
    func = dispatcher.py_func
    name = func.__name__[:-3] if func.__name__.endswith('_py') else func.__name__
    module = sys.modules.get(func.__module__)
    if dispatcher._public or getattr(module, name, None) is not dispatcher._twin:
        return None
    return _Load(func.__module__, name, tuple(args))


def _call_by_symbol(load, argtypes, restype, argnames, wait):
    """Numba's lowering of a call to a kernel, made a call to its symbol (:func:`_symbol`).

    The caller's cache entry gets ``load``; with ``wait`` (compiled by a helper process) its
    machine code is finalized only after the kernel is loaded and its symbol defined.
    """
    symbol = _symbol(load)

    def call(context, builder, sig, args):
        fnty = context.call_conv.get_function_type(restype, argtypes)
        fn = cgutils.get_or_insert_function(builder.module, fnty, symbol)
        context.apply_target_attributes(fn, argtypes, restype)
        context.call_conv.decorate_function(fn, argnames, argtypes)
        library = context.active_code_library
        library._reload_init.add(load)
        if wait:
            _load_before_finalize(library, load)
        status, retval = context.call_conv.call_function(builder, fn, restype, argtypes, args)
        with cgutils.if_unlikely(builder, status.is_error):
            context.call_conv.return_status_propagate(builder, status)
        retval = fix_returning_optional(context, builder, sig, status, retval)
        return impl_ret_new_ref(context, builder, restype, retval)

    call.signature = argtypes
    call.libs = ()
    return call


def _bind(dispatcher, cres):
    """Export a compiled kernel under :func:`_symbol` and make callers call it there.

    Numba links a callee's LLVM module into every caller and optimizes it there again, so
    the cost of a kernel grew with everything below it (``advance`` re-optimized the whole
    event search). Here a call is a plain call to an external symbol that the JIT resolves
    to the callee's machine code, compiled once; LLVM cannot inline across it, so the small
    hot helpers stay ``forceinline`` (linked) kernels.
    """
    load = _load_of(dispatcher, cres.signature.args)
    if load is None:
        return
    fndesc = cres.fndesc
    if dispatcher.returns is not None and fndesc.restype != dispatcher.returns:
        raise TypeError(f'kernel {load.name} returns {fndesc.restype}, declared '
                        f'{dispatcher.returns}')
    llvm_binding.add_symbol(_symbol(load),
                            cres.library.get_pointer_to_function(fndesc.llvm_func_name))
    overloads = dispatcher.targetctx._defns[cres.entry_point]
    call = _call_by_symbol(load, fndesc.argtypes, fndesc.restype, fndesc.args, wait=False)
    overloads.versions = [(call.signature, call)]   # replaces Numba's linking call
    overloads._cache.clear()


#: Kernels being compiled by helper processes: ``(dispatcher, args) -> _Load``.
_FARMED = {}
#: The helper process of each :class:`_Load`.
_HELPERS = {}
#: Environment variable: how many helper processes this process may still start.
HELPERS_ENV = 'IMPACT_DAMPER_SIM_COMPILE_HELPERS'
_HELPER_CODE = """
import pickle, sys
sys.path[:] = pickle.load(sys.stdin.buffer)
pickle.load(sys.stdin.buffer)()
"""


def _helper_budget():
    """Helper processes this process may start: ``$IMPACT_DAMPER_SIM_COMPILE_HELPERS``, by
    default the number of cores (none on one core). A helper may start helpers of its own,
    within what its parent had left."""
    try:
        return int(os.environ[HELPERS_ENV])
    except (KeyError, ValueError):
        cores = os.cpu_count() or 1
        return cores if cores > 1 else 0


def _in_cache(dispatcher, args):
    """True when Numba's cache holds the kernel for ``args`` (it is loaded, not compiled);
    False when unsure (the caller then locks or farms)."""
    try:
        cache = dispatcher._cache
        key = cache._index_key(args, dispatcher.targetctx.codegen())
        return cache._cache_file._load_index().get(key) is not None
    except Exception:   # noqa: BLE001 - no cache, or a Numba without these internals
        return False


def _farm(dispatcher, args):
    """Have a helper process compile a kernel that a caller being typed needs.

    Numba compiles a callee when it types the call, so a cold start compiled the kernels one
    after another on one core. A kernel whose return type is declared can be typed without
    it: a helper process (a fresh interpreter, sharing the cache directory) compiles and
    caches it while this one goes on, and this one loads it before it finalizes the caller.
    Returns True when the kernel is (already) being compiled elsewhere.
    """
    if (dispatcher, args) in _FARMED:
        return True
    budget = _helper_budget() - len(_HELPERS)
    if budget <= 0 or _CACHE_DIR is None or not dispatcher._can_compile or \
            type(dispatcher._cache).__name__ == 'NullCache' or _in_cache(dispatcher, args):
        return False   # nothing to share the result through, or nothing to compile
    load = _load_of(dispatcher, args)
    if load is None:
        return False
    env = dict(os.environ, **{HELPERS_ENV: str(budget - 1)})
    try:
        helper = subprocess.Popen([sys.executable, '-c', _HELPER_CODE], stdin=subprocess.PIPE,
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                  env=env)
        with helper.stdin:
            pickle.dump(sys.path, helper.stdin)
            pickle.dump(load, helper.stdin)
    except (OSError, TypeError, ValueError, pickle.PicklingError):
        return False   # no interpreter to start (an embedded Python): compile here
    _HELPERS[load] = helper
    _FARMED[dispatcher, args] = load
    call = _call_by_symbol(load, args, dispatcher.returns,
                           list(inspect.signature(dispatcher.py_func).parameters), wait=True)
    dispatcher.targetctx._defns[load].append(call, call.signature)
    return True


def _load_before_finalize(library, load):
    """Make ``library`` (a caller's code) into machine code only after ``load`` is loaded: its
    helper process has finished (or failed: then this process compiles it).

    The caller's LLVM optimization needs no callee (a call by symbol is opaque to it), so it
    runs first, while the helper works; only the step that resolves the symbols waits
    (``_finalize_final_module``: the caller's machine code and its links). Waiting before the
    whole ``finalize`` left this process idle through the helper's compile and then optimized
    ``advance`` alone (a quarter of its compile time).
    """
    pending = library.__dict__.setdefault('_impact_damper_sim_loads', [])
    if not pending:
        make_machine_code = library._finalize_final_module

        def after_loads():
            for item in pending:
                helper = _HELPERS.get(item)
                if helper is not None:
                    helper.wait()
                item()
            make_machine_code()
        library._finalize_final_module = after_loads
    if load not in pending:
        pending.append(load)


def kernel(*, linked=False, returns=None, **options):
    """The decorator of a kernel: ``numba.njit`` with :data:`KERNEL_OPTIONS` and ``options``
    (such as ``forceinline=True``), dispatched by :class:`Kernel`.

    Other kernels call it by symbol (:func:`_bind`) unless it is ``forceinline`` or
    ``linked`` (its LLVM code then goes into every caller, where it can be inlined).
    ``returns`` (a Numba type) declares its return type: a caller is then typed without it,
    and a cold start compiles it in a helper process (:func:`_farm`).
    """
    def compile_lazily(func):
        dispatcher = njit(**{**KERNEL_OPTIONS, **options})(func)
        if type(dispatcher) is CPUDispatcher:   # not the plain function of NUMBA_DISABLE_JIT
            dispatcher.__class__ = Kernel
            dispatcher.by_symbol = not (linked or options.get('forceinline', False))
            dispatcher.returns = returns if dispatcher.by_symbol else None
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


#: The kernels' cache directory (``Path``), ``None`` when it cannot be written.
_CACHE_DIR = guard_cache()
