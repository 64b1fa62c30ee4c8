"""The lint and the type check of `make test`: ruff (ruff.toml) and mypy (mypy.ini), clean.

Both read their configuration from the checkout's root. mypy keeps its cache in the ignored
``.mypy_cache/`` there: a cold run takes 10-35 s on a loaded 2-core machine, a warm one 1-2 s;
ruff takes well under a second and writes no cache.
"""
import os
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
LINTED = ('impact_damper_sim', 'test', 'bench', 'tools')


def _tool(name):
    """The tool's console script beside this Python (the venv's), or skip saying why."""
    path = os.path.join(os.path.dirname(sys.executable), name)
    if not os.path.exists(path):
        pytest.skip(f'{name} is not installed in this venv (requirements-dev.txt)')
    return path


def _run(cmd):
    return subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=600)


def test_ruff_finds_nothing():
    done = _run([_tool('ruff'), 'check', '--no-cache', '--output-format', 'concise', *LINTED])
    assert done.returncode == 0, f'ruff check (ruff.toml):\n{done.stdout}{done.stderr}'


def test_mypy_finds_nothing():
    # the packages come from mypy.ini's `files`
    done = _run([_tool('mypy'), '--cache-dir', os.path.join(ROOT, '.mypy_cache')])
    assert done.returncode == 0, f'mypy (mypy.ini):\n{done.stdout}{done.stderr}'
    assert 'Success' in done.stdout, done.stdout


def test_the_checks_can_fail(tmp_path):
    """A finding of each tool makes a non-zero exit (so the two tests above can fail)."""
    bad = tmp_path / 'bad.py'
    bad.write_text('import os\n\n\ndef f(x: int) -> str:\n    return x\n')
    ruff = _run([_tool('ruff'), 'check', '--no-cache', '--config',
                 os.path.join(ROOT, 'ruff.toml'), str(bad)])
    assert ruff.returncode == 1 and 'F401' in ruff.stdout, ruff.stdout + ruff.stderr
    mypy = _run([_tool('mypy'), '--config-file', os.path.join(ROOT, 'mypy.ini'),
                 '--cache-dir', str(tmp_path / 'cache'), str(bad)])
    assert mypy.returncode == 1 and 'return-value' in mypy.stdout, mypy.stdout + mypy.stderr
