"""The planner node over DDS: maps from a map_server file, from the ``map`` topic, and bad
maps refused with the reason while the current map is kept."""
import math
import time
from pathlib import Path

import numpy as np
import pytest
from action_msgs.msg import GoalStatus
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import OccupancyGrid, Odometry
from nav_msgs.msg import Path as PathMsg
from nav_msgs.srv import GetPlan
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters

from sela_ros.core.planning import load_map_file
from sela_ros.core.planning.maps import DEFAULT_MAP, grid_from_description
from sela_ros.nodes import conversions as conv
from sela_ros.nodes import grid_conversions as grids
from sela_ros.nodes.interface import GOAL_QOS, LATCHED_QOS, STATE_QOS

from ros_graph import Client, NodeProcesses

pytestmark = [pytest.mark.dds]

MAPS = Path(__file__).resolve().parents[2] / 'config' / 'maps'


class PlannerWatch:
    """What the planner publishes: its map, its paths, its diagnostics."""

    def __init__(self, client):
        self.client = client
        self.maps, self.paths, self.statuses = [], [], []
        node = client.node
        node.create_subscription(OccupancyGrid, '/planner/map', self.maps.append, LATCHED_QOS)
        node.create_subscription(PathMsg, '/planner/path', self.paths.append, LATCHED_QOS)
        node.create_subscription(DiagnosticArray, '/diagnostics',
                                 lambda m: self.statuses.extend(m.status), STATE_QOS)
        self.make_plan = node.create_client(GetPlan, '/planner/make_plan')
        self.set_params = node.create_client(SetParameters, '/planner/set_parameters')
        self.stamp = 100.0

    def errors(self, text):
        return [s.message for s in self.statuses
                if s.name == 'planner' and s.level == DiagnosticStatus.ERROR
                and text in s.message]

    def map_grid(self):
        return grids.occupancy_grid_from_msg(self.maps[-1])

    def path(self, start, goal):
        """The full path the planner publishes for a plan from ``start`` to ``goal``."""
        self.stamp += 1.0
        request = GetPlan.Request(start=conv.pose_stamped(start, stamp=self.stamp),
                                  goal=conv.pose_stamped(goal))
        self.client.call(self.make_plan, request)
        stamp = conv.time_to_msg(self.stamp)
        self.client.spin_until(lambda: any(p.header.stamp == stamp for p in self.paths), 30,
                               'the path of the plan')
        path = next(p for p in reversed(self.paths) if p.header.stamp == stamp)
        return conv.path_from_msg(path)

    def set_map_file(self, value):
        request = SetParameters.Request(parameters=[Parameter(
            name='map.file', value=ParameterValue(type=ParameterType.PARAMETER_STRING,
                                                  string_value=str(value)))])
        return self.client.call(self.set_params, request).results[0]


def _segments_free(grid, path):
    for a, b in zip(path, path[1:]):
        for t in np.linspace(0.0, 1.0, 40):
            if not grid.is_free(grid.world_to_cell(a + t * (b - a))):
                return False
    return True


def _wall_map(frame_id='map'):
    """A 4 m x 3 m field at 0.1 m with a wall x in [1.5, 1.7) for y < 2 m; row 0 at y = -1."""
    values = np.zeros((30, 40), dtype=np.int8)
    values[:20, 15:17] = 100
    values[25:, :5] = -1  # unknown: occupied by default
    msg = grids.occupancy_grid_to_msg(values > 0, 0.1, (-1.0, -1.0), frame_id=frame_id)
    msg.data = values.reshape(-1).tolist()
    return msg


@pytest.fixture
def planner():
    nodes = NodeProcesses({'planner': {'map.file': str(MAPS / 'maze.yaml')}},
                          names=('planner',))
    client = Client()
    yield nodes, PlannerWatch(client)
    client.close()
    nodes.stop()


def test_maps_from_a_file_and_the_map_topic_and_bad_ones_refused(planner, tmp_path):
    nodes, watch = planner
    client = watch.client
    maze = load_map_file(MAPS / 'maze.yaml')
    client.spin_until(lambda: watch.maps, 60, 'the planner map')
    occupied, resolution, origin = watch.map_grid()
    assert np.array_equal(occupied, maze.occupied) and resolution == pytest.approx(0.05)
    np.testing.assert_allclose(origin, maze.origin)
    path = watch.path((0.0, 0.0), (4.5, 4.5))
    assert np.allclose(path[0], (0.0, 0.0)) and np.allclose(path[-1], (4.5, 4.5))
    assert _segments_free(maze, path) and len(path) > 3  # through the maze, around walls

    # A map on /map (as map_server latches it) replaces the file's.
    map_pub = client.node.create_publisher(OccupancyGrid, '/map', LATCHED_QOS)
    map_pub.publish(_wall_map())
    client.spin_until(lambda: watch.map_grid()[0].shape == (30, 40), 30,
                      'the map from /map in use')
    occupied = watch.map_grid()[0]
    assert occupied[5, 15] and occupied[29, 0] and not occupied[25, 10]
    path = watch.path((0.0, 0.0), (2.5, 0.0))
    assert path[:, 1].max() > 1.0 + 0.25  # around the wall's end (y 1 m) with the margin

    # Bad maps: refused with the reason, the current one kept and still planned on.
    bad = _wall_map()
    bad.data = bad.data[:-1]
    map_pub.publish(bad)
    client.spin_until(lambda: watch.errors('map on topic rejected'), 30, 'bad map reported')
    assert '1199 cells for 40 x 30' in watch.errors('map on topic rejected')[0]
    rotated = _wall_map()
    rotated.info.origin.orientation = conv.yaw_to_quaternion(0.3)
    map_pub.publish(rotated)
    client.spin_until(lambda: watch.errors('yaw'), 30, 'rotated map reported')
    # Cells and corners the map.* parameters' ranges refuse are refused on the topic too.
    for field, value, reason in (('resolution', 1e-38, 'resolution 1e-38 m is out of'),
                                 ('resolution', 3e38, 'resolution 3e+38 m is out of'),
                                 ('x', 1e300, 'origin x 1e+300 m is out of')):
        odd = _wall_map()
        if field == 'resolution':
            odd.info.resolution = value
        else:
            odd.info.origin.position.x = value
        map_pub.publish(odd)
        client.spin_until(lambda r=reason: watch.errors(r), 30, f'{field} {value} reported')
    bad_file = tmp_path / 'bad.yaml'
    bad_file.write_text('image: wall.pgm\nresolution: 0.05\norigin: 5\n')
    result = watch.set_map_file(bad_file)
    assert not result.successful and 'origin must be a list' in result.reason
    client.spin_until(lambda: watch.errors('origin must be a list'), 30, 'bad file reported')
    assert watch.map_grid()[0].shape == (30, 40)
    assert watch.path((0.0, 0.0), (2.5, 0.0))[:, 1].max() > 1.25

    # A good file at run time is taken.
    assert watch.set_map_file(MAPS / 'corridor.yaml').successful
    corridor = load_map_file(MAPS / 'corridor.yaml')
    client.spin_until(lambda: watch.map_grid()[0].shape == corridor.occupied.shape, 30,
                      'the corridor map in use')
    # '' is the map.* parameters' map again (config/sela.yaml's field).
    assert watch.set_map_file('').successful
    field = grid_from_description(DEFAULT_MAP['resolution'], DEFAULT_MAP['origin'],
                                  DEFAULT_MAP['width'], DEFAULT_MAP['height'], [])
    client.spin_until(lambda: watch.map_grid()[0].shape == field.occupied.shape, 30,
                      "the map.* parameters' map in use")
    assert not watch.map_grid()[0].any()
    assert np.allclose(watch.path((0.0, 0.0), (-1.5, -1.5))[-1], (-1.5, -1.5))
    assert all(nodes.alive().values()), nodes.logs()

    # A request make_plan cannot take: an empty plan, and the field that is wrong said.
    for start, goal, reason in (((math.inf, 0.0), (1.0, 1.0), 'start: position.x is inf'),
                                ((0.0, 0.0), (1.0, math.nan), 'goal: position.y is nan')):
        request = GetPlan.Request(start=conv.pose_stamped(start), goal=conv.pose_stamped(goal))
        assert not client.call(watch.make_plan, request).plan.poses
        client.spin_until(lambda r=reason: watch.errors(r), 30, f'{reason} reported')


def test_a_goal_sent_before_any_odometry_is_planned_when_the_first_pose_comes(planner):
    """A goal can reach the planner before the robot's first odometry (a stack just
    started): its path comes with the first pose, not never."""
    nodes, watch = planner
    client = watch.client
    goal, start = (4.5, 4.5), (0.0, 0.0, 0.0)
    goal_pub = client.node.create_publisher(PoseStamped, '/goal_pose', GOAL_QOS)
    client.spin_until(lambda: goal_pub.get_subscription_count() >= 1, 60, 'the planner')
    client.spin_until(lambda: watch.make_plan.service_is_ready(), 60, 'make_plan')
    goal_stamp = conv.time_to_msg(7.0)

    def taken():
        """The planner holds the goal: ``make_plan`` with an empty goal plans to it."""
        goal_pub.publish(conv.pose_stamped(goal, stamp=7.0))
        answer = client.call(watch.make_plan, GetPlan.Request(
            start=conv.pose_stamped((0.5, 0.5), stamp=1.0), goal=PoseStamped()))
        return answer.plan.poses and np.allclose(conv.path_from_msg(answer.plan)[-1], goal)
    client.spin_until(taken, 60, 'the goal taken')
    assert not any(p.header.stamp == goal_stamp for p in watch.paths)  # no pose yet

    odom_pub = client.node.create_publisher(Odometry, '/hexapod/odom', STATE_QOS)
    sent = []

    def planned():
        if not sent or time.monotonic() - sent[-1] > 0.5:  # as sim_bridge: a stream
            odom_pub.publish(conv.odometry_msg(start, stamp=8.0))
            sent.append(time.monotonic())
        return any(p.header.stamp == goal_stamp for p in watch.paths)
    client.spin_until(planned, 60, "the goal's path from the first pose")
    path = conv.path_from_msg(next(p for p in watch.paths if p.header.stamp == goal_stamp))
    assert np.allclose(path[0], start[:2]) and np.allclose(path[-1], goal)
    assert all(nodes.alive().values()), nodes.logs()


def test_a_new_map_replans_the_current_goal_and_publishes_its_path(planner):
    """A map that arrives during a mission (a wall seen) gives the current goal a new path
    at once, free on the new map: nobody has to ask for it."""
    nodes, watch = planner
    client = watch.client
    goal, start = (2.5, 0.0), (0.0, 0.0, 0.0)
    field = grid_from_description(0.1, (-1.0, -1.0), 4.0, 3.0, [])
    walled = grid_from_description(0.1, (-1.0, -1.0), 4.0, 3.0, [1.5, -1.0, 1.7, 1.0])
    map_pub = client.node.create_publisher(OccupancyGrid, '/map', LATCHED_QOS)
    map_pub.publish(grids.occupancy_grid_to_msg(field.occupied, 0.1, (-1.0, -1.0),
                                               frame_id='map'))
    client.spin_until(lambda: watch.maps and watch.map_grid()[0].shape == (30, 40), 60,
                      'the open field in use')
    odom_pub = client.node.create_publisher(Odometry, '/hexapod/odom', STATE_QOS)
    goal_pub = client.node.create_publisher(PoseStamped, '/goal_pose', GOAL_QOS)
    client.spin_until(lambda: goal_pub.get_subscription_count() >= 1
                      and odom_pub.get_subscription_count() >= 1, 60, 'the planner')
    goal_stamp = conv.time_to_msg(7.0)

    def straight_path():
        odom_pub.publish(conv.odometry_msg(start, stamp=8.0))
        goal_pub.publish(conv.pose_stamped(goal, stamp=7.0))
        return any(p.header.stamp == goal_stamp for p in watch.paths)
    client.spin_until(straight_path, 60, "the goal's path on the open field")
    first = conv.path_from_msg(next(p for p in watch.paths if p.header.stamp == goal_stamp))
    assert not _segments_free(walled, first)  # straight through where the wall will be
    count = len(watch.paths)

    map_pub.publish(grids.occupancy_grid_to_msg(walled.occupied, 0.1, (-1.0, -1.0),
                                               frame_id='map'))
    # (Paths of the goals sent above may still come: the one around the wall is awaited.)
    client.spin_until(lambda: any(_segments_free(walled, conv.path_from_msg(p))
                                  for p in watch.paths[count:]), 60,
                      "the goal's path on the new map")
    path = next(conv.path_from_msg(p) for p in watch.paths[count:]
                if _segments_free(walled, conv.path_from_msg(p)))
    assert np.allclose(path[0], start[:2], atol=0.1) and np.allclose(path[-1], goal)
    assert path[:, 1].max() > 1.0  # around the wall's end
    assert all(nodes.alive().values()), nodes.logs()


def test_compute_path_to_pose_answers_as_nav2s_planner_server(planner):
    """nav2's ComputePathToPose and ComputePathThroughPoses (BasicNavigator.getPath and
    getPathThroughPoses): the path, or the code saying why."""
    from rclpy.action import ActionClient

    from sela_ros.nodes import interface as ifc

    nodes, watch = planner
    client = watch.client
    action = ifc.COMPUTE_PATH_TO_POSE.type
    compute = ActionClient(client.node, action, ifc.COMPUTE_PATH_TO_POSE.root_name)
    client.spin_until(compute.server_is_ready, 60, 'compute_path_to_pose')
    maze = load_map_file(MAPS / 'maze.yaml')

    def ask(goal, start=None, planner_id='', frame_id='odom'):
        request = action.Goal(goal=conv.pose_stamped(goal, frame_id=frame_id),
                              planner_id=planner_id, use_start=start is not None)
        if start is not None:
            request.start = conv.pose_stamped(start, frame_id=frame_id)
        sent = compute.send_goal_async(request)
        client.spin_until(sent.done, 30, 'the goal response')
        assert sent.result().accepted
        done = sent.result().get_result_async()
        client.spin_until(done.done, 30, 'the result')
        return done.result()

    answer = ask((4.5, 4.5), start=(0.0, 0.0))
    assert answer.status == GoalStatus.STATUS_SUCCEEDED and answer.result.error_code == 0
    path = conv.path_from_msg(answer.result.path)
    assert np.allclose(path[0], (0.0, 0.0)) and np.allclose(path[-1], (4.5, 4.5))
    assert _segments_free(maze, path) and len(path) > 3
    assert answer.result.path.header.frame_id == 'odom'
    # nav2's getPath sends poses in map: the same frame here, the path the same.
    in_map = ask((4.5, 4.5), start=(0.0, 0.0), frame_id='map')
    assert in_map.status == GoalStatus.STATUS_SUCCEEDED, in_map.result.error_msg
    assert np.allclose(conv.path_from_msg(in_map.result.path), path)
    wall = next(maze.cell_to_world((ix, iy)) for iy, ix in np.argwhere(maze.occupied)
                if maze.in_map(maze.cell_to_world((ix, iy))))
    for kwargs, code, words in (
            ({'goal': (4.5, 4.5)}, action.Result.UNKNOWN, 'no odometry yet'),
            ({'goal': (50.0, 0.0), 'start': (0.0, 0.0)}, action.Result.GOAL_OUTSIDE_MAP,
             'off the map'),
            ({'goal': tuple(wall), 'start': (0.0, 0.0)}, action.Result.GOAL_OCCUPIED,
             'inside an obstacle'),
            ({'goal': (4.5, 4.5), 'start': (-50.0, 0.0)}, action.Result.START_OUTSIDE_MAP,
             'off the map'),
            ({'goal': (4.5, 4.5), 'start': (0.0, 0.0), 'frame_id': 'base_link'},
             action.Result.TF_ERROR, "frame 'base_link'"),
            ({'goal': (4.5, 4.5), 'start': (0.0, 0.0), 'planner_id': 'Smac'},
             action.Result.INVALID_PLANNER, "'Smac'")):
        answer = ask(**kwargs)
        assert answer.status == GoalStatus.STATUS_ABORTED, (kwargs, answer.result)
        assert answer.result.error_code == code, (kwargs, answer.result)
        assert words in answer.result.error_msg, (kwargs, answer.result.error_msg)
        assert not answer.result.path.poses

    # Through poses in order: one path, each leg from where the one before ends.
    through_type = ifc.COMPUTE_PATH_THROUGH_POSES.type
    through = ActionClient(client.node, through_type, ifc.COMPUTE_PATH_THROUGH_POSES.root_name)
    client.spin_until(through.server_is_ready, 60, 'compute_path_through_poses')

    def ask_through(goals):
        request = through_type.Goal(goals=[conv.pose_stamped(g) for g in goals],
                                    start=conv.pose_stamped((0.0, 0.0)), use_start=True)
        sent = through.send_goal_async(request)
        client.spin_until(sent.done, 30, 'the goal response')
        done = sent.result().get_result_async()
        client.spin_until(done.done, 30, 'the result')
        return done.result()

    answer = ask_through([(4.5, 4.5), (0.5, 4.5)])
    assert answer.status == GoalStatus.STATUS_SUCCEEDED, answer.result
    path = conv.path_from_msg(answer.result.path)
    assert np.allclose(path[0], (0.0, 0.0)) and np.allclose(path[-1], (0.5, 4.5))
    assert np.isclose(np.hypot(*(path - (4.5, 4.5)).T), 0.0).sum() == 1  # passed once
    assert _segments_free(maze, path)
    for goals, code in (([], through_type.Result.NO_VIAPOINTS_GIVEN),
                        ([(4.5, 4.5), (50.0, 0.0)], through_type.Result.GOAL_OUTSIDE_MAP)):
        answer = ask_through(goals)
        assert answer.status == GoalStatus.STATUS_ABORTED and answer.result.error_code == code

    # use_start false: from the robot's pose (its odometry).
    odom_pub = client.node.create_publisher(Odometry, '/hexapod/odom', STATE_QOS)
    sent = []

    def from_the_robot():
        odom_pub.publish(conv.odometry_msg((0.5, 0.5, 0.0), stamp=3.0))
        sent.append(1)
        return len(sent) > 1 and ask((4.5, 4.5)).status == GoalStatus.STATUS_SUCCEEDED
    client.spin_until(from_the_robot, 60, 'a path from the odometry pose')
    path = conv.path_from_msg(ask((4.5, 4.5), planner_id='GridBased').result.path)
    assert np.allclose(path[0], (0.5, 0.5)) and np.allclose(path[-1], (4.5, 4.5))
    assert all(nodes.alive().values()), nodes.logs()
