"""ament_python package setup for impact_damper_sim."""
from pathlib import Path

from setuptools import find_packages, setup
from setuptools.command.install_scripts import install_scripts as _install_scripts

package_name = 'impact_damper_sim'
here = Path(__file__).resolve().parent

# Console scripts. pip puts them on the PATH (<prefix>/bin), where generic names such as
# `monitor` or `replay` would clash with other tools, so there they carry the package's prefix
# (impact_damper_monitor, impact_damper_replay, impact_damper_study, impact_damper_plant_host,
# impact_damper_recorder; vibration_node is already specific). `ros2 run impact_damper_sim NAME`
# runs <prefix>/lib/impact_damper_sim/NAME, off the PATH: there they are installed under their
# short names (monitor, replay, study, plant_host, recorder, vibration_node), by colcon through
# the commands below and, for the editable install of `make`, by tools/ament_develop.py.
SCRIPT_PREFIX = 'impact_damper_'


def ros2_run_name(script_name):
    """The name ``ros2 run`` knows a console script by: without the ``impact_damper_`` prefix."""
    return script_name[len(SCRIPT_PREFIX):] if script_name.startswith(SCRIPT_PREFIX) \
        else script_name


def _ament_layout(directory):
    """True when ``directory`` is ``<prefix>/lib/<package>``, where ``ros2 run`` looks."""
    return directory is not None and Path(directory).parts[-2:] == ('lib', package_name)


class install_scripts(_install_scripts):
    """``setup.py install`` (colcon build): short names in ``lib/<package>/``."""

    def write_script(self, script_name, *args, **kwargs):
        if _ament_layout(self.install_dir):
            script_name = ros2_run_name(script_name)
        return super().write_script(script_name, *args, **kwargs)


cmdclass = {'install_scripts': install_scripts}
try:   # `setup.py develop` (colcon build --symlink-install) with the setuptools colcon uses
    from setuptools.command.develop import develop as _develop
except ImportError:   # pragma: no cover - setuptools without develop
    _develop = None
if _develop is not None and hasattr(_develop, 'write_script'):
    class develop(_develop):
        """``setup.py develop`` (``colcon build --symlink-install``): short names in
        ``lib/<package>/``."""

        def write_script(self, script_name, *args, **kwargs):
            if _ament_layout(getattr(self, 'script_dir', None)):
                script_name = ros2_run_name(script_name)
            return super().write_script(script_name, *args, **kwargs)

    cmdclass['develop'] = develop


def _config_files():
    """Return (install_dir, [files]) pairs for everything under config/."""
    pairs = {}
    for path in sorted((here / 'config').rglob('*')):
        if path.is_file():
            rel = path.relative_to(here)
            dest = str(Path('share') / package_name / rel.parent)
            pairs.setdefault(dest, []).append(str(rel))
    return sorted(pairs.items())


setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*', 'bench', 'bench.*', 'tools', 'tools.*']),
    # tools/ament_develop.py installs the same layout (as links) for the editable install
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/launch', sorted(str(p.relative_to(here)) for p in
                                                     (here / 'launch').glob('*.launch.py'))),
        *_config_files(),
    ],
    # what the package imports outside the standard library and ROS (ROS packages: package.xml;
    # test/test_dependencies.py checks both). mcap: recording, replay, study report/recover;
    # mcap-ros2-support: study report
    install_requires=['setuptools', 'numpy', 'scipy', 'numba', 'llvmlite', 'pyyaml', 'mcap',
                      'mcap-ros2-support'],
    # plots: study --plot and the validation/convergence figures; dask: parallel sweeps
    extras_require={'test': ['pytest'], 'plots': ['matplotlib'],
                    'dask': ['dask[distributed]']},
    zip_safe=False,
    maintainer='impact_damper_sim developers',
    maintainer_email='dev@impact-damper-sim.invalid',
    description='Impact-damper vibration simulation for rotating machinery, with ROS 2 nodes.',
    license='Apache-2.0',
    cmdclass=cmdclass,
    entry_points={
        'console_scripts': [
            'impact_damper_study = impact_damper_sim.cli.study:main',
            'vibration_node = impact_damper_sim.ros.vibration_node:main',
            'impact_damper_monitor = impact_damper_sim.ros.monitor:main',
            'impact_damper_replay = impact_damper_sim.ros.replay:main',
            # several machines (VibrationNode instances) in one process, one executor
            'impact_damper_plant_host = impact_damper_sim.ros.plant_host:main',
            # records the batch topics of a plant's machines into one log or one each
            'impact_damper_recorder = impact_damper_sim.ros.recorder:main',
        ],
    },
)
