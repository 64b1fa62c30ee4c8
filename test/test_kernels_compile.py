"""How kernels call each other and compile (``impact_damper_sim.integrate.kernels``).

A kernel calls another through its symbol, not with the callee's LLVM code linked in; a cold
start compiles a kernel with a declared return type in a helper process; a warm start loads a
caller and, before it, the kernels it calls. The last two run fresh interpreters on a small
module of kernels written to ``tmp_path``, with an empty ``NUMBA_CACHE_DIR``.
"""
import os
import re
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

from impact_damper_sim.integrate import kernels
from impact_damper_sim.integrate.kernels import flow_eval

pytestmark = pytest.mark.skipif(os.environ.get('NUMBA_DISABLE_JIT', '0') != '0',
                                reason='the kernels run as Python: nothing is compiled')

MODULE = '''
import numpy as np
from numba import types
from impact_damper_sim.integrate.kernels import kernel


def leaf_py(x, out):
    """Sum of squares into out[0] (a declared return type: compiled by a helper when cold)."""
    acc = 0.0
    for v in x:
        acc += v * v
    out[0] = acc
    return acc


leaf = kernel(returns=types.float64)(leaf_py)


def middle_py(x, out):
    return 2.0 * leaf(x, out)


middle = kernel()(middle_py)


def top_py(x, out):
    return middle(x, out) + leaf(x, out)


top = kernel()(top_py)


def wrong_py(x):
    return x.size


wrong = kernel(returns=types.float64)(wrong_py)


def calls_wrong_py(x):
    return wrong(x)


calls_wrong = kernel()(calls_wrong_py)
'''

RUN = '''
import sys
import numpy as np
import kernel_module as m
from impact_damper_sim.integrate import kernels
x = np.arange(4.0)
out = np.zeros(1)
value = m.top(x, out)
misses = sum(m.top.stats.cache_misses.values()) + sum(
    sum(k.internal().stats.cache_misses.values()) for k in (m.middle, m.leaf))
print(value, out[0], len(kernels._HELPERS), misses)
'''


def run(tmp_path, code, helpers):
    """``code`` in a fresh interpreter with the module importable and the test's cache."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / 'cache'),
               PYTHONPATH=os.pathsep.join([str(tmp_path)] + sys.path),
               **{kernels.HELPERS_ENV: str(helpers)})
    return subprocess.run([sys.executable, '-c', code], env=env, capture_output=True,
                          text=True, cwd=tmp_path)


def test_a_kernel_calls_another_by_symbol_without_its_code():
    rng = np.random.default_rng(1)
    n2, nf, nh = 4, 2, 1
    lam = -rng.uniform(1, 5, n2) + 1j * rng.uniform(1, 50, n2)
    c = lambda *shape: rng.normal(size=shape) + 1j * rng.normal(size=shape)  # noqa: E731
    args = (c(n2), lam, c(n2, nf), c(n2), c(n2), c(nh, n2), c(nh, n2), np.array([3.0]),
            c(nh, nf), rng.normal(size=nf), rng.normal(size=nf), 0.1,
            c(2, n2), 2, np.empty(n2, complex), np.empty(n2, complex), np.empty((3, nf)),
            np.empty((3, n2), complex), np.empty((3, 2)))
    expected = [a.copy() if isinstance(a, np.ndarray) else a for a in args]
    flow_eval.housing_velocity_py(*expected)
    caller = kernels.kernel(cache=False)(flow_eval.housing_velocity_py)   # inspectable: not cached
    caller(*args)
    np.testing.assert_array_equal(args[-1][:2], expected[-1][:2])
    ir = next(iter(caller.inspect_llvm().values()))
    callee = flow_eval.point_eval.internal()
    symbol = kernels._symbol(kernels._load_of(callee, callee.signatures[0]))
    uses = [line for line in ir.splitlines() if re.search(f'@"?{re.escape(symbol)}"?\\(', line)]
    assert any(line.startswith('declare ') for line in uses)
    assert not any(line.startswith('define ') for line in uses)
    # point_eval's own code (its mangled name) is not in its caller's module
    assert callee.overloads[callee.signatures[0]].fndesc.mangled_name not in ir


@pytest.mark.parametrize('helpers', [1, 0])
def test_cold_compile_in_a_helper_then_a_warm_load(tmp_path, helpers):
    (tmp_path / 'kernel_module.py').write_text(MODULE)
    cold = run(tmp_path, RUN, helpers)
    assert cold.returncode == 0, cold.stderr
    value, out, started, misses = cold.stdout.split()
    assert float(value) == 3 * 14.0 and float(out) == 14.0
    assert int(started) == helpers   # leaf was compiled by a helper when one was allowed
    # compiled here: top, middle, and leaf without a helper (a helper's result is loaded)
    assert int(misses) == 3 - helpers
    warm = run(tmp_path, RUN, helpers)
    assert warm.returncode == 0, warm.stderr
    value, out, started, misses = warm.stdout.split()
    assert float(value) == 3 * 14.0 and int(started) == 0 and int(misses) == 0


def test_a_wrong_declared_return_type_is_an_error(tmp_path):
    (tmp_path / 'kernel_module.py').write_text(MODULE)
    code = textwrap.dedent('''
        import numpy as np
        import kernel_module as m
        try:
            m.calls_wrong(np.zeros(3))
        except TypeError as exc:
            print('TypeError', exc)
    ''')
    result = run(tmp_path, code, 0)
    assert 'TypeError kernel wrong returns int64, declared float64' in result.stdout, \
        result.stdout + result.stderr


HOLD = '''
import sys
import numpy as np
from numba.core.dispatcher import Dispatcher
import kernel_module as m
from impact_damper_sim.integrate import kernels
leaf = m.leaf.internal()
args = (kernels.types.float64[::1], kernels.types.float64[::1])
with kernels._compile_lock(leaf, args):
    print(kernels._CACHE_DIR, flush=True)
    sys.stdin.readline()                  # go: another process now waits for this lock
    Dispatcher.compile(leaf, args)        # compiled and cached under the lock
'''


def _waiters_on(path):
    """Processes blocked on a flock of ``path`` (Linux /proc/locks: a '->' line)."""
    inode = os.stat(path).st_ino
    with open('/proc/locks') as locks:
        return [line for line in locks if '->' in line and f':{inode} ' in line]


@pytest.mark.skipif(not os.path.exists('/proc/locks') or kernels.fcntl is None,
                    reason='needs flock and /proc/locks (Linux)')
def test_a_kernel_another_process_is_compiling_is_waited_for_and_loaded(tmp_path):
    """Issue 24: the event search's helper and the main process call the same kernels; the
    second to reach one waits on its lock and loads the first one's result."""
    (tmp_path / 'kernel_module.py').write_text(MODULE)
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / 'cache'),
               PYTHONPATH=os.pathsep.join([str(tmp_path)] + sys.path),
               **{kernels.HELPERS_ENV: '0'})
    holder = subprocess.Popen([sys.executable, '-c', HOLD], env=env, cwd=tmp_path, text=True,
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE)
    cache_dir = holder.stdout.readline().strip()
    lock = next(p for p in os.listdir(cache_dir) if p.endswith('.lock'))
    waiter = subprocess.Popen([sys.executable, '-c', RUN], env=env, cwd=tmp_path, text=True,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        deadline = 120
        while not _waiters_on(os.path.join(cache_dir, lock)) and deadline > 0:
            assert waiter.poll() is None, waiter.communicate()
            deadline -= 0.05
            time.sleep(0.05)
        assert deadline > 0, 'the second process never waited for the lock'
        holder.stdin.write('go\n')
        holder.stdin.close()
        assert holder.wait(120) == 0
        out, err = waiter.communicate(timeout=300)
    finally:
        for proc in (holder, waiter):
            if proc.poll() is None:
                proc.kill()
    assert waiter.returncode == 0, err
    value, result, started, misses = out.split()
    assert float(value) == 3 * 14.0 and float(result) == 14.0
    assert int(misses) == 2   # top and middle compiled there; leaf loaded, not compiled twice


HOLD_ONLY = '''
import sys
import kernel_module as m
from impact_damper_sim.integrate import kernels
args = (kernels.types.float64[::1], kernels.types.float64[::1])
with kernels._compile_lock(m.leaf.internal(), args):
    print(kernels._CACHE_DIR, flush=True)
    sys.stdin.readline()                  # held until the test lets go
'''


@pytest.mark.skipif(kernels.fcntl is None, reason='needs flock (POSIX)')
def test_a_warm_load_takes_no_lock(tmp_path):
    """Issue 39: ten nodes starting at once queued on these locks for every kernel they
    loaded (seconds at 0 % CPU, and a staggered start). A kernel the cache holds is loaded
    while another process holds its lock: the load finishes, nothing is compiled."""
    (tmp_path / 'kernel_module.py').write_text(MODULE)
    assert run(tmp_path, RUN, 0).returncode == 0   # warm the cache
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / 'cache'),
               PYTHONPATH=os.pathsep.join([str(tmp_path)] + sys.path),
               **{kernels.HELPERS_ENV: '0'})
    holder = subprocess.Popen([sys.executable, '-c', HOLD_ONLY], env=env, cwd=tmp_path,
                              text=True, stdin=subprocess.PIPE, stdout=subprocess.PIPE)
    try:
        assert holder.stdout.readline().strip()   # the lock is held from here
        # before issue 39 this blocked on the lock until the holder let go
        warm = subprocess.run([sys.executable, '-c', RUN], env=env, capture_output=True,
                              text=True, cwd=tmp_path, timeout=60)
        assert warm.returncode == 0, warm.stderr
        value, _, _, misses = warm.stdout.split()
        assert float(value) == 3 * 14.0 and int(misses) == 0
        assert holder.poll() is None              # the lock was held all along
    finally:
        holder.stdin.close()
        holder.wait(60)


PREFETCH = '''
from impact_damper_sim.integrate import kernels
from impact_damper_sim.integrate.kernels.prefetch import prefetch
started = prefetch()
again = prefetch()   # already farmed: nothing more started
for helper in kernels._HELPERS.values():   # the compile itself is not this test's subject
    helper.kill()
    helper.wait()
print(','.join(started), len(kernels._HELPERS), ','.join(again))
'''


@pytest.mark.parametrize('helpers, expected', [(2, 'search,scan_multi 2 '), (0, ' 0 ')])
def test_prefetch_farms_the_event_search_on_a_cold_cache(tmp_path, helpers, expected):
    """Issue 24: a run's first second starts the event search and its fallback scan in helper
    processes (none when no helper may start, and nothing twice)."""
    result = run(tmp_path, PREFETCH, helpers)
    assert result.returncode == 0, result.stderr
    assert result.stdout.rstrip('\n') == expected
