"""The three learning-side ROS 2 nodes and what they share: conversions, parameters, QoS.

Imported before numpy by every node's entry point, so the default set here holds in each
node process: one BLAS thread unless the user's environment sets its own. The GP step is
memory-bound, and a BLAS thread per core fights the simulator and the other nodes for the
cores (``benchmarks/bench_sela_step.py``: one thread is faster idle and under load).
"""
import os

for _variable in ('OPENBLAS_NUM_THREADS', 'OMP_NUM_THREADS', 'MKL_NUM_THREADS'):
    os.environ.setdefault(_variable, '1')
