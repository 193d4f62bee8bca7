"""The three learning-side ROS 2 nodes and what they share: conversions, parameters, QoS."""
