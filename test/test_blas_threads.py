"""Each node process and ``sela-experiment`` run one BLAS thread unless the user's
environment says otherwise."""
import json
import os
import subprocess
import sys

import pytest

from sela_ros import BLAS_THREAD_VARIABLES

PROBE = ('import {module}, scipy.linalg, threadpoolctl, json; '
         'print(json.dumps([i["num_threads"] for i in threadpoolctl.threadpool_info() '
         'if i["user_api"] == "blas"]))')


def _blas_threads(module, **env):
    clean = {k: v for k, v in os.environ.items() if k not in BLAS_THREAD_VARIABLES}
    out = subprocess.run([sys.executable, '-c', PROBE.format(module=module)],
                         env={**clean, **env},
                         capture_output=True, text=True, timeout=120, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.skipif(os.cpu_count() < 2, reason='one core: one BLAS thread whatever is set')
@pytest.mark.parametrize('module', ['sela_ros.nodes.adapter_node', 'sela_ros.experiments.cli'])
def test_one_blas_thread_by_default_and_the_users_setting_kept(module):
    default = _blas_threads(module)  # numpy's and scipy's BLAS
    assert default and set(default) == {1}, default
    assert set(_blas_threads(module, OPENBLAS_NUM_THREADS='2')) == {2}
