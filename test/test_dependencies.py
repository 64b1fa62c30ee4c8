"""Packaging that users meet: declared dependencies, console-script names, the launch file's
argument types, and the editable install as an ament package (tools/ament_develop.py).

No ROS command line needed: test/test_ros2_tools.py runs the real tools.
"""
import ast
import importlib.metadata
import os
import re
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PKG = 'impact_damper_sim'
ROS2_RUN_NAMES = {'vibration_node', 'monitor', 'replay', 'study', 'recorder', 'plant_host'}

#: third-party modules that are not ROS packages: import name -> (PyPI distribution, rosdep
#: key). mcap has no rosdep key of its own (rosdistro's rosdep/python.yaml, 2026-08): the pip
#: key mcap-ros2-support installs it (its package requires mcap), see package.xml.
PYPI = {
    'numpy': ('numpy', 'python3-numpy'),
    'scipy': ('scipy', 'python3-scipy'),
    'numba': ('numba', 'python3-numba'),
    # numba's own dependency; noble's python3-numba depends on python3-llvmlite
    'llvmlite': ('llvmlite', 'python3-numba'),
    'yaml': ('pyyaml', 'python3-yaml'),
    'mcap': ('mcap', 'mcap-ros2-support'),
    'mcap_ros2': ('mcap-ros2-support', 'mcap-ros2-support'),
}
#: optional: import name -> setup.py extra; imported only inside functions, never required
OPTIONAL = {'matplotlib': 'plots', 'dask': 'dask'}
#: ROS packages that come with ros-jazzy-rclpy (no wheel of their own in requirements.txt)
WITH_RCLPY = {'rclpy', 'rcl_interfaces', 'builtin_interfaces'}


def _norm(name):
    return re.sub(r'[-_.]+', '-', name).lower()


def _req_name(spec):
    return _norm(re.split(r'[\[<>=!~;\s]', spec.strip(), maxsplit=1)[0])


def _setup():
    """setup.py's keywords, read by setuptools without running a command."""
    pytest.importorskip('setuptools')
    import distutils.core  # setuptools' copy (its distutils shim)
    cwd = os.getcwd()
    try:
        os.chdir(ROOT)
        return distutils.core.run_setup(str(ROOT / 'setup.py'), stop_after='init')
    finally:
        os.chdir(cwd)


def _package_xml_depends(tag='exec_depend'):
    root = ET.parse(ROOT / 'package.xml').getroot()
    return {e.text.strip() for e in [*root.findall(tag), *root.findall('depend')]}


def _requirements(path):
    names = set()
    for line in (ROOT / path).read_text().splitlines():
        line = line.split('#')[0].strip()
        if line and not line.startswith('-'):
            names.add(_req_name(line))
    return names


def _imports():
    """{top-level module: {(file, line, at_module_level)}} of the package's absolute imports
    of modules outside the standard library and the package itself."""
    found = {}
    for path in sorted((ROOT / PKG).rglob('*.py')):
        if '__pycache__' in path.parts:
            continue
        tree = ast.parse(path.read_text(), filename=str(path))
        module_level = {id(n) for n in tree.body}
        # imports directly in the module body, or in its if/try blocks, run at import
        for node in tree.body:
            if isinstance(node, (ast.If, ast.Try)):
                module_level |= {id(n) for n in ast.walk(node)}
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            else:
                continue
            for name in names:
                top = name.split('.')[0]
                if top in sys.stdlib_module_names or top in (PKG, '__future__'):
                    continue
                found.setdefault(top, set()).add(
                    (str(path.relative_to(ROOT)), node.lineno, id(node) in module_level))
    return found


def _installed_dist():
    """The pip-installed distribution of the package (not an egg-info of the source tree,
    which a cwd on sys.path would find first), or None."""
    for dist in importlib.metadata.distributions(name=PKG):
        if dist.read_text('direct_url.json') is not None:
            return dist
    return None


def _is_ros_package(name):
    """A ROS package: in the ament index of this environment (share/ament_index)."""
    return any((Path(prefix) / 'share' / 'ament_index' / 'resource_index' / 'packages' /
                name).is_file()
               for prefix in [sys.prefix, *os.environ.get('AMENT_PREFIX_PATH', '').split(
                   os.pathsep)] if prefix)


def test_every_third_party_import_is_declared():
    """Each module the package imports is in setup.py's install_requires, requirements.txt and
    package.xml (ROS packages: package.xml and a ros-jazzy-* wheel); optional plotting and
    dask are extras, imported only inside functions, and nowhere required."""
    dist = _setup()
    install_requires = {_req_name(r) for r in dist.install_requires}
    extras = {k: {_req_name(r) for r in v} for k, v in dist.extras_require.items()}
    runtime = _requirements('requirements.txt')
    exec_depends = _package_xml_depends()
    problems = []
    for module, where in sorted(_imports().items()):
        first = '%s:%d' % sorted(where)[0][:2]
        if module in OPTIONAL:
            extra = OPTIONAL[module]
            if _norm(module) not in extras.get(extra, set()):
                problems.append(f'{module} ({first}): not in extras_require[{extra!r}]')
            eager = sorted(f'{f}:{line}' for f, line, top in where if top)
            if eager:
                problems.append(f'{module} is optional but imported at module level: {eager}')
            if _norm(module) in install_requires | runtime or \
                    f'python3-{module}' in exec_depends:
                problems.append(f'{module} is optional but declared as required')
        elif module in PYPI:
            dist_name, key = PYPI[module]
            if dist_name not in install_requires:
                problems.append(f'{module} ({first}): {dist_name} not in setup.py install_requires')
            if dist_name not in runtime:
                problems.append(f'{module} ({first}): {dist_name} not in requirements.txt')
            if key not in exec_depends:
                problems.append(f'{module} ({first}): rosdep key {key} not in package.xml')
        elif _is_ros_package(module):
            if module not in exec_depends:
                problems.append(f'{module} ({first}): no <exec_depend>{module}</exec_depend>')
            wheel = 'ros-jazzy-' + module.replace('_', '-')
            if module not in WITH_RCLPY and wheel not in runtime:
                problems.append(f'{module} ({first}): {wheel} not in requirements.txt')
        else:
            problems.append(
                f'{module} ({first}): an undeclared third-party import; declare it (setup.py '
                f'install_requires, requirements.txt, package.xml with its rosdep key) and add '
                f'it to PYPI or OPTIONAL in this test')
    assert not problems, '\n'.join(problems)


def test_the_import_to_distribution_map_is_what_is_installed():
    """PYPI names the distributions that really provide the modules, and the key used for
    mcap installs it."""
    provided = importlib.metadata.packages_distributions()
    for module, (dist_name, _key) in PYPI.items():
        if module in provided:
            assert dist_name in {_norm(d) for d in provided[module]}, (module, provided[module])
    requires = importlib.metadata.requires('mcap-ros2-support') or []
    assert any(_req_name(r) == 'mcap' for r in requires), requires


def test_optional_plotting_is_not_a_hard_dependency():
    assert 'python3-matplotlib' not in _package_xml_depends()
    assert 'matplotlib' not in _requirements('requirements.txt')
    assert 'matplotlib' in _requirements('requirements-dev.txt')


def test_console_script_names_cannot_clash():
    """On the PATH: vibration_node and impact_damper_*; under ros2 run: the short names."""
    dist = _setup()
    scripts = dict(spec.split('=', 1) for spec in
                   (s.replace(' ', '') for s in dist.entry_points['console_scripts']))
    assert all(name == 'vibration_node' or name.startswith('impact_damper_')
               for name in scripts), sorted(scripts)
    assert {_setup_py_function('ros2_run_name')(name) for name in scripts} == ROS2_RUN_NAMES
    # the environment's install is the current one: no generic names left in its bin/
    dist = _installed_dist()
    if dist is None:
        pytest.skip(f'{PKG} is not pip-installed in this Python')
    installed = {ep.name for ep in dist.entry_points if ep.group == 'console_scripts'}
    assert installed == set(scripts), (
        f'the installed {PKG} has console scripts {sorted(installed)}, setup.py '
        f'{sorted(scripts)}: run `make` (the .venv/.installed rule) again')
    for generic in ('monitor', 'replay', 'study'):
        path = Path(sys.prefix) / 'bin' / generic
        assert not (path.exists() and PKG in path.read_text(errors='replace')), path


def _setup_py_function(name):
    """A function of setup.py (with the module constants it reads), without running setup()."""
    tree = ast.parse((ROOT / 'setup.py').read_text())
    body = [n for n in tree.body
            if (isinstance(n, ast.FunctionDef) and n.name == name)
            or (isinstance(n, ast.Assign) and all(isinstance(t, ast.Name) and t.id.isupper()
                                                  for t in n.targets))]
    namespace = {}
    exec(compile(ast.Module(body=body, type_ignores=[]), 'setup.py', 'exec'), namespace)
    return namespace[name]


def _parameter_dict():
    tree = ast.parse((ROOT / 'launch' / 'vibration.launch.py').read_text())
    node = next(n for n in ast.walk(tree) if isinstance(n, ast.Call)
                and getattr(n.func, 'id', None) == 'Node'
                and any(k.arg == 'executable' and getattr(k.value, 'value', None) ==
                        'vibration_node' for k in n.keywords))
    params = next(k.value for k in node.keywords if k.arg == 'parameters')
    return next(d for d in params.elts if isinstance(d, ast.Dict))


def test_launch_arguments_reach_the_node_typed():
    """Every launch argument handed to the node is a ParameterValue with its parameter's type
    (launch would read 'scene:=0123' as the integer 83 otherwise)."""
    pytest.importorskip('rclpy')
    from impact_damper_sim.ros.parameters import PARAMETERS, kind_of
    python_type = {'string': 'str', 'double': 'float', 'int': 'int', 'bool': 'bool'}
    d = _parameter_dict()
    for key, value in zip(d.keys, d.values):
        name = key.value
        assert isinstance(value, ast.Call) and value.func.id == 'ParameterValue', name
        value_type = next(k.value.id for k in value.keywords if k.arg == 'value_type')
        assert value_type == python_type[kind_of(PARAMETERS[name][0])], (name, value_type)
    assert {k.value for k in d.keys} >= {'scene', 'record', 'real_time_factor'}


# --------------------------------------------------------------------------- ament layout

def _editable():
    dist = _installed_dist()
    text = (dist.read_text('direct_url.json') or '') if dist else ''
    return '"editable": true' in text and \
        Path(__import__(PKG).__file__).resolve().is_relative_to(ROOT)


def _data_files():
    """setup.py's data_files as {installed path: source path}."""
    out = {}
    for dest, files in _setup().data_files:
        for f in files:
            out[Path(dest) / Path(f).name] = ROOT / f
    return out


def _check_layout(prefix, python):
    missing, wrong = [], []
    for rel, source in _data_files().items():
        installed = prefix / rel
        if not installed.is_file():
            missing.append(str(rel))
        elif rel.parts[:3] != ('share', 'ament_index', 'resource_index') and \
                not installed.samefile(source):
            wrong.append(str(rel))
    assert not missing, f'setup.py data_files missing under {prefix}: {missing}'
    assert not wrong, f'not linked to the checkout (an edit would not take effect): {wrong}'
    lib = prefix / 'lib' / PKG
    assert {p.name for p in lib.iterdir()} == ROS2_RUN_NAMES
    for name in ROS2_RUN_NAMES:
        text = (lib / name).read_text()
        head = '\n'.join(text.splitlines()[:2])   # #!python, or the /bin/sh exec line
        assert os.access(lib / name, os.X_OK) and python in head, (name, text)


def test_make_setup_made_the_editable_install_an_ament_package():
    """After `make`'s set-up the venv holds the ament index marker, share/impact_damper_sim
    linked to this checkout and lib/impact_damper_sim launchers; ament_index_python finds it."""
    if not _editable():
        pytest.skip(f'{PKG} is not installed editable from {ROOT} in this Python')
    prefix = Path(sys.prefix)
    if not (prefix / 'share' / 'ament_index' / 'resource_index' / 'packages' / PKG).is_file():
        pytest.fail(f'{PKG} is not in the ament index of {prefix}: run `make` (the '
                    f'.venv/.installed rule runs tools/ament_develop.py)', pytrace=False)
    _check_layout(prefix, str(prefix / 'bin' / 'python'))
    pytest.importorskip('ament_index_python')
    env = dict(os.environ, AMENT_PREFIX_PATH=str(prefix))
    proc = subprocess.run(
        [sys.executable, '-c', 'from ament_index_python.packages import '
         f'get_package_share_directory as g; print(g({PKG!r}))'],
        env=env, capture_output=True, text=True, timeout=60)
    assert proc.stdout.strip() == str(prefix / 'share' / PKG), proc.stderr


@pytest.mark.parametrize('prefix_name', ['prefix', 'a prefix with spaces'])
def test_ament_develop_installs_setup_pys_layout(tmp_path, prefix_name):
    """tools/ament_develop.py writes what setup.py's data_files and colcon's lib/ hold, as
    links; its launchers run the entry points with the given Python (a path with spaces
    too); it is idempotent and removes launchers of scripts that are gone."""
    if not _editable():
        pytest.skip(f'{PKG} is not installed editable from {ROOT} in this Python')
    prefix = tmp_path / prefix_name
    stale = prefix / 'lib' / PKG / 'old_tool'
    stale.parent.mkdir(parents=True)
    stale.write_text('#!/bin/sh\n# Written by tools/ament_develop.py for `ros2 run '
                     f'{PKG}`:\n')
    python = sys.executable
    if ' ' in prefix_name:   # a Python whose path cannot be a #! line: the /bin/sh trick
        wrapper = prefix / 'bin' / 'python'
        wrapper.parent.mkdir()
        wrapper.write_text(f'#!/bin/sh\nexec "{sys.executable}" "$@"\n')
        wrapper.chmod(0o755)
        python = str(wrapper)
    for _ in range(2):
        proc = subprocess.run([sys.executable, str(ROOT / 'tools' / 'ament_develop.py'),
                               '--prefix', str(prefix), '--python', python],
                              capture_output=True, text=True, timeout=60)
        assert proc.returncode == 0, proc.stderr
    assert not stale.exists()
    _check_layout(prefix, python)
    run = subprocess.run([str(prefix / 'lib' / PKG / 'study'), 'keys'], capture_output=True,
                         text=True, timeout=120)
    assert run.returncode == 0 and 'impactors' in run.stdout, run.stderr


def test_ament_develop_refuses_without_the_package(tmp_path):
    """Run by a Python without the package, it says so in one line (exit status not 0)."""
    python = shutil.which('python3')
    if python is None or Path(python).resolve() == Path(sys.executable).resolve():
        pytest.skip('no other python3 on the PATH')
    probe = subprocess.run([python, '-c', f'import importlib.metadata as m; '
                            f'm.distribution({PKG!r})'], capture_output=True, timeout=60,
                           cwd=tmp_path)
    if probe.returncode == 0:
        pytest.skip(f'{python} has {PKG} installed')
    proc = subprocess.run([python, str(ROOT / 'tools' / 'ament_develop.py'), '--prefix',
                           str(tmp_path)], capture_output=True, text=True, timeout=60,
                          cwd=tmp_path)
    assert proc.returncode != 0
    assert 'not installed' in proc.stderr and 'Traceback' not in proc.stderr, proc.stderr
