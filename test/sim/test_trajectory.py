"""A gait as a joint trajectory: the checks that refuse one, and playing one in the
simulator, which must do exactly what the controller's own gait does."""
import math

import numpy as np
import pytest

from sim_bridge import hexapod as hx
from sim_bridge import trajectory as tj
from sim_bridge.controller import tripod_gait
from sim_bridge.environment import ObservedHexapod
from sim_bridge.model import ALL_JOINT_NAMES, FALL_TILT, p
from sim_bridge.robots import ROBOTS, get_robot
from sim_bridge.settings import FAST_SETTINGS

RNG = np.random.default_rng(3)


def test_the_boundary_names_the_simulated_robot():
    assert tj.joint_names() == ALL_JOINT_NAMES
    urdf_limits = {}
    robot = hx.Hexapod(**FAST_SETTINGS)
    try:
        for j in range(p.getNumJoints(robot.robot_id, physicsClientId=robot.client_id)):
            info = p.getJointInfo(robot.robot_id, j, physicsClientId=robot.client_id)
            if info[2] == p.JOINT_REVOLUTE:
                urdf_limits[info[1].decode()] = (info[8], info[9])
    finally:
        robot.close()
    assert urdf_limits.keys() == tj.joint_limits().keys()
    for name, (lower, upper) in tj.joint_limits().items():
        assert urdf_limits[name] == pytest.approx((lower, upper)), name
    assert math.isclose(FALL_TILT, math.radians(60.0))


def test_gait_trajectory_samples_the_controller_at_its_rate():
    params = RNG.uniform(size=36)
    times, positions = tj.gait_trajectory(params, 3.0)
    assert len(times) == 301 and times[0] == 0.0 and times[-1] == 3.0
    assert np.allclose(np.diff(times), 0.01)
    tj.check_trajectory(tj.joint_names(), times, positions)  # the controller stays in limits
    assert np.array_equal(positions[:100], positions[100:200])  # periodic, 1 s
    with pytest.raises(ValueError, match=r'\[0, 1\]'):
        tj.gait_trajectory(np.full(36, 2.0), 3.0)


@pytest.mark.parametrize('damage', ['intact', 'remove:middle_right,block:front_left.knee=0.3'])
def test_a_held_trajectory_reproduces_the_direct_gait_bitwise(damage):
    params = [tripod_gait(0.5, 0.5), RNG.uniform(size=36)]
    direct = hx.Hexapod(damage=damage, **FAST_SETTINGS)
    played = hx.Hexapod(damage=damage, **FAST_SETTINGS)
    try:
        for gait in params + params:  # chained, from where the last gait left the legs
            a = direct.execute(gait)
            times, positions = tj.gait_trajectory(gait, direct.gait_duration)
            b = played.execute_targets(tj.hold_targets(tj.joint_names(), times, positions,
                                                       played.dt))
            assert np.array_equal(a.end_pose, b.end_pose)
            assert np.array_equal(a.duty_factors, b.duty_factors)
            assert (a.fallen, a.sim_time, a.standing_start) == (b.fallen, b.sim_time,
                                                                b.standing_start)
    finally:
        direct.close()
        played.close()


def test_the_observation_model_is_the_same_for_both_paths():
    gait = tripod_gait(0.5, 0.5)
    envs = [ObservedHexapod(hx.Hexapod(**FAST_SETTINGS), noise_std=0.01, seed=5)
            for _ in range(2)]
    try:
        times, positions = tj.gait_trajectory(gait, envs[1].robot.gait_duration)
        targets = tj.hold_targets(tj.joint_names(), times, positions, envs[1].robot.dt)
        for _ in range(2):
            a = envs[0].execute(gait)
            b = envs[1].execute_targets(targets)
            assert np.array_equal(a.observed_generic_reward, b.observed_generic_reward)
            assert np.array_equal(a.observed_end, b.observed_end)
    finally:
        for env in envs:
            env.robot.close()


def test_hold_targets_holds_each_point_and_leaves_undriven_joints_standing():
    names = ['front_left.knee']
    targets = tj.hold_targets(names, [0.1, 0.5, 1.0], [[0.1], [0.2], [0.3]], dt=0.25)
    column = tj.joint_names().index('front_left.knee')
    # steps at 0, 0.25, 0.5, 0.75: before the first point it is held too
    assert targets[:, column].tolist() == [0.1, 0.1, 0.2, 0.2]
    assert not np.delete(targets, column, axis=1).any()


@pytest.mark.parametrize('names, times, positions, message', [
    (['front_left.hip_yaw', 'front_left.elbow'], [1.0], [[0.0, 0.0]],
     "unknown joint.*'front_left.elbow'"),
    (['front_left.knee', 'front_left.knee'], [1.0], [[0.0, 0.0]], 'named twice'),
    (['front_left.knee'], [], np.zeros((0, 1)), 'no points'),
    (['front_left.knee'], [1.0, 1.0], [[0.0], [0.0]], 'strictly increase'),
    (['front_left.knee'], [1.0], [[math.nan]], 'finite'),
    (['front_left.knee'], [1.0], [[0.0, 0.0]], 'one position per joint'),
    (['front_left.hip_pitch', 'rear_right.knee'], [0.5, 1.0], [[0.1, 0.2], [0.3, 0.9]],
     r'rear_right.knee at point 1 \(t = 1.000 s\): 0.9000 rad is beyond its limits '
     r'\[-0.7854, 0.7854\]'),
])
def test_check_trajectory_refuses_with_a_clear_message(names, times, positions, message):
    with pytest.raises(tj.TrajectoryError, match=message):
        tj.check_trajectory(names, times, positions)


@pytest.mark.parametrize('name', sorted(ROBOTS))
def test_every_robots_gait_is_a_trajectory_within_its_urdf_limits_played_as_the_gait(name):
    from sim_bridge.simulator import Simulator

    description = get_robot(name)
    assert tj.joint_limits(name).keys() == set(description.joint_names)
    gait = description.example_gait()
    times, positions = tj.gait_trajectory(gait, description.gait_duration, robot=name)
    assert np.allclose(np.diff(times)[:-1], description.period / description.n_samples)
    tj.check_trajectory(description.joint_names, times, positions, robot=name)
    direct, played = (Simulator(robot=description, **FAST_SETTINGS) for _ in range(2))
    try:
        a = direct.execute(gait)
        b = played.execute_targets(tj.hold_targets(description.joint_names, times, positions,
                                                   played.dt, robot=name))
        assert np.array_equal(a.end_pose, b.end_pose) and a.fallen == b.fallen
    finally:
        direct.close()
        played.close()
