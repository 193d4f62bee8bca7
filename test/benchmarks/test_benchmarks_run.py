"""Every benchmark runs, at a tiny size, and prints its figures (never an assertion on them:
figures are read, not tested). ``make bench`` runs them all at their own sizes."""
import os
import subprocess
import sys
from pathlib import Path

import pytest
from archive_fixtures import tiny_archive

ROOT = Path(__file__).resolve().parents[2]
BENCHMARKS = ROOT / 'benchmarks'

pytestmark = pytest.mark.slow

# benchmark -> (its arguments at a tiny size, what its figures' lines say). {tiny}: a
# synthetic archive of 8 gaits.
TINY = {
    'bench_detection_policy': (['--replicates', '1', '--max-steps', '2', '--scenarios', '1'],
                               ['middle_right removed', 'evidence']),
    'bench_hexapod': (['--gaits', '2', '--repeats', '1', '--workers', '1'],
                      ['real-time factor', 'speed-up']),
    'bench_hexapod_experiment': (['--archive', '{tiny}', '--replicates', '1', '--workers', '1',
                                  '--max-steps', '2', '--methods', 'sela,oracle'],
                                 ['ms/gait', 'extrapolated 50-replicate wall time']),
    'bench_map_elites': (['--evals', '400', '--gaits', '2', '--workers', '1'],
                         ['evals/s', 'gaits/s']),
    'bench_physics': (['--random', '1', '--elites', '1', '--reference', '1'],
                      ['evaluations/s per core']),
    'bench_planning': (['--sizes', '100', '--steps', '2', '--astar-steps', '1'],
                       ['| 100 x 100 |']),
    'bench_restarts': (['--goals', '1', '--seeds', '0', '--damages', 'remove:middle_right'],
                       ['false restarts:']),
    'bench_sela_step': (['--toy-replicates', '0', '--max-candidates', '1000', '--tables', '0'],
                        ['1000 candidates', 'shipped 8-D map']),
    'bench_sela_step interleaved': (['--interleave', '1', '--mean-affine', '0.5',
                                     '--mean-descriptor', '1.0'],
                                    ['round 1/1, given', 'defaults: median', 'given: median']),
    'bench_sela_step progress': (['--interleave-progress', '1.0', '--rounds', '1'],
                                 ['round 1/1, acquisition.progress 1.0',
                                  "acquisition.progress 1.0: median of the rounds' medians"]),
    'bench_state_file': (['--observations', '20'], ['20 observations', 'taken back in']),
}
#: Over DDS, the four nodes: test/dds/test_bench_ros.py.
DDS_BENCHMARK = 'bench_ros'


def run_benchmark(name, args, tmp_path):
    """Run ``benchmarks/<name>.py args``; returns what it printed (it must end well)."""
    args = [str(tiny_archive(tmp_path / 'tiny.npz')) if a == '{tiny}' else a for a in args]
    script = BENCHMARKS / f"{name.split()[0]}.py"
    done = subprocess.run([sys.executable, str(script), *args], cwd=ROOT, env=dict(
        os.environ, OPENBLAS_NUM_THREADS='1'), capture_output=True, text=True, timeout=280)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    return done.stdout


def test_every_benchmark_has_a_smoke_run_and_make_bench_runs_it():
    sys.path.insert(0, str(BENCHMARKS))
    from run_all import BENCHMARKS as RUN_ALL
    scripts = {p.stem for p in BENCHMARKS.glob('bench_*.py')}
    assert scripts == {*(n.split()[0] for n in TINY), DDS_BENCHMARK}
    assert {n.split()[0] for n in RUN_ALL} == scripts


@pytest.mark.parametrize('name', sorted(TINY))
def test_a_benchmark_runs_at_a_tiny_size_and_prints_its_figures(name, tmp_path):
    args, says = TINY[name]
    out = run_benchmark(name, args, tmp_path)
    print(out)
    for text in says:
        assert text in out, out
