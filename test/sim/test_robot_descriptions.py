"""Robots are descriptions: the hexapod's gaits pinned to their outcomes, and the interface
every description gives the simulator, the map builder and the nodes."""
import numpy as np
import pytest

from sim_bridge.controller import tripod_gait
from sim_bridge.damage import DamageSpecError
from sim_bridge.evaluation import evaluate_gait
from sim_bridge.robots import ROBOTS, RobotDescription, get_robot, robot_of
from sim_bridge.settings import simulator_settings


def _random_gaits():
    rng = np.random.default_rng(7)
    return [rng.random(36) for _ in range(2)]


# Outcomes of the hexapod's gaits (generic reward, duty factors) with the default physics,
# written down from the simulator as the hexapod had it before robots were descriptions:
# moving the hexapod behind its description changed none of them by a bit.
PINNED = [
    ('intact', 'tripod', [0.7079795603334743, 0.07905420317479181, 0.04414416298161232],
     [0.10833333333333334, 0.43194444444444446, 0.39305555555555555, 0.17222222222222222,
      0.4444444444444444, 0.39166666666666666]),
    ('intact', 'tripod_left', [0.0005339217435121955, 0.003712019613430879, 2.23936430298773],
     [0.4638888888888889, 0.44305555555555554, 0.475, 0.46805555555555556,
      0.45555555555555555, 0.4638888888888889]),
    ('remove:middle_right', 'tripod',
     [0.22621640388220296, -0.14037283996107305, -1.109315326513368],
     [0.43333333333333335, 0.4486111111111111, 0.4625, 0.5777777777777777, 0.0, 0.9375]),
    ('block:front_left.knee=0.3,weaken:rear_right.hip_pitch=0.2', 'random_0',
     [0.04191110074520786, 0.002156276963099276, -0.06702967543720728],
     [0.1125, 0.7916666666666666, 0.19027777777777777, 0.6277777777777778,
      0.36944444444444446, 0.30277777777777776]),
    ('shorten:rear_left:0.6', 'random_1',
     [-0.054688531970963926, 0.04727865587067548, -0.3448748232964473],
     [0.37777777777777777, 0.6819444444444445, 0.07777777777777778, 0.2875,
      0.16111111111111112, 0.85]),
]


@pytest.mark.parametrize('damage, gait, reward, duty', PINNED)
def test_the_hexapod_s_gaits_end_exactly_where_they_always_did(damage, gait, reward, duty):
    gaits = {'tripod': tripod_gait(), 'tripod_left': tripod_gait(turn=1.0)}
    gaits.update({f'random_{i}': g for i, g in enumerate(_random_gaits())})
    outcome = evaluate_gait(gaits[gait], damage)
    # To 1e-12 (m, rad), far below any change of the physics: the last bits of the
    # trigonometry differ between machines' math libraries. The foot contacts are exact.
    np.testing.assert_allclose(outcome.generic_reward, reward, rtol=0, atol=1e-12)
    assert outcome.duty_factors.tolist() == duty
    assert not outcome.fallen


def test_the_hexapod_through_its_name_is_the_hexapod():
    gait = tripod_gait()
    by_default = evaluate_gait(gait, 'remove:middle_right')
    by_name = evaluate_gait(gait, 'remove:middle_right', robot='hexapod')
    assert by_name.generic_reward.tolist() == by_default.generic_reward.tolist()


def test_the_hexapod_s_settings_stamp_is_unchanged():
    # Maps built before robots were descriptions must stay valid: no key added.
    assert simulator_settings(robot=get_robot('hexapod')) == simulator_settings()
    assert robot_of({}) == 'hexapod'


@pytest.mark.parametrize('name', sorted(ROBOTS))
def test_every_description_is_consistent(name):
    robot = get_robot(name)
    assert isinstance(robot, RobotDescription) and robot.name == name
    assert len(robot.foot_links) == len(robot.legs) >= 1
    assert robot.n_params >= 1 and len(robot.joint_names) >= 1
    table = robot.target_table(robot.example_gait())
    assert table.shape == (robot.n_samples, len(robot.joint_names))
    assert np.all(np.isfinite(table))
    assert robot.standing_targets().shape == (len(robot.joint_names),)
    assert robot.descriptor_dims['final_xy_duty_factors'] == 2 + len(robot.legs)
    assert len(robot.descriptor_bounds()) == 2 + len(robot.legs)
    assert robot.parse_damage(robot.default_damage).canonical() == \
        robot.parse_damage(robot.parse_damage(robot.default_damage).canonical()).canonical()
    with pytest.raises(ValueError, match=f'shape \\({robot.n_params},\\)'):
        robot.validate_params(np.zeros(robot.n_params + 1))
    stamp = simulator_settings(robot=robot)
    assert stamp['model_version'] == robot.model_version


@pytest.mark.parametrize('name', sorted(ROBOTS))
def test_a_damage_names_the_robot_s_own_legs(name):
    robot = get_robot(name)
    with pytest.raises(DamageSpecError, match='valid legs: ' + ', '.join(robot.legs)):
        robot.parse_damage(f'block:no_such_leg.{robot.vocabulary.joints[0]}')


def test_a_damage_kind_the_robot_does_not_take_is_said_so_with_the_kinds_it_takes():
    a1 = get_robot('a1')
    assert 'remove' not in a1.vocabulary.kinds
    with pytest.raises(DamageSpecError) as exc:
        a1.parse_damage('remove:front_left')
    assert str(exc.value).startswith("the a1 does not take damage kind 'remove' (in "
                                     "'remove:front_left'); valid kinds: "
                                     + ', '.join(a1.vocabulary.kinds))
    with pytest.raises(DamageSpecError, match="unknown damage kind 'melt'"):
        a1.parse_damage('melt:front_left')


def test_an_unknown_robot_is_refused_with_the_known_ones():
    with pytest.raises(ValueError, match='known robots: hexapod'):
        get_robot('octopod')
    with pytest.raises(ValueError, match='cannot import'):
        get_robot('no_such_module:ROBOT')


def test_robot_spec_finds_a_description_in_another_process_by_a_string():
    from sim_bridge.robots import robot_spec
    from sim_bridge.robots.toy import TOY

    assert robot_spec('hexapod') == 'hexapod' and robot_spec(TOY) == 'toy'
    with pytest.raises(ValueError, match='unknown robot'):
        robot_spec('no_such_robot')
