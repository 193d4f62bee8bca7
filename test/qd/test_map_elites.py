"""The 2-D map with pyribs: grid insertion, determinism, executors, checkpoints and SIGKILL
resume, and a build that SELA takes.

pyribs is a map-builder extra (requirements-qd.txt) that `make venv` installs: without it
these tests fail, they never skip."""
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from killed_build import sigkill_once_journalled

from sela_ros.core.storage import load_archive
from sela_ros.qd.evaluators import EvaluationResult, SyntheticEvaluator, arc_fitness
from sela_ros.qd.executors import DaskEvaluator, ProcessPoolEvaluator, SerialEvaluator
from sela_ros.qd.map_elites import GridMapElites, default_run

REPO = Path(__file__).resolve().parents[2]


def test_grid_rejects_bad_shapes():
    evaluate = SyntheticEvaluator()
    with pytest.raises(ValueError, match='one \\(low, high\\) pair per dimension'):
        GridMapElites((4, 4), [(0, 1)], evaluate)
    with pytest.raises(ValueError, match='low < high'):
        GridMapElites((4, 4), [(0, 1), (1, 0)], evaluate)
    with pytest.raises(ValueError, match='positive cell counts'):
        GridMapElites((0, 4), [(0, 1), (0, 1)], evaluate)
    with pytest.raises(ValueError, match='batch_size'):
        GridMapElites((4, 4), [(0, 1), (0, 1)], evaluate, batch_size=0)


def _told(run, measures, objectives, valid=None):
    """Ask a batch of len(measures) and tell these results for it."""
    solutions = run.ask()
    assert len(solutions) == len(measures)
    valid = [True] * len(measures) if valid is None else valid
    return run.tell(solutions, [EvaluationResult(v, f, np.asarray(m, float), np.zeros(3))
                                for v, f, m in zip(valid, objectives, measures)])


def test_grid_keeps_the_best_per_cell_and_no_fall():
    run = GridMapElites((4, 4), [(0, 1), (0, 1)], SyntheticEvaluator(), batch_size=4,
                        n_initial=4, seed=0)
    # three candidates in the same cell; the middle one is best
    assert _told(run, [[0.1, 0.1], [0.12, 0.1], [0.1, 0.15], [0.9, 0.9]],
                 [-1.0, -0.2, -0.5, -3.0]) == 2
    best = run.archive.retrieve_single([0.1, 0.1])[1]
    assert best['objective'] == pytest.approx(-0.2)
    # a fall (even with a finite fitness) never takes a cell; out of bounds: the edge cell
    assert _told(run, [[0.5, 0.5], [0.6, 0.6], [5.0, -5.0], [0.05, 0.05]],
                 [-0.1, -0.1, -0.1, -0.1], valid=[False, True, True, True]) == 2
    assert run.n_invalid == 1 and run.archive.stats.num_elites == 4
    assert run.archive.retrieve_single([0.1, 0.1])[1]['objective'] == pytest.approx(-0.1)
    assert run.archive.index_of_single([5.0, -5.0]) == run.archive.index_of_single([0.99, 0.0])
    with pytest.raises(ValueError, match='ask'):
        run.tell(np.zeros((4, 36)), [])


def test_arc_fitness():
    # straight forward, straight backward, quarter circle to the left: all perfect arcs
    gr = np.array([[0.5, 0.0, 0.0], [-0.5, 0.0, 0.0], [0.3, 0.3, np.pi / 2]])
    np.testing.assert_allclose(arc_fitness(gr), 0.0, atol=1e-12)
    # forward but turned by 1 rad: off the arc by 1 rad
    assert arc_fitness([0.5, 0.0, 1.0]) == pytest.approx(-1.0)
    assert arc_fitness([0.5, 0.0, np.pi]) == pytest.approx(-np.pi)


def _run(executor, n=400, **kwargs):
    run = default_run(SyntheticEvaluator(), dims=(16, 16), batch_size=50, seed=7,
                      executor=executor, **kwargs)
    run.run(n, progress=False)
    return run


def _elites(run):
    data = run.archive.data()
    order = np.argsort(data['index'])
    return {k: np.asarray(v)[order] for k, v in data.items()}


def _assert_same(a, b):
    assert a.n_evaluations == b.n_evaluations and a.n_batches == b.n_batches
    ea, eb = _elites(a), _elites(b)
    assert ea.keys() == eb.keys()
    for key in ea:
        np.testing.assert_array_equal(ea[key], eb[key], err_msg=key)
    # the same random streams from here on: the next batches are the same
    np.testing.assert_array_equal(a.ask(), b.ask())


def test_run_fills_archive_and_discards_falls():
    run = _run(SerialEvaluator(), n=1000)
    assert run.n_evaluations == 1000 and run.n_invalid > 0
    assert run.archive.stats.num_elites > 50
    archive = run.to_archive(**SyntheticEvaluator().settings(), descriptor_name='final_xy',
                             fitness_name='arc_yaw_error')
    assert len(archive) == run.archive.stats.num_elites
    assert np.all(np.isfinite(archive.fitness)) and archive.fitness.min() >= -np.pi
    assert archive.metadata['n_evaluations'] == 1000
    assert archive.metadata['grid_shape'] == [16, 16]
    # the falls (synthetic: params 0 and 1 above 0.95) never enter the archive
    assert not np.any((archive.params[:, 0] > 0.95) & (archive.params[:, 1] > 0.95))


def test_a_seed_gives_the_same_map_and_another_seed_another():
    a, b = _run(SerialEvaluator()), _run(SerialEvaluator())
    _assert_same(a, b)
    other = default_run(SyntheticEvaluator(), dims=(16, 16), batch_size=50, seed=8)
    other.run(400, progress=False)
    assert not np.array_equal(_elites(a)['solution'], _elites(other)['solution'])


def test_a_small_2d_build_is_an_archive_sela_takes(tmp_path):
    from sela_ros.core.mission import make_sela

    run = default_run(SyntheticEvaluator(), dims=(12, 12), bounds=((-1, 1), (-1, 1)),
                      batch_size=40, n_initial=80, seed=3)
    run.run(400, progress=False)
    path = run.to_archive(**SyntheticEvaluator().settings(), descriptor_name='final_xy',
                          fitness_name='arc_yaw_error').save(tmp_path / 'map.npz')
    archive = load_archive(path, expected_settings=SyntheticEvaluator().settings())
    assert len(archive) == run.archive.stats.num_elites and archive.descriptors.shape[1] == 2
    assert np.all((archive.params >= 0) & (archive.params <= 1))
    sela = make_sela(archive)
    assert sela.config.gp_kernel_sigma == 0.1 and sela.config.planner_horizon == 1
    sela.set_goal([1.0, 0.0])
    decision = sela.ask([0.0, 0.0, 0.0])
    assert 0 <= decision.index < len(archive)


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
    ckpt = tmp_path / 'ck.pkl'
    part = _run(SerialEvaluator(), n=250, checkpoint_path=ckpt, checkpoint_every=2)
    assert part.n_evaluations == 250
    resumed = GridMapElites.resume(ckpt, SyntheticEvaluator(), SerialEvaluator(),
                                   checkpoint_every=2)
    assert resumed.n_evaluations == 250
    resumed.run(600, progress=False)
    _assert_same(full, resumed)


def test_journal_replays_batches_after_last_checkpoint(tmp_path):
    ckpt = tmp_path / 'ck.pkl'
    run = default_run(SyntheticEvaluator(), dims=(16, 16), batch_size=50, seed=7,
                      checkpoint_path=ckpt, checkpoint_every=4)
    for _ in range(7):  # checkpoint after batch 4, batches 5-7 journalled only
        run.step()
    assert len(list(run.journal_dir.glob('batch_*.npz'))) == 3
    resumed = GridMapElites.resume(ckpt, SyntheticEvaluator(), checkpoint_every=4)
    assert resumed.n_batches == 7 and resumed.n_evaluations == 350
    _assert_same(run, resumed)  # which asks a batch of each: resume afresh to go on
    resumed = GridMapElites.resume(ckpt, SyntheticEvaluator(), checkpoint_every=4)
    resumed.step()  # batch 8: a checkpoint, which prunes the journal
    assert not list(run.journal_dir.glob('batch_*.npz'))


def test_resume_rejects_garbage_and_cvt_checkpoints(tmp_path):
    from sela_ros.qd.cvt import CVTMapElites

    path = tmp_path / 'ck.pkl'
    path.write_bytes(b'garbage')
    with pytest.raises(ValueError, match='cannot resume'):
        GridMapElites.resume(path, SyntheticEvaluator())
    eight = SyntheticEvaluator(descriptor='final_xy_duty_factors')
    bounds = ((-1.0, 1.0), (-1.0, 1.0)) + ((0.0, 1.0),) * 6
    cvt = CVTMapElites(np.random.default_rng(0).random((8, 8)), bounds, eight, batch_size=5)
    cvt.step()
    with pytest.raises(ValueError, match='not a grid checkpoint'):
        GridMapElites.resume(cvt.save_checkpoint(tmp_path / 'cvt.pkl'), SyntheticEvaluator())


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
    subprocess.run(_cli(reference, tmp_path / 'ref_ck.pkl'), check=True, cwd=REPO, env=env,
                   timeout=120, capture_output=True)

    out, ckpt = tmp_path / 'killed.npz', tmp_path / 'killed_ck.pkl'
    # Killed once a checkpoint and at least one journalled batch after it exist.
    assert sigkill_once_journalled(_cli(out, ckpt), ckpt, REPO, env) == -signal.SIGKILL
    assert not out.exists()

    killed_at = GridMapElites.resume(ckpt, SyntheticEvaluator())
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


def test_cli_refuses_an_out_it_cannot_write_before_any_evaluation(tmp_path):
    blocker = tmp_path / 'a_file'
    blocker.write_text('')
    for args, reason in ((['--out', str(blocker / 'map.npz')],
                          f'--out: cannot write in {blocker}'),
                         (['--out', str(tmp_path / 'map.npz'), '--checkpoint',
                           str(blocker / 'map.pkl')], f'--checkpoint: cannot write in {blocker}')):
        proc = subprocess.run([sys.executable, '-m', 'sela_ros.tools.build_archive', '--synthetic',
                               '--evaluations', '10', *args], cwd=REPO, capture_output=True,
                              text=True, timeout=60, env=dict(os.environ, PYTHONPATH=str(REPO)))
        assert proc.returncode == 2, (args, proc.stderr)
        assert reason in proc.stderr and 'Traceback' not in proc.stderr, proc.stderr
        assert 'evaluations' not in proc.stdout  # refused before the build started
    assert not (tmp_path / 'map.npz').exists()


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
