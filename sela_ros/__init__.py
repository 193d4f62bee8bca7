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

import os

__version__ = '0.1.0'

#: The thread-count variables of the BLAS libraries numpy and scipy are built on.
BLAS_THREAD_VARIABLES = ('OPENBLAS_NUM_THREADS', 'OMP_NUM_THREADS', 'MKL_NUM_THREADS')


def single_blas_thread():
    """One BLAS thread per process unless the environment sets its own: called by the
    nodes and ``sela-experiment`` before numpy is loaded. SELA's products are memory-bound,
    and a BLAS thread per core fights the simulator and the other processes for the cores
    (``benchmarks/bench_sela_step.py``; docs/ros.md has the figures)."""
    for variable in BLAS_THREAD_VARIABLES:
        os.environ.setdefault(variable, '1')
