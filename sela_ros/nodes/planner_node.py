"""The ``planner`` node: A* over an occupancy grid, the reward selection layer of SELA.

Serves ``~/make_plan`` (nav_msgs/GetPlan): the answer's ``plan`` is the path from the
request's start up to and ending at the next waypoint, ``planner.lookahead`` metres along
the path to the goal (or the goal itself when closer): the waypoint the specialised reward is
built on is its last pose. An empty plan means no path (the reason goes to ``diagnostics``).
After each plan the full path to the goal is published on ``~/path`` and the waypoint on
``sela/target`` for observers. The map is published once, latched, on ``~/map``. A goal on
``goal_pose`` is checked against the map and planned from the latest odometry, so a bad goal
is reported as soon as it is sent.
"""
import math

import numpy as np
import yaml
from diagnostic_msgs.msg import DiagnosticStatus
from nav_msgs.msg import Path
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node

from sela_ros.core.planning import GridPlanner, OccupancyGrid, PlanningError, next_waypoint
from sela_ros.nodes import conversions as conv
from sela_ros.nodes import interface as ifc
from sela_ros.nodes.guard import guard, guard_parameters, guard_service
from sela_ros.nodes.heartbeat import add_heartbeat
from sela_ros.nodes.node_main import run_node
from sela_ros.nodes.params import Spec, declare


def grid_from_description(resolution, origin, width, height, obstacles):
    """Build an :class:`OccupancyGrid` from the planner's map parameters.

    ``obstacles`` is a flat list ``[xmin, ymin, xmax, ymax, ...]`` of rectangles in metres.
    """
    origin = [float(v) for v in origin]
    if len(origin) != 2:
        raise ValueError(f'map.origin must be [x, y], got {origin}')
    for name, value in (('map.resolution', resolution), ('map.width', width),
                        ('map.height', height)):
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise ValueError(f'{name} must be a number > 0, got {value!r}')
    obstacles = [float(v) for v in obstacles]
    if len(obstacles) % 4:
        raise ValueError('map.obstacles must be a flat list of rectangles '
                         f'[xmin, ymin, xmax, ymax, ...]; got {len(obstacles)} numbers')
    grid = OccupancyGrid.empty(origin[0], origin[0] + width, origin[1], origin[1] + height,
                               resolution)
    occupied = grid.occupied.copy()
    ys = grid.origin[1] + (np.arange(grid.height) + 0.5) * grid.resolution
    xs = grid.origin[0] + (np.arange(grid.width) + 0.5) * grid.resolution
    for xmin, ymin, xmax, ymax in np.reshape(obstacles, (-1, 4)):
        if not (xmax > xmin and ymax > ymin):
            raise ValueError(f'obstacle [{xmin}, {ymin}, {xmax}, {ymax}] is empty: '
                             'expected xmin < xmax and ymin < ymax')
        occupied[np.ix_((ys >= ymin) & (ys <= ymax), (xs >= xmin) & (xs <= xmax))] = True
    return OccupancyGrid(occupied, grid.resolution, grid.origin)


def load_map_file(path):
    """Read a map YAML: keys resolution, origin, width, height, obstacles (as the params)."""
    try:
        with open(path) as handle:
            data = yaml.safe_load(handle)
    except OSError as exc:
        raise ValueError(f'map file {path}: {exc.strerror}') from exc
    except yaml.YAMLError as exc:
        raise ValueError(f'map file {path} is not valid YAML: {exc}') from exc
    if not isinstance(data, dict):
        raise ValueError(f'map file {path}: expected a mapping with resolution, origin, '
                         'width, height, obstacles')
    missing = {'resolution', 'origin', 'width', 'height'} - set(data)
    if missing:
        raise ValueError(f'map file {path}: missing key(s) {sorted(missing)}')
    return grid_from_description(data['resolution'], data['origin'], data['width'],
                                 data['height'], data.get('obstacles', []))


def path_up_to(path_xy, waypoint):
    """The path's points before ``waypoint`` (a point on it), then the waypoint itself."""
    path_xy = np.asarray(path_xy, dtype=float).reshape(-1, 2)
    if len(path_xy) < 2:
        return np.vstack([path_xy[:1], waypoint])
    a, seg = path_xy[:-1], np.diff(path_xy, axis=0)
    t = np.clip(np.sum((waypoint - a) * seg, axis=1) / np.maximum(np.sum(seg * seg, axis=1),
                                                                 1e-18), 0.0, 1.0)
    k = int(np.argmin(np.hypot(*(a + t[:, None] * seg - waypoint).T)))
    return np.vstack([path_xy[:k + 1], waypoint])


def _origin_rule(value):
    return None if len(value) == 2 else f'must be [x, y], got {list(value)}'


def _obstacles_rule(value):
    return None if len(value) % 4 == 0 else (
        'must be a flat list of rectangles [xmin, ymin, xmax, ymax, ...]; '
        f'got {len(value)} numbers')


PARAMETERS = (
    Spec('map.resolution', 0.05, 'size of a grid cell', low=0.001, high=1.0, unit=' m',
         read_only=True),
    Spec('map.origin', [-1.0, -1.0], 'lower-left corner [x, y] of the grid in odom (m)',
         rule=_origin_rule, read_only=True),
    Spec('map.width', 4.0, 'width of the grid', low=0.01, high=1000.0, unit=' m',
         read_only=True),
    Spec('map.height', 4.0, 'height of the grid', low=0.01, high=1000.0, unit=' m',
         read_only=True),
    # Not set by default: ROS cannot hold an empty typed array in YAML.
    Spec('map.obstacles', None, 'rectangles [xmin, ymin, xmax, ymax, ...] in m',
         kind='double_array', rule=_obstacles_rule, read_only=True),
    Spec('map.file', '', "a map YAML (resolution, origin, width, height, obstacles); '' = the "
         'map.* parameters', read_only=True),
    Spec('planner.lookahead', 0.6, 'distance along the path to the waypoint of the reward',
         low=0.01, high=100.0, unit=' m'),
    Spec('planner.inflation', 0.25, 'clearance kept from obstacles', low=0.0, high=10.0,
         unit=' m'),
    Spec('frame_id', 'odom', 'frame of goals, paths and waypoints', read_only=True),
)


class PlannerNode(Node):
    def __init__(self):
        super().__init__(ifc.PLANNER)
        values = declare(self, PARAMETERS, on_change=self.parameters_callback)
        self.frame_id = values['frame_id']
        self.lookahead = values['planner.lookahead']
        self.map_error = None
        self.grid = self._load_grid()
        self.planner = GridPlanner(self.grid, inflation=values['planner.inflation'])
        self.pose = None
        self.goal = None

        self.map_pub = ifc.publisher(self, ifc.MAP)
        self.path_pub = ifc.publisher(self, ifc.PATH)
        self.target_pub = ifc.publisher(self, ifc.TARGET)
        self.diag_pub = ifc.publisher(self, ifc.DIAGNOSTICS)
        ifc.subscription(self, ifc.ODOM, self.odom_callback)
        ifc.subscription(self, ifc.GOAL, self.goal_callback)
        ifc.server(self, ifc.MAKE_PLAN, self.make_plan_callback)
        add_heartbeat(self)
        self.map_pub.publish(conv.occupancy_grid_to_msg(
            self.grid.occupied, self.grid.resolution, self.grid.origin, frame_id=self.frame_id))
        if self.map_error:
            self._report(DiagnosticStatus.ERROR, self.map_error)
        self.get_logger().info(f'map {self.grid.width}x{self.grid.height} cells of '
                               f'{self.grid.resolution} m, bounds {self.grid.bounds_text()}, '
                               f'lookahead {self.lookahead} m, inflation '
                               f'{self.planner.inflation} m')

    def _load_grid(self):
        path = self.get_parameter('map.file').value
        if path:
            try:
                return load_map_file(path)
            except Exception as exc:  # noqa: BLE001 - whatever the file holds (origin: 5)
                # A bad map file must not take the planner down: say why, use the params.
                detail = exc if isinstance(exc, ValueError) else (
                    f'map file {path}: {type(exc).__name__}: {exc}')
                self.map_error = f'{detail}; planning on the map.* parameters instead'
                self.get_logger().error(self.map_error)
        return grid_from_description(
            self.get_parameter('map.resolution').value, self.get_parameter('map.origin').value,
            self.get_parameter('map.width').value, self.get_parameter('map.height').value,
            self._obstacles())

    def _obstacles(self):
        # Not set (None) when none are given: ROS cannot hold an empty typed array in YAML.
        return list(self.get_parameter('map.obstacles').value or [])

    @guard_parameters
    def parameters_callback(self, params):
        # Called by params.declare with values its check accepted (map.* are read-only).
        for param in params:
            if param.name == 'planner.lookahead':
                self.lookahead = float(param.value)
            elif param.name == 'planner.inflation':
                self.planner = GridPlanner(self.grid, inflation=float(param.value))
        return SetParametersResult(successful=True)

    @guard
    def odom_callback(self, msg):
        try:
            self.pose = conv.pose_from_odometry(msg)
        except conv.MessageError as exc:
            self.get_logger().error(f'ignored odometry: {exc}')

    @guard
    def goal_callback(self, msg):
        try:
            goal = conv.goal_from_pose_stamped(msg, self.frame_id)
            if not self.grid.in_map(goal):
                raise PlanningError(f'goal ({goal[0]:.2f}, {goal[1]:.2f}) is off the map '
                                    f'{self.grid.bounds_text()}')
            if not self.grid.is_free(self.grid.world_to_cell(goal)):
                raise PlanningError(f'goal ({goal[0]:.2f}, {goal[1]:.2f}) is inside an '
                                    'obstacle')
        except (conv.MessageError, PlanningError) as exc:
            self._report(DiagnosticStatus.ERROR, f'goal rejected: {exc}')
            return
        self.goal = goal
        self.get_logger().info(f'goal ({goal[0]:.2f}, {goal[1]:.2f})')
        if self.pose is not None:
            self._plan(self.pose[:2], goal, msg.header.stamp)

    @guard_service
    def make_plan_callback(self, request, response):
        try:
            start = conv.goal_from_pose_stamped(request.start, self.frame_id)
            if (request.goal.header.frame_id == '' and request.goal.pose.position.x == 0.0
                    and request.goal.pose.position.y == 0.0 and self.goal is not None):
                goal = self.goal  # an empty goal means: the current /goal_pose
            else:
                goal = conv.goal_from_pose_stamped(request.goal, self.frame_id)
            response.plan = self._plan(start, goal, request.start.header.stamp)
        except (conv.MessageError, PlanningError, ValueError) as exc:
            self._report(DiagnosticStatus.ERROR, f'make_plan failed: {exc}')
            response.plan = Path()
            response.plan.header.frame_id = self.frame_id
        return response

    def _plan(self, start, goal, stamp):
        """Plan, publish the path and the target; returns the plan up to the waypoint."""
        path_xy = self.planner(start, goal)
        waypoint = next_waypoint(path_xy, start, self.lookahead)
        self.target_pub.publish(conv.point_stamped(waypoint, stamp=stamp,
                                                   frame_id=self.frame_id))
        self.path_pub.publish(conv.path_to_msg(path_xy, stamp=stamp, frame_id=self.frame_id))
        return conv.path_to_msg(path_up_to(path_xy, waypoint), stamp=stamp,
                                frame_id=self.frame_id)

    def _report(self, level, message):
        self.get_logger().error(message) if level >= DiagnosticStatus.ERROR else \
            self.get_logger().info(message)
        self.diag_pub.publish(conv.diagnostic_array(
            conv.diagnostic_status(level, 'planner', message,
                                   {'bounds': self.grid.bounds_text()}),
            self.get_clock().now().to_msg()))


def main(args=None):
    run_node(PlannerNode, args)


if __name__ == '__main__':
    main()
