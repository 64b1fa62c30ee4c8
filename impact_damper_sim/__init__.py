"""impact_damper_sim: impact-damper vibration simulation for rotating machinery.

The core (``fem``, ``modal``, ``dampers``, ``integrate``, ``scene``) never imports rclpy;
``impact_damper_sim.ros`` holds the thin ROS 2 node adapters. Importing the package points
Numba's cache at a per-user directory unless ``NUMBA_CACHE_DIR`` is set (:mod:`._cache_dir`).
"""
from ._cache_dir import use_user_cache

__version__ = '0.1.0'

use_user_cache()
