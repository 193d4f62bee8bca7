"""The DDS benchmark runs, at a tiny size, and prints its figures (never an assertion on
them): the ROS overhead per step of a mission of a step or two, and a long run of three."""
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'benchmarks'))
from test_benchmarks_run import run_benchmark  # noqa: E402

pytestmark = [pytest.mark.dds, pytest.mark.slow]

TINY = {
    'overhead': (['--rounds', '1', '--goal', '0.6', '0.0'],
                 ['round 1:', 'same decisions', 'ROS overhead per step:']),
    'long': (['--steps', '3'], ['consecutive gaits over DDS', 'memory (RSS, MB) at step']),
}


@pytest.mark.parametrize('mode', sorted(TINY))
def test_bench_ros_runs_at_a_tiny_size_and_prints_its_figures(mode, tmp_path):
    args, says = TINY[mode]
    out = run_benchmark('bench_ros', [mode, *args], tmp_path)
    print(out)
    for text in says:
        assert text in out, out
