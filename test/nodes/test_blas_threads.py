"""Each node process runs one BLAS thread unless the user's environment says otherwise."""
import json
import os
import subprocess
import sys

import pytest

PROBE = ('import sela_ros.nodes.adapter_node, threadpoolctl, json; '
         'print(json.dumps([i["num_threads"] for i in threadpoolctl.threadpool_info() '
         'if i["user_api"] == "blas"]))')


def _blas_threads(**env):
    clean = {k: v for k, v in os.environ.items()
             if k not in ('OPENBLAS_NUM_THREADS', 'OMP_NUM_THREADS', 'MKL_NUM_THREADS')}
    out = subprocess.run([sys.executable, '-c', PROBE], env={**clean, **env},
                         capture_output=True, text=True, timeout=120, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.skipif(os.cpu_count() < 2, reason='one core: one BLAS thread whatever is set')
def test_a_node_runs_one_blas_thread_by_default_and_the_users_setting_is_kept():
    default = _blas_threads()  # numpy's and scipy's BLAS
    assert default and set(default) == {1}, default
    assert set(_blas_threads(OPENBLAS_NUM_THREADS='2')) == {2}
