"""sela_ros: the Semi-Episodic Learning Algorithm (SELA) for damage recovery, on ROS 2.

The learning core (Gaussian processes, UCB, archive, MAP-Elites, A*, the SELA loop, the toy
world, baselines, experiments) imports numpy/scipy only; the ``*_node`` modules are thin ROS
adapters over it.
"""

__version__ = '0.1.0'
