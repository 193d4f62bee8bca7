"""The hardware path over DDS: the gait executor plays the adapter's gaits through a
joint_trajectory_controller's topic and measures them on an odometry topic; sim_bridge's
hardware face plays them in the simulator (or this test plays a robot itself)."""
import math
import time

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticStatus

from sela_ros.core.geometry import generic_reward
from sela_ros.core.storage import default_archive_path, load_archive
from sela_ros.nodes import conversions as conv
from sela_ros.nodes import interface as ifc
from sela_ros.tools.demo import simulated_hardware
from sim_bridge import trajectory as tj
from sim_bridge.robots import get_robot

from ros_graph import Client, NodeProcesses

pytestmark = [pytest.mark.dds, pytest.mark.slow]

FAKE_ODOM = 'fake_robot/odom'


class Recorder:
    """What the executor and the simulator say: trajectories, outcomes, errors."""

    def __init__(self, client, trajectories=True):
        self.client = client
        node = client.node
        self.trajectories, self.outcomes, self.errors = [], [], []
        if trajectories:  # a subscriber: the executor sees a controller
            ifc.subscription(node, ifc.JOINT_TRAJECTORY,
                             lambda m: self.trajectories.append(conv.trajectory_from_msg(m)))
        ifc.subscription(node, ifc.OUTCOME,
                         lambda m: self.outcomes.append(conv.outcome_from_msg(m)))
        ifc.subscription(node, ifc.DIAGNOSTICS, self._diagnostics)
        self.behavior_pub = ifc.publisher(node, ifc.BEHAVIOR)

    def _diagnostics(self, msg):
        self.errors += [(s.name, s.message) for s in msg.status
                        if s.level in (DiagnosticStatus.WARN, DiagnosticStatus.ERROR)
                        and 'heartbeat' not in s.name]

    def error(self, name, *words, timeout=30.0):
        """Wait for an ERROR (or WARN) named ``name`` whose message holds every one of
        ``words``."""
        def found():
            return next((m for n, m in self.errors if n == name
                         and all(w in m for w in words)), None)
        self.client.spin_until(found, timeout, f'an error {name} saying {words}: {self.errors}')
        return found()

    def wait_for_odometry(self, topic=ifc.ODOM_OBSERVED, count=5):
        """Until this client has heard ``count`` messages of the executor's odometry (the
        executor, started first, hears them too: a gait sent before would be refused)."""
        heard = []
        sub = ifc.subscription(self.client.node, topic, heard.append)
        self.client.spin_until(lambda: len(heard) >= count, 60, f'odometry on {topic.name}')
        self.client.node.destroy_subscription(sub)

    def play(self, gaits, first_id, nodes, attempts=5, timeout=120):
        """Each gait in turn, its outcome awaited, as ids ``first_id``, ``first_id + 1``...
        A gait the executor refused before it moved (its odometry subscription can match the
        simulator after this client's did) is sent again, as the adapter does after its
        outcome_timeout; the robot then plays the gaits in the same order."""
        for k, gait in enumerate(gaits):
            behavior_id, heard = first_id + k, len(self.errors)
            for _ in range(attempts):
                since = len(self.errors)
                self.command(gait, behavior_id)
                try:
                    self.client.spin_until(lambda b=behavior_id, r=since: self._answered(b, r),
                                           timeout, f'the outcome of gait {behavior_id}')
                except TimeoutError as exc:  # what each node said, to tell why
                    raise AssertionError((str(exc), self.errors[heard:], nodes.logs())) from None
                if self._outcome(behavior_id):
                    break
            assert self._outcome(behavior_id), (behavior_id, self.errors[heard:], nodes.logs())

    def _outcome(self, behavior_id):
        return any(o.behavior_id == behavior_id for o in self.outcomes)

    def _answered(self, behavior_id, since):
        """Its outcome came, or an error since the ``since``-th says it was not played."""
        return self._outcome(behavior_id) or any(f'gait {behavior_id} not played' in m
                                                 for _, m in self.errors[since:])

    def command(self, params, behavior_id):
        self.client.spin_until(lambda: self.behavior_pub.get_subscription_count() > 0, 30,
                               'a subscriber of the gait commands')
        self.behavior_pub.publish(conv.behavior_to_msg(params, behavior_id))


def _forward_gait():
    archive = load_archive(default_archive_path())
    return archive.params[int(np.argmax(archive.generic_reward[:, 0]))]


@pytest.fixture
def fake_robot():
    """The gait executor alone, on a robot this test plays: odometry on FAKE_ODOM."""
    nodes = NodeProcesses({'gait_executor': {'odometry_topic': FAKE_ODOM,
                                             'odometry.timeout': 1.5}},
                          names=('gait_executor',))
    client = Client()
    yield nodes, client, Recorder(client, trajectories=False)
    client.close()
    nodes.stop()


def test_executor_refuses_without_odometry_or_controller_and_measures_any_robot(fake_robot):
    nodes, client, rec = fake_robot
    node = client.node
    gait = _forward_gait()
    client.wait_for_publishers([ifc.DIAGNOSTICS.root_name, ifc.OUTCOME.root_name])

    # No odometry at all: refused, nothing sent to the controller.
    rec.command(gait, 1)
    rec.error('gait_executor: odometry', 'gait 1 not played',
              f'no odometry received on {FAKE_ODOM}')

    # Odometry, but no controller listening: refused.
    odom_pub = node.create_publisher(ifc.ODOM.type, FAKE_ODOM, ifc.STATE_QOS)
    stamp = [100.0]
    pose = [0.2, -0.1, 0.3]
    tilt = [0.0]

    sent = [0]

    def publish_odometry():
        sent[0] += 1
        # The body rolled by tilt, then turned by yaw: q = q_yaw * q_roll.
        sr, cr = math.sin(tilt[0] / 2), math.cos(tilt[0] / 2)
        sy, cy = math.sin(pose[2] / 2), math.cos(pose[2] / 2)
        odom_pub.publish(conv.odometry_3d_msg((pose[0], pose[1], 0.1),
                                              (cy * sr, sy * sr, sy * cr, cy * cr), stamp[0]))

    streaming = [True]
    timer = node.create_timer(0.05, lambda: streaming[0] and publish_odometry())
    client.spin_until(lambda: odom_pub.get_subscription_count() > 0, 30, 'the executor')
    heard_from = sent[0]
    client.spin_until(lambda: sent[0] > heard_from + 5, 30, 'odometry sent to the executor')
    rec.command(gait, 2)
    rec.error('gait_executor: controller', 'gait 2 not played', 'nothing subscribes')

    # A controller (this test): the gait comes as a trajectory of the description's joints,
    # the controller's samples at 100/s, within the limits.
    received = []
    node.create_subscription(ifc.JOINT_TRAJECTORY.type, ifc.JOINT_TRAJECTORY.name,
                             received.append, ifc.COMMAND_QOS)
    client.wait_for_publishers([ifc.JOINT_TRAJECTORY.root_name], settle=1.0)
    rec.command(gait, 3)
    client.spin_until(lambda: received, 30, 'the trajectory')
    # The adapter's resend of a late outcome's command: not walked twice.
    rec.command(gait, 3)
    rec.error('gait_executor: command', 'gait 3 is already running or queued')
    names, times, positions = conv.trajectory_from_msg(received[0])
    assert names == list(tj.joint_names())
    expected_times, expected = tj.gait_trajectory(gait, 3.0)
    assert np.allclose(times, expected_times) and np.array_equal(positions, expected)
    # The robot walks: the pose stamped at the gait's end (3 s after the start pose's) is its
    # end; the body is rolled 70 deg there: fallen.
    start = list(pose)
    stamp[0] += 1.5
    pose[:] = [0.3, 0.0, 0.5]
    for _ in range(5):  # a few poses mid-gait
        client.executor.spin_once(timeout_sec=0.05)
    assert not rec.outcomes
    stamp[0] += 1.5
    pose[:] = [0.5, 0.1, 0.6]
    tilt[0] = math.radians(70.0)
    client.spin_until(lambda: rec.outcomes, 30, 'the outcome of gait 3')
    assert len(received) == 1  # one trajectory for gait 3
    outcome = rec.outcomes[0]
    assert outcome.behavior_id == 3 and outcome.fallen and outcome.standing_start
    assert np.allclose(outcome.start_pose, start) and np.allclose(outcome.end_pose, pose)
    assert np.allclose(outcome.generic_reward, generic_reward(start, pose))
    assert outcome.sim_time == pytest.approx(103.0)
    rec.error('gait_executor: robot', 'robot fell during gait 3')

    # Upright again; the next gait starts standing (after the fall), and its odometry stops
    # mid-gait: it ends without an outcome, reported.
    tilt[0] = 0.0
    rec.command(gait, 4)
    client.spin_until(lambda: len(received) == 2, 30, 'the second trajectory')
    streaming[0] = False
    rec.error('gait_executor: gait', 'gait 4 ended without an outcome', 'stale or stopped',
              timeout=30)
    assert [o.behavior_id for o in rec.outcomes] == [3]
    assert len(received) == 2  # gaits 3 and 4, gait 3 once
    timer.cancel()
    assert all(nodes.alive().values()), nodes.logs()


def test_stamps_of_two_clocks_refuse_a_gait_and_a_clock_reset_ends_one(fake_robot):
    """Odometry from two publishers on different clocks (a simulator's and the wall's) cannot
    tell a gait's end: refused, said. On one clock the gait runs; a clock that goes back
    during it (a simulator restarted) ends it without an outcome, said, at once."""
    nodes, client, rec = fake_robot
    node = client.node
    gait = _forward_gait()
    client.wait_for_publishers([ifc.DIAGNOSTICS.root_name, ifc.OUTCOME.root_name])
    received = []
    node.create_subscription(ifc.JOINT_TRAJECTORY.type, ifc.JOINT_TRAJECTORY.name,
                             received.append, ifc.COMMAND_QOS)
    odom_pub = node.create_publisher(ifc.ODOM.type, FAKE_ODOM, ifc.STATE_QOS)
    stamps, clocks, sent = [100.0, 1.7e9], [2], [0]

    def publish_odometry():  # the clocks in turn, each advancing 0.05 s a message
        sent[0] += 1
        which = sent[0] % clocks[0]
        stamps[which] += 0.05
        odom_pub.publish(conv.odometry_3d_msg((0.0, 0.0, 0.1), (0.0, 0.0, 0.0, 1.0),
                                              stamps[which]))
    timer = node.create_timer(0.05, publish_odometry)
    client.spin_until(lambda: odom_pub.get_subscription_count() > 0, 30, 'the executor')
    heard_from = sent[0]
    client.spin_until(lambda: sent[0] > heard_from + 10, 30, 'odometry sent to the executor')
    client.wait_for_publishers([ifc.JOINT_TRAJECTORY.root_name], settle=1.0)
    rec.command(gait, 1)
    rec.error('gait_executor: odometry', 'gait 1 not played', 'went back twice', FAKE_ODOM)
    assert not received

    # One clock: the gait is played once the other has been gone a while (the adapter sends
    # a refused gait again, as here).
    clocks[0] = 1
    tries = []

    def played():
        refused = tries and any('gait 2 not played' in m for _, m in rec.errors[tries[-1][1]:])
        if not received and (not tries or refused and time.monotonic() - tries[-1][0] > 1.0):
            tries.append((time.monotonic(), len(rec.errors)))
            rec.command(gait, 2)
        return bool(received)
    client.spin_until(played, 60, 'gait 2 played on one clock')
    stamps[0] = 0.5  # the simulator restarted mid-gait
    rec.error('gait_executor: gait', 'gait 2 ended without an outcome', 'went back')
    assert not any(o.behavior_id == 2 for o in rec.outcomes)
    timer.cancel()
    assert all(nodes.alive().values()), nodes.logs()


def test_a_gait_sent_before_the_first_odometry_waits_for_it_after_a_start():
    """Just started, the executor's subscriptions may not have matched the robot's yet: a
    gait sent then waits (up to odometry.timeout) and is played once odometry comes."""
    nodes = NodeProcesses({'gait_executor': {'odometry_topic': FAKE_ODOM,
                                             'odometry.timeout': 120.0}},
                          names=('gait_executor',))
    client = Client()
    try:
        rec = Recorder(client)  # a controller: the executor plays to it
        client.wait_for_publishers([ifc.DIAGNOSTICS.root_name, ifc.JOINT_TRAJECTORY.root_name],
                                   settle=1.0)
        rec.command(_forward_gait(), 1)  # no odometry yet
        odom_pub = client.node.create_publisher(ifc.ODOM.type, FAKE_ODOM, ifc.STATE_QOS)
        client.spin_until(lambda: odom_pub.get_subscription_count() > 0, 30, 'the executor')
        timer = client.node.create_timer(0.05, lambda: odom_pub.publish(
            conv.odometry_3d_msg((0.0, 0.0, 0.1), (0.0, 0.0, 0.0, 1.0), 5.0)))
        client.spin_until(lambda: rec.trajectories, 60, 'the trajectory of gait 1')
        timer.cancel()
        assert not [m for _, m in rec.errors if 'not played' in m], rec.errors
        assert all(nodes.alive().values()), nodes.logs()
    finally:
        client.close()
        nodes.stop()


# As the launch file and sela-demo run it (test_launch_and_config checks they agree).
HARDWARE = {'sim_bridge': {'interface': 'trajectory'},
            'gait_executor': simulated_hardware(get_robot('hexapod'))}


def _hardware(overrides, names):
    merged = {node: {**HARDWARE.get(node, {}), **overrides.get(node, {})}
              for node in set(HARDWARE) | set(overrides)}
    return NodeProcesses(merged, names=names)


def test_a_mission_through_the_executor_takes_the_direct_paths_gaits_and_outcomes():
    from test_ros_mission import Watcher, _experiment_runner_mission

    from sim_bridge.environment import ObservedHexapod
    from sim_bridge.hexapod import Hexapod
    from sim_bridge.settings import read_archive_settings

    damage, seed, goal = 'remove:middle_right', 7, (1.5, 1.0)
    nodes = _hardware({'sim_bridge': {'damage': damage, 'seed': seed}},
                      names=('sim_bridge', 'planner', 'damage_detector', 'sela_adapter',
                             'gait_executor'))
    client = Client()
    try:
        rec = Recorder(client)
        watcher = Watcher(client)
        commands = {}
        ifc.subscription(client.node, ifc.BEHAVIOR, lambda m: commands.setdefault(
            conv.behavior_from_msg(m)[1], conv.behavior_from_msg(m)[0]))
        client.wait_for_publishers([ifc.JOINT_TRAJECTORY.root_name])
        watcher.send_goal(*goal)
        try:  # within pytest's own timeout (pytest.ini), so that a stall says where it was
            client.spin_until(watcher.get_result, 270, 'the end of the mission')
        except TimeoutError as exc:
            raise AssertionError((str(exc), len(watcher.steps), rec.errors, nodes.logs())) \
                from None
        assert watcher.get_result().success, (watcher.get_result(), nodes.logs())
        # Each command: one trajectory of the description's joints, one outcome (the
        # executor's: the simulator gives none on its hardware face). A command the adapter
        # sent again (the executor had not heard odometry yet, or its outcome was late) is one.
        ids = list(dict.fromkeys(watcher.commands))
        mine = {o.behavior_id: o for o in watcher.outcomes if o.behavior_id in set(ids)}
        assert sorted(mine) == sorted(ids) and len(watcher.outcomes) == len(ids)
        assert len(rec.trajectories) == len(ids)
        assert all(names == list(tj.joint_names()) for names, _, _ in rec.trajectories)
        outcomes = [mine[i] for i in ids]
        assert [o.standing_start for o in outcomes] == [True] + [o.fallen
                                                                for o in outcomes[:-1]]

        # The direct path, in process, with the simulator's settings and the same noise
        # seed: the same outcome for every gait.
        physics = read_archive_settings(default_archive_path())
        env = ObservedHexapod(Hexapod(damage=damage, **physics), noise_std=0.01, seed=seed)
        gap = 0.0
        try:
            for outcome, behavior_id in zip(outcomes, ids):
                direct = env.execute(commands[behavior_id])
                gap = max(gap, np.abs(outcome.generic_reward
                                      - direct.observed_generic_reward).max())
                assert np.allclose(outcome.generic_reward, direct.observed_generic_reward,
                                   atol=1e-9), behavior_id
                assert np.allclose(outcome.end_pose, direct.observed_end, atol=1e-9)
                assert outcome.fallen == direct.fallen
                assert outcome.sim_time == pytest.approx(direct.sim_time, abs=1e-6)
        finally:
            env.robot.close()
        print(f'{len(ids)} gaits through the executor, {sum(o.fallen for o in outcomes)} '
              f'fallen; largest difference from the direct path {gap:.3g} (noise std 0.01 m)')
        # And the same decisions as the experiment runner's for that seed.
        runner = _experiment_runner_mission(damage, seed, goal)
        assert [s.behavior_index for s in watcher.steps] == runner['behaviors']
        assert all(nodes.alive().values()), nodes.logs()
    finally:
        client.close()
        nodes.stop()


def test_bad_trajectories_move_nothing_and_are_said():
    tight = [-0.1, 0.1] * len(tj.joint_names())
    nodes = _hardware({'sim_bridge': {'damage': 'intact'},
                       'gait_executor': {'joint_limits': tight}},
                      names=('sim_bridge', 'gait_executor'))
    client = Client()
    try:
        node = client.node
        rec = Recorder(client)
        poses = []
        ifc.subscription(node, ifc.ODOM, lambda m: poses.append(conv.pose_from_odometry(m)))
        pub = ifc.publisher(node, ifc.JOINT_TRAJECTORY)
        client.wait_for_publishers([ifc.DIAGNOSTICS.root_name, ifc.ODOM.root_name,
                                    ifc.OUTCOME.root_name])
        client.spin_until(lambda: pub.get_subscription_count() > 0, 30, 'the simulator')
        client.spin_until(lambda: poses, 30, 'odometry')
        standing = poses[-1]
        gait = _forward_gait()
        times, positions = tj.gait_trajectory(gait, 3.0)
        names = list(tj.joint_names())

        # The simulator as a controller: unknown joints, targets beyond the limits.
        pub.publish(conv.trajectory_to_msg(names[:-1] + ['rear_right.ankle'], times,
                                           positions))
        rec.error('sim_bridge: trajectory', 'unknown joint', "'rear_right.ankle'")
        beyond = positions.copy()
        beyond[40, names.index('middle_left.knee')] = 1.2
        pub.publish(conv.trajectory_to_msg(names, times, beyond))
        rec.error('sim_bridge: trajectory', 'middle_left.knee at point 40', '1.2000 rad',
                  'beyond its limits')
        # The executor: a gait beyond the robot's limits (tighter than the model's here).
        rec.wait_for_odometry()
        sent = len(rec.trajectories)
        rec.command(gait, 5)
        rec.error('gait_executor: trajectory', 'gait 5 not played', 'beyond its limits')
        n = len(poses)
        client.spin_until(lambda: len(poses) > n, 30, 'odometry')
        assert np.array_equal(poses[-1], standing), (poses[-1], standing)  # nothing moved
        assert len(rec.trajectories) == sent and not rec.outcomes

        # A good trajectory is played: the robot walks forward.
        pub.publish(conv.trajectory_to_msg(names, times, positions))
        client.spin_until(lambda: poses and poses[-1][0] > 0.1, 60, 'the robot walking')
        assert all(nodes.alive().values()), nodes.logs()
    finally:
        client.close()
        nodes.stop()


def test_falls_are_told_from_the_imu_as_the_direct_path_tells_them():
    from sim_bridge.environment import ObservedHexapod
    from sim_bridge.hexapod import Hexapod
    from sim_bridge.settings import read_archive_settings

    damage, seed = 'remove:front_left,remove:rear_left', 3
    nodes = _hardware({'sim_bridge': {'damage': damage, 'seed': seed}},
                      names=('sim_bridge', 'gait_executor'))
    client = Client()
    try:
        rec = Recorder(client)
        client.wait_for_publishers([ifc.OUTCOME.root_name, ifc.DIAGNOSTICS.root_name])
        rec.wait_for_odometry()
        archive = load_archive(default_archive_path())
        # Gait 0 of the shipped map falls with both left legs front and rear gone.
        gaits = [archive.params[0], _forward_gait(), archive.params[0]]
        rec.play(gaits, 100, nodes)
        physics = read_archive_settings(default_archive_path())
        env = ObservedHexapod(Hexapod(damage=damage, **physics), noise_std=0.01, seed=seed)
        try:
            direct = [env.execute(g) for g in gaits]
        finally:
            env.robot.close()
        assert [o.behavior_id for o in rec.outcomes] == [100, 101, 102]
        assert direct[0].fallen  # what this test is about
        for outcome, expected in zip(rec.outcomes, direct):
            assert outcome.fallen == expected.fallen
            assert outcome.standing_start == expected.standing_start
            assert np.allclose(outcome.generic_reward, expected.observed_generic_reward,
                               atol=1e-9)
            assert outcome.sim_time == pytest.approx(expected.sim_time, abs=1e-6)
        rec.error('gait_executor: robot', 'robot fell during gait 100')
        assert all(nodes.alive().values()), nodes.logs()
    finally:
        client.close()
        nodes.stop()


@pytest.mark.parametrize('value, says', [
    ('[front_left.hip_yaw, front_left.knee]', 'joint_names must name the 18 joints'),
    ('[' + ', '.join(['same'] * 18) + ']', 'joint_names must be distinct'),
])
def test_joint_names_that_are_not_the_descriptions_stop_the_executor(value, says, ros_env):
    import subprocess

    from sela_ros.tools.ros_env import executable

    proc = subprocess.run([str(executable('gait_executor')), '--ros-args', '-p',
                           f'joint_names:={value}'], env=ros_env, capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert says in proc.stderr and 'not started' in proc.stderr, proc.stderr


def test_another_robot_takes_the_same_path_the_a1():
    from sim_bridge.environment import ObservedHexapod
    from sim_bridge.simulator import Simulator

    a1 = get_robot('a1')
    seed = 4
    nodes = NodeProcesses({'sim_bridge': {'robot': 'a1', 'archive': 'none', 'seed': seed,
                                          'damage': 'intact', 'interface': 'trajectory'},
                           'gait_executor': simulated_hardware(a1)},
                          names=('sim_bridge', 'gait_executor'))
    client = Client()
    try:
        rec = Recorder(client)
        client.wait_for_publishers([ifc.OUTCOME.root_name, ifc.DIAGNOSTICS.root_name])
        rec.wait_for_odometry()
        rng = np.random.default_rng(seed)
        gaits = [a1.example_gait(), rng.uniform(size=a1.n_params)]
        rec.play(gaits, 200, nodes)
        # The A1's joints, at its controller's rate.
        assert all(names == list(a1.joint_names) for names, _, _ in rec.trajectories)
        # The direct path with the simulator's sim.* defaults (archive none).
        env = ObservedHexapod(Simulator(robot=a1), noise_std=0.01, seed=seed)
        try:
            direct = [env.execute(g) for g in gaits]
        finally:
            env.robot.close()
        for outcome, expected in zip(rec.outcomes, direct):
            assert outcome.fallen == expected.fallen
            assert np.allclose(outcome.generic_reward, expected.observed_generic_reward,
                               atol=1e-9)
            assert outcome.duty_factors.shape == (len(a1.legs),)
        assert rec.outcomes[0].generic_reward[0] > 0.1  # the trot walks forward
        assert all(nodes.alive().values()), nodes.logs()
    finally:
        client.close()
        nodes.stop()
