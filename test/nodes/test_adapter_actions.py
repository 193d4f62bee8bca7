"""The adapter's action goals as missions, without DDS: FollowWaypoints' ``goal_index`` and
``number_of_loops``, the waypoints reported missed, the result codes."""
from types import SimpleNamespace

import numpy as np
import pytest
from nav2_msgs.action import FollowWaypoints, NavigateToPose

from sela_ros.nodes import conversions as conv
from sela_ros.nodes import interface as ifc
from sela_ros.nodes.adapter_actions import MissionActions, goal_count, unused_request


@pytest.fixture
def actions():
    stand_in = MissionActions.__new__(MissionActions)  # no node: only the translation
    stand_in.node = SimpleNamespace(frame_id='odom', goal_frames=conv.goal_frames('odom', 'map'),
                                    map=None)
    return stand_in


def _poses(*xy):
    return [conv.pose_stamped(p, frame_id='odom') for p in xy]


def test_follow_waypoints_starts_at_goal_index_and_loops(actions):
    poses = _poses((1, 0), (1, 1), (0, 1))
    goal = FollowWaypoints.Goal(poses=poses, goal_index=1, number_of_loops=1)
    goals, sent, first = actions._goals_of(ifc.FOLLOW_WAYPOINTS, goal)
    assert goals == [(1, 1), (0, 1), (1, 0), (1, 1), (0, 1)] and first == 1 and sent == poses
    binding = SimpleNamespace(first_index=first, poses=poses)
    assert [actions._rank(binding, i) for i in range(len(goals))] == [1, 2, 0, 1, 2]
    # Two of the five reached: the rest are missed, each with its rank among the poses.
    missed = actions._missed(poses, first, 2, goals, ended_at=(2, ifc.FAILED_TO_MAKE_PROGRESS))
    assert [m.index for m in missed] == [0, 1, 2]
    # Where the mission ended, why; after it, never attempted.
    assert [m.error_code for m in missed] == [ifc.FAILED_TO_MAKE_PROGRESS, ifc.NOT_ATTEMPTED,
                                              ifc.NOT_ATTEMPTED]
    assert goal_count(goal) == len(goals)


@pytest.mark.parametrize('goal, problem', [
    (FollowWaypoints.Goal(poses=[]), 'no poses'),
    (FollowWaypoints.Goal(poses=_poses((1, 0)), goal_index=1), 'past the 1 poses'),
    (FollowWaypoints.Goal(poses=[conv.pose_stamped((1, 0), frame_id='base_link')]),
     "frame 'base_link'.*send the goals in 'odom' \\(or 'map', taken as 'odom'\\)"),
])
def test_a_bad_waypoint_goal_says_what_is_wrong(actions, goal, problem):
    with pytest.raises(conv.MessageError, match=problem):
        actions._goals_of(ifc.FOLLOW_WAYPOINTS, goal)


def test_navigate_to_pose_takes_the_pose_in_the_odom_frame_or_the_map_frame(actions):
    goal = NavigateToPose.Goal(pose=conv.pose_stamped((0.5, -0.2), frame_id='odom'))
    assert actions._goals_of(ifc.NAVIGATE_TO_POSE, goal)[0] == [(0.5, -0.2)]
    # nav2's clients send goals in map: the same frame here (no localisation).
    goal = NavigateToPose.Goal(pose=conv.pose_stamped((0.5, -0.2), frame_id='map'))
    assert actions._goals_of(ifc.NAVIGATE_TO_POSE, goal)[0] == [(0.5, -0.2)]
    with pytest.raises(conv.MessageError, match="frame 'base_link'"):
        actions._goals_of(ifc.NAVIGATE_TO_POSE, NavigateToPose.Goal(
            pose=conv.pose_stamped((0.5, -0.2), frame_id='base_link')))
    # map_frame '' (a robot whose map frame is a localisation's): map is refused.
    actions.node.goal_frames = conv.goal_frames('odom', '')
    with pytest.raises(conv.MessageError, match="frame 'map'.*send it in 'odom'$"):
        actions._goals_of(ifc.NAVIGATE_TO_POSE, goal)


def test_a_behavior_tree_asked_for_is_said_to_be_unused_and_nothing_else_is():
    pose = conv.pose_stamped((0.5, 0.0))
    said = unused_request(ifc.NAVIGATE_TO_POSE,
                          NavigateToPose.Goal(pose=pose, behavior_tree='/bt/custom.xml'))
    assert "behavior_tree '/bt/custom.xml' is not used here" in said
    assert 'the goal goes on' in said and said.startswith('navigate_to_pose')
    assert unused_request(ifc.NAVIGATE_TO_POSE, NavigateToPose.Goal(pose=pose)) is None
    assert unused_request(ifc.FOLLOW_WAYPOINTS, FollowWaypoints.Goal(poses=[pose])) is None


def test_result_codes_are_navs_and_waypoints_carry_their_own(actions):
    nav = actions._message(ifc.NAVIGATE_TO_POSE, ifc.GOAL_OUTSIDE_MAP, 'off the map', [])
    assert (nav.error_code, nav.error_msg) == (204, 'off the map')
    poses = _poses((1, 0), (1, 1))
    missed = actions._missed(poses, 0, 1, [(1, 0), (1, 1)], ended_at=(1, ifc.NO_VALID_PATH))
    follow = actions._message(ifc.FOLLOW_WAYPOINTS, ifc.NO_VALID_PATH, 'no path', missed)
    assert follow.error_code == FollowWaypoints.Result.UNKNOWN
    assert [(m.index, m.error_code) for m in follow.missed_waypoints] == [(1, 208)]
    done = actions._message(ifc.FOLLOW_WAYPOINTS, 0, 'goal reached', [])
    assert done.error_code == 0 and list(done.missed_waypoints) == []
    assert {code: ifc.END_ERROR_CODES[code] for code in ('succeeded', 'canceled')} == {
        'succeeded': 0, 'canceled': 0}


def test_waypoints_refused_before_a_step_are_all_missed_each_with_its_own_code(actions):
    from sela_ros.core.planning import OccupancyGrid

    actions.node.map = OccupancyGrid(np.zeros((40, 40), bool), 0.1, (-2.0, -2.0))
    goals = [(0.3, 0.0), (50.0, 50.0), (0.3, 0.3), (60.0, 0.0)]
    index, code, why = actions._problem(goals)
    assert (index, code) == (1, ifc.GOAL_OUTSIDE_MAP) and 'off the map' in why
    missed = actions._missed(_poses(*goals), 0, 0, goals, ended_at=(index, code))
    assert [(m.index, m.error_code) for m in missed] == [
        (0, ifc.NOT_ATTEMPTED), (1, ifc.GOAL_OUTSIDE_MAP), (2, ifc.NOT_ATTEMPTED),
        (3, ifc.GOAL_OUTSIDE_MAP)]


def test_a_goal_of_a_million_loops_is_refused_without_expanding_it(actions):
    actions.node.stepper = object()
    actions.node.values = {'max_waypoints': 1000}
    actions.active = 0
    big = FollowWaypoints.Goal(poses=_poses((1, 0), (1, 1)), goal_index=1,
                               number_of_loops=10**6)
    assert goal_count(big) == 1 + 2 * 10**6
    assert 'make 2000001 waypoints, more than max_waypoints 1000' in actions._refusal(big)
    assert actions._refusal(FollowWaypoints.Goal(poses=_poses((1, 0)),
                                                 number_of_loops=999)) is None
    from nav2_msgs.action import NavigateThroughPoses

    many = NavigateThroughPoses.Goal(poses=_poses(*[(0.001 * i, 0.0) for i in range(1001)]))
    assert 'navigate_through_poses: 1001 poses, more than max_waypoints 1000' \
        in actions._refusal(many)
    assert actions._refusal(NavigateThroughPoses.Goal(poses=many.poses[:1000])) is None
    actions.active = 200
    assert 'accepted goals have not ended yet' in actions._refusal(NavigateToPose.Goal())


class _Handle:
    def __init__(self):
        self.is_active, self.sent = True, []

    def publish_feedback(self, feedback):
        self.sent.append(feedback)


class _Clock:
    def __init__(self, seconds):
        self.seconds = seconds

    def now(self):
        return SimpleNamespace(nanoseconds=int(self.seconds * 1e9))


def _bound(actions, action, goals, clock, stamp):
    from sela_ros.nodes.adapter_actions import Binding

    actions.node = SimpleNamespace(frame_id='odom', map=None, get_clock=lambda: clock,
                                   stepper=SimpleNamespace(pose_stamp=stamp))
    handle = _Handle()
    actions.bindings = {7: Binding(handle, action, goals, _poses(*goals), 0, 100.0)}
    return handle


def test_navigate_through_poses_is_one_mission_and_its_feedback_says_what_is_left(actions):
    from nav2_msgs.action import NavigateThroughPoses

    goal = NavigateThroughPoses.Goal(poses=_poses((1, 0), (1, 1), (0, 1)))
    goals, _, first = actions._goals_of(ifc.NAVIGATE_THROUGH_POSES, goal)
    assert goals == [(1, 0), (1, 1), (0, 1)] and first == 0 and goal_count(goal) == 3
    handle = _bound(actions, ifc.NAVIGATE_THROUGH_POSES, goals, _Clock(102.0), 101.0)
    actions.status_released(0, '', {'mission': '7', 'goal_index': '2', 'end_pose': '1.0 0.2 0.0',
                             'pose': '0.0 0.0 0.0'})
    sent = handle.sent[-1]
    assert sent.number_of_poses_remaining == 2
    assert sent.distance_remaining == pytest.approx(0.8 + 1.0)  # to (1, 1), then to (0, 1)
    assert sent.navigation_time.sec == 2
    result = actions._message(ifc.NAVIGATE_THROUGH_POSES, ifc.NO_VALID_PATH, 'no path', [])
    assert (result.error_code, result.error_msg) == (208, 'no path')


def test_a_feedback_is_timed_by_its_outcome_when_the_clock_lags_behind_it(actions):
    """The simulator's clock and its outcomes travel apart: a gait's feedback says the time
    its outcome was stamped at, not that none has passed since the goal."""
    handle = _bound(actions, ifc.NAVIGATE_TO_POSE, [(1.0, 0.0)], _Clock(100.0), 103.5)
    actions.status_released(0, '', {'mission': '7', 'goal_index': '1', 'end_pose': '0.5 0.0 0.0'})
    sent = handle.sent[-1]
    assert sent.navigation_time.sec == 3 and sent.navigation_time.nanosec == 500_000_000
    assert sent.current_pose.header.stamp.sec == 103
    # An outcome stamped on another clock (far ahead) does not take over the node's.
    handle = _bound(actions, ifc.NAVIGATE_TO_POSE, [(1.0, 0.0)], _Clock(104.0), 1e9)
    actions.status_released(0, '', {'mission': '7', 'goal_index': '1', 'end_pose': '0.5 0.0 0.0'})
    assert handle.sent[-1].navigation_time.sec == 4



def test_a_status_said_before_its_goal_was_bound_is_said_again_with_the_goals_id(actions):
    """The mission's first status can go out within the event that starts it (no save
    pending), before the goal is bound to its mission: the client waiting for a status that
    names its goal hears it again, with the id. A step is never said twice."""
    from unique_identifier_msgs.msg import UUID

    from sela_ros.nodes.adapter_actions import goal_id_text

    said = []
    stepper = SimpleNamespace(mission_id=7, goal=None, running=lambda: True)

    def feed(event):  # the stepper starts mission 8; its status is released at once
        stepper.mission_id, stepper.goal = 8, event.goal
        actions.status_released(1, 'planning', {'mission': '8', 'goal_id': '',
                                                'state': 'planning'})
        actions.status_released(1, 'step 1', {'mission': '8', 'goal_id': '', 'step': '1'})

    actions.node = SimpleNamespace(
        frame_id='odom', goal_frames=('odom',), map=None, get_clock=lambda: _Clock(5.0),
        stepper=stepper, feed=feed,
        sim_check=SimpleNamespace(poll=lambda: None),
        say=lambda level, message, values: said.append((level, message, values)))
    actions.bindings, actions._unbound, actions._said_unbound = {}, {}, {}
    handle = _Handle()
    handle.request = NavigateToPose.Goal(pose=conv.pose_stamped((1.0, 0.0), frame_id='odom'))
    handle.goal_id = UUID(uuid=list(range(16)))
    handle.is_cancel_requested = False
    run = actions._run(handle)
    run.send(None)  # up to the wait for its mission's end
    assert 8 in actions.bindings
    assert said == [(1, 'planning', {'mission': '8', 'state': 'planning',
                                     'goal_id': goal_id_text(handle)})]
    run.close()
