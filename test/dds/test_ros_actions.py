"""Missions as nav2's actions, over DDS: ``navigate_to_pose``, ``navigate_through_poses`` and
``follow_waypoints`` of the adapter, driven by plain rclpy ``ActionClient``s, in the root
namespace and under one.

Short missions on the intact robot (goals ~0.5 m from where it stands); every wait is on a
condition, with a timeout.
"""
import math

import numpy as np
import pytest
from action_msgs.msg import GoalStatus
from diagnostic_msgs.msg import DiagnosticStatus
from nav2_msgs.action import FollowWaypoints, NavigateThroughPoses, NavigateToPose

from sela_ros.nodes import conversions as conv
from sela_ros.nodes import interface as ifc
from sela_ros.tools.mission_client import send_goal_answered

from ros_graph import Client, NodeProcesses

pytestmark = [pytest.mark.dds, pytest.mark.slow]

MISSION_TIMEOUT = 300  # s: a few gaits each, on a loaded machine
EPS = 0.1  # goal.eps in config/sela.yaml


class ActionUser:
    """A user of the stack's actions, plus what it watches: odometry, the gaits sent and the
    adapter's mission statuses."""

    def __init__(self, client, namespace):
        self.client, self.namespace = client, namespace
        node = client.node
        self.navigate = ifc.action_client(node, ifc.NAVIGATE_TO_POSE, namespace)
        self.follow = ifc.action_client(node, ifc.FOLLOW_WAYPOINTS, namespace)
        self.through = ifc.action_client(node, ifc.NAVIGATE_THROUGH_POSES, namespace)
        self.names = {self.navigate: ifc.NAVIGATE_TO_POSE.name,
                      self.follow: ifc.FOLLOW_WAYPOINTS.name,
                      self.through: ifc.NAVIGATE_THROUGH_POSES.name}
        self.gaits, self.statuses, self.errors, self.pose, self.stamp = [], [], [], None, None
        def name(relative):
            return f'{namespace}/{relative}' if namespace else relative

        node.create_subscription(ifc.BEHAVIOR.type, name(ifc.BEHAVIOR.name),
                                 lambda m: self.gaits.append(conv.behavior_from_msg(m)[1]),
                                 ifc.BEHAVIOR.qos)
        node.create_subscription(ifc.ODOM.type, name(ifc.ODOM.name), self._odom, ifc.ODOM.qos)
        node.create_subscription(ifc.DIAGNOSTICS.type, name(ifc.DIAGNOSTICS.name),
                                 self._diagnostics, ifc.DIAGNOSTICS.qos)

    def _odom(self, msg):
        self.pose = conv.pose_from_odometry(msg)
        self.stamp = _seconds(msg.header.stamp)  # the simulator's clock

    def _diagnostics(self, msg):
        self.statuses += [conv.status_values(s) for s in msg.status
                          if s.name == ifc.MISSION_STATUS]
        self.errors += [s.message for s in msg.status if s.name == ifc.MISSION_STATUS
                        and s.level == DiagnosticStatus.ERROR]

    def ready(self):
        self.client.spin_until(lambda: self.navigate.server_is_ready()
                               and self.follow.server_is_ready()
                               and self.through.server_is_ready() and self.pose is not None,
                               90, 'the action servers and odometry')
        # The adapter takes goals once it knows the robot's pose and the planner's map.
        self.client.spin_until(lambda: self.pose is not None, 30, 'odometry')

    def goal_ahead(self, dx, dy):
        """A pose (dx, dy) from where the robot stands, in the odom frame."""
        return conv.pose_stamped((self.pose[0] + dx, self.pose[1] + dy), frame_id='odom')

    def send(self, action_client, goal, feedback):
        """The goal's answer, asked again while none comes (as the product's client)."""
        return send_goal_answered(action_client, self.names[action_client], goal,
                                  self.client.spin_until, 60,
                                  lambda f: feedback.append(f.feedback))

    def result(self, handle, timeout=MISSION_TIMEOUT):
        future = handle.get_result_async()
        self.client.spin_until(future.done, timeout, 'the result')
        return future.result()

    def results_said(self, mission):
        return [s for s in self.statuses if s.get('mission') == mission and 'success' in s]

    def said_end(self, mission, times=1):
        """Wait until the adapter's statuses said the mission's end ``times`` times (it says
        it again every second while idle): every status of the mission is in by then, and a
        gait sent after its end would have come before the repeat."""
        self.client.spin_until(lambda: len(self.results_said(mission)) >= times, 30,
                               f'the end of mission {mission} said {times} time(s)')

    def steps_of(self, mission):
        return [s for s in self.statuses if s.get('mission') == mission and 'end_pose' in s]


@pytest.fixture(scope='module', params=['', '/robot1'], ids=['root', 'namespaced'])
def stack(request):
    namespace = request.param
    nodes = NodeProcesses({'sim_bridge': {'damage': 'intact'}}, namespace=namespace)
    client = Client('sela_action_user')
    user = ActionUser(client, namespace)
    try:
        user.ready()
        yield nodes, user
    finally:
        client.close()
        nodes.stop()


def _seconds(t):
    """A builtin_interfaces Time or Duration in seconds."""
    return t.sec + t.nanosec * 1e-9


def _mission_of(user, goal_handle):
    goal_id = bytes(goal_handle.goal_id.uuid).hex()
    found = [s['mission'] for s in user.statuses if s.get('goal_id') == goal_id]
    return found[0] if found else None


def test_navigate_to_pose_succeeds_with_feedback_every_gait(stack):
    nodes, user = stack
    # A behaviour tree asked for (nav2's field) is said to be unused; the goal goes on.
    goal = NavigateToPose.Goal(pose=user.goal_ahead(0.5, 0.0), behavior_tree='custom_bt.xml')
    feedback = []
    gaits_before = len(user.gaits)
    sent = user.stamp
    handle = user.send(user.navigate, goal, feedback)
    assert handle.accepted
    answer = user.result(handle)
    assert answer.status == GoalStatus.STATUS_SUCCEEDED, (answer.result, nodes.logs())
    assert answer.result.error_code == 0
    mission = _mission_of(user, handle)
    assert mission is not None  # its statuses name its goal
    user.said_end(mission)
    gaits = len(set(user.gaits[gaits_before:]))
    steps = user.steps_of(mission)
    assert gaits >= 1 and len(steps) == gaits
    # Feedback and result travel apart: the feedback of the last gait may come after it.
    user.client.spin_until(lambda: len(feedback) >= gaits, 30, 'a feedback per gait')
    target = (goal.pose.pose.position.x, goal.pose.pose.position.y)
    end = conv_vector(steps[-1]['end_pose'])[:2]
    assert math.dist(end, target) <= EPS
    last = feedback[-1]
    assert last.distance_remaining <= EPS and math.isclose(
        last.distance_remaining, math.dist(end, target), abs_tol=1e-4)
    assert last.navigation_time.sec + last.navigation_time.nanosec > 0
    # navigation_time runs on the node's clock, the simulator's (use_sim_time), as the
    # feedback's stamps do: from the goal (the simulator idle since the odometry before it)
    # to each feedback, and between two feedbacks, both advance alike.
    for f in feedback:
        assert math.isclose(_seconds(f.navigation_time),
                            _seconds(f.current_pose.header.stamp) - sent, abs_tol=0.2), (
            _seconds(f.navigation_time), _seconds(f.current_pose.header.stamp), sent)
    for a, b in zip(feedback, feedback[1:]):
        assert math.isclose(_seconds(b.navigation_time) - _seconds(a.navigation_time),
                            _seconds(b.current_pose.header.stamp)
                            - _seconds(a.current_pose.header.stamp), abs_tol=1e-6)
    assert all(f.current_pose.header.frame_id == 'odom' for f in feedback)
    log = (nodes.logdir / 'sela_adapter.log').read_text()
    assert "behavior_tree 'custom_bt.xml' is not used here" in log
    print(f'navigate_to_pose: {gaits} gait(s), {len(feedback)} feedback(s), ended '
          f'{math.dist(end, target):.3f} m from the goal')


def test_a_cancel_ends_the_mission_after_the_running_gait(stack):
    nodes, user = stack
    goal = NavigateToPose.Goal(pose=user.goal_ahead(1.5, 0.0))
    feedback = []
    before = set(user.gaits)
    handle = user.send(user.navigate, goal, feedback)
    assert handle.accepted
    # A gait runs once the first feedback (a step done) is followed by the next command.
    user.client.spin_until(lambda: feedback, MISSION_TIMEOUT, 'the first step')
    sent = len(set(user.gaits))
    user.client.spin_until(lambda: len(set(user.gaits)) > sent, 60, 'the next gait')
    at_cancel = set(user.gaits)
    cancel = handle.cancel_goal_async()
    user.client.spin_until(cancel.done, 30, 'the cancel response')
    assert cancel.result().goals_canceling
    answer = user.result(handle)
    assert answer.status == GoalStatus.STATUS_CANCELED, (answer.result, nodes.logs())
    user.said_end(_mission_of(user, handle), times=2)
    assert set(user.gaits) == at_cancel  # the running gait ended the mission: none after it
    print(f'cancel: {len(at_cancel - before)} gait(s), the last running at the cancel; '
          f'{answer.result.error_msg!r}')


def test_a_goal_off_the_map_is_aborted_with_the_reason(stack):
    nodes, user = stack
    handle = user.send(user.navigate, NavigateToPose.Goal(pose=user.goal_ahead(50.0, 50.0)), [])
    if not handle.accepted:
        return  # rejected: as good as aborted for the user (nothing walks)
    answer = user.result(handle, 60)
    print(f'off the map: status {answer.status}, error_code {answer.result.error_code}, '
          f'{answer.result.error_msg!r}')
    assert answer.status == GoalStatus.STATUS_ABORTED
    assert answer.result.error_code in (ifc.GOAL_OUTSIDE_MAP, ifc.NO_VALID_PATH)
    assert answer.result.error_msg, answer.result
    if answer.result.error_code == ifc.GOAL_OUTSIDE_MAP:
        assert 'off the map' in answer.result.error_msg


@pytest.mark.parametrize('field, value, reason', [
    ('frame_id', 'base_link', "frame 'base_link' is not supported"),
    ('x', math.nan, 'goal_pose: position.x is nan; expected finite numbers')])
def test_a_malformed_goal_is_aborted_and_said_on_diagnostics(stack, field, value, reason):
    nodes, user = stack
    pose = user.goal_ahead(0.5, 0.0)
    if field == 'frame_id':
        pose.header.frame_id = value
    else:
        pose.pose.position.x = value
    errors_before = len(user.errors)
    handle = user.send(user.navigate, NavigateToPose.Goal(pose=pose), [])
    assert handle.accepted
    answer = user.result(handle, 60)
    assert answer.status == GoalStatus.STATUS_ABORTED
    assert answer.result.error_code == ifc.UNKNOWN_ERROR
    assert 'navigate_to_pose goal refused' in answer.result.error_msg
    assert reason in answer.result.error_msg, answer.result.error_msg
    user.client.spin_until(lambda: any(answer.result.error_msg in e
                                       for e in user.errors[errors_before:]), 30,
                           'the refusal said on /diagnostics')
    assert all(nodes.alive().values()), nodes.logs()


def test_a_new_goal_preempts_the_running_one(stack):
    nodes, user = stack
    first_feedback, feedback = [], []
    first = user.send(user.navigate, NavigateToPose.Goal(pose=user.goal_ahead(1.5, 0.0)),
                      first_feedback)
    user.client.spin_until(lambda: first_feedback, MISSION_TIMEOUT, 'the first step')
    second_goal = NavigateToPose.Goal(pose=user.goal_ahead(0.0, 0.4))
    second = user.send(user.navigate, second_goal, feedback)
    assert second.accepted
    old = user.result(first, 120)
    assert old.status == GoalStatus.STATUS_ABORTED and 'preempted' in old.result.error_msg
    new = user.result(second)
    assert new.status == GoalStatus.STATUS_SUCCEEDED, (new.result, nodes.logs())


def _walk_through(user, nodes, action_client, goal, poses):
    """Send a goal of several ``poses``; it must succeed, ending within goal.eps of the last.
    Returns its result, its feedback, the statuses of the poses reached on the way, and the
    poses' (x, y)."""
    feedback = []
    seen = len(user.statuses)
    handle = user.send(action_client, goal, feedback)
    assert handle.accepted
    answer = user.result(handle)
    assert answer.status == GoalStatus.STATUS_SUCCEEDED, (answer.result, nodes.logs())
    assert answer.result.error_code == 0
    mission = _mission_of(user, handle)
    user.said_end(mission)
    reached = [s for s in user.statuses[seen:]
               if s.get('mission') == mission and 'goal_reached' in s]
    xy = [(p.pose.position.x, p.pose.position.y) for p in poses]
    assert math.dist(conv_vector(user.steps_of(mission)[-1]['end_pose'])[:2], xy[-1]) <= EPS
    return answer.result, feedback, reached, xy


def test_follow_waypoints_reaches_every_waypoint_in_order(stack):
    nodes, user = stack
    poses = [user.goal_ahead(*d) for d in ((0.4, 0.0), (0.4, 0.4), (0.0, 0.4))]
    poses[1].header.frame_id = 'map'  # as nav2's clients send them: the same frame here
    result, feedback, reached, xy = _walk_through(user, nodes, user.follow,
                                                  FollowWaypoints.Goal(poses=poses), poses)
    assert list(result.missed_waypoints) == []
    ranks = [f.current_waypoint for f in feedback]
    print(f'follow_waypoints: feedback current_waypoint {ranks}')
    assert ranks == sorted(ranks) and set(ranks) == {0, 1, 2}, ranks
    assert [int(s['goal_index']) for s in reached] == [2, 3]
    assert np.allclose([conv_vector(s['goal_reached']) for s in reached], xy[:2], atol=1e-6)


def conv_vector(text):
    return [float(v) for v in text.split()]


def test_navigate_through_poses_reaches_each_pose_in_order_with_what_is_left(stack):
    """nav2's NavigateThroughPoses (BasicNavigator.goThroughPoses): one mission through the
    poses; each feedback says how many poses are left and how far it is through them."""
    nodes, user = stack
    poses = [user.goal_ahead(*d) for d in ((0.4, 0.0), (0.4, 0.4))]
    _, feedback, reached, xy = _walk_through(user, nodes, user.through,
                                             NavigateThroughPoses.Goal(poses=poses), poses)
    assert [int(s['goal_index']) for s in reached] == [2]
    assert np.allclose(conv_vector(reached[0]['goal_reached']), xy[0], atol=1e-6)
    left = [f.number_of_poses_remaining for f in feedback]
    print(f'navigate_through_poses: poses remaining {left}, distances '
          f'{[round(f.distance_remaining, 2) for f in feedback]}')
    assert left == sorted(left, reverse=True) and set(left) <= {1, 2} and left[-1] == 1, left
    for f in feedback:  # to the pose walked to, then on through the ones after it
        pose = (f.current_pose.pose.position.x, f.current_pose.pose.position.y)
        rest = 0.4 if f.number_of_poses_remaining == 2 else 0.0
        target = xy[len(xy) - f.number_of_poses_remaining]
        assert f.distance_remaining == pytest.approx(math.dist(pose, target) + rest, abs=1e-3)


def test_navigate_through_poses_with_a_pose_off_the_map_is_aborted_with_the_code(stack):
    nodes, user = stack
    poses = [user.goal_ahead(0.3, 0.0), conv.pose_stamped((40.0, 0.0), frame_id='odom')]
    gaits_before = len(user.gaits)
    handle = user.send(user.through, NavigateThroughPoses.Goal(poses=poses), [])
    answer = user.result(handle)
    assert answer.status == GoalStatus.STATUS_ABORTED, (answer.result, nodes.logs())
    if answer.result.error_code == ifc.GOAL_OUTSIDE_MAP:  # the adapter knew the map
        assert 'off the map' in answer.result.error_msg, answer.result.error_msg
        assert len(user.gaits) == gaits_before  # refused before any gait
    else:  # not yet: the planner found no path to it, once the first pose was reached
        assert answer.result.error_code == ifc.NO_VALID_PATH, answer.result
