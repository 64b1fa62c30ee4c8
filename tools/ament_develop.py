#!/usr/bin/env python3
"""Make the editable install of impact_damper_sim an ament package of its prefix (the venv).

``pip install -e .`` puts the package on ``sys.path`` and its console scripts in
``<prefix>/bin``, and nothing else. ROS 2 tools find a package through the ament index under
``AMENT_PREFIX_PATH`` (ament_index_python, ``ros2 run``, ``ros2 launch``, ``ros2 pkg``), so this
script adds under ``<prefix>`` what ``colcon build --symlink-install`` would (setup.py's
``data_files`` and ``lib/<package>/``):

* ``share/ament_index/resource_index/packages/impact_damper_sim`` (the index marker);
* ``share/impact_damper_sim/package.xml``, ``config`` and ``launch/*.launch.py``: links to the
  checkout, so that an edit there takes effect at once, as the editable Python code does (a
  new launch file needs this script run again, as with colcon);
* ``lib/impact_damper_sim/<name>``: one launcher per console script under the name ``ros2 run``
  knows it by (``vibration_node``, ``monitor``, ``replay``, ``study``), running the entry point
  with this Python, read from the installed distribution's metadata.

Idempotent; ``make`` runs it after the editable install. Standard library only.

Usage: ``.venv/bin/python tools/ament_develop.py [--prefix PREFIX] [--python PYTHON]``
"""
from __future__ import annotations

import argparse
import importlib.metadata
import os
import shutil
import sys
from pathlib import Path

PACKAGE = 'impact_damper_sim'
ROOT = Path(__file__).resolve().parents[1]
#: console scripts carry this prefix on the PATH; ``ros2 run`` knows them without it
#: (setup.py's ``ros2_run_name``, which colcon builds use)
SCRIPT_PREFIX = 'impact_damper_'
_MARK = f'# Written by tools/ament_develop.py for `ros2 run {PACKAGE}`'


def ros2_run_name(script_name):
    """The name ``ros2 run`` knows a console script by (setup.py's rule)."""
    return script_name[len(SCRIPT_PREFIX):] if script_name.startswith(SCRIPT_PREFIX) \
        else script_name


def shebang(python):
    """A ``#!`` line running ``python``; the ``/bin/sh`` trick when the path cannot be one
    (spaces, or longer than the kernel reads), as pip's script maker does."""
    if ' ' not in python and len(python) < 120:
        return f'#!{python}'
    return f"#!/bin/sh\n'''exec' \"{python}\" \"$0\" \"$@\"\n' '''"


def launcher(python, script_name, value):
    """The text of a ``lib/<package>/`` launcher for the entry point ``module:attr``."""
    module, _, attr = value.partition(':')
    top = attr.split('.')[0] if attr else None
    call = attr.strip() if attr else None
    if not (module and call):
        raise SystemExit(f'ament_develop: entry point {script_name} = {value!r} has no '
                         f'module:function form')
    return (f'{shebang(python)}\n'
            f'{_MARK}:\n# the console script {script_name} ({value}).\n'
            f'import sys\n\n'
            f'from {module.strip()} import {top}\n\n'
            f"if __name__ == '__main__':\n"
            f'    sys.exit({call}())\n')


def console_scripts():
    """``{name: 'module:attr'}`` of the installed distribution's console scripts."""
    try:
        dist = importlib.metadata.distribution(PACKAGE)
    except importlib.metadata.PackageNotFoundError:
        raise SystemExit(f'ament_develop: {PACKAGE} is not installed in this Python '
                         f'({sys.executable}); run `pip install -e .` first') from None
    scripts = {ep.name: ep.value for ep in dist.entry_points if ep.group == 'console_scripts'}
    if not scripts:
        raise SystemExit(f'ament_develop: {PACKAGE} declares no console scripts')
    return scripts


def _replace(path):
    """Remove whatever is at ``path`` (file, link or directory) so that it can be rewritten."""
    if path.is_symlink() or path.is_file():
        path.unlink()
    elif path.is_dir():
        shutil.rmtree(path)


def _link(target, path):
    _replace(path)
    path.symlink_to(target, target_is_directory=target.is_dir())


def install(prefix, python):
    """Install the ament layout under ``prefix``; return the paths written (list of Path)."""
    prefix = Path(prefix)
    written = []

    index = prefix / 'share' / 'ament_index' / 'resource_index' / 'packages'
    index.mkdir(parents=True, exist_ok=True)
    marker = index / PACKAGE
    _replace(marker)
    shutil.copyfile(ROOT / 'resource' / PACKAGE, marker)   # an empty file, as colcon's
    written.append(marker)

    share = prefix / 'share' / PACKAGE
    if share.is_symlink() or share.is_file():
        share.unlink()
    share.mkdir(parents=True, exist_ok=True)
    for name in ('package.xml', 'config'):
        _link(ROOT / name, share / name)
        written.append(share / name)
    # launch/ is a directory of links, as colcon --symlink-install makes it: `ros2 launch`
    # finds a launch file by os.walk, which does not enter a linked directory
    launch = share / 'launch'
    if launch.is_symlink() or launch.is_file():
        launch.unlink()
    launch.mkdir(exist_ok=True)
    for old in launch.iterdir():
        if old.is_symlink() and not old.exists():   # a launch file since removed
            old.unlink()
    for source in sorted((ROOT / 'launch').glob('*.launch.py')):   # setup.py's rule
        _link(source, launch / source.name)
        written.append(launch / source.name)

    lib = prefix / 'lib' / PACKAGE
    if lib.is_symlink() or lib.is_file():
        lib.unlink()
    lib.mkdir(parents=True, exist_ok=True)
    wanted = {}
    for script_name, value in sorted(console_scripts().items()):
        wanted[ros2_run_name(script_name)] = launcher(python, script_name, value)
    for old in lib.iterdir():   # launchers of console scripts that are gone
        if old.name not in wanted and old.is_file() and _MARK in old.read_text(errors='replace'):
            old.unlink()
    for name, text in wanted.items():
        path = lib / name
        _replace(path)
        path.write_text(text)
        path.chmod(0o755)
        written.append(path)
    return written


def main(argv=None):
    parser = argparse.ArgumentParser(
        prog='ament_develop', description=__doc__.split('\n\n')[0])
    parser.add_argument('--prefix', default=sys.prefix,
                        help='the install prefix, an AMENT_PREFIX_PATH entry (default: this '
                             "Python's, the venv)")
    parser.add_argument('--python', default=None,
                        help="the Python the launchers run (default: the prefix's bin/python, "
                             'else this one)')
    args = parser.parse_args(argv)
    prefix = Path(os.path.abspath(args.prefix))
    python = args.python
    if python is None:
        candidate = prefix / 'bin' / 'python'
        python = str(candidate) if candidate.exists() else sys.executable
    python = os.path.abspath(python)   # not resolved: a venv's python is a link to the base one
    written = install(prefix, python)
    lib = sorted(p.name for p in written if p.parent.name == PACKAGE and
                 p.parent.parent.name == 'lib')
    print(f'ament_develop: {PACKAGE} is an ament package of {prefix} (share/{PACKAGE} links to '
          f'{ROOT}; ros2 run executables: {", ".join(lib)})')
    return 0


if __name__ == '__main__':
    sys.exit(main())
