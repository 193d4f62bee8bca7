"""A robot the stack did not know gets its map through the same builder: the toy description
(four hip joints, 12 gait parameters) through ``sela-build-archive``, resumed, and its elites
doing again what the map says they do."""
import numpy as np
import pytest

pytest.importorskip('ribs')

from sela_ros.core.storage import load_archive  # noqa: E402
from sela_ros.tools import build_archive  # noqa: E402
from sim_bridge.evaluation import evaluate_gait  # noqa: E402
from sim_bridge.robots import get_robot, robot_of  # noqa: E402

TOY_ARGS = ['--robot', 'toy', '--descriptor', 'duty', '--cells', '24', '--batch-size', '8',
            '--initial', '8', '--workers', '1', '--seed', '3', '--no-progress']


def test_a_tiny_map_of_the_toy_is_built_resumed_and_true(tmp_path, capsys):
    out = tmp_path / 'toy.npz'
    assert build_archive.main([*TOY_ARGS, '--evaluations', '24', '--out', str(out)]) == 0
    first = load_archive(out)
    assert build_archive.main([*TOY_ARGS, '--evaluations', '40', '--out', str(out),
                               '--resume']) == 0
    archive = load_archive(out)
    assert 'resuming from' in capsys.readouterr().out
    toy = get_robot('toy')
    assert first.metadata['n_evaluations'] < archive.metadata['n_evaluations'] == 40
    # Sizes from the description, none from a constant: 12 parameters, x, y + 4 duty factors.
    assert archive.params.shape[1] == toy.n_params == 12
    assert archive.descriptors.shape[1] == 2 + len(toy.legs) == 6
    assert robot_of(archive.metadata) == 'toy'
    assert archive.metadata['model_version'] == toy.model_version
    assert archive.stability is not None and archive.stability.shape == (len(archive),)
    assert len(archive) >= 5
    settings = archive.simulator_settings
    for i in range(0, len(archive), max(1, len(archive) // 4)):
        outcome = evaluate_gait(archive.params[i], 'intact', dt=settings['dt'],
                                gait_duration=settings['gait_duration'],
                                solver_iterations=settings['solver_iterations'], robot='toy')
        np.testing.assert_allclose(outcome.generic_reward, archive.generic_reward[i],
                                   atol=1e-6)
        np.testing.assert_allclose(outcome.duty_factors, archive.descriptors[i, 2:], atol=1e-6)


def test_a_toy_map_is_not_resumed_as_another_robot_s(tmp_path, capsys):
    out = tmp_path / 'toy.npz'
    assert build_archive.main([*TOY_ARGS, '--evaluations', '8', '--out', str(out)]) == 0
    args = [a if a != 'toy' else 'hexapod' for a in TOY_ARGS]
    with pytest.raises(SystemExit):
        build_archive.main([*args, '--evaluations', '16', '--out', str(out), '--resume'])
    assert 'simulator settings' in capsys.readouterr().err


def test_the_shipped_a1_map_is_the_a1_s_and_its_gaits_do_what_it_says():
    from sela_ros.core.storage import resolve_archive_path

    archive = load_archive(resolve_archive_path('a1'))
    a1 = get_robot('a1')
    assert robot_of(archive.metadata) == 'a1' == a1.archive
    assert archive.params.shape == (len(archive), a1.n_params)
    assert archive.descriptors.shape[1] == 2 + len(a1.legs)
    settings = archive.simulator_settings
    for i in np.random.default_rng(0).choice(len(archive), 3, replace=False):
        outcome = evaluate_gait(archive.params[i], 'intact', dt=settings['dt'],
                                gait_duration=settings['gait_duration'],
                                solver_iterations=settings['solver_iterations'], robot='a1')
        np.testing.assert_allclose(outcome.generic_reward, archive.generic_reward[i],
                                   atol=1e-6)


USER_ROBOT = '''
from sim_bridge.robots.toy import ToyDescription


class UserBot(ToyDescription):
    name = 'userbot'
    model_version = 'userbot-v1'


DESCRIPTION = UserBot()
'''


def test_a_robot_of_the_user_s_own_module_runs_the_experiment_in_worker_processes(tmp_path):
    """Its map stamps only its name; the experiment finds it by ``--robot module:ATTR``, its
    runs and its oracle's table in worker processes too, and without ``--robot`` says why."""
    import json
    import os
    import subprocess
    import sys

    (tmp_path / 'userbot_description.py').write_text(USER_ROBOT)
    env = {**os.environ, 'PYTHONPATH': os.pathsep.join(
        [str(tmp_path), *filter(None, [os.environ.get('PYTHONPATH')])])}
    spec = 'userbot_description:DESCRIPTION'
    out = tmp_path / 'userbot.npz'
    args = ['--robot', spec, *TOY_ARGS[2:], '--evaluations', '24', '--out', str(out)]
    subprocess.run([sys.executable, '-m', 'sela_ros.tools.build_archive', *args], env=env,
                   check=True, capture_output=True, timeout=300)
    assert robot_of(load_archive(out).metadata) == 'userbot'

    def experiment(*extra):
        return subprocess.run(
            [sys.executable, '-m', 'sela_ros.experiments.cli', 'robot', '--archive', str(out),
             '--goal', '0.2,0', '--replicates', '2', '--max-steps', '3', '--workers', '2',
             '--methods', 'sela,oracle', '--oracle-cache', str(tmp_path / 'cache'),
             '--out', str(tmp_path / 'exp'), *extra],
            env=env, capture_output=True, text=True, timeout=300)

    refused = experiment()
    assert refused.returncode == 2, refused.stderr
    assert "a map of the robot 'userbot'" in refused.stderr, refused.stderr
    assert '--robot package.module:DESCRIPTION' in refused.stderr
    assert 'Traceback' not in refused.stderr
    done = experiment('--robot', spec)
    assert done.returncode == 0, done.stderr
    assert "the oracle's table of 'intact' is not cached" in done.stderr, done.stderr
    doc = json.loads((tmp_path / 'exp' / 'results.json').read_text())
    assert doc['parameters']['robot'] == 'userbot'
    assert len(doc['methods']['oracle']['steps']) == 2
    assert list((tmp_path / 'cache').glob('oracle_*.npz'))
