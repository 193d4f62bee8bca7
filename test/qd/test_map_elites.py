"""MAP-Elites: grid insertion, emitter determinism, executors, checkpoints and SIGKILL resume."""
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from sela_ros.core.storage import load_archive
from sela_ros.qd.emitter import MapElitesEmitter
from sela_ros.qd.evaluators import EvaluationResult, SyntheticEvaluator, arc_fitness
from sela_ros.qd.executors import DaskEvaluator, ProcessPoolEvaluator, SerialEvaluator
from sela_ros.qd.grid_archive import GridArchive
from sela_ros.qd.map_elites import MapElites, default_run

REPO = Path(__file__).resolve().parents[2]


def test_grid_rejects_bad_shapes():
    with pytest.raises(ValueError, match='one \\(low, high\\) pair per dimension'):
        GridArchive((4, 4), [(0, 1)])
    with pytest.raises(ValueError, match='low < high'):
        GridArchive((4, 4), [(0, 1), (1, 0)])
    with pytest.raises(ValueError, match='positive cell counts'):
        GridArchive((0, 4), [(0, 1), (0, 1)])


def test_grid_keeps_best_per_cell():
    grid = GridArchive((4, 4), [(0, 1), (0, 1)], solution_dim=2)
    gr = np.zeros((4, 3))
    sols = np.array([[0.1, 0.1], [0.2, 0.2], [0.3, 0.3], [0.4, 0.4]])
    # three candidates in the same cell (0.1, 0.1); the middle one is best.
    meas = np.array([[0.1, 0.1], [0.12, 0.1], [0.1, 0.15], [0.9, 0.9]])
    status = grid.add(sols, [-1.0, -0.2, -0.5, -3.0], meas, generic_reward=gr)
    assert status.tolist() == [2, 1, 0, 2]
    assert grid.num_elites == 2
    cell = grid.index_of([[0.1, 0.1]])[0]
    assert grid.objectives[cell] == -0.2
    np.testing.assert_array_equal(grid.solutions[cell], [0.2, 0.2])
    # worse later: not added; better later: replaces
    assert grid.add([[0.5, 0.5]], [-0.3], [[0.05, 0.05]], generic_reward=gr[:1])[0] == 0
    assert grid.add([[0.6, 0.6]], [-0.1], [[0.05, 0.05]], generic_reward=gr[:1])[0] == 1
    np.testing.assert_array_equal(grid.solutions[cell], [0.6, 0.6])
    # non-finite objective (a fall) is rejected; out-of-bounds goes to the edge cell
    assert grid.add([[0.7, 0.7]], [-np.inf], [[0.5, 0.5]], generic_reward=gr[:1])[0] == 0
    assert grid.index_of([[5.0, -5.0]])[0] == grid.index_of([[0.99, 0.0]])[0]


def test_arc_fitness():
    # straight forward, straight backward, quarter circle to the left: all perfect arcs
    gr = np.array([[0.5, 0.0, 0.0], [-0.5, 0.0, 0.0], [0.3, 0.3, np.pi / 2]])
    np.testing.assert_allclose(arc_fitness(gr), 0.0, atol=1e-12)
    # forward but turned by 1 rad: off the arc by 1 rad
    assert arc_fitness([0.5, 0.0, 1.0]) == pytest.approx(-1.0)
    assert arc_fitness([0.5, 0.0, np.pi]) == pytest.approx(-np.pi)


def _emitter(seed, variation='iso_line'):
    grid = GridArchive((8, 8), [(-1, 1), (-1, 1)])
    evaluate = SyntheticEvaluator()
    emitter = MapElitesEmitter(grid, batch_size=20, n_initial=40, variation=variation, seed=seed)
    batches = []
    for _ in range(5):
        sols = emitter.ask()
        results = [evaluate(s) for s in sols]
        grid.add(sols, [r.fitness for r in results], [r.descriptor for r in results],
                 generic_reward=[r.generic_reward for r in results])
        batches.append(sols)
    return np.concatenate(batches)


@pytest.mark.parametrize('variation', ['iso_line', 'polynomial'])
def test_emitter_is_deterministic_with_seed(variation):
    a, b, c = _emitter(3, variation), _emitter(3, variation), _emitter(4, variation)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    assert a.min() >= 0.0 and a.max() <= 1.0


def test_emitter_rejects_bad_arguments():
    grid = GridArchive((8, 8), [(-1, 1), (-1, 1)])
    with pytest.raises(ValueError, match='variation must be one of'):
        MapElitesEmitter(grid, variation='gaussian')
    with pytest.raises(ValueError, match='batch_size'):
        MapElitesEmitter(grid, batch_size=0)


def _run(executor, n=400, **kwargs):
    run = default_run(SyntheticEvaluator(), dims=(16, 16), batch_size=50, seed=7,
                      executor=executor, **kwargs)
    run.run(n, progress=False)
    return run


def _assert_same(a: MapElites, b: MapElites):
    assert a.n_evaluations == b.n_evaluations
    for key, value in a.archive.state_dict().items():
        np.testing.assert_array_equal(value, b.archive.state_dict()[key], err_msg=key)


def test_run_fills_archive_and_discards_falls():
    run = _run(SerialEvaluator(), n=1000)
    assert run.n_evaluations == 1000
    assert run.archive.num_elites > 50
    assert np.all(np.isfinite(run.archive.objectives[run.archive.occupied]))
    archive = run.to_archive(**SyntheticEvaluator().settings(), descriptor_name='final_xy',
                             fitness_name='arc_yaw_error')
    assert len(archive) == run.archive.num_elites
    assert archive.metadata['n_evaluations'] == 1000


def test_process_pool_matches_serial():
    serial = _run(SerialEvaluator())
    with ProcessPoolEvaluator(workers=2) as pool:
        pooled = _run(pool)
    _assert_same(serial, pooled)


@pytest.mark.slow
def test_dask_local_cluster_matches_serial():
    try:  # a declared dependency (requirements-qd.txt): its absence is a failure
        import distributed
    except ImportError:
        pytest.fail('Dask is not installed: pip install -r requirements-qd.txt (rosdep does '
                    'not install it)')
    serial = _run(SerialEvaluator())
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  host='127.0.0.1', dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        dask = _run(DaskEvaluator(client=client))
    _assert_same(serial, dask)


def test_checkpoint_resume_in_process(tmp_path):
    full = _run(SerialEvaluator(), n=600)
    ckpt = tmp_path / 'ck.npz'
    part = _run(SerialEvaluator(), n=250, checkpoint_path=ckpt, checkpoint_every=2)
    assert part.n_evaluations == 250
    resumed = MapElites.resume(ckpt, SyntheticEvaluator(), SerialEvaluator(),
                               checkpoint_every=2)
    assert resumed.n_evaluations == 250
    resumed.run(600, progress=False)
    _assert_same(full, resumed)


def test_journal_replays_batches_after_last_checkpoint(tmp_path):
    ckpt = tmp_path / 'ck.npz'
    run = default_run(SyntheticEvaluator(), dims=(16, 16), batch_size=50, seed=7,
                      checkpoint_path=ckpt, checkpoint_every=4)
    for _ in range(7):  # checkpoint after batch 4, batches 5-7 journalled only
        run.step()
    assert len(list(run.journal_dir.glob('batch_*.npz'))) == 3
    resumed = MapElites.resume(ckpt, SyntheticEvaluator(), checkpoint_every=4)
    assert resumed.n_batches == 7 and resumed.n_evaluations == 350
    _assert_same(run, resumed)
    resumed.step()  # batch 8: a checkpoint, which prunes the journal
    assert not list(run.journal_dir.glob('batch_*.npz'))


def test_resume_rejects_garbage(tmp_path):
    path = tmp_path / 'ck.npz'
    path.write_bytes(b'garbage')
    with pytest.raises(ValueError, match='cannot resume'):
        MapElites.resume(path, SyntheticEvaluator())


def test_invalid_results_are_counted():
    grid = GridArchive((4, 4), [(-1, 1), (-1, 1)])
    run = MapElites(grid, MapElitesEmitter(grid, batch_size=2, seed=0), SyntheticEvaluator())
    sols = run.ask()
    run.tell(sols, [EvaluationResult(False, 0.0, np.zeros(2), np.zeros(3)),
                    EvaluationResult(True, -0.1, np.zeros(2), np.zeros(3))])
    assert run.n_invalid == 1 and grid.num_elites == 1


def _cli(out, ckpt, *extra):
    return [sys.executable, '-m', 'sela_ros.tools.build_archive', '--synthetic',
            '--synthetic-delay', '0.004', '--evaluations', '1500', '--batch-size', '50',
            '--workers', '1', '--seed', '5', '--grid', '16', '16', '--bounds', '-1', '1', '-1',
            '1', '--checkpoint-every', '3', '--checkpoint', str(ckpt), '--out', str(out),
            '--no-progress', *extra]


@pytest.mark.slow
def test_sigkill_then_resume_matches_uninterrupted(tmp_path):
    env = dict(os.environ, PYTHONPATH=str(REPO))
    reference = tmp_path / 'ref.npz'
    subprocess.run(_cli(reference, tmp_path / 'ref_ck.npz'), check=True, cwd=REPO, env=env,
                   timeout=120, capture_output=True)

    out, ckpt = tmp_path / 'killed.npz', tmp_path / 'killed_ck.npz'
    proc = subprocess.Popen(_cli(out, ckpt), cwd=REPO, env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    journal = Path(str(ckpt) + '.journal')
    deadline = time.monotonic() + 60
    # kill once a checkpoint and at least one journalled batch after it exist
    while time.monotonic() < deadline:
        if ckpt.exists() and journal.is_dir() and any(journal.glob('batch_*.npz')):
            break
        assert proc.poll() is None, 'the run ended before it could be killed'
        time.sleep(0.01)
    else:
        proc.kill()
        pytest.fail('no checkpoint within 60 s')
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(timeout=10)
    assert proc.returncode == -signal.SIGKILL
    assert not out.exists()

    killed_at = MapElites.resume(ckpt, SyntheticEvaluator())
    assert 0 < killed_at.n_evaluations < 1500
    subprocess.run(_cli(out, ckpt, '--resume'), check=True, cwd=REPO, env=env, timeout=120,
                   capture_output=True)
    a, b = load_archive(reference), load_archive(out)
    assert a.metadata['n_evaluations'] == b.metadata['n_evaluations'] == 1500
    for key in ('params', 'descriptors', 'generic_reward', 'fitness'):
        np.testing.assert_array_equal(getattr(a, key), getattr(b, key))


def test_cli_usage_errors(tmp_path):
    for args in (['--evaluations', '0', '--out', str(tmp_path / 'a.npz')],
                 ['--evaluations', '10', '--out', str(tmp_path / 'a.npz'),
                  '--bounds', '1', '0', '0', '1'],
                 ['--evaluations', '10'],
                 ['--evaluations', '10', '--out', str(tmp_path / 'a.npz'), '--resume']):
        proc = subprocess.run([sys.executable, '-m', 'sela_ros.tools.build_archive', '--synthetic',
                               *args], cwd=REPO, capture_output=True, text=True, timeout=60,
                              env=dict(os.environ, PYTHONPATH=str(REPO)))
        assert proc.returncode == 2, (args, proc.stderr)
        assert 'usage: sela-build-archive' in proc.stderr


def test_cli_writes_archive_and_figure(tmp_path):
    from sela_ros.tools.build_archive import main

    out, fig = tmp_path / 'a.npz', tmp_path / 'a.png'
    assert main(['--synthetic', '--evaluations', '600', '--batch-size', '100', '--workers', '1',
                 '--out', str(out), '--figure', str(fig), '--no-progress',
                 '--bounds', '-1', '1', '-1', '1']) == 0
    archive = load_archive(out, expected_settings=SyntheticEvaluator().settings())
    assert archive.metadata['n_evaluations'] == 600
    assert archive.metadata['descriptor_name'] == 'final_xy'
    assert fig.stat().st_size > 10_000
