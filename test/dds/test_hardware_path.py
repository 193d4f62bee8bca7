"""The hardware path over DDS: the gait executor plays the adapter's gaits through a
joint_trajectory_controller's topic and measures them on an odometry topic; sim_bridge's
hardware face plays them in the simulator (or this test plays a robot itself)."""
import math

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticStatus

from sela_ros.core.geometry import generic_reward
from sela_ros.core.storage import default_archive_path, load_archive
from sela_ros.nodes import conversions as conv
from sela_ros.nodes import interface as ifc
from sim_bridge import trajectory as tj

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
                        if s.level == DiagnosticStatus.ERROR and 'heartbeat' not in s.name]

    def error(self, name, *words, timeout=30.0):
        """Wait for an ERROR named ``name`` whose message holds every one of ``words``."""
        def found():
            return next((m for n, m in self.errors if n == name
                         and all(w in m for w in words)), None)
        self.client.spin_until(found, timeout, f'an error {name} saying {words}: {self.errors}')
        return found()

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
    timer.cancel()
    assert all(nodes.alive().values()), nodes.logs()
