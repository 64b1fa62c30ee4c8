"""Where Numba caches the compiled kernels: a per-user directory, never the source tree.

Each case runs a fresh interpreter (``NUMBA_CACHE_DIR`` is read when Numba is imported) with
``XDG_CACHE_HOME`` pointing into ``tmp_path``, so the user's own cache is never touched.
"""
import os
import subprocess
import sys
from pathlib import Path

import pytest

import impact_damper_sim
from impact_damper_sim._cache_dir import default_cache_dir

SOURCE = Path(impact_damper_sim.__file__).parent

# a small simulation: Newmark on the SDOF scene without its impactor, 10 steps (its kernels
# compile in a few seconds)
SIMULATE = '''
import os
import impact_damper_sim
from impact_damper_sim.scene.build import load
load('sdof', ['impactors=[]']).make_simulation('newmark').advance(10)
print(os.environ['NUMBA_CACHE_DIR'])
'''

# one flow kernel, with Numba imported before the package
NUMBA_FIRST = '''
import os
import numba
import numpy as np
from impact_damper_sim.integrate.kernels import flow_eval
lam = np.array([-1.0 + 2.0j])
flow_eval.step_factors(lam, 1e-3, *(np.empty(1, complex) for _ in range(3)))
print(os.environ['NUMBA_CACHE_DIR'])
'''

pytestmark = pytest.mark.skipif(os.environ.get('NUMBA_DISABLE_JIT', '0') != '0',
                                reason='the kernels run as Python: nothing is cached')


def cache_files(root):
    """Numba's cache files under ``root``: ``{path: modification time (ns)}``."""
    return {p: p.stat().st_mtime_ns for p in Path(root).rglob('*')
            if p.suffix in ('.nbi', '.nbc')}


def run(code, tmp_path, **env):
    """Run ``code`` in a fresh interpreter without ``NUMBA_CACHE_DIR`` (unless given in
    ``env``) and with ``XDG_CACHE_HOME`` in ``tmp_path``; return its last output line."""
    child_env = {k: v for k, v in os.environ.items() if k != 'NUMBA_CACHE_DIR'}
    child_env.update(XDG_CACHE_HOME=str(tmp_path / 'xdg'), **env)
    out = subprocess.run([sys.executable, '-c', code], env=child_env, capture_output=True,
                         text=True, check=True, cwd=tmp_path).stdout
    return out.strip().splitlines()[-1]


def test_a_simulation_caches_its_kernels_per_user_not_in_the_source_tree(tmp_path):
    before = cache_files(SOURCE)
    used = run(SIMULATE, tmp_path)
    after = cache_files(SOURCE)
    assert {p for p, t in after.items() if before.get(p) != t} == set()
    expected = tmp_path / 'xdg' / 'impact_damper_sim' / 'numba'
    assert used == str(expected)
    assert any(p.name.startswith('newmark_step.') for p in cache_files(expected))


def test_the_user_directory_also_when_numba_is_imported_first(tmp_path):
    before = cache_files(SOURCE)
    used = run(NUMBA_FIRST, tmp_path)
    assert {p for p, t in cache_files(SOURCE).items() if before.get(p) != t} == set()
    assert used == str(tmp_path / 'xdg' / 'impact_damper_sim' / 'numba')
    assert any(p.name.startswith('flow_eval.step_factors') for p in cache_files(used))


def test_a_numba_cache_dir_the_user_set_is_kept(tmp_path):
    own = tmp_path / 'own'
    assert run(NUMBA_FIRST, tmp_path, NUMBA_CACHE_DIR=str(own)) == str(own)
    assert cache_files(own) and not cache_files(tmp_path / 'xdg')


def test_default_cache_dir_follows_xdg(monkeypatch, tmp_path):
    monkeypatch.setenv('HOME', str(tmp_path / 'home'))
    monkeypatch.setenv('XDG_CACHE_HOME', str(tmp_path / 'cache'))
    assert default_cache_dir() == tmp_path / 'cache' / 'impact_damper_sim' / 'numba'
    home_cache = tmp_path / 'home' / '.cache' / 'impact_damper_sim' / 'numba'
    for unusable in ('', 'relative/cache'):   # the XDG specification ignores both
        monkeypatch.setenv('XDG_CACHE_HOME', unusable)
        assert default_cache_dir() == home_cache
    monkeypatch.delenv('XDG_CACHE_HOME')
    assert default_cache_dir() == home_cache
