"""The ROS-free live core of the nodes: stepping a scene in chunks against the wall clock
(:mod:`.realtime`), streaming anti-alias filters and decimators (:mod:`.filters`) and the
rolling vibration statistics the monitor node publishes (:mod:`.monitoring`). Nothing here
imports rclpy; the adapters in :mod:`impact_damper_sim.ros` own these objects."""
