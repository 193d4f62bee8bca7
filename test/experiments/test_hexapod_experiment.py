"""``sela-experiment hexapod``: results schema, argument errors, the oracle table."""
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from archive_fixtures import tiny_archive

from sela_ros.experiments.cli import main
from sim_bridge import experiment_env
from sim_bridge.evaluation import evaluate_gait
from sim_bridge.experiment_env import HexapodEnvironment, chained_runs, oracle_table

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope='module')
def archive_path(tmp_path_factory):
    return tiny_archive(tmp_path_factory.mktemp('archive') / 'tiny.npz')


def test_hexapod_cli_writes_schema(archive_path, tmp_path):
    out = tmp_path / 'hex'
    argv = ['hexapod', '--replicates', '2', '--seed', '3', '--out', str(out),
            '--archive', str(archive_path), '--max-steps', '2', '--ite-iterations', '1',
            '--oracle-cache', str(tmp_path / 'cache'), '--quiet', '--workers', '2']
    assert main(argv) == 0
    doc = json.loads((out / 'results.json').read_text())
    assert doc['scenario'] == 'hexapod' and doc['replicates'] == 2
    assert list(doc['methods']) == ['sela', 'ite_uncertainty', 'ite_4dir', 'oracle']
    for m in doc['methods'].values():
        assert {'success', 'steps', 'learning_iterations', 'falls'} <= set(m)
        assert len(m['success']) == len(m['steps']) == len(m['learning_iterations']) == 2
        assert all(isinstance(s, bool) for s in m['success'])
        assert all(isinstance(s, int) for s in m['steps'] + m['learning_iterations'])
        assert all(0 <= s <= 2 for s in m['steps'])
    assert doc['methods']['sela']['learning_iterations'] == [0, 0]
    assert doc['methods']['ite_uncertainty']['learning_iterations'] == [1, 1]
    assert doc['methods']['ite_4dir']['learning_iterations'] == [4, 4]
    assert doc['parameters']['damage'] == 'remove:middle_right'
    assert (out / 'figure.png').stat().st_size > 1000
    # Same seed, same results (the oracle table now comes from the cache), serially too.
    out2 = tmp_path / 'hex2'
    argv2 = [a if a != str(out) else str(out2) for a in argv][:-2] + ['--workers', '1']
    assert main(argv2) == 0
    assert json.loads((out2 / 'results.json').read_text())['methods'] == doc['methods']


def test_hexapod_cli_on_a_course_counts_collisions_and_draws_paths(archive_path, tmp_path):
    out = tmp_path / 'maze'
    argv = ['hexapod', '--replicates', '1', '--seed', '3', '--out', str(out), '--map', 'maze',
            '--archive', str(archive_path), '--max-steps', '2', '--ite-iterations', '1',
            '--methods', 'sela,ite_4dir', '--quiet']
    assert main(argv) == 0
    doc = json.loads((out / 'results.json').read_text())
    assert doc['parameters']['course'] == 'maze' and doc['parameters']['planner'] == 'grid'
    # Without --goal: the course's mission, its goals in order.
    assert doc['parameters']['goal'] == [4.5, 4.5]
    assert doc['parameters']['via'] == [[3.0, 0.0], [1.5, 1.5], [3.0, 3.0]]
    for name, m in doc['methods'].items():
        assert m['collisions'][0] >= 0 and doc['summary'][name]['collisions'] >= 0
        # The start, then one point per gait (learning trials included).
        assert len(m['paths'][0]) == 1 + m['steps'][0] + m['learning_iterations'][0]
        assert m['goal_steps'][0] == []  # 2 steps reach none of the goals
    assert (out / 'paths.png').stat().st_size > 1000


def test_course_environment_counts_steps_that_end_in_an_obstacle():
    from sela_ros.core.planning import OccupancyGrid
    from sela_ros.experiments.courses import CourseEnvironment

    class Walker:  # moves 1 m along x per gait
        def __init__(self):
            self.x = 0.0

        def reset(self):
            self.x = 0.0

        def true_pose(self):
            return np.array([self.x + 0.5, 0.5, 0.0])

        def observed_pose(self):
            return self.true_pose()

        def execute(self, index):
            self.x += 1.0
            return self.true_pose()

    occ = np.zeros((1, 5), dtype=bool)
    occ[0, 2] = True  # x in [2, 3)
    env = CourseEnvironment(Walker(), OccupancyGrid(occ, 1.0))
    env.reset()
    for _ in range(6):  # 1.5 free, 2.5 in the obstacle, 3.5, 4.5 free, then off the map
        env.execute(0)
    assert env.collisions == 1
    assert env.path[0] == [0.5, 0.5] and len(env.path) == 7


@pytest.mark.parametrize('extra', [
    ['--map', 'no_such_course'],
    ['--damage', 'remove:tail'],
    ['--goal', '2'],
    ['--goal', '2,nan'],
    ['--lookahead', '0'],
    ['--archive', 'no_such_archive.npz'],
    ['--methods', 'sela,nope'],
    ['--noise-std', '-0.1'],
    ['--max-steps', '0'],
])
def test_bad_arguments_exit_2_without_traceback(extra, archive_path, tmp_path):
    args = ['hexapod', '--replicates', '2', '--out', 'x', '--archive', str(archive_path),
            *extra]
    proc = subprocess.run([sys.executable, '-m', 'sela_ros.experiments.cli', *args],
                          capture_output=True, text=True, cwd=tmp_path, timeout=120,
                          env={**os.environ, 'PYTHONPATH': str(REPO)})
    assert proc.returncode == 2, proc.stderr
    assert 'usage:' in proc.stderr and 'Traceback' not in proc.stderr


def test_oracle_table_matches_evaluate_gait_and_is_cached(tmp_path, monkeypatch):
    params = np.random.default_rng(7).random((3, 36))
    gr, fallen = oracle_table(params, 'remove:middle_right', workers=2, cache_dir=tmp_path)
    for i in range(3):
        outcome = evaluate_gait(params[i], 'remove:middle_right')
        np.testing.assert_allclose(gr[i], outcome.generic_reward, atol=1e-9)
        assert fallen[i] == outcome.fallen
    assert len(list(tmp_path.glob('oracle_*.npz'))) == 1

    def boom(*a, **k):
        raise AssertionError('recomputed instead of reading the cache')

    monkeypatch.setattr(experiment_env, 'compute_oracle_table', boom)
    gr2, fallen2 = oracle_table(params, 'remove:middle_right', cache_dir=tmp_path)
    np.testing.assert_array_equal(gr2, gr)
    np.testing.assert_array_equal(fallen2, fallen)
    with pytest.raises(AssertionError):  # another damage is another table
        oracle_table(params, 'remove:front_left', cache_dir=tmp_path)


def test_environment_walks_without_reset_and_checks_index():
    params = np.random.default_rng(1).random((2, 36))
    with HexapodEnvironment(params, 'remove:middle_right', noise_std=0.0, seed=0) as env:
        env.reset()
        np.testing.assert_allclose(env.true_pose(), [0, 0, 0], atol=0.02)
        assert env.standing  # the first gait starts as the tables' do
        first = env.execute(0)
        assert env.standing == (env.falls == 1)  # chained next, unless righted after a fall
        np.testing.assert_allclose(first, env.true_pose())
        second = env.execute(0)  # starts where the first ended
        expected = evaluate_gait(params[0], 'remove:middle_right').generic_reward
        np.testing.assert_allclose(first[:2], expected[:2], atol=0.02)
        assert not np.allclose(second[:2], first[:2])
        assert env.sim_seconds > 0
        with pytest.raises(IndexError):
            env.execute(2)
        env.reset()
        assert env.standing


def test_chained_runs_count_each_pair_and_are_cached(tmp_path, monkeypatch):
    """Each gait after each of its predecessors, from a standing start per pair; a pair whose
    predecessor fell does not count; the second call reads the cache."""
    params = np.random.default_rng(3).random((3, 36))
    runs, falls = chained_runs(params, 'remove:rear_left', [0, 1], [[1, 2], [2, 2]],
                               cache_dir=tmp_path)
    assert runs.shape == falls.shape == (2,) and np.all(falls <= runs) and np.all(runs <= 2)
    assert runs[1] in (0, 2)  # the same predecessor twice: both count or neither
    assert [len(a) for a in chained_runs(params, 'remove:rear_left', [], [])] == [0, 0]

    def boom(job):
        raise AssertionError('ran again instead of reading the cache')

    monkeypatch.setattr(experiment_env, '_chained_chunk', boom)
    again = chained_runs(params, 'remove:rear_left', [0, 1], [[1, 2], [2, 2]],
                         cache_dir=tmp_path)
    assert np.array_equal(again[0], runs) and np.array_equal(again[1], falls)
    with pytest.raises(AssertionError, match='ran again'):  # other pairs: not cached
        chained_runs(params, 'remove:rear_left', [0], [[2, 1]], cache_dir=tmp_path)


def test_a_replicate_told_a_prior_mean_chooses_by_it(archive_path):
    """``Job.prior_mean`` replaces the map's generic rewards as the GPs' prior mean (the
    bounds of scripts/compare_priors.py): the same table changes nothing, and a table in
    which one gait alone moves, straight to the first waypoint, has that gait chosen."""
    from sela_ros.core.storage import load_archive
    from sela_ros.experiments.hexapod import Job, run_method

    def first(prior_mean):
        return run_method(Job('sela', np.random.SeedSequence(0), str(archive_path), 'intact',
                              (1.0, 0.0), max_steps=1, priors='none', noise_seed=0,
                              prior_mean=prior_mean))['behaviors']

    archive = load_archive(archive_path)
    chosen = first(None)
    assert first(archive.generic_reward) == chosen
    only = (chosen[0] + 1) % len(archive)
    table = np.zeros_like(archive.generic_reward)
    table[only, 0] = 0.6
    assert first(table) == [only]


def _usage_error(argv, capsys):
    """The last line of the usage error ``argv`` gives (exit code 2, no traceback)."""
    with pytest.raises(SystemExit) as exc:
        main(argv)
    err = capsys.readouterr().err
    assert exc.value.code == 2, err
    assert 'Traceback' not in err
    return err.strip().splitlines()[-1]


@pytest.mark.parametrize('scenario', ['hexapod', 'campaign'])
@pytest.mark.parametrize('option', ['--kernel-sigma', '--fall-kernel-sigma'])
@pytest.mark.parametrize('value', ['1e-300', '1e-160', '0.0009', '101'])
def test_kernel_lengths_out_of_range_are_usage_errors(scenario, option, value, capsys):
    from sela_ros.experiments.cli import build_parser

    with pytest.raises(SystemExit) as exc:
        build_parser().parse_args([scenario, '--replicates', '1', '--out', 'x', option, value])
    assert exc.value.code == 2
    error = capsys.readouterr().err.strip().splitlines()[-1]
    assert f'{option}: expected a kernel length in [0.001, 100]' in error


def test_the_shortest_kernel_length_taken_runs(archive_path, tmp_path):
    out = tmp_path / 'short'
    assert main(['hexapod', '--replicates', '1', '--out', str(out), '--archive',
                 str(archive_path), '--methods', 'sela', '--max-steps', '2', '--quiet',
                 '--kernel-sigma', '0.001', '--fall-kernel-sigma', '0.001']) == 0
    doc = json.loads((out / 'results.json').read_text())
    assert doc['parameters']['gp.kernel.sigma'] == 0.001
    assert doc['parameters']['fall.kernel.sigma'] == 0.001
    assert 1 <= doc['methods']['sela']['steps'][0] <= 2


def _map(path, obstacles, origin=(-1, -1), size=(4, 4)):
    """A map in the project's format: ``size`` metres from ``origin``, rectangles occupied."""
    path.write_text(f'resolution: 0.1\norigin: [{origin[0]}, {origin[1]}]\nwidth: {size[0]}\n'
                    f'height: {size[1]}\nobstacles: {list(obstacles)}\n')
    return str(path)


def _no_simulation(monkeypatch):
    """Running anything (a replicate, the oracle's table) fails the test: the error must
    come before."""
    from sela_ros.experiments import hexapod

    def boom(*args, **kwargs):
        raise AssertionError('ran before refusing the arguments')

    monkeypatch.setattr(experiment_env, 'compute_oracle_table', boom)
    monkeypatch.setattr(hexapod, 'run_method', boom)


@pytest.mark.parametrize('extra, said', [
    # the maze's corridors are narrower than 2 m: no free cell at all
    (['--map', 'maze', '--inflation', '1'],
     'goal (3, 0) cannot be reached from the start (0, 0) on the map'),
    (['--map', 'maze', '--inflation', '10'], 'with --inflation 10 m: no free cell'),
    # a goal walled in: a ring around (2, 2)
    (['--goal', '2,2', '--map', 'WALLED', '--inflation', '0.2'],
     'goal (2, 2) cannot be reached from the start (0, 0) on the map'),
    (['--goal', '2,2', '--map', 'WALLED', '--inflation', '0.2'], 'with --inflation 0.2 m'),
    (['--goal', '3.5,2', '--map', 'WALLED'], 'goal (3.5, 2) is off the map'),
    (['--map', 'START_IN_OBSTACLE', '--goal', '2,2'],
     'the start (0, 0), where every run begins, is inside an obstacle'),
    (['--map', 'START_OFF', '--goal', '2,2'],
     'the start (0, 0), where every run begins, is off the map'),
])
def test_a_mission_the_planner_cannot_plan_is_a_usage_error_before_anything_runs(
        extra, said, archive_path, tmp_path, monkeypatch, capsys):
    _no_simulation(monkeypatch)
    maps = {'WALLED': _map(tmp_path / 'walled.yaml', [1.5, 1.5, 2.5, 1.6, 1.5, 2.4, 2.5, 2.5,
                                      1.5, 1.5, 1.6, 2.5, 2.4, 1.5, 2.5, 2.5]),
            'START_IN_OBSTACLE': _map(tmp_path / 'start_in.yaml', [-0.5, -0.5, 0.5, 0.5]),
            'START_OFF': _map(tmp_path / 'start_off.yaml', [], origin=(0.5, 0.5))}
    extra = [maps.get(e, e) for e in extra]
    error = _usage_error(['hexapod', '--replicates', '1', '--out', str(tmp_path / 'out'),
                          '--archive', str(archive_path), '--methods', 'sela', '--quiet',
                          *extra], capsys)
    assert said in error


def test_goal_off_a_given_map_asks_for_another_map_or_goal(archive_path, tmp_path, capsys):
    error = _usage_error(['hexapod', '--replicates', '1', '--out', str(tmp_path / 'out'),
                          '--archive', str(archive_path), '--map', 'maze', '--goal', '9,9'],
                         capsys)
    assert 'goal (9, 9) is off the map' in error and 'give another --map' in error
    error = _usage_error(['hexapod', '--replicates', '1', '--out', str(tmp_path / 'out'),
                          '--archive', str(archive_path), '--goal', '9,9'], capsys)
    assert 'give a map that holds it: --map' in error


@pytest.mark.parametrize('cache, said', [
    ('FILE', 'is not a directory'),
    ('FILE/tables', 'cannot be made: Not a directory'),
])
def test_an_oracle_cache_that_cannot_hold_the_table_is_refused_before_it_is_computed(
        cache, said, archive_path, tmp_path, monkeypatch, capsys):
    _no_simulation(monkeypatch)
    (tmp_path / 'FILE').write_text('x')
    cache = str(tmp_path / cache)
    argv = ['hexapod', '--replicates', '1', '--out', str(tmp_path / 'out'), '--archive',
            str(archive_path), '--methods', 'oracle', '--quiet']
    error = _usage_error([*argv, '--oracle-cache', cache], capsys)
    assert f"--oracle-cache '{cache}' {said}" in error
    monkeypatch.setenv('SELA_CACHE_DIR', cache)  # the default cache, when none is given
    assert said in _usage_error(argv, capsys)


def test_a_missing_oracle_cache_is_made(archive_path, tmp_path):
    cache = tmp_path / 'new' / 'cache'
    assert main(['hexapod', '--replicates', '1', '--out', str(tmp_path / 'out'), '--archive',
                 str(archive_path), '--methods', 'sela', '--max-steps', '1', '--quiet',
                 '--oracle-cache', str(cache)]) == 0
    assert cache.is_dir()


def test_an_error_found_while_running_is_said_with_the_scenarios_usage(archive_path, tmp_path,
                                                                      capsys):
    with pytest.raises(SystemExit) as exc:
        main(['hexapod', '--replicates', '1', '--out', str(tmp_path / 'out'), '--archive',
              str(archive_path), '--methods', 'sela', '--quiet', '--priors',
              str(tmp_path / 'no_such_priors.npz')])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and 'no_such_priors.npz' in err
    assert err.startswith('usage: sela-experiment hexapod ')
