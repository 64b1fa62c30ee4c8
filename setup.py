"""ament_python package setup for impact_damper_sim."""
from pathlib import Path

from setuptools import find_packages, setup

package_name = 'impact_damper_sim'
here = Path(__file__).resolve().parent


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
    packages=find_packages(exclude=['test', 'test.*', 'bench', 'bench.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/launch', sorted(str(p.relative_to(here)) for p in
                                                     (here / 'launch').glob('*.launch.py'))),
        *_config_files(),
    ],
    install_requires=['setuptools', 'numpy', 'scipy', 'numba', 'pyyaml'],
    # plots: study --plot and the validation/convergence figures; dask: parallel sweeps
    extras_require={'test': ['pytest'], 'plots': ['matplotlib'],
                    'dask': ['dask[distributed]']},
    zip_safe=False,
    maintainer='impact_damper_sim developers',
    maintainer_email='dev@impact-damper-sim.invalid',
    description='Impact-damper vibration simulation for rotating machinery, with ROS 2 nodes.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'study = impact_damper_sim.cli.study:main',
            'vibration_node = impact_damper_sim.ros.vibration_node:main',
            'monitor = impact_damper_sim.ros.monitor:main',
            'replay = impact_damper_sim.ros.replay:main',
        ],
    },
)
