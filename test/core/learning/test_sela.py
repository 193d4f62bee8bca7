"""SELA ask/tell: motion models, config, reaching the toy goal, state round trip."""
import dataclasses
import json
import math
from types import SimpleNamespace

import numpy as np
import pytest

from sela_ros.core.learning import (
    SELA,
    PointMotion,
    SE2Motion,
    SELAConfig,
    observed_generic_reward,
)
from sela_ros.experiments.baselines import METHODS, run_oracle, run_sela
from sela_ros.experiments.toy_world import ToyWorld, toy_problem


def toy(noise_std=0.01, seed=0):
    world = ToyWorld(360, noise_std=noise_std, rng=np.random.default_rng(seed))
    return world, toy_problem(world)


def test_se2_predict_and_afun_are_inverse():
    m = SE2Motion()
    pose = np.array([1.0, -2.0, 2.5])
    gr = np.array([0.3, -0.1, 1.2])
    after = m.predict(pose, gr)
    np.testing.assert_allclose(after[:2], pose[:2] + [0.3 * math.cos(2.5) + 0.1 * math.sin(2.5),
                                                      0.3 * math.sin(2.5) - 0.1 * math.cos(2.5)])
    assert -math.pi <= after[2] < math.pi  # 3.7 rad wrapped
    np.testing.assert_allclose(observed_generic_reward(pose, after, m), gr, atol=1e-12)
    np.testing.assert_allclose(m.predict(pose, np.array([gr, gr]))[1], after)


def test_point_afun():
    np.testing.assert_allclose(observed_generic_reward([1, 1], [1.5, 0.5], PointMotion()),
                               [0.5, -0.5])


def test_config_dotted_names():
    c = SELAConfig.from_dict({'gp.kernel.sigma': 0.2, 'acquisition.ucb.alpha': 0.1})
    assert c.gp_kernel_sigma == 0.2 and c.acquisition_ucb_alpha == 0.1
    assert c.goal_eps == 0.1 and c.gp_noise == 0.001
    assert set(c.to_dict()) == {'gp.kernel.sigma', 'gp.kernel.variance', 'gp.noise',
                                'gp.mean.affine', 'gp.mean.descriptor', 'gp.hyper.sd',
                                'acquisition.ucb.alpha', 'acquisition.caution',
                                'acquisition.progress', 'acquisition.reach',
                                'planner.lookahead', 'goal.eps',
                                'fall.risk.threshold', 'fall.kernel.sigma', 'fall.risk.cost',
                                'priors.max.misfit', 'priors.max.misfit.reproduced',
                                'priors.weights.sd', 'planner.horizon', 'planner.reach'}
    with pytest.raises(ValueError, match="unknown SELA parameter.*gp.kernel.sgima"):
        SELAConfig.from_dict({'gp.kernel.sgima': 0.2})
    with pytest.raises(ValueError, match='goal.eps'):
        SELAConfig(goal_eps=-1.0)


def test_auto_and_none_are_words_not_numbers():
    from sela_ros.core.mission import archive_config

    c = SELAConfig.from_dict({'fall.kernel.sigma': 'auto', 'priors.max.misfit': 'none',
                              'priors.weights.sd': 'none'})
    assert c.fall_kernel_sigma is None and c.priors_max_misfit is None
    assert c.priors_weights_sd is None
    written = c.to_dict()
    assert written['fall.kernel.sigma'] == 'auto' and written['priors.weights.sd'] == 'none'
    assert written['priors.max.misfit'] == 'none'
    assert SELAConfig.from_dict(written) == c
    assert SELAConfig().to_dict()['fall.kernel.sigma'] == 'auto'
    assert SELAConfig().to_dict()['acquisition.caution'] == 0.15
    assert SELAConfig.from_dict({'acquisition.caution': 'none'}).acquisition_caution is None
    assert SELAConfig(acquisition_caution=None).to_dict()['acquisition.caution'] == 'none'
    assert SELAConfig.from_dict({'acquisition.caution': 0.15}).acquisition_caution == 0.15
    # A state file's 0 where none is meant reads as none.
    assert SELAConfig.from_dict({'priors.weights.sd': 0.0}).priors_weights_sd is None
    # 0 is no kernel length, no horizon, no cap: the words say what 0 cannot.
    for field in ('gp_kernel_sigma', 'fall_kernel_sigma', 'priors_max_misfit',
                  'priors_weights_sd', 'acquisition_caution', 'gp_mean_affine',
                  'acquisition_progress', 'gp_mean_descriptor', 'planner_reach',
                  'gp_hyper_sd', 'acquisition_reach'):
        with pytest.raises(ValueError, match='must be'):
            SELAConfig(**{field: 0.0})
    with pytest.raises(ValueError, match='fall.kernel.sigma'):
        SELAConfig.from_dict({'fall.kernel.sigma': 0.0})
    with pytest.raises(ValueError, match="priors.weights.sd must be a number or none, got 'auto'"):
        SELAConfig.from_dict({'priors.weights.sd': 'auto'})
    for name in ('gp.kernel.sigma', 'planner.horizon'):
        with pytest.raises(ValueError, match=f"{name} auto is the archive's value"):
            SELAConfig.from_dict({name: 'auto'})
    archive = SimpleNamespace(kernel_sigma=0.3, fall_kernel_sigma=0.12, planner_horizon=2)
    resolved = archive_config(archive, {'gp.kernel.sigma': 'auto', 'planner.horizon': 'auto',
                                        'fall.kernel.sigma': 'auto'})
    assert (resolved.gp_kernel_sigma, resolved.fall_kernel_sigma,
            resolved.planner_horizon) == (0.3, 0.12, 2)
    assert archive_config(archive, {}) == resolved
    told = archive_config(archive, {'gp.kernel.sigma': 0.2, 'planner.horizon': 1})
    assert told.gp_kernel_sigma == 0.2 and told.planner_horizon == 1
    with pytest.raises(ValueError, match='gp.kernel.sigma'):
        archive_config(archive, {'gp.kernel.sigma': 0})


def test_constructor_checks_shapes():
    with pytest.raises(ValueError, match='prior_gr'):
        SELA(np.zeros((5, 1)), np.zeros((5, 2)), SE2Motion())
    with pytest.raises(ValueError, match='normalised'):
        SELA(np.full((5, 1), 2.0), np.zeros((5, 2)), PointMotion())
    sela = SELA(np.zeros((5, 1)), np.zeros((5, 2)), PointMotion())
    with pytest.raises(RuntimeError, match='goal'):
        sela.ask([0.0, 0.0])
    sela.set_goal([1.0, 1.0])
    with pytest.raises(ValueError, match='pose'):
        sela.ask([0.0, 0.0, 0.0])


def test_ask_decision_on_intact_prior():
    world, problem = toy(noise_std=0.0)
    sela = problem.make_sela()
    d = sela.ask(np.zeros(2))
    # The intact model says: step at 45 degrees lands on the waypoint.
    np.testing.assert_allclose(d.waypoint, [0.1 / math.sqrt(2)] * 2, atol=1e-9)
    assert abs(world.thetas[d.index] - math.pi / 4) <= math.pi / 360
    assert d.reward == pytest.approx(-np.linalg.norm(d.predicted_pose - d.waypoint))
    assert d.sigma == pytest.approx(1.0)


def test_tell_learns_the_damage():
    world, problem = toy(noise_std=0.0)
    sela = problem.make_sela()
    d = sela.ask(np.zeros(2))
    after = world.execute(d.index)
    sela.tell(d.index, observed_generic_reward(np.zeros(2), after, sela.motion))
    mu, sigma = sela.predict()
    np.testing.assert_allclose(mu[d.index], world.damaged_generic_reward()[d.index], atol=1e-3)
    assert sigma[d.index] < 0.05
    d2 = sela.ask(world.true_pose())
    assert d2.index != d.index


@pytest.mark.parametrize('seed', [0, 1, 2])
def test_sela_reaches_goal_nearly_as_fast_as_the_oracle(seed):
    world, problem = toy(seed=seed)
    res = run_sela(world, problem, np.random.default_rng(seed))
    assert res.success
    assert np.linalg.norm(world.true_pose() - [2.0, 2.0]) < 0.1
    oracle = run_oracle(world, problem, np.random.default_rng(seed))
    assert oracle.success and oracle.steps == 28
    assert res.steps <= 31 and res.learning_iterations == 0
    # Looking two steps ahead with the true outcomes gets there too, never slower here.
    ahead = METHODS['oracle_2step'](world, problem, np.random.default_rng(seed))
    assert ahead.success and ahead.steps <= oracle.steps


def test_sela_is_told_which_steps_started_standing(monkeypatch):
    """The runner tells SELA whether each step started standing, as the environment says
    (after a reset, and after a fallen robot was righted), for the damage priors."""
    class Righted(ToyWorld):
        def reset(self):
            super().reset()
            self.standing = True

        def execute(self, index):
            self.standing = len(told) == 1  # as if the second step had been righted
            return super().execute(index)

    told = []
    tell = SELA.tell
    monkeypatch.setattr(SELA, 'tell', lambda self, i, gr, standing_start=False: (
        told.append(standing_start), tell(self, i, gr, standing_start))[1])
    world = Righted(360, noise_std=0.01, rng=np.random.default_rng(0))
    assert run_sela(world, toy_problem(world), np.random.default_rng(0)).success
    assert told[:4] == [True, False, True, False] and not any(told[3:])


def test_every_method_returns_a_result():
    for name, run in METHODS.items():
        world, problem = toy(seed=3)
        res = run(world, problem, np.random.default_rng(3))
        assert res.steps <= problem.max_steps, name
        if name in ('sela', 'oracle', 'oracle_2step'):
            assert res.learning_iterations == 0
        else:
            assert res.learning_iterations > 0, name


def test_state_dict_round_trip_through_json():
    world, problem = toy(seed=4)
    sela = problem.make_sela()
    pose = world.observed_pose()
    for _ in range(5):
        d = sela.ask(pose)
        after = world.execute(d.index)
        sela.tell(d.index, observed_generic_reward(pose, after, sela.motion))
        pose = after
    state = json.loads(json.dumps(sela.state_dict()))
    other = problem.make_sela()
    other.load_state_dict(state)
    np.testing.assert_allclose(other.predict()[0], sela.predict()[0], atol=1e-12)
    assert other.observations[0].tolist() == sela.observations[0].tolist()
    assert other.ask(pose).index == sela.ask(pose).index
    sela.reset_learning()
    assert len(sela.observations[0]) == 0
    with pytest.raises(ValueError, match='candidates'):
        SELA(np.zeros((3, 1)), np.zeros((3, 2)), PointMotion()).load_state_dict(state)


def test_the_latest_observations_are_kept_and_taken_back_as_learnt():
    world, problem = toy(seed=5)
    sela = problem.make_sela()
    pose = world.observed_pose()
    for _ in range(12):
        d = sela.ask(pose)
        after = world.execute(d.index)
        sela.tell(d.index, observed_generic_reward(pose, after, sela.motion))
        sela.tell_fall(d.index, False)
        pose = after
    state = json.loads(json.dumps(sela.state_dict()))
    indices = sela.observations[0].tolist()
    # Taken back whole: what the steps scored, and the posterior, as learnt.
    whole = problem.make_sela()
    whole.load_state_dict(state)
    np.testing.assert_allclose(whole.predict()[0], sela.predict()[0], atol=1e-9)
    assert whole.state_dict()['surprises'] == state['surprises']
    assert whole.state_dict()['prior_scores'] == state['prior_scores']
    # The latest 5 only: as if only they had been learnt.
    latest = problem.make_sela()
    latest.load_state_dict(state, keep=5)
    reference = problem.make_sela()
    for i, y in zip(indices[-5:], sela.observations[1][-5:]):
        reference.tell(int(i), y)
    np.testing.assert_allclose(latest.predict()[0], reference.predict()[0], atol=1e-9)
    assert latest.observations[0].tolist() == indices[-5:]
    assert latest.fall_observations == 5
    # Bounded in place: the same.
    assert sela.keep_latest(5) == 7
    assert sela.observations[0].tolist() == indices[-5:] and sela.fall_observations == 5
    np.testing.assert_allclose(sela.predict()[0], reference.predict()[0], atol=1e-9)
    assert sela.keep_latest(5) == 0


def test_goal_reached():
    sela = SELA(np.zeros((2, 1)), np.zeros((2, 2)), PointMotion(), goal=[2.0, 2.0])
    assert sela.goal_reached([1.95, 2.05])
    assert not sela.goal_reached([1.9, 1.9])


@pytest.mark.parametrize('method', ['sela', 'ite_uncertainty', 'oracle'])
def test_a_mission_visits_its_goals_in_order_and_carries_learning(method):
    world, problem = toy()
    problem.via = ((1.0, -0.5), (-0.5, 1.0))
    problem.max_steps = 200
    visits = []
    execute = world.execute

    def execute_and_watch(index):  # the pose the goal is judged on, after every step
        out = execute(index)
        # SELA runs the adapter's loop, which judges the goal on the observed pose, as the
        # node does; the baselines judge it on the true pose.
        visits.append(out if method == 'sela' else world.true_pose())
        return out

    world.execute = execute_and_watch
    result = METHODS[method](world, problem, np.random.default_rng(0))
    assert result.success and len(result.goal_steps) == 3
    assert result.goal_steps == sorted(result.goal_steps)
    offset = result.learning_iterations  # learning trials also move the robot
    for goal, steps in zip([*problem.via, (2.0, 2.0)], result.goal_steps):
        assert np.linalg.norm(visits[offset + steps - 1] - goal) < 0.1
    np.testing.assert_allclose(problem.goal, (2.0, 2.0))  # the last goal again after


def test_two_steps_ahead_keeps_the_robot_placed_for_the_next_step():
    # Gait 0 lands on the first waypoint but turns the robot around; gait 1 stops a little
    # short facing the same way, from where gait 1 again lands near the second waypoint.
    gr = np.array([[0.5, 0.0, np.pi], [0.45, 0.0, 0.0], [0.0, 0.0, 0.0]])
    candidates = np.array([[0.0], [0.5], [1.0]])
    chosen = {}
    for horizon in (1, 2):
        config = SELAConfig(acquisition_ucb_alpha=0.0, planner_horizon=horizon,
                            planner_lookahead=0.5)
        sela = SELA(candidates, gr, SE2Motion(), goal=(3.0, 0.0), config=config)
        chosen[horizon] = sela.ask(np.zeros(3)).index
        # Given the planner node's waypoint, the next one is passed in (or the stepper's
        # extrapolation: learning.following_waypoint).
        assert sela.ask(np.zeros(3), waypoint=(0.5, 0.0),
                        next_waypoint_xy=(1.0, 0.0)).index == chosen[horizon]
    assert chosen == {1: 0, 2: 1}
    # Near the goal there is no second step: the nearest landing wins.
    near = SELA(candidates, gr, SE2Motion(), goal=(0.5, 0.0),
                config=SELAConfig(planner_horizon=2, planner_lookahead=0.5,
                                  acquisition_ucb_alpha=0.0))
    assert near.ask(np.zeros(3)).index == 0
    with pytest.raises(ValueError, match='planner.horizon'):
        SELAConfig(planner_horizon=3)


@pytest.mark.parametrize('motion', [SE2Motion(), PointMotion()])
def test_landing_distances_of_many_poses_at_once_are_those_of_each(motion):
    rng = np.random.default_rng(4)
    gr_t = rng.normal(0, 0.4, (motion.gr_dim, 50))
    poses = rng.normal(0, 1, (7, motion.pose_dim))
    target = np.array([0.3, -1.2])
    sq = motion.landing_sq_distances(poses, gr_t, target)
    for k, pose in enumerate(poses):
        x, y = motion.predict_xy_columns(pose, gr_t)
        assert np.allclose(sq[k], (x - target[0]) ** 2 + (y - target[1]) ** 2)


def test_the_step_after_a_given_waypoint_goes_on_the_same_way_and_stops_at_the_goal():
    from sela_ros.core.mission.logic import following_waypoint

    assert np.allclose(following_waypoint((0, 0, 1.0), (0.6, 0.0), (3.0, 0.0)), (1.2, 0.0))
    assert np.allclose(following_waypoint((0, 0), (0.6, 0.0), (0.8, 0.0)), (0.8, 0.0))
    assert following_waypoint((0, 0), (0.6, 0.0), (0.6, 0.0)) is None


def test_another_config_keeps_what_was_learnt_and_a_wrong_one_is_refused():

    rng = np.random.default_rng(0)
    candidates = rng.random((20, 2))
    sela = SELA(candidates, np.zeros((20, 2)), PointMotion(), goal=[1.0, 0.0])
    sela.tell(3, np.array([0.1, 0.0]))
    sela.set_config(dataclasses.replace(sela.config, acquisition_ucb_alpha=0.0))
    assert sela.config.acquisition_ucb_alpha == 0.0 and sela.observations[0].tolist() == [3]
    with pytest.raises(TypeError, match='SELAConfig'):
        sela.set_config(0.5)


def _surprised(caution, goal=(2.0, 0.0)):
    """Five gaits the map says all step 0.5 m east; three tried: the one gait that goes
    0.35 m, and two that go 0.1 m (the map 0.15 and 0.4 m off: about 0.18 m per axis). The
    goal is far east: the waypoint 0.6 m east."""
    sela = SELA(np.linspace(0, 1, 5)[:, None], np.tile([0.5, 0.0], (5, 1)), PointMotion(),
                goal=goal, config={'gp.kernel.sigma': 0.05, 'acquisition.ucb.alpha': 0.0,
                                   'acquisition.caution': caution, 'gp.mean.affine': 'none'})
    for index, dx in ((4, 0.1), (0, 0.35), (1, 0.1)):
        sela.tell(index, [dx, 0.0])
    return sela


def test_caution_prefers_a_gait_tried_once_the_map_proves_wrong():
    # Untried gaits are predicted to land 0.1 m short of the waypoint, but the steps showed
    # how far off the map is for this robot: the gait tried that lands 0.25 m short is surer.
    assert _surprised(0.15).ask(np.zeros(2)).index == 0
    # Without caution (or above the error learnt) the prediction is taken at its word.
    assert _surprised(None).ask(np.zeros(2)).index in (2, 3)
    assert _surprised(0.3).ask(np.zeros(2)).index in (2, 3)

@pytest.mark.parametrize('name, chosen', [('remove:a', (0,)),
                                          ('self-model remove:a', (2, 3))])
def test_a_self_models_table_is_used_with_the_caution_of_its_own_record(name, chosen):
    from sela_ros.core.learning import DamagePriors

    # The map proved wrong on three steps; then a table arrives that reproduces them and
    # says the two untried gaits step 0.55 m. A table of the library is used with the
    # caution the map's errors taught; the self-model's, made for the damage the feet
    # showed, with that of the steps chosen on it (none yet).
    sela = _surprised(0.15)
    table = np.array([[0.35, 0.0], [0.1, 0.0], [0.55, 0.0], [0.55, 0.0], [0.1, 0.0]])
    sela.priors = DamagePriors((name,), table[None], np.zeros((1, 5), bool), 'sum')
    decision = sela.ask(np.zeros(2))
    assert decision.prior == name and decision.index in chosen


def test_on_the_step_to_the_goal_caution_never_stays_put():
    """A gait tried that barely moves would always seem surer than one that could land on
    the goal: on the step to it, only gaits that bring the robot a goal.eps nearer count."""
    from sela_ros.core.learning.acquisition import (
        expected_distance,
        landing_variance,
        learnt_error,
    )

    sela = SELA(np.linspace(0, 1, 5)[:, None], np.tile([0.5, 0.0], (5, 1)), PointMotion(),
                goal=(0.32, 0.0), config={'gp.kernel.sigma': 0.05, 'acquisition.ucb.alpha': 0.0,
                                          'acquisition.caution': 0.15,
                                          'gp.mean.affine': 'none'})
    sela.tell(0, [0.0, 0.0])  # stays put: its landing 0.32 m from the goal, surely
    mu, sigma = sela.predict()
    error = learnt_error(sela.state_dict()['surprises'])
    expected = expected_distance((mu[:, 0] - 0.32) ** 2 + mu[:, 1] ** 2,
                                 landing_variance(sigma ** 2, error))
    assert int(np.argmin(expected)) == 0  # by expected distance alone it would stay put
    assert sela.ask(np.zeros(2)).index in (1, 2, 3, 4)


def _three_gaits(progress, goal=(2.0, 0.0)):
    """Three gaits on the map: 0.25 m east, 1.2 m east, and 0.45 m east with 0.3 m north."""
    return SELA(np.array([[0.0], [0.5], [1.0]]),
                np.array([[0.25, 0.0], [1.2, 0.0], [0.45, 0.3]]), PointMotion(), goal=goal,
                config={'acquisition.ucb.alpha': 0.0, 'acquisition.caution': 'none',
                        'gp.mean.affine': 'none', 'acquisition.progress': progress})


def test_progress_takes_the_gait_that_goes_furthest_along_the_path():
    # By the distance to the waypoint (0.6 m east) the gait that goes 0.45 m at a slant is
    # the best (0.34 m from it), and the one that lands 0.6 m beyond it the worst.
    assert _three_gaits('none').ask(np.zeros(2)).index == 2
    # Along the path to the goal the long step is the best, and the slant (0.45 m along,
    # 0.3 m off) is worth less than the short straight step when being off counts double.
    assert _three_gaits(1.0).ask(np.zeros(2)).index == 1
    decision = _three_gaits(2.0).ask(np.zeros(2))
    assert decision.index == 1 and decision.reward == pytest.approx(0.6)
    # The node's way, the waypoint given (the path runs on from it to the goal): the same.
    assert _three_gaits(1.0).ask(np.zeros(2), waypoint=[0.6, 0.0]).index == 1
    # Near the goal a landing beyond it is as far off as its distance to the goal.
    near = _three_gaits(1.0, goal=(0.3, 0.0)).ask(np.zeros(2))
    assert near.index == 0


def test_progress_is_a_parameter_with_a_word_for_off():
    assert SELAConfig().acquisition_progress is None
    assert SELAConfig().to_dict()['acquisition.progress'] == 'none'
    assert SELAConfig.from_dict({'acquisition.progress': 1.5}).acquisition_progress == 1.5
    with pytest.raises(ValueError, match='acquisition.progress'):
        SELAConfig.from_dict({'acquisition.progress': -1.0})


def test_progress_two_steps_ahead_leaves_the_robot_facing_the_path():
    """Two steps ahead, the first gait is the one after which the best next gait goes
    furthest along the path: not the longest step if it turns the robot away."""
    # Gaits (dx, dy, dyaw): 0.45 m ahead turning 1.5 rad, 0.3 m and 0.35 m straight ahead.
    gr = np.array([[0.45, 0.0, 1.5], [0.3, 0.0, 0.0], [0.35, 0.0, 0.0]])

    def choice(horizon):
        sela = SELA(np.array([[0.0], [0.5], [1.0]]), gr, SE2Motion(), goal=(3.0, 0.0),
                    config={'acquisition.ucb.alpha': 0.0, 'acquisition.caution': 'none',
                            'gp.mean.affine': 'none', 'acquisition.progress': 1.0,
                            'planner.horizon': horizon})
        return sela.ask(np.zeros(3), waypoint=[0.6, 0.0], next_waypoint_xy=[1.2, 0.0]).index

    assert choice(1) == 0  # one step: the furthest along
    assert choice(2) == 2  # two: the longer straight step, then the long one


def _reach_sela(prior, reach, sigma=0.02, horizon=1):
    """SELA over gaits on a 1-D map far apart (no gait's step says anything of another's),
    caution on from the first step, no UCB bonus; the goal 2 m east (waypoint 0.6 m)."""
    return SELA(np.linspace(0.0, 1.0, len(prior))[:, None], np.asarray(prior, dtype=float),
                PointMotion(), goal=(2.0, 0.0),
                config={'gp.kernel.sigma': sigma, 'acquisition.ucb.alpha': 0.0,
                        'acquisition.caution': 0.01, 'gp.mean.affine': 'none',
                        'acquisition.reach': reach, 'planner.horizon': horizon})


def test_reach_a_gait_that_surely_stays_put_does_not_beat_one_that_may_reach():
    # Gait 0 goes 0.1 m, as predicted; gaits 1-5 were predicted to reach the waypoint and
    # stayed put; gaits 6-11 are predicted to reach it, untried.
    prior = [[0.1, 0.0]] + [[0.6, 0.0]] * 11

    def choice(reach):
        sela = _reach_sela(prior, reach)
        sela.tell(0, [0.1, 0.0])
        for i in range(1, 6):
            sela.tell(i, [0.0, 0.0])
        return sela.ask(np.zeros(2))

    # By the expected distance the sure short step (0.5 m from the waypoint, surely) beats an
    # untried gait that lands anywhere within 0.36 m (per axis) of the waypoint.
    assert choice('none').index == 0
    # Gait 0 is unlikely to land within 0.45 m of the waypoint; an untried one is likely to.
    decision = choice(0.45)
    assert decision.index in range(6, 12)
    assert 0.5 * 0.45 - 0.01 < decision.reward < 0.6 * 0.45  # reach x a chance of 0.5-0.6


def test_reach_a_fast_sure_gait_beats_a_fast_unsure_one():
    # Gait 0 was tried and lands on the waypoint; gait 2 is predicted to, untried, while
    # gait 1 showed the untried gaits land 0.3 m from where they are predicted.
    sela = _reach_sela([[0.6, 0.0], [0.6, 0.3], [0.6, 0.0]], 0.3)
    sela.tell(0, [0.6, 0.0])
    sela.tell(1, [0.6, 0.0])
    decision = sela.ask(np.zeros(2))
    assert decision.index == 0 and decision.reward > 0.29


def test_reach_falls_back_to_the_expected_distance_where_no_gait_has_a_chance():
    # Every gait goes at most 0.15 m: none can land within 0.15 m of a waypoint 0.6 m away.
    prior = [[0.05, 0.0], [0.15, 0.0], [0.1, 0.05], [0.0, 0.0]]
    plain, aprol = _reach_sela(prior, 'none'), _reach_sela(prior, 0.15)
    for sela in (plain, aprol):
        sela.tell(3, [0.0, 0.0])
    assert aprol.ask(np.zeros(2)).index == plain.ask(np.zeros(2)).index == 1
    assert aprol.ask(np.zeros(2)).reward == plain.ask(np.zeros(2)).reward


def test_reach_two_steps_ahead_prefers_the_first_step_from_which_the_second_can_reach():
    """Gaits (dx, dy, dyaw): 0.6 m ahead turning 1.5 rad, 0.5 m ahead straight, 0.1 m ahead.
    Both long steps are likely to land within 0.3 m of the first waypoint; only the straight
    one leaves the robot where a second gait can land within reach of the second."""
    gr = np.array([[0.6, 0.0, 1.5], [0.5, 0.0, 0.0], [0.1, 0.0, 0.0]])

    def choice(horizon):
        sela = SELA(np.array([[0.0], [0.5], [1.0]]), gr, SE2Motion(), goal=(3.0, 0.0),
                    config={'gp.kernel.sigma': 0.02, 'acquisition.ucb.alpha': 0.0,
                            'acquisition.caution': 0.01, 'gp.mean.affine': 'none',
                            'acquisition.reach': 0.3, 'planner.horizon': horizon})
        for i in range(3):
            sela.tell(i, gr[i])
        return sela.ask(np.zeros(3), waypoint=[0.6, 0.0], next_waypoint_xy=[1.2, 0.0]).index

    assert choice(1) == 0  # one step: the turning one lands on the waypoint
    assert choice(2) == 1


def test_reach_is_a_parameter_with_a_word_for_off():
    assert SELAConfig().acquisition_reach is None
    assert SELAConfig().to_dict()['acquisition.reach'] == 'none'
    assert SELAConfig.from_dict({'acquisition.reach': 0.3}).acquisition_reach == 0.3
    with pytest.raises(ValueError, match='acquisition.reach'):
        SELAConfig.from_dict({'acquisition.reach': -0.3})
