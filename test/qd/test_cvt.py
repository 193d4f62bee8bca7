"""The 8-D CVT map (pyribs): build, checkpoint/journal resume, carried checkpoints, archives.

pyribs is a map-builder extra (requirements-qd.txt) that `make venv` installs: without it
these tests fail, they never skip."""
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from killed_build import sigkill_once_journalled

from sela_ros.core.storage import Archive, ArchiveError, load_archive
from sela_ros.qd.cvt import XY_DUTY_BOUNDS, CVTMapElites, disc_samples, make_centroids
from sela_ros.qd.evaluators import EvaluationResult, SyntheticEvaluator
from sela_ros.qd.executors import SerialEvaluator

REPO = Path(__file__).resolve().parents[2]
EIGHT_D = SyntheticEvaluator(descriptor='final_xy_duty_factors')
# The synthetic (x, y) spans [-1, 1]^2: bounds that cover it.
BOUNDS = ((-1.0, 1.0), (-1.0, 1.0)) + ((0.0, 1.0),) * 6


def _centroids(cells=64, seed=3):
    return disc_samples(BOUNDS, cells, np.random.default_rng(seed))


def _run(n=600, executor=None, **kwargs):
    run = CVTMapElites(_centroids(), BOUNDS, EIGHT_D, executor or SerialEvaluator(),
                       batch_size=50, n_initial=100, seed=11, **kwargs)
    run.run(n, progress=False)
    return run


def _elites(run):
    data = run.scheduler.archive.data()
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


def test_cvt_build_fills_cells_with_8d_elites():
    run = _run(n=1000)
    archive = run.to_archive(dt=1 / 120, gait_duration=3.0, controller_version='synthetic',
                             model_version='synthetic', solver_iterations=30,
                             descriptor_name='final_xy_duty_factors', fitness_name='arc')
    assert run.n_evaluations == 1000
    assert 20 <= len(archive) <= 64
    assert archive.descriptors.shape == (len(archive), 8)
    assert archive.centroids.shape == (64, 8)
    assert archive.metadata['archive_kind'] == 'cvt' and archive.metadata['cells'] == 64
    # each elite lies in the Voronoi cell of its own centroid: none nearer than it
    d = np.linalg.norm(archive.descriptors[:, None] - archive.centroids[None], axis=2)
    assert len(np.unique(d.argmin(axis=1))) == len(archive)
    # the falls (synthetic: params 0 and 1 above 0.95) never enter the archive
    assert not np.any((archive.params[:, 0] > 0.95) & (archive.params[:, 1] > 0.95))


def test_falls_are_told_but_kept_out():
    run = CVTMapElites(_centroids(8), BOUNDS, EIGHT_D, batch_size=2, n_initial=2, seed=0)
    sols = run.ask()
    run.tell(sols, [EvaluationResult(False, -np.inf, np.full(8, np.nan), np.zeros(3)),
                    EvaluationResult(True, -0.1, np.full(8, 0.5), np.ones(3))])
    assert run.n_invalid == 1 and run.scheduler.archive.stats.num_elites == 1
    with pytest.raises(ValueError, match='ask'):
        run.tell(sols, [EvaluationResult(True, -0.1, np.full(8, 0.5), np.ones(3))] * 2)


def test_resume_after_a_kill_matches_uninterrupted(tmp_path):
    full = _run(n=900)
    ckpt = tmp_path / 'ck.pkl'
    killed = CVTMapElites(_centroids(), BOUNDS, EIGHT_D, batch_size=50, n_initial=100, seed=11,
                          checkpoint_path=ckpt, checkpoint_every=4)
    for _ in range(7):  # checkpoint after batch 4; batches 5-7 only journalled; then "killed"
        killed.step()
    assert len(list(killed.journal_dir.glob('batch_*.npz'))) == 3
    resumed = CVTMapElites.resume(ckpt, EIGHT_D, SerialEvaluator(), checkpoint_every=4)
    assert resumed.n_batches == 7 and resumed.n_evaluations == killed.n_evaluations
    resumed.run(900, progress=False)
    _assert_same(full, resumed)


def test_checkpoint_carried_to_another_path_resumes(tmp_path):
    full = _run(n=900)
    here = tmp_path / 'here' / 'ck.pkl'
    part = _run(n=500, checkpoint_path=here, checkpoint_every=3)
    # what a user copies to another machine: the checkpoint and the journal beside it
    there = tmp_path / 'elsewhere' / 'map.pkl'
    there.parent.mkdir()
    shutil.copy(here, there)
    if part.journal_dir.is_dir():
        shutil.copytree(part.journal_dir, Path(str(there) + '.journal'))
    shutil.rmtree(here.parent)
    resumed = CVTMapElites.resume(there, EIGHT_D, SerialEvaluator(), checkpoint_every=3)
    assert resumed.n_evaluations == part.n_evaluations
    resumed.run(900, progress=False)
    _assert_same(full, resumed)
    assert there.is_file()  # checkpoints keep going to the carried path


def test_resume_rejects_garbage_and_grid_checkpoints(tmp_path):
    garbage = tmp_path / 'ck.pkl'
    garbage.write_bytes(b'garbage')
    with pytest.raises(ValueError, match='cannot resume'):
        CVTMapElites.resume(garbage, EIGHT_D)


def test_archive_round_trips_with_centroids(tmp_path):
    run = _run(n=400)
    archive = run.to_archive(dt=1 / 120, gait_duration=3.0, controller_version='synthetic',
                             model_version='synthetic', solver_iterations=30,
                             descriptor_name='final_xy_duty_factors', fitness_name='arc')
    path = archive.save(tmp_path / 'map8d.npz')
    loaded = load_archive(path, expected_settings={'dt': 1 / 120, 'solver_iterations': 30})
    for key in ('params', 'descriptors', 'generic_reward', 'fitness', 'centroids'):
        np.testing.assert_array_equal(getattr(loaded, key), getattr(archive, key), err_msg=key)
    assert np.asarray(loaded.descriptor_bounds).shape == (8, 2)
    assert loaded.normalised_descriptors().shape == (len(loaded), 8)
    assert loaded.simulator_settings['solver_iterations'] == 30
    with pytest.raises(ArchiveError, match='solver_iterations'):
        load_archive(path, expected_settings={'solver_iterations': 50})
    # a CVT archive without its centroids, or centroids of the wrong width, are refused
    with pytest.raises(ArchiveError, match='centroids'):
        Archive(archive.params, archive.descriptors, archive.generic_reward, archive.fitness,
                archive.metadata)
    with pytest.raises(ArchiveError, match='centroids'):
        Archive(archive.params, archive.descriptors, archive.generic_reward, archive.fitness,
                archive.metadata, centroids=archive.centroids[:, :2])


def test_make_centroids_cover_the_disc_and_duty_factors():
    centroids = make_centroids(50, XY_DUTY_BOUNDS, seed=0, samples=3000)
    assert centroids.shape == (50, 8)
    radius = np.hypot(centroids[:, 0], centroids[:, 1])
    assert radius.max() <= 0.45 + 1e-9  # k-means over the disc: no centroid in a corner
    assert np.all((centroids[:, 2:] >= 0) & (centroids[:, 2:] <= 1))
    np.testing.assert_array_equal(centroids, make_centroids(50, XY_DUTY_BOUNDS, seed=0,
                                                            samples=3000))


def _cli(out, ckpt, *extra):
    return [sys.executable, '-m', 'sela_ros.tools.build_archive', '--synthetic',
            '--synthetic-delay', '0.004', '--descriptor', '8d', '--cells', '40',
            '--evaluations', '1500', '--batch-size', '50', '--workers', '1', '--seed', '5',
            '--checkpoint-every', '3', '--checkpoint', str(ckpt), '--out', str(out),
            '--no-progress', *extra]


@pytest.mark.slow
def test_cli_sigkill_then_resume_matches_uninterrupted(tmp_path):
    env = dict(os.environ, PYTHONPATH=str(REPO))
    reference = tmp_path / 'ref.npz'
    subprocess.run(_cli(reference, tmp_path / 'ref_ck.pkl'), check=True, cwd=REPO, env=env,
                   timeout=240, capture_output=True)
    out, ckpt = tmp_path / 'killed.npz', tmp_path / 'killed_ck.pkl'
    returncode = sigkill_once_journalled(_cli(out, ckpt), ckpt, REPO, env)
    assert returncode == -signal.SIGKILL and not out.exists()
    subprocess.run(_cli(out, ckpt, '--resume'), check=True, cwd=REPO, env=env, timeout=240,
                   capture_output=True)
    a, b = load_archive(reference), load_archive(out)
    assert a.metadata['n_evaluations'] == b.metadata['n_evaluations'] == 1500
    assert a.metadata['archive_kind'] == 'cvt' and a.metadata['cells'] == 40
    for key in ('params', 'descriptors', 'generic_reward', 'fitness', 'centroids'):
        np.testing.assert_array_equal(getattr(a, key), getattr(b, key), err_msg=key)


def test_cli_export_reads_a_checkpoint_without_touching_it(tmp_path):
    from sela_ros.tools.build_archive import main

    out, ckpt = tmp_path / 'a.npz', tmp_path / 'a_ck.pkl'
    common = ['--synthetic', '--descriptor', '8d', '--cells', '30', '--batch-size', '50',
              '--workers', '1', '--checkpoint', str(ckpt), '--checkpoint-every', '4',
              '--no-progress']
    assert main([*common, '--evaluations', '350', '--out', str(out)]) == 0
    before = ckpt.read_bytes()
    exported = tmp_path / 'exported.npz'
    assert main([*common, '--evaluations', '1', '--out', str(exported), '--export']) == 0
    assert ckpt.read_bytes() == before  # nothing written beside a running build
    a, b = load_archive(out), load_archive(exported)
    assert b.metadata['n_evaluations'] == 350
    np.testing.assert_array_equal(a.params, b.params)


def test_a_budget_smaller_than_the_random_first_batch_is_the_whole_build(tmp_path, capsys):
    """``--evaluations 120`` evaluates 120 gaits, not the default first batch of five
    batches; a first batch asked larger than the budget is refused."""
    from sela_ros.tools.build_archive import main

    out = tmp_path / 'small.npz'
    common = ['--synthetic', '--descriptor', '8d', '--cells', '30', '--batch-size', '50',
              '--workers', '1', '--no-progress', '--out', str(out)]
    assert main([*common, '--evaluations', '120']) == 0
    assert load_archive(out).metadata['n_evaluations'] == 120
    with pytest.raises(SystemExit) as exit_:
        main([*common, '--evaluations', '120', '--initial', '200'])
    assert exit_.value.code == 2
    assert '--initial 200 random gaits per emitter exceed the budget' in capsys.readouterr().err


def test_regrid_carries_every_elite_into_a_finer_cvt_and_goes_on(tmp_path):
    run = _run(n=600, checkpoint_path=tmp_path / 'ck.pkl', checkpoint_every=2)
    old = _elites(run)
    fine = _centroids(cells=400, seed=4)
    elites = run.regrid(fine)
    new = _elites(run)
    # Each old elite went to its nearest new centroid; a cell that got two keeps the better.
    cell = np.linalg.norm(old['measures'][:, None] - fine[None], axis=2).argmin(axis=1)
    best = {c: old['objective'][cell == c].max() for c in np.unique(cell)}
    assert elites == len(best) == len(new['index'])
    np.testing.assert_array_equal(np.sort(new['index']), sorted(best))
    np.testing.assert_allclose([best[i] for i in new['index']], new['objective'])
    assert run.info['regrids'][0]['to_cells'] == 400 and run.n_evaluations == 600
    # Nothing is evaluated again; the run goes on in the finer CVT and finds more elites.
    run.save_checkpoint()
    run.run(1200, progress=False)
    assert run.n_evaluations == 1200 and len(_elites(run)['index']) > elites
    # ... and resumes from its checkpoint in it as any run.
    resumed = CVTMapElites.resume(tmp_path / 'ck.pkl', EIGHT_D, SerialEvaluator())
    assert resumed.scheduler.archive.cells == 400
    with pytest.raises(ValueError, match='more cells'):
        resumed.regrid(_centroids(cells=64))


def test_cli_regrid_on_resume(tmp_path):
    from sela_ros.tools.build_archive import main

    out, ckpt = tmp_path / 'a.npz', tmp_path / 'a_ck.pkl'
    common = ['--synthetic', '--descriptor', '8d', '--cells', '30', '--batch-size', '50',
              '--workers', '1', '--checkpoint', str(ckpt), '--no-progress', '--out', str(out)]
    assert main([*common, '--evaluations', '300']) == 0
    assert main([*common, '--evaluations', '400', '--resume', '--regrid', '120']) == 0
    archive = load_archive(out)
    assert archive.metadata['cells'] == 120 and archive.metadata['n_evaluations'] == 400
    # The same --regrid again (a script that always passes it) changes nothing.
    assert main([*common, '--evaluations', '450', '--resume', '--regrid', '120']) == 0
    assert load_archive(out).metadata['cells'] == 120
    with pytest.raises(SystemExit):  # coarser: refused
        main([*common, '--evaluations', '500', '--resume', '--regrid', '60'])
    with pytest.raises(SystemExit):  # a fresh run has nothing to regrid
        main([*common, '--evaluations', '500', '--regrid', '200'])


def test_the_nodes_never_import_the_map_builder_extras():
    # pyribs and Dask are offline extras (requirements-qd.txt): a robot needs neither.
    code = ('import sys\n'
            'import sim_bridge.node, sela_ros.nodes.adapter_node, sela_ros.nodes.planner_node\n'
            'import sela_ros.nodes.damage_detector_node\n'
            'bad = sorted(m for m in sys.modules if m.split(".")[0] in '
            '("ribs", "dask", "distributed", "sklearn", "numba"))\n'
            'assert not bad, bad\n')
    proc = subprocess.run([sys.executable, '-c', code], cwd=REPO, capture_output=True,
                          text=True, timeout=120, env=dict(os.environ, PYTHONPATH=str(REPO)))
    assert proc.returncode == 0, proc.stderr[-2000:]
