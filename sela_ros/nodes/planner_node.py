"""The ``planner`` node: optimal grid paths over an occupancy grid, the reward selection layer.

Serves ``~/make_plan`` (nav_msgs/GetPlan): the answer's ``plan`` is the whole path from the
request's start to its goal, as GetPlan promises (the ``sela_adapter`` takes the waypoint of
the reward off it, ``planner.lookahead`` along it). A start off the map or in an obstacle is
led back onto the map from the nearest free cell. An empty plan means no path (the reason
goes to ``diagnostics``). After each plan the path is also published on ``~/path`` for
observers. Paths come from a cost-to-go field computed once per goal
and map (:class:`~sela_ros.core.planning.GridPlanner`): milliseconds per plan on a million
cells.

The map comes from ``map.file`` (map_server's YAML + image, or the project's YAML), else the
``map.*`` parameters, and is replaced by any ``nav_msgs/OccupancyGrid`` received on ``map``
(what map_server publishes: reliable, transient local). A map that cannot be used is reported
on ``diagnostics`` and the current one kept. The map in use is published, latched, on
``~/map``. A goal on ``goal_pose`` is checked against the map and planned from the latest
odometry, so a bad goal is reported as soon as it is sent; a goal sent before the first
odometry is planned when it comes.

Serves nav2's ``compute_path_to_pose`` and ``compute_path_through_poses`` actions (nav2
Jazzy's types, as nav2's planner server: ``BasicNavigator.getPath`` and
``getPathThroughPoses`` work): the path from ``start`` (``use_start``) or the robot's latest
pose to the goal, or through the goals in order, with nav2's codes when there is none (for
ComputePathToPose 203 start off the map, 204 goal off the map, 206 goal in an obstacle, 208
no path, 202 a frame other than the planning frame, 201 a ``planner_id`` other than '' or
``GridBased``; ComputePathThroughPoses' are the same plus 100, and 309 no goals).
"""
import time

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus
from nav_msgs.msg import Path
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node

from sela_ros.core.planning import (
    DEFAULT_INFLATION,
    DEFAULT_MAP,
    ORIGIN_LIMIT,
    RESOLUTION_RANGE,
    SIDE_RANGE,
    GridPlanner,
    MapError,
    PlanningError,
    check_geometry,
    grid_from_description,
    grid_from_ros,
    load_map_file,
)
from sela_ros.nodes import conversions as conv
from sela_ros.nodes import grid_conversions as grids
from sela_ros.nodes import interface as ifc
from sela_ros.nodes.guard import guard, guard_parameters, guard_service
from sela_ros.nodes.heartbeat import add_heartbeat
from sela_ros.nodes.node_main import run_node
from sela_ros.nodes.params import Spec, declare

#: The planner ids the actions answer to: nav2's default plugin name, or none.
PLANNER_IDS = ('', 'GridBased')

__all__ = ['PlannerNode', 'grid_from_description', 'load_map_file', 'main']


def _origin_rule(value):
    if len(value) != 2:
        return f'must be [x, y], got {list(value)}'
    try:
        check_geometry(RESOLUTION_RANGE[0], value, SIDE_RANGE[0], SIDE_RANGE[0])
    except MapError:
        return f'must be within [{-ORIGIN_LIMIT:g}, {ORIGIN_LIMIT:g}] m, got {list(value)}'
    return None


def _obstacles_rule(value):
    return None if len(value) % 4 == 0 else (
        'must be a flat list of rectangles [xmin, ymin, xmax, ymax, ...]; '
        f'got {len(value)} numbers')


PARAMETERS = (
    Spec('map.resolution', DEFAULT_MAP['resolution'], 'size of a grid cell',
         low=RESOLUTION_RANGE[0], high=RESOLUTION_RANGE[1], unit=' m', read_only=True),
    Spec('map.origin', list(DEFAULT_MAP['origin']), 'lower-left corner [x, y] of the grid in '
         'odom (m)', rule=_origin_rule, read_only=True),
    Spec('map.width', DEFAULT_MAP['width'], 'width of the grid', low=SIDE_RANGE[0],
         high=SIDE_RANGE[1], unit=' m', read_only=True),
    Spec('map.height', DEFAULT_MAP['height'], 'height of the grid', low=SIDE_RANGE[0],
         high=SIDE_RANGE[1], unit=' m', read_only=True),
    # Not set by default: ROS cannot hold an empty typed array in YAML.
    Spec('map.obstacles', None, 'rectangles [xmin, ymin, xmax, ymax, ...] in m',
         kind='double_array', rule=_obstacles_rule, read_only=True),
    Spec('map.file', '', "a map YAML: map_server's (image, resolution, origin, ...) or the "
         "project's (resolution, origin, width, height, obstacles); '' = the map.* "
         'parameters. Settable at run time: a file that cannot be used is refused'),
    Spec('map.unknown_is_occupied', True, 'unknown cells (-1) of a map_server map or a map '
         'message are obstacles (false: free)', read_only=True),
    Spec('planner.inflation', DEFAULT_INFLATION, 'clearance kept from obstacles', low=0.0,
         high=10.0, unit=' m'),
    Spec('frame_id', 'odom', 'frame of goals, paths and waypoints', read_only=True),
    Spec('map_frame', 'map', 'a frame taken as frame_id: goals and paths in it are used as '
         'given in frame_id (no localisation here: the odometry is the map, as in the simulator '
         "or with motion capture; '' = refused)", read_only=True),
)


def _map_file_problem(path, exc):
    """What is wrong with a map file: a MapError says it; anything else is named."""
    return str(exc) if isinstance(exc, ValueError) else \
        f'map file {path}: {type(exc).__name__}: {exc}'


class PlannerNode(Node):
    def __init__(self):
        super().__init__(ifc.PLANNER)
        self._pending_grid = None
        values = declare(self, PARAMETERS, on_change=self.parameters_callback)
        self.frame_id = values['frame_id']
        self.goal_frames = conv.goal_frames(self.frame_id, values['map_frame'])
        self.unknown_is_occupied = values['map.unknown_is_occupied']
        self.inflation = values['planner.inflation']
        self.map_error = None
        self.pose = None
        self.goal = None
        self._goal_stamp = None  # a goal taken before any odometry: planned on the first pose
        self.grid = self.planner = None

        self.map_pub = ifc.publisher(self, ifc.MAP)
        self.path_pub = ifc.publisher(self, ifc.PATH)
        self.diag_pub = ifc.publisher(self, ifc.DIAGNOSTICS)
        ifc.subscription(self, ifc.ODOM, self.odom_callback)
        ifc.subscription(self, ifc.GOAL, self.goal_callback)
        # map_server's topic and QoS: a map published before the planner started still comes.
        ifc.subscription(self, ifc.MAP_IN, self.map_callback)
        ifc.server(self, ifc.MAKE_PLAN, self.make_plan_callback)
        self.path_actions = [
            ifc.action_server(self, action,
                              lambda handle, action=action: self.compute_path(action, handle))
            for action in ifc.PLANNER_ACTIONS]
        self.add_post_set_parameters_callback(self.parameters_applied_callback)
        grid, source = self._initial_grid()
        add_heartbeat(self, problem=lambda: self.map_error)  # said at every beat until fixed
        self._use_grid(grid, source)
        if self.map_error:
            self._report(DiagnosticStatus.ERROR, self.map_error)

    def _initial_grid(self):
        path = self.get_parameter('map.file').value
        if path:
            try:
                return load_map_file(path, self.unknown_is_occupied), f'file {path}'
            except Exception as exc:  # noqa: BLE001 - whatever the file holds (origin: 5)
                # A bad map file must not take the planner down: say why, use the params.
                self.map_error = f'{_map_file_problem(path, exc)}; planning on the map.* ' \
                    'parameters instead'
                self.get_logger().error(self.map_error)
        return self._described_grid()

    def _described_grid(self):
        """The map of the map.* parameters, or, when they are wrong, an empty default field
        (and ``map_error`` says why)."""
        try:
            return grid_from_description(
                self.get_parameter('map.resolution').value,
                self.get_parameter('map.origin').value, self.get_parameter('map.width').value,
                self.get_parameter('map.height').value, self._obstacles()), 'map.* parameters'
        except MapError as exc:
            # Wrong map.* parameters: still run (and say so) on an empty default field.
            self.map_error = f'{exc}; planning on an empty 4 m x 4 m field instead'
            self.get_logger().error(self.map_error)
            return grid_from_description(0.05, [-1.0, -1.0], 4.0, 4.0, []), 'default field'

    def _use_grid(self, grid, source):
        """Plan on ``grid`` from now on and publish it; the current goal's field is built."""
        self.grid = grid
        self.planner = GridPlanner(grid, inflation=float(self.inflation))
        self.map_pub.publish(grids.occupancy_grid_to_msg(
            grid.occupied, grid.resolution, grid.origin, frame_id=self.frame_id))
        message = (f'map from {source}: {grid.width}x{grid.height} cells of '
                   f'{grid.resolution} m, bounds {grid.bounds_text()}, inflation '
                   f'{self.planner.inflation} m')
        self._report(DiagnosticStatus.OK, message)
        self._prepare_goal()

    def _prepare_goal(self, replan=True):
        """Build the current goal's field on the map in use; with ``replan``, where the
        robot's pose is known, plan to the goal again and publish the path: a client watching
        ``path`` sees the route on the new map, not one through what is now a wall."""
        if self.goal is None:
            return
        try:
            self.planner.field(self.goal)  # paid now, not by the next step
            if replan and self.pose is not None and self._goal_stamp is None:
                self._plan(self.pose[:2], self.goal, self.get_clock().now().to_msg())
        except PlanningError as exc:
            self._report(DiagnosticStatus.ERROR, f'current goal not reachable on the new map '
                         f'or inflation: {exc}')

    @guard
    def map_callback(self, msg):
        try:
            values, resolution, origin = grids.occupancy_values_from_msg(msg)
            grid = grid_from_ros(values, resolution, origin, self.unknown_is_occupied)
        except (conv.MessageError, MapError) as exc:
            self._report(DiagnosticStatus.ERROR, f'map on topic rejected: {exc}; keeping '
                         'the current map')
            return
        source = f'topic {self.resolve_topic_name(ifc.MAP_IN.name)}'
        if msg.header.frame_id not in ('', self.frame_id):
            # No tf here: the map is taken as drawn in the planning frame (true in the
            # simulator, where odom does not drift); say so rather than refuse it.
            source += f' (frame {msg.header.frame_id!r} taken as {self.frame_id!r})'
        self.map_error = None  # a good map replaces the one that could not be used
        self._use_grid(grid, source)

    def _obstacles(self):
        # Not set (None) when none are given: ROS cannot hold an empty typed array in YAML.
        return list(self.get_parameter('map.obstacles').value or [])

    @guard_parameters
    def parameters_callback(self, params):
        """Check what needs the node (a map file must load); params.declare checked types."""
        self._pending_grid = None
        for param in params:
            if param.name == 'map.file' and not param.value:
                self._pending_grid = self._described_grid  # back to the map.* parameters
            elif param.name == 'map.file':
                # Reading the file is the check: a bad one is refused, the map stays.
                try:
                    loaded = (load_map_file(param.value, self.unknown_is_occupied),
                              f'file {param.value}')
                    self._pending_grid = lambda loaded=loaded: loaded
                except Exception as exc:  # noqa: BLE001 - whatever the file holds
                    problem = f'map.file: {_map_file_problem(param.value, exc)}'
                    self._report(DiagnosticStatus.ERROR, f'parameter refused: {problem}; '
                                 'keeping the current map')
                    return SetParametersResult(successful=False, reason=problem)
        return None

    @guard
    def parameters_applied_callback(self, params):
        rebuild = False
        for param in params:
            if param.name == 'planner.inflation':
                self.inflation = float(param.value)
                rebuild = True
        if self._pending_grid is not None:
            make, self._pending_grid = self._pending_grid, None
            self.map_error = None
            grid, source = make()
            self._use_grid(grid, source)
            if self.map_error:
                self._report(DiagnosticStatus.ERROR, self.map_error)
        elif rebuild:
            self._use_grid(self.grid, 'the same map with the new inflation')

    @guard
    def odom_callback(self, msg):
        try:
            self.pose = conv.pose_from_odometry(msg)
        except conv.MessageError as exc:
            self.get_logger().error(f'ignored odometry: {exc}', throttle_duration_sec=1.0)
            return
        if self._goal_stamp is not None and self.goal is not None:
            stamp, self._goal_stamp = self._goal_stamp, None
            try:
                self._plan(self.pose[:2], self.goal, stamp)
            except PlanningError as exc:
                self._report(DiagnosticStatus.ERROR, f'goal ({self.goal[0]:.2f}, '
                             f'{self.goal[1]:.2f}) not planned: {exc}')

    @guard
    def goal_callback(self, msg):
        try:
            goal = conv.goal_from_pose_stamped(msg, self.goal_frames)
            problem = self.grid.goal_problem(goal)
            if problem:
                raise PlanningError(f'goal ({goal[0]:.2f}, {goal[1]:.2f}) is {problem}')
        except (conv.MessageError, PlanningError) as exc:
            self._report(DiagnosticStatus.ERROR, f'goal rejected: {exc}')
            return
        self.goal = goal
        self.get_logger().info(f'goal ({goal[0]:.2f}, {goal[1]:.2f})')
        self._prepare_goal(replan=False)
        if self.pose is None:
            self._goal_stamp = msg.header.stamp
        else:
            self._goal_stamp = None
            self._plan(self.pose[:2], goal, msg.header.stamp)

    @guard_service
    def make_plan_callback(self, request, response):
        try:
            start = conv.goal_from_pose_stamped(request.start, self.goal_frames, 'start')
            if (request.goal.header.frame_id == '' and request.goal.pose.position.x == 0.0
                    and request.goal.pose.position.y == 0.0 and self.goal is not None):
                goal = self.goal  # an empty goal means: the current /goal_pose
            else:
                goal = conv.goal_from_pose_stamped(request.goal, self.goal_frames, 'goal')
            response.plan = self._plan(start, goal, request.start.header.stamp)
        except (conv.MessageError, PlanningError, ValueError) as exc:
            self._report(DiagnosticStatus.ERROR, f'make_plan failed: {exc}')
            response.plan = Path()
            response.plan.header.frame_id = self.frame_id
        return response

    def compute_path(self, action, handle):
        """nav2's ComputePathToPose or ComputePathThroughPoses (``action``): the path, or an
        empty one and the code saying why."""
        result = action.type.Result()
        begin = time.monotonic()
        try:
            result.path = self._requested_path(handle.request, result)
            handle.succeed()
        except _Refused as exc:
            result.error_code, result.error_msg = exc.code, str(exc)
            result.path = Path()
            result.path.header.frame_id = self.frame_id
            self._report(DiagnosticStatus.ERROR, f'{action.name}: {exc}')
            handle.abort()
        except Exception as exc:  # noqa: BLE001 - a client's goal must get its answer
            result.error_code = result.UNKNOWN
            result.error_msg = f'{type(exc).__name__}: {exc}'
            self.get_logger().error(f'{action.name} failed: {result.error_msg}')
            handle.abort()
        seconds = time.monotonic() - begin
        result.planning_time.sec = int(seconds)
        result.planning_time.nanosec = int((seconds - int(seconds)) * 1e9)
        return result

    def _requested_path(self, request, result):
        if request.planner_id not in PLANNER_IDS:
            raise _Refused(result.INVALID_PLANNER, f'planner_id {request.planner_id!r} is not '
                           f"served here; use '' or 'GridBased'")
        through = hasattr(request, 'goals')
        poses = list(request.goals) if through else [request.goal]
        sent = poses + ([request.start] if request.use_start else [])
        frame = next((p.header.frame_id for p in sent
                      if not conv.frame_accepted(p.header.frame_id, self.goal_frames)), None)
        if frame is not None:  # no tf here: only the planning frame (and the map's) is known
            raise _Refused(result.TF_ERROR, f"frame '{frame}' is not supported; send the poses "
                           f"in {conv.send_in(self.goal_frames)}")
        try:
            names = [f'goals[{i}]' for i in range(len(poses))] if through else ['goal']
            goals = [conv.goal_from_pose_stamped(p, self.goal_frames, n)
                     for p, n in zip(poses, names)]
            if request.use_start:
                start = conv.goal_from_pose_stamped(request.start, self.goal_frames, 'start')
            elif self.pose is None:
                raise _Refused(result.UNKNOWN, 'no odometry yet: the robot\'s pose is not '
                               'known (set use_start and a start)')
            else:
                start = self.pose[:2]
        except conv.MessageError as exc:
            raise _Refused(result.UNKNOWN, str(exc)) from None
        if not goals:
            raise _Refused(result.NO_VIAPOINTS_GIVEN, 'no goals given')
        for goal in goals:
            problem = self.grid.goal_problem(goal)
            if problem:
                code = result.GOAL_OUTSIDE_MAP if not self.grid.in_map(goal) \
                    else result.GOAL_OCCUPIED
                raise _Refused(code, f'goal ({goal[0]:.2f}, {goal[1]:.2f}) is {problem}')
        if not self.grid.in_map(start):
            raise _Refused(result.START_OUTSIDE_MAP, f'start ({start[0]:.2f}, {start[1]:.2f}) '
                           f'is off the map ({self.grid.bounds_text()})')
        try:
            legs, at = [], start
            for goal in goals:  # each leg from where the one before ends
                leg = np.asarray(self.planner(at, goal), dtype=float)
                legs.append(leg if not legs else leg[1:])
                at = goal
        except PlanningError as exc:
            raise _Refused(result.NO_VALID_PATH, str(exc)) from None
        return self._publish_path(np.vstack(legs), poses[-1].header.stamp)

    def _plan(self, start, goal, stamp):
        """Plan and publish the path; returns it (the whole path to the goal)."""
        return self._publish_path(self.planner(start, goal), stamp)

    def _publish_path(self, points, stamp):
        path = conv.path_to_msg(points, stamp=stamp, frame_id=self.frame_id)
        self.path_pub.publish(path)
        return path

    def _report(self, level, message):
        self.get_logger().error(message) if level >= DiagnosticStatus.ERROR else \
            self.get_logger().info(message)
        self.diag_pub.publish(conv.diagnostic_array(
            conv.diagnostic_status(level, 'planner', message,
                                   {'bounds': self.grid.bounds_text()}),
            self.get_clock().now().to_msg()))


class _Refused(Exception):
    """No path for a path action's goal: ``code`` (its result's) says why."""

    def __init__(self, code, message):
        super().__init__(message)
        self.code = code


def main(args=None):
    run_node(PlannerNode, args)


if __name__ == '__main__':
    main()
