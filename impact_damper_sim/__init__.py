"""impact_damper_sim: impact-damper vibration simulation for rotating machinery.

The core (``fem``, ``modal``, ``dampers``, ``integrate``, ``scene``) never imports rclpy;
``impact_damper_sim.ros`` holds the thin ROS 2 node adapters.
"""
__version__ = '0.1.0'
