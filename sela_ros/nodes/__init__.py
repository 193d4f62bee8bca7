"""The learning-side ROS 2 nodes and what they share: conversions, parameters, QoS.

Importing this package (every node's entry point does, before numpy is loaded) sets one
BLAS thread unless the environment names a number: the GPs' (N, M) products are
memory-bound, and BLAS threads fight the simulator and the other nodes for the cores
(docs/benchmarks.md). ``OPENBLAS_NUM_THREADS`` set by the user is kept.
"""
import os

os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')
