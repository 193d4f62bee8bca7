"""The learning core: numpy/scipy only, no ROS, nothing above it.

Its subpackages, bottom up (imports only go down, ``test/test_layers.py``):
:mod:`~sela_ros.core.validation` (checks at the edge: numbers, outcomes),
:mod:`~sela_ros.core.storage` (the archive, the state file, atomic writes),
:mod:`~sela_ros.core.planning` (occupancy grids, maps, the reward selection layer),
:mod:`~sela_ros.core.detection` (has the robot changed?),
:mod:`~sela_ros.core.learning` (GPs, UCB, SELA, damage priors, fall risk),
:mod:`~sela_ros.core.mission` (the step cycle, in process or driven by the adapter node);
:mod:`~sela_ros.core.geometry` (planar geometry) under them all.

The robot's sizes (gait parameters, descriptor dimensions) are the archive's: the core holds
no robot's constants.
"""
