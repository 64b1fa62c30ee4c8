"""The package's layers (docs/development.md, "Layers"), enforced by import-linter.

``.importlinter`` states them: imports run down the layers (``cli | ros`` on top, ``fem``,
``dampers`` and ``units`` at the bottom; ``|`` separates independent siblings), and rclpy and
the ROS message packages stay inside ``impact_damper_sim.ros``, so the core runs without ROS.
"""
import configparser
import os
import pkgutil
import subprocess
import sys

import pytest

import impact_damper_sim

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CONFIG = os.path.join(ROOT, '.importlinter')
LINT = os.path.join(os.path.dirname(sys.executable), 'lint-imports')


def _layers():
    config = configparser.ConfigParser()
    config.read(CONFIG)
    rows = config['importlinter:contract:layers']['layers'].split('\n')
    return [[m.strip() for m in row.split('|')] for row in rows if row.strip()]


def test_every_module_of_the_package_is_in_a_layer():
    """A new top-level module or package outside every layer would be unconstrained."""
    in_layers = {m for row in _layers() for m in row}
    top = {f'impact_damper_sim.{m.name}' for m in pkgutil.iter_modules(
        impact_damper_sim.__path__) if not m.name.startswith('_')}
    assert top == in_layers, (f'not in a layer: {sorted(top - in_layers)}; '
                              f'no such module: {sorted(in_layers - top)}')


def test_the_package_root_holds_packages_only():
    """Issue 27: every module lives in a package that names its layer (private set-up aside)."""
    loose = sorted(m.name for m in pkgutil.iter_modules(impact_damper_sim.__path__)
                   if not m.ispkg and not m.name.startswith('_'))
    assert loose == [], f'modules at the package root, outside every layer: {loose}'


@pytest.mark.skipif(not os.path.exists(LINT), reason='import-linter is not installed '
                    '(make installs it from requirements-dev.txt)')
def test_imports_keep_the_layers_and_rclpy_inside_ros():
    proc = subprocess.run([LINT, '--config', CONFIG], cwd=ROOT, capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:]
    assert 'Contracts: 2 kept, 0 broken.' in proc.stdout, proc.stdout[-2000:]
