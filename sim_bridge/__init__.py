"""sim_bridge: the PyBullet hexapod (usable without ROS) and its ROS node."""
