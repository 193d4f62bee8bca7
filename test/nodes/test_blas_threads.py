"""The nodes' entry points run numpy's BLAS on one thread unless the user names a number."""
import json
import os
import subprocess
import sys

PROBE = ('import json, threadpoolctl, sela_ros.nodes.adapter_node; '
         'print(json.dumps([p["num_threads"] for p in threadpoolctl.threadpool_info() '
         'if p["user_api"] == "blas"]))')


def _blas_threads(**env_vars):
    env = {k: v for k, v in os.environ.items()
           if k not in ('OPENBLAS_NUM_THREADS', 'OMP_NUM_THREADS', 'GOTO_NUM_THREADS')}
    env.update(env_vars)
    out = subprocess.run([sys.executable, '-c', PROBE], env=env, capture_output=True,
                         text=True, timeout=120, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_a_node_process_runs_blas_on_one_thread_by_default():
    threads = _blas_threads()
    assert threads, 'numpy loaded no BLAS that threadpoolctl sees'
    assert all(t == 1 for t in threads), threads


def test_the_users_own_thread_count_is_kept():
    assert all(t == 2 for t in _blas_threads(OPENBLAS_NUM_THREADS='2'))
