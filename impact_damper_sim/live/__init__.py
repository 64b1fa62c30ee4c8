"""The ROS-free live core of the nodes: stepping a scene in chunks against the wall clock
(:mod:`.realtime`) and what a scene streams (:mod:`.streams`), streaming anti-alias filters
and decimators (:mod:`.filters`), the rolling vibration statistics the monitor node publishes
(:mod:`.monitoring`, with their spectral estimate in :mod:`.spectrum`) and the pacing of a
replayed log (:mod:`.playback`). Nothing here imports rclpy; the adapters in
:mod:`impact_damper_sim.ros` own these objects."""
