"""Damage priors for a robot other than the hexapod: its damages in its own names, its
tables run on it, found beside its map by the adapter's ``priors.tables: auto``."""
import numpy as np
import pytest
from script_modules import load_script

pytest.importorskip('ribs')

from sela_ros.core.learning.damage_priors import resolve_priors  # noqa: E402
from sela_ros.core.storage import load_archive  # noqa: E402
from sela_ros.tools import build_archive  # noqa: E402
from sim_bridge.evaluation import evaluate_gait  # noqa: E402

TOY_DAMAGES = 'shorten:front_left:0.5;block:rear_right.hip=0.3'


@pytest.fixture(scope='module')
def toy_map(tmp_path_factory):
    out = tmp_path_factory.mktemp('toy') / 'toy.npz'
    assert build_archive.main(['--robot', 'toy', '--descriptor', 'duty', '--cells', '24',
                               '--batch-size', '8', '--initial', '8', '--workers', '1',
                               '--seed', '3', '--no-progress', '--evaluations', '24',
                               '--out', str(out)]) == 0
    return out


def test_the_toys_priors_are_its_own_damages_run_on_it_and_found_beside_its_map(
        toy_map, tmp_path, monkeypatch, capsys):
    monkeypatch.setenv('SELA_CACHE_DIR', str(tmp_path / 'cache'))
    build = load_script('build_priors')
    assert build.main([str(toy_map), '--damages', TOY_DAMAGES, '--chained-repeats', '2']) == 0
    assert 'wrote' in capsys.readouterr().out
    archive = load_archive(toy_map)
    priors = resolve_priors('auto', toy_map, archive.params)
    assert priors.names == ('shorten:front_left:0.5', 'block:rear_right.hip=0.3')
    settings = archive.simulator_settings
    for d, damage in enumerate(priors.names):  # each table: the gaits run on the damaged toy
        for i in range(0, len(archive), max(1, len(archive) // 3)):
            outcome = evaluate_gait(archive.params[i], damage, dt=settings['dt'],
                                    gait_duration=settings['gait_duration'],
                                    solver_iterations=settings['solver_iterations'],
                                    robot='toy')
            np.testing.assert_allclose(priors.generic_reward[d, i], outcome.generic_reward,
                                       atol=1e-6)
            assert priors.fallen[d, i] == outcome.fallen
    # The chained runs of the gaits the fall model fears, on the toy too (shapes as stored).
    assert priors.chained_runs.shape == priors.fallen.shape


@pytest.mark.parametrize('args, said', [
    ([], 'give the damages of the toy, in its names (legs front_left'),
    (['--damages', 'remove:middle_right'], "the toy does not take damage kind 'remove'"),
    (['--damages', 'shorten:middle_left:0.5'], "unknown leg 'middle_left'"),
    (['--robot', 'hexapod', '--damages', 'single-legs'], 'is a map of the toy, not of the '
     'hexapod'),
])
def test_damages_not_in_the_maps_robots_names_are_refused_before_any_table(
        toy_map, tmp_path, monkeypatch, capsys, args, said):
    monkeypatch.setenv('SELA_CACHE_DIR', str(tmp_path / 'cache'))
    build = load_script('build_priors')
    with pytest.raises(SystemExit) as exit_:
        build.main([str(toy_map), '--chained-repeats', '0', '--out',
                    str(tmp_path / 'p.npz'), *args])
    assert exit_.value.code == 2
    assert said in capsys.readouterr().err
    assert not (tmp_path / 'cache').exists()  # nothing run


def test_chained_runs_play_the_maps_own_robot(toy_map, tmp_path):
    """Gaits of the toy (12 parameters) run chained on the toy: the hexapod's simulator
    could not play them."""
    from sim_bridge.experiment_env import chained_runs

    archive = load_archive(toy_map)
    settings = archive.simulator_settings
    runs, falls = chained_runs(archive.params, 'shorten:front_left:0.5', [0, 1], [[2, 3], [3, 2]],
                               dt=settings['dt'], gait_duration=settings['gait_duration'],
                               solver_iterations=settings['solver_iterations'],
                               cache_dir=tmp_path, robot='toy')
    assert runs.tolist() == [2, 2] and falls.tolist() == [0, 0]  # the toy never falls here
    assert len(list(tmp_path.glob('chained_*.npz'))) == 1
