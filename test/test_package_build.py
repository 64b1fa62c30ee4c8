"""The package builds with colcon and installs where ROS 2 tools look for it.

Two groups of checks:

* ``colcon``-marked tests build a copy of the source tree with ``colcon build`` into a temporary
  directory (once per module, a few seconds) and inspect the install space: console scripts in
  ``lib/<pkg>/`` (where ``ros2 run`` looks) under their ``ros2 run`` names (``monitor``, not
  ``impact_damper_monitor``), ``config/`` and ``package.xml`` under ``share/<pkg>/``, the ament
  index marker, every Python module, and a working ``study --help``; the same for a
  ``--symlink-install`` build (``setup.py develop``).
* Static checks (no build) of ``package.xml``, ``setup.cfg``, ``setup.py`` and the package layout.

colcon comes from ``requirements-dev.txt`` (``colcon-common-extensions``). If it is missing
from the environment running pytest, the build tests fail rather than skip.
"""
import ast
import configparser
import filecmp
import os
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

PKG = 'impact_damper_sim'
ROOT = Path(__file__).resolve().parents[1]

# Not copied into the build: local environments, colcon output, VCS and caches.
_SKIP_AT_ROOT = {'.venv', 'build', 'install', 'log', '.git', 'out'}
_SKIP_ANYWHERE = {'__pycache__', '.pytest_cache', '.mypy_cache', '.ruff_cache'}
_SKIP_SUFFIXES = ('.egg-info', '.pyc', '.mcap')

# A file the build copy gets under config/, two levels deep, so that the recursive data_files
# rule in setup.py is exercised even while config/ holds no (or only flat) files.
_CONFIG_PROBE = Path('config') / '_build_probe' / 'nested' / 'probe.txt'

REQUIRED_EXEC_DEPENDS = {
    'rclpy', 'std_msgs', 'std_srvs', 'sensor_msgs', 'geometry_msgs', 'diagnostic_msgs',
    'rosgraph_msgs', 'rcl_interfaces', 'builtin_interfaces', 'ament_index_python',
    'python3-yaml', 'launch', 'launch_ros',
    'python3-numpy', 'python3-scipy',
    'python3-numba',  # rosdistro has no pip key for numba; see the comment in package.xml
    'mcap-ros2-support',  # also installs mcap, which has no rosdep key
}
#: optional (study plots, parallel sweeps): never a hard dependency
OPTIONAL_DEPENDS = {'python3-matplotlib', 'python3-dask'}
REQUIRED_TEST_DEPENDS = {'python3-pytest'}
#: what ``ros2 run impact_damper_sim NAME`` runs: lib/<pkg>/NAME
ROS2_RUN_NAMES = {'vibration_node', 'monitor', 'replay', 'study', 'recorder', 'plant_host'}


# --------------------------------------------------------------------------- helpers

def _setup_call(setup_py=ROOT / 'setup.py'):
    """Return the ``setup(...)`` call node of setup.py, parsed without executing it."""
    tree = ast.parse(setup_py.read_text(), filename=str(setup_py))
    calls = [
        node for node in ast.walk(tree)
        if isinstance(node, ast.Call)
        and ((isinstance(node.func, ast.Name) and node.func.id == 'setup')
             or (isinstance(node.func, ast.Attribute) and node.func.attr == 'setup'))
    ]
    assert len(calls) == 1, f'expected exactly one setup(...) call in setup.py, found {len(calls)}'
    return calls[0]


def _setup_kwarg(name):
    for kw in _setup_call().keywords:
        if kw.arg == name:
            return kw.value
    raise AssertionError(f'setup.py: setup() has no {name}= keyword')


def ros2_run_name(script):
    """setup.py's rule: lib/<pkg>/ holds a console script without its ``impact_damper_``."""
    return script[len('impact_damper_'):] if script.startswith('impact_damper_') else script


def _console_scripts():
    """Map script name -> 'module:func' from setup.py's entry_points literal."""
    entry_points = ast.literal_eval(_setup_kwarg('entry_points'))
    scripts = {}
    for spec in entry_points.get('console_scripts', []):
        name, sep, target = spec.partition('=')
        assert sep, f'malformed console_scripts entry {spec!r}'
        scripts[name.strip()] = target.strip()
    return scripts


def _ignore(root):
    def ignore(directory, names):
        skipped = set()
        for name in names:
            if Path(directory) == root and name in _SKIP_AT_ROOT:
                skipped.add(name)
            elif name in _SKIP_ANYWHERE or name.endswith(_SKIP_SUFFIXES):
                skipped.add(name)
        return skipped
    return ignore


def _files_under(directory):
    return sorted(p.relative_to(directory) for p in directory.rglob('*') if p.is_file())


def _colcon_env(venv_bin):
    env = dict(os.environ)
    env['PATH'] = os.pathsep.join([str(venv_bin), env.get('PATH', '')])
    env['AMENT_PREFIX_PATH'] = sys.prefix
    # Keep a developer's ~/.colcon/defaults.yaml (e.g. --symlink-install) out of the build.
    for var in ('COLCON_DEFAULTS_FILE', 'COLCON_HOME', 'COLCON_LOG_PATH', 'PYTHONPATH'):
        env.pop(var, None)
    return env


# --------------------------------------------------------------------------- the build

def _build(tmp_path_factory, *extra_args):
    """Build a copy of the source tree with colcon; return the package's install prefix."""
    venv_bin = Path(sys.executable).parent
    colcon = venv_bin / 'colcon'
    if not (colcon.is_file() and os.access(colcon, os.X_OK)):
        pytest.fail(
            f'colcon not found at {colcon}. It comes from requirements-dev.txt '
            f'(colcon-common-extensions, with ros-jazzy-ament-package): run `make test`, or '
            f'`{sys.executable} -m pip install -r requirements-dev.txt -c constraints.txt`.',
            pytrace=False,
        )

    tmp = tmp_path_factory.mktemp('colcon')
    src = tmp / 'src' / PKG
    shutil.copytree(ROOT, src, symlinks=False, ignore=_ignore(ROOT))
    probe = src / _CONFIG_PROBE
    probe.parent.mkdir(parents=True)
    probe.write_text('written by test/test_package_build.py\n')
    (tmp / 'colcon_home').mkdir()
    env = _colcon_env(venv_bin)
    env['COLCON_HOME'] = str(tmp / 'colcon_home')

    cmd = [
        str(colcon), '--log-base', str(tmp / 'log'), 'build',
        '--base-paths', str(src),
        '--build-base', str(tmp / 'build'),
        '--install-base', str(tmp / 'install'),
        '--event-handlers', 'console_cohesion+', *extra_args,
    ]
    proc = subprocess.run(cmd, cwd=tmp, env=env, capture_output=True, text=True, timeout=300)
    if proc.returncode != 0:
        pytest.fail(
            f'colcon build failed (exit {proc.returncode}): {" ".join(cmd)}\n'
            f'--- stdout ---\n{proc.stdout}\n--- stderr ---\n{proc.stderr}',
            pytrace=False,
        )
    prefix = tmp / 'install' / PKG
    assert prefix.is_dir(), f'colcon succeeded but {prefix} is missing:\n{proc.stdout}'
    return {'tmp': tmp, 'src': src, 'prefix': prefix, 'env': env}


@pytest.fixture(scope='module')
def built(tmp_path_factory):
    """A ``colcon build`` (``setup.py install``) of a copy of the source tree."""
    return _build(tmp_path_factory)


@pytest.fixture(scope='module')
def built_symlink(tmp_path_factory):
    """A ``colcon build --symlink-install`` (``setup.py develop``) of a copy of the tree."""
    return _build(tmp_path_factory, '--symlink-install')


def _site_packages(prefix):
    found = sorted(prefix.glob('lib/python3*/site-packages'))
    assert len(found) == 1, f'expected one lib/python3.*/site-packages under {prefix}: {found}'
    return found[0]


@pytest.mark.colcon
def test_colcon_build_succeeds(built):
    marker = built['prefix'] / 'share' / 'colcon-core' / 'packages' / PKG
    assert marker.is_file(), f'colcon did not register {PKG} in its install space'


def _check_ros2_run_scripts(prefix):
    scripts = _console_scripts()
    assert scripts, "setup.py declares no entry_points['console_scripts']"
    assert {ros2_run_name(s) for s in scripts} == ROS2_RUN_NAMES
    libexec = prefix / 'lib' / PKG
    held = sorted(p.name for p in libexec.iterdir()) if libexec.is_dir() else 'nothing'
    for script in scripts:
        name = ros2_run_name(script)
        path = libexec / name
        assert path.is_file(), (
            f'console script {script!r} is not at {path}; `ros2 run {PKG} {name}` looks there '
            f'(setup.cfg [install] install_scripts, setup.py install_scripts). lib/{PKG}/ '
            f'holds: {held}'
        )
        assert os.access(path, os.X_OK), f'{path} is not executable'
        assert path.read_text().startswith('#!'), f'{path} has no shebang line'
    # only the ros2 run names: `ros2 pkg executables` lists exactly these
    assert set(held) == ROS2_RUN_NAMES, held


@pytest.mark.colcon
def test_console_scripts_installed_for_ros2_run(built):
    _check_ros2_run_scripts(built['prefix'])


@pytest.mark.colcon
def test_symlink_install_has_the_ros2_run_scripts_and_runs_the_source(built_symlink):
    """``colcon build --symlink-install`` (``setup.py develop``): the same names in lib/, and
    ``study`` runs the package from the build's source copy."""
    prefix = built_symlink['prefix']
    _check_ros2_run_scripts(prefix)
    env = dict(built_symlink['env'])
    env['AMENT_PREFIX_PATH'] = os.pathsep.join([str(prefix), sys.prefix])
    # colcon's hook for a develop install puts the build directory (links to the source) first
    env['PYTHONPATH'] = os.pathsep.join(
        [str(built_symlink['tmp'] / 'build' / PKG), str(_site_packages(prefix))])
    env.pop('COLCON_HOME', None)
    proc = subprocess.run([str(prefix / 'lib' / PKG / 'study'), '--help'],
                          cwd=built_symlink['tmp'], env=env, capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 0 and proc.stdout.strip(), proc.stderr


@pytest.mark.colcon
def test_config_package_xml_and_ament_index_installed(built):
    src, share = built['src'], built['prefix'] / 'share'
    config_files = _files_under(src / 'config')
    assert _CONFIG_PROBE.relative_to('config') in config_files
    missing, differ = [], []
    for rel in config_files:
        installed = share / PKG / 'config' / rel
        if not installed.is_file():
            missing.append(str(rel))
        elif not filecmp.cmp(src / 'config' / rel, installed, shallow=False):
            differ.append(str(rel))
    assert not missing, f'config files not installed under share/{PKG}/config/: {missing}'
    assert not differ, f'installed config files differ from the source: {differ}'

    assert (share / PKG / 'package.xml').is_file(), f'share/{PKG}/package.xml is missing'
    for launch_file in (src / 'launch').glob('*.launch.py'):
        installed = share / PKG / 'launch' / launch_file.name
        assert installed.is_file(), f'{launch_file.name} not installed under share/{PKG}/launch'
    marker = share / 'ament_index' / 'resource_index' / 'packages' / PKG
    assert marker.is_file(), (
        f'ament index marker {marker.relative_to(built["prefix"])} is missing: '
        f'ament_index_python (and `ros2 pkg`/`ros2 run`) will not find the package'
    )


@pytest.mark.colcon
def test_every_module_installed(built):
    """find_packages silently drops a directory without __init__.py; nothing may go missing."""
    src_pkg = built['src'] / PKG
    inst_pkg = _site_packages(built['prefix']) / PKG
    source = {p for p in _files_under(src_pkg) if p.suffix == '.py'}
    installed = {p for p in _files_under(inst_pkg) if p.suffix == '.py'}
    assert not source - installed, f'modules not installed: {sorted(map(str, source - installed))}'


@pytest.mark.colcon
def test_installed_study_runs(built):
    prefix = built['prefix']
    site = _site_packages(prefix)
    env = dict(built['env'])
    env['PYTHONPATH'] = str(site)
    env['AMENT_PREFIX_PATH'] = os.pathsep.join([str(prefix), sys.prefix])
    env.pop('COLCON_HOME', None)

    # The installed copy, not the editable checkout, must be the one imported.
    where = subprocess.run(
        [sys.executable, '-c', f'import {PKG}; print({PKG}.__file__)'],
        cwd=built['tmp'], env=env, capture_output=True, text=True, timeout=60,
    )
    assert where.returncode == 0, where.stderr
    assert Path(where.stdout.strip()).is_relative_to(site), (
        f'{PKG} imported from {where.stdout.strip()}, not from the install space {site}'
    )

    study = prefix / 'lib' / PKG / 'study'
    proc = subprocess.run(
        [str(study), '--help'],
        cwd=built['tmp'], env=env, capture_output=True, text=True, timeout=60,
    )
    assert proc.returncode == 0, (
        f'`{study} --help` exited {proc.returncode}\n'
        f'--- stdout ---\n{proc.stdout}\n--- stderr ---\n{proc.stderr}'
    )
    assert proc.stdout.strip(), '`study --help` printed nothing'


# --------------------------------------------------------------------------- static checks

def _package_xml():
    return ET.parse(ROOT / 'package.xml').getroot()


def test_package_xml_format_and_build_type():
    root = _package_xml()
    assert root.tag == 'package' and root.get('format') == '3', 'package.xml must be format 3'
    assert root.findtext('name') == PKG
    assert [e.text for e in root.findall('export/build_type')] == ['ament_python']


def test_package_xml_matches_setup_py():
    root = _package_xml()
    assert ast.literal_eval(_setup_kwarg('version')) == root.findtext('version')
    name = _setup_kwarg('name')
    if isinstance(name, ast.Name):  # name=package_name
        tree = ast.parse((ROOT / 'setup.py').read_text())
        values = [
            node.value for node in tree.body
            if isinstance(node, ast.Assign)
            and any(isinstance(t, ast.Name) and t.id == name.id for t in node.targets)
        ]
        assert len(values) == 1, f'cannot resolve setup(name={name.id})'
        name = values[0]
    assert ast.literal_eval(name) == root.findtext('name') == PKG


def test_package_xml_dependencies():
    root = _package_xml()
    exec_deps = {e.text.strip() for e in root.findall('exec_depend')}
    exec_deps |= {e.text.strip() for e in root.findall('depend')}
    test_deps = {e.text.strip() for e in root.findall('test_depend')}
    assert not REQUIRED_EXEC_DEPENDS - exec_deps, (
        f'package.xml lacks exec_depend: {sorted(REQUIRED_EXEC_DEPENDS - exec_deps)}'
    )
    assert not REQUIRED_TEST_DEPENDS - test_deps, (
        f'package.xml lacks test_depend: {sorted(REQUIRED_TEST_DEPENDS - test_deps)}'
    )
    assert not OPTIONAL_DEPENDS & exec_deps, (
        f'optional dependencies declared as required: {sorted(OPTIONAL_DEPENDS & exec_deps)}'
    )


def test_setup_cfg_installs_scripts_for_ros2_run():
    cfg = configparser.ConfigParser(interpolation=None)
    cfg.read(ROOT / 'setup.cfg')
    assert cfg.get('install', 'install_scripts', fallback=None) == f'$base/lib/{PKG}'
    assert cfg.get('develop', 'script_dir', fallback=None) == f'$base/lib/{PKG}'


def test_setup_py_packages_and_test_extra():
    packages = _setup_kwarg('packages')
    assert (isinstance(packages, ast.Call) and isinstance(packages.func, ast.Name)
            and packages.func.id == 'find_packages'), 'setup(packages=...) must be find_packages()'
    exclude = {kw.arg: kw.value for kw in packages.keywords}.get('exclude')
    assert exclude is not None, 'find_packages() must exclude the test directory'
    assert 'test' in ast.literal_eval(exclude)

    extras = ast.literal_eval(_setup_kwarg('extras_require'))
    test_reqs = [r.split(';')[0].strip() for r in extras.get('test', [])]
    assert any(r.split('[')[0].split('=')[0].split('<')[0].split('>')[0].strip() == 'pytest'
               for r in test_reqs), (
        "setup.py needs extras_require={'test': ['pytest']} (colcon test relies on it)"
    )


def _imports_rclpy(tree):
    def is_rclpy(module):
        return module == 'rclpy' or module.startswith('rclpy.')
    for node in ast.walk(tree):
        if isinstance(node, ast.Import) and any(is_rclpy(a.name) for a in node.names):
            yield node.lineno
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and is_rclpy(node.module or ''):
            yield node.lineno
        elif (isinstance(node, ast.Call) and node.args
              and isinstance(node.args[0], ast.Constant) and isinstance(node.args[0].value, str)
              and is_rclpy(node.args[0].value)
              and ((isinstance(node.func, ast.Name) and node.func.id == '__import__')
                   or (isinstance(node.func, ast.Attribute)
                       and node.func.attr == 'import_module'))):
            yield node.lineno


def test_only_ros_subpackage_imports_rclpy():
    pkg = ROOT / PKG
    offenders = []
    for path in sorted(pkg.rglob('*.py')):
        rel = path.relative_to(pkg)
        if rel.parts[0] == 'ros' or '__pycache__' in rel.parts:
            continue
        tree = ast.parse(path.read_text(), filename=str(path))
        offenders += [f'{PKG}/{rel}:{line}' for line in _imports_rclpy(tree)]
    assert not offenders, f'rclpy imported outside {PKG}/ros/: {offenders}'


def test_every_subpackage_has_init():
    pkg = ROOT / PKG
    missing = []
    for directory in sorted(d for d in [pkg, *pkg.rglob('*')] if d.is_dir()):
        rel = directory.relative_to(ROOT)
        if any(part == '__pycache__' or part.startswith('.') for part in rel.parts):
            continue
        has_python = any(p.suffix == '.py' for p in directory.rglob('*.py')
                         if '__pycache__' not in p.parts)
        if has_python and not (directory / '__init__.py').is_file():
            missing.append(str(rel))
    assert not missing, (
        f'directories with Python code but no __init__.py (find_packages drops them): {missing}'
    )


# --------------------------------------------------------------------------- launch file
# Static checks: the launch file's names against what the package declares, without launch
# installed. test/test_ros2_tools.py runs it with `ros2 launch`.

def _launch_calls(name):
    tree = ast.parse((ROOT / 'launch' / 'vibration.launch.py').read_text())
    return [n for n in ast.walk(tree) if isinstance(n, ast.Call)
            and getattr(n.func, 'id', getattr(n.func, 'attr', None)) == name]


def _kw(call, key):
    return next((k.value for k in call.keywords if k.arg == key), None)


def test_launch_file_parses_and_defines_the_entry_point():
    tree = ast.parse((ROOT / 'launch' / 'vibration.launch.py').read_text())
    names = {n.name for n in tree.body if isinstance(n, ast.FunctionDef)}
    assert 'generate_launch_description' in names


def test_launch_file_executables_and_parameters_exist():
    pytest.importorskip('rclpy')
    from impact_damper_sim.ros.parameters import PARAMETERS
    scripts = {ros2_run_name(name) for name in _console_scripts()}
    nodes = _launch_calls('Node')
    assert len(nodes) == 2
    executables = {_kw(n, 'executable').value for n in nodes}
    assert executables == {'vibration_node', 'monitor'} and executables <= scripts
    assert all(_kw(n, 'package').id == 'PACKAGE' for n in nodes)
    vib = next(n for n in nodes if _kw(n, 'executable').value == 'vibration_node')
    dicts = [d for d in _kw(vib, 'parameters').elts if isinstance(d, ast.Dict)]
    keys = {k.value for d in dicts for k in d.keys}
    assert keys and keys <= set(PARAMETERS), keys - set(PARAMETERS)
    declared = {c.args[0].value for c in _launch_calls('DeclareLaunchArgument')}
    used = {c.args[0].value for c in _launch_calls('LaunchConfiguration')}
    assert declared == used == {'scene', 'namespace', 'params_file', 'record',
                                'real_time_factor', 'monitor'}
    # the default params file is the one the package installs
    assert (ROOT / 'config' / 'vibration_node.yaml').is_file()


def _requirement_names(path):
    names = []
    for line in (ROOT / path).read_text().splitlines():
        line = line.split('#')[0].strip()
        if line and not line.startswith('-'):
            names.append(line.split('[')[0].split('=')[0].split('<')[0].split('>')[0].lower())
    return names


def test_runtime_requirements_hold_no_tooling_and_the_used_message_packages():
    runtime = set(_requirement_names('requirements.txt'))
    assert not runtime & {'pytest', 'pytest-cov', 'coverage', 'colcon-common-extensions',
                          'ros-jazzy-ament-package', 'matplotlib', 'dask', 'setuptools',
                          'ros-jazzy-common-interfaces'}
    assert {'ros-jazzy-std-msgs', 'ros-jazzy-std-srvs', 'ros-jazzy-sensor-msgs',
            'ros-jazzy-geometry-msgs', 'ros-jazzy-diagnostic-msgs'} <= runtime
    dev = (ROOT / 'requirements-dev.txt').read_text()
    assert '-r requirements.txt' in dev
    assert {'pytest', 'colcon-common-extensions', 'matplotlib', 'dask'} <= set(
        _requirement_names('requirements-dev.txt'))


def test_constraints_pin_no_egg_info_names_of_the_ros_wheels():
    pinned = {line.split('==')[0] for line in (ROOT / 'constraints.txt').read_text().split()
              if '==' in line}
    # these exist only as egg-info inside ros-* wheels; PyPI has no such distributions
    assert not pinned & {'rclpy', 'std_msgs', 'sensor_msgs', 'rcl_interfaces',
                         'builtin_interfaces', 'rosidl_parser', 'rosgraph_msgs'}
    assert 'ros-jazzy-rclpy' in pinned
