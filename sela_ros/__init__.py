"""sela_ros: the Semi-Episodic Learning Algorithm (SELA) for damage recovery, on ROS 2.

Subpackages are layers; imports only go down (a test checks it):

- ``core``: GP, acquisition, SELA, planning, archive, detection, mission, persistence
  (numpy/scipy only, no ROS);
- ``qd``: map building (MAP-Elites) over the core's archive;
- ``experiments``: toy world, baselines, scenarios, figures and the ``sela-experiment`` CLI;
- ``nodes``: the three learning-side ROS 2 nodes and the conversions they share;
- ``tools``: the demo, the archive builder, recording.

The simulator and its node are the sibling package ``sim_bridge``.
"""

__version__ = '0.1.0'
