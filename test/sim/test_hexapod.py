"""Tests of the PyBullet hexapod: walking, damage, determinism, continuity, falls."""
import json
import math
import pickle

import numpy as np
import pybullet as p
import pytest

from sela_ros.core.geometry import wrap_angle
from sim_bridge import hexapod as hx
from sim_bridge.controller import tripod_gait
from sim_bridge.damage import LEG_NAMES, DamageSpecError
from sim_bridge.evaluation import evaluate_gait
from sim_bridge.model import ALL_JOINT_NAMES, URDF_PATH, hexapod_urdf
from sim_bridge.settings import (
    MODEL_VERSION,
    SIM_DEFAULTS,
    physics_settings,
    read_archive_settings,
    simulator_settings,
)

STRAIGHT = tripod_gait(0.5, 0.5)


@pytest.fixture(scope='module')
def sim():
    robot = hx.Hexapod()
    yield robot
    robot.close()


@pytest.fixture(scope='module')
def intact_outcome():
    return evaluate_gait(STRAIGHT)


def _same(a: hx.GaitOutcome, b: hx.GaitOutcome):
    for name in ('generic_reward', 'start_pose', 'end_pose', 'duty_factors'):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert a.fallen == b.fallen


def test_model_mass_names_and_standing(sim):
    sim.set_damage('intact')
    sim.reset()
    assert math.isclose(sim.total_mass(), 2.5, abs_tol=1e-9)
    assert sim.joint_names == list(ALL_JOINT_NAMES)
    assert sim.joint_names[:3] == ['front_left.hip_yaw', 'front_left.hip_pitch',
                                   'front_left.knee']
    np.testing.assert_allclose(sim.pose(), 0.0, atol=1e-3)
    assert not sim.is_fallen()
    pos, _ = sim.base_pose_3d()
    assert 0.15 < pos[2] < 0.18


def test_shipped_urdf_is_the_intact_model():
    with open(URDF_PATH, encoding='utf-8') as handle:
        assert handle.read() == hexapod_urdf('intact')


def test_settings_stamp():
    s = simulator_settings(1 / 240, 3.0)
    assert s == SIM_DEFAULTS
    assert set(s) == {'dt', 'gait_duration', 'controller_version', 'model_version',
                      'solver_iterations'}
    assert s['solver_iterations'] == 50
    with pytest.raises(ValueError, match='dt'):
        simulator_settings(0.0, 3.0)
    with pytest.raises(ValueError, match='solver_iterations'):
        simulator_settings(1 / 240, 3.0, solver_iterations=2.5)
    with pytest.raises(ValueError, match='solver_iterations'):
        simulator_settings(1 / 240, 3.0, solver_iterations=0)


def test_archive_without_solver_iterations_means_the_old_default(tmp_path):
    # The shipped 2-D archive predates the key: it was built with 50 iterations.
    old = {'dt': 1 / 240, 'gait_duration': 3.0, 'model_version': MODEL_VERSION}
    assert physics_settings(old) == {'dt': 1 / 240, 'gait_duration': 3.0,
                                        'solver_iterations': 50}
    path = tmp_path / 'a.npz'
    np.savez(path, metadata=np.array(json.dumps({**old, 'solver_iterations': 30,
                                                 'dt': 1 / 120})))
    assert read_archive_settings(path) == {'dt': 1 / 120, 'gait_duration': 3.0,
                                              'solver_iterations': 30}
    with pytest.raises(ValueError, match='cannot read'):
        read_archive_settings(tmp_path / 'missing.npz')


def test_solver_iterations_reach_the_physics_and_change_outcomes():
    gait = tripod_gait()
    with hx.Hexapod(solver_iterations=30) as sim:
        assert sim.settings['solver_iterations'] == 30
        sim.reset()
        fewer = sim.execute(gait)
    default = evaluate_gait(gait)
    again = evaluate_gait(gait, solver_iterations=30)
    # Same settings, same outcome (cached simulators are keyed by the setting too) ...
    np.testing.assert_array_equal(again.end_pose, fewer.end_pose)
    # ... and a different setting is really used: outcomes differ, by centimetres at most.
    assert not np.array_equal(default.end_pose, fewer.end_pose)
    assert np.hypot(*(default.end_pose[:2] - fewer.end_pose[:2])) < 0.1


def test_tripod_walks_forward(intact_outcome):
    dx, dy, dyaw = intact_outcome.generic_reward
    assert 0.15 < dx < 0.6
    assert abs(dy) < 0.1 and abs(dyaw) < 0.2
    assert not intact_outcome.fallen
    assert np.all(intact_outcome.duty_factors > 0.1)
    assert math.isclose(intact_outcome.sim_time, 3.0)


def test_a_gait_says_whether_it_started_from_the_settled_standing_state():
    """Built, reset or rebuilt (a damage, a righting): the next gait starts standing, as
    every archive gait and damage-prior table was evaluated; a gait after a gait does not."""
    with hx.Hexapod() as robot:
        first = robot.execute(STRAIGHT)
        second = robot.execute(STRAIGHT)
        assert first.standing_start and not second.standing_start and not robot.standing
        robot.set_damage('remove:middle_right')
        assert robot.execute(STRAIGHT).standing_start
        robot.reset()
        again = robot.execute(STRAIGHT)
        assert again.standing_start and not robot.execute(STRAIGHT).standing_start


@pytest.mark.parametrize('turn', [1, -1])
def test_turning_gait_turns(turn):
    out = evaluate_gait(tripod_gait(1.0, 0.5, turn=turn))
    assert turn * out.generic_reward[2] > 1.0
    assert abs(out.generic_reward[0]) < 0.15 and not out.fallen


def test_same_gait_twice_is_bitwise_identical(sim):
    sim.set_damage('intact')
    sim.reset()
    a = sim.execute(STRAIGHT)
    sim.reset()
    b = sim.execute(STRAIGHT)
    _same(a, b)
    # A fresh instance and the cached evaluate_gait agree too.
    _same(a, evaluate_gait(STRAIGHT))


def test_consecutive_gaits_continue(sim):
    sim.set_damage('intact')
    sim.reset()
    t0 = sim.sim_time
    first = sim.execute(STRAIGHT)
    second = sim.execute(STRAIGHT)
    np.testing.assert_array_equal(second.start_pose, first.end_pose)
    assert math.isclose(second.sim_time - t0, 6.0)
    # The second gait's generic reward is expressed in its own start frame.
    expected = hx.generic_reward(second.start_pose, second.end_pose)
    np.testing.assert_array_equal(second.generic_reward, expected)


def test_callback_period(sim):
    sim.set_damage('intact')
    sim.reset()
    calls = []
    sim.execute(STRAIGHT, callback=lambda t, pose, q, v: calls.append((t, pose, q, v)),
                callback_period=0.1)
    assert len(calls) == 30
    times = np.array([c[0] for c in calls])
    np.testing.assert_allclose(np.diff(times), 0.1, atol=1e-9)
    assert calls[-1][2].shape == (18,) and calls[-1][3].shape == (18,)
    assert calls[-1][1].shape == (3,)


def test_remove_leg_drops_mass_and_contacts(sim, intact_outcome):
    sim.set_damage('remove:middle_right')
    try:
        assert math.isclose(sim.total_mass(), 2.5 - 0.245, abs_tol=1e-9)
        assert len(sim.joint_names) == 15
        assert not any(n.startswith('middle_right.') for n in sim.joint_names)
        sim.reset()
        out = sim.execute(STRAIGHT)
        assert out.duty_factors[LEG_NAMES.index('middle_right')] == 0.0
        # Its links are gone, not just hidden: no foot link is left to touch the ground.
        assert sim._foot_links[LEG_NAMES.index('middle_right')] == -1
        assert not np.allclose(out.generic_reward, intact_outcome.generic_reward, atol=0.02)
    finally:
        sim.set_damage('intact')


def test_shorten_changes_outcome(intact_outcome):
    out = evaluate_gait(STRAIGHT, damage='shorten:front_left:0.5')
    assert np.linalg.norm(out.generic_reward - intact_outcome.generic_reward) > 0.02


def test_shortened_leg_is_shorter():
    with hx.Hexapod(damage='shorten:rear_right:0.5') as robot:
        cid, rid = robot.client_id, robot.robot_id
        feet = robot._foot_links
        z = {leg: p.getLinkState(rid, feet[i], physicsClientId=cid)[0][2]
             for i, leg in enumerate(LEG_NAMES)}
        # The short leg hangs above the ground (the others carry the body).
        assert z['rear_right'] > z['rear_left'] + 0.03


def test_block_keeps_joint_at_angle(intact_outcome):
    with hx.Hexapod(damage='block:front_left.hip_pitch=0.3') as robot:
        index = robot.joint_names.index('front_left.hip_pitch')
        seen = []
        out = robot.execute(STRAIGHT, callback=lambda t, pose, q, v: seen.append(q[index]))
        assert seen and all(q == 0.3 for q in seen)
        # The femur really is welded at 0.3 rad: its pitch w.r.t. the coxa does not move.
        cid, rid = robot.client_id, robot.robot_id
        names = {p.getJointInfo(rid, j, physicsClientId=cid)[12].decode(): j
                 for j in range(p.getNumJoints(rid, physicsClientId=cid))}
        coxa = p.getLinkState(rid, names['front_left.coxa'], physicsClientId=cid)[1]
        femur = p.getLinkState(rid, names['front_left.femur'], physicsClientId=cid)[1]
        _, rel = p.invertTransform([0, 0, 0], coxa)
        _, rel = p.multiplyTransforms([0, 0, 0], rel, [0, 0, 0], femur)
        axis, angle = p.getAxisAngleFromQuaternion(rel)
        assert math.isclose(angle, 0.3, abs_tol=1e-5)
    assert np.linalg.norm(out.generic_reward - intact_outcome.generic_reward) > 0.01


def test_a_limp_joint_lags_its_commands_and_changes_the_walk(intact_outcome):
    def lag(damage):
        with hx.Hexapod(damage=damage) as robot:
            index = robot.joint_names.index('front_left.hip_pitch')
            seen = []
            out = robot.execute(STRAIGHT, callback=lambda t, pose, q, v: seen.append(q[index]))
            return np.array(seen), out

    followed, _ = lag('intact')
    limp, weak = lag('weaken:front_left.hip_pitch=0.0')
    # No torque: the joint is only dragged along by the body and the ground, it does not
    # follow the gait's commands as the intact one does.
    assert np.mean(np.abs(limp - followed)) > 0.1
    assert np.linalg.norm(weak.generic_reward - intact_outcome.generic_reward) > 0.01


def test_a_payload_adds_its_mass_where_it_was_put(sim):
    sim.set_damage('payload:1.0@0.08,0.05')
    try:
        assert math.isclose(sim.total_mass(), 3.5, abs_tol=1e-9)
        cid, rid = sim.client_id, sim.robot_id
        names = {p.getJointInfo(rid, j, physicsClientId=cid)[12].decode(): j
                 for j in range(p.getNumJoints(rid, physicsClientId=cid))}
        base, orn = sim.base_pose_3d()
        where = p.getLinkState(rid, names['payload'], physicsClientId=cid)[0]
        _, back = p.invertTransform(base, orn)
        local, _ = p.multiplyTransforms([0, 0, 0], back, np.subtract(where, base).tolist(),
                                        [0, 0, 0, 1])
        np.testing.assert_allclose(local[:2], (0.08, 0.05), atol=1e-6)
        assert sim.joint_names == list(ALL_JOINT_NAMES) and not sim.is_fallen()
        sim.reset()
        assert sim.execute(STRAIGHT).generic_reward[0] > 0.0  # it still walks
    finally:
        sim.set_damage('intact')


def test_the_grounds_friction_changes_the_walk_and_comes_back(sim, intact_outcome):
    cid = sim.client_id
    sim.set_damage('friction:0.3')
    try:
        assert p.getDynamicsInfo(sim._ground, -1, physicsClientId=cid)[1] == 0.3
        sim.reset()
        slippery = sim.execute(STRAIGHT)
        assert np.linalg.norm(slippery.generic_reward - intact_outcome.generic_reward) > 0.01
    finally:
        sim.set_damage('intact')
    assert p.getDynamicsInfo(sim._ground, -1, physicsClientId=cid)[1] == 1.0
    sim.reset()
    _same(sim.execute(STRAIGHT), intact_outcome)


def test_set_damage_keeps_pose(sim):
    sim.set_damage('intact')
    sim.reset()
    sim.execute(tripod_gait(1.0, 0.5, turn=1))
    before = sim.pose()
    t = sim.sim_time
    sim.set_damage('remove:middle_right,block:front_left.knee')
    np.testing.assert_allclose(sim.pose()[:2], before[:2], atol=2e-3)
    assert abs(wrap_angle(sim.pose()[2] - before[2])) < 2e-3
    assert sim.sim_time == t and not sim.is_fallen()
    sim.reset()
    np.testing.assert_allclose(sim.pose(), 0.0, atol=1e-3)
    sim.set_damage('intact')


def test_unknown_damage_lists_valid_names():
    with pytest.raises(DamageSpecError, match='middle_right'):
        evaluate_gait(STRAIGHT, damage='remove:middle')


def test_fall_detection_upside_down(sim):
    sim.set_damage('intact')
    sim.reset()
    assert not sim.is_fallen()
    p.resetBasePositionAndOrientation(sim.robot_id, [0, 0, 0.3],
                                      p.getQuaternionFromEuler([math.pi, 0, 0]),
                                      physicsClientId=sim.client_id)
    assert sim.is_fallen()
    p.resetBasePositionAndOrientation(sim.robot_id, [0, 0, 0.3],
                                      p.getQuaternionFromEuler([0, math.radians(70), 0]),
                                      physicsClientId=sim.client_id)
    assert sim.is_fallen()
    sim.reset()
    assert not sim.is_fallen()


def test_generic_reward_frame_and_wrap():
    gr = hx.generic_reward([1.0, 1.0, math.pi / 2], [1.0, 2.0, -math.pi + 0.1])
    # Facing +y, a step of +1 in world y is straight ahead; yaw change wraps to +pi/2+0.1.
    np.testing.assert_allclose(gr, [1.0, 0.0, math.pi / 2 + 0.1], atol=1e-12)
    assert wrap_angle(-math.pi) == math.pi


def test_several_instances_coexist():
    a, b = hx.Hexapod(), hx.Hexapod(damage='remove:front_left')
    try:
        assert a.client_id != b.client_id
        _same(a.execute(STRAIGHT), evaluate_gait(STRAIGHT))
    finally:
        a.close()
        b.close()


def test_evaluate_gait_is_picklable_and_validates():
    assert pickle.loads(pickle.dumps(evaluate_gait)) is evaluate_gait
    with pytest.raises(ValueError, match='shape'):
        evaluate_gait(np.zeros(3))


def test_gui_without_display_is_a_clear_error(monkeypatch):
    monkeypatch.delenv('DISPLAY', raising=False)
    monkeypatch.delenv('WAYLAND_DISPLAY', raising=False)
    with pytest.raises(RuntimeError, match='display'):
        hx.Hexapod(gui=True)


@pytest.mark.slow
def test_random_gaits_mostly_upright():
    rng = np.random.default_rng(0)
    outcomes = [evaluate_gait(rng.random(36)) for _ in range(20)]
    assert sum(o.fallen for o in outcomes) <= 2
    assert all(np.all(np.abs(o.generic_reward[:2]) < 1.5) for o in outcomes)


def test_the_observation_noise_can_change_and_a_bad_one_is_refused():
    from sim_bridge.environment import ObservedHexapod

    with hx.Hexapod() as robot:
        env = ObservedHexapod(robot, 0.0, seed=1)
        with pytest.raises(ValueError, match='noise_std'):
            env.set_noise_std(float('nan'))
        with pytest.raises(ValueError, match='noise_std'):
            env.set_noise_std(-0.1)
        env.set_noise_std(0.5)
        env.reset()
        assert np.linalg.norm(env.observed_pose()[:2] - env.true_pose()[:2]) > 1e-3


def test_a_forked_child_leaves_the_physics_client_to_the_process_that_connected_it():
    import os

    robot = hx.Hexapod()
    client = robot._client
    child = os.fork()
    if child == 0:  # the child: closing its copy of the robot must not disconnect
        calls = []
        p.disconnect = lambda **kwargs: calls.append(kwargs)
        robot.close()
        os._exit(0 if not calls and robot._client == -1 else 1)
    _, status = os.waitpid(child, 0)
    assert os.waitstatus_to_exitcode(status) == 0
    assert p.getConnectionInfo(physicsClientId=client)['isConnected']
    robot.execute(STRAIGHT)
    robot.close()  # the owner's close does disconnect
    assert not p.getConnectionInfo(physicsClientId=client)['isConnected']


def test_worker_pools_start_fresh_never_forked_from_the_caller():
    import os

    from sim_bridge.evaluation import worker_pool

    with worker_pool(1) as pool:
        # A forked worker's parent would be this process; a fresh one's is the server.
        assert pool.submit(os.getppid).result(timeout=120) != os.getpid()
