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
