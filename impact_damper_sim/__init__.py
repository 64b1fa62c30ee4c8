"""impact_damper_sim: impact-damper vibration simulation for rotating machinery.

The core (``fem``, ``modal``, ``dampers``, ``integrate``, ``scene``) never imports rclpy;
``impact_damper_sim.ros`` holds the thin ROS 2 node adapters. Importing the package points
Numba's cache at a per-user directory unless ``NUMBA_CACHE_DIR`` is set (:mod:`._cache_dir`).

Quick tour (SI units throughout; ``study --help`` is the same from the command line). Load a
shipped scene by name (or a YAML file by path), with its modal model:

>>> import numpy as np
>>> from impact_damper_sim.scene.build import load
>>> model = load('sdof')
>>> model
SceneModel('sdof', 1 modes, 1 impactors, source='...sdof.yaml')
>>> [round(f, 3) for f in model.basis.frequencies_hz.tolist()]     # natural frequencies (Hz)
[25.165]

Run it from rest for 0.5 s at the scene's method and sample period (``dt`` = 0.1 ms): the
impactor first reaches a wall at 0.208 s, and every impact is an impulse the averaged
acceleration shows as a 97 g spike (the scene file's comment says why):

>>> sim = model.make_simulation()
>>> samples = sim.advance_to(0.5)           # sensor outputs every dt up to t = 0.5 s
>>> samples.displacement.shape, sim.sensor_names
((5000, 1), ('primary',))
>>> events = sim.take_events()              # impacts (sticks, releases) since the last call
>>> len(events), f"first at {events['t'][0]:.4f} s"
(17, 'first at 0.2080 s')
>>> f'{np.abs(sim.mean_acceleration(samples)).max() / 9.80665:.0f} g'
'97 g'
>>> bool(abs(sim.energy().relative_residual) < 1e-9)     # the energy ledger closes
True

``study record`` writes the same run as the ROS 2 node's MCAP log, and
:class:`impact_damper_sim.studies.log_reader.RosLog` reads one back (an example there).
"""
from ._cache_dir import use_user_cache

__version__ = '0.1.0'

use_user_cache()
