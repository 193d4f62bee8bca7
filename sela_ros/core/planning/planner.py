"""The reward selection layer: occupancy grid, optimal 8-connected paths, waypoint selection.

At each SELA step the planner gives a path from the robot to the goal and
:func:`next_waypoint` picks the point ``lookahead`` metres along it; the specialised reward
of a behaviour is then minus the distance from that waypoint to where it is predicted to
take the robot.

:class:`GridPlanner` reads the path off a cost-to-go field computed once per goal and map
(:mod:`sela_ros.core.planning.costfield`), so a step costs milliseconds on a million-cell map;
:func:`astar` and :class:`AStarPlanner` (A* from scratch at every call) are kept as the
reference its paths are tested against and benchmarked beside
(``benchmarks/bench_planning.py``).
"""
from __future__ import annotations

import heapq
import math
from collections import OrderedDict

import numpy as np

from sela_ros.core.planning.costfield import CostField, grid_graph
from sela_ros.core.planning.grid import (
    MOVES,
    SQRT2,
    InObstacleError,
    OccupancyGrid,
    OffMapError,
    PlanningError,
    UnreachableError,
    inflate,
    nearest_free_cell,
)

DEFAULT_SMOOTH_HORIZON = 5.0  # m of path smoothed by GridPlanner (see there)
#: Cells of cost-to-go fields a GridPlanner keeps (about 45 bytes each): its cache_size fields
#: on a small map, only the current goal's on a large one (memory bounded, not grown per goal).
FIELD_CELLS_KEPT = 8_000_000


def _octile(a, b):
    dx, dy = abs(a[0] - b[0]), abs(a[1] - b[1])
    return max(dx, dy) + (SQRT2 - 1.0) * min(dx, dy)


def _endpoint_cell(grid, xy, which, in_obstacle_ok=False):
    try:
        cell = grid.world_to_cell(xy)
    except OffMapError as err:
        raise OffMapError(f'{which} {err}') from None
    if not in_obstacle_ok and not grid.is_free(cell):
        raise InObstacleError(f'{which} ({xy[0]:g}, {xy[1]:g}) is in an obstacle '
                              f'(cell {cell}; map {grid.bounds_text()})')
    return cell


def astar_cells(grid: OccupancyGrid, start_cell, goal_cell):
    """Shortest 8-connected cell path (straight 1, diagonal sqrt 2, in cells) and its cost.

    Diagonal moves may not cut the corner of an occupied cell. The octile heuristic is
    admissible and consistent, so the path is optimal.

    Returns:
        ``(cells, cost)``: list of ``(ix, iy)`` from start to goal, cost in cells.
    """
    start, goal = tuple(start_cell), tuple(goal_cell)
    g = {start: 0.0}
    parent = {start: None}
    counter = 0
    heap = [(_octile(start, goal), 0.0, counter, start)]
    closed = set()
    while heap:
        cell = heapq.heappop(heap)[3]
        if cell in closed:
            continue
        cost = g[cell]
        if cell == goal:
            path = []
            while cell is not None:
                path.append(cell)
                cell = parent[cell]
            return path[::-1], cost
        closed.add(cell)
        for dx, dy, step in MOVES:
            nxt = (cell[0] + dx, cell[1] + dy)
            if nxt in closed or not grid.is_free(nxt):
                continue
            if dx and dy and not (grid.is_free((cell[0] + dx, cell[1]))
                                  and grid.is_free((cell[0], cell[1] + dy))):
                continue
            new_cost = cost + step
            if new_cost < g.get(nxt, math.inf) - 1e-12:
                g[nxt] = new_cost
                parent[nxt] = cell
                counter += 1
                # Ties on f go to the larger g (closer to the goal): fewer expansions.
                heapq.heappush(heap, (new_cost + _octile(nxt, goal), -new_cost, counter, nxt))
    raise UnreachableError(f'goal cell {goal} is unreachable from start cell {start} '
                           f'(map {grid.bounds_text()})')


def astar(grid: OccupancyGrid, start_xy, goal_xy) -> np.ndarray:
    """Optimal 8-connected path from ``start_xy`` to ``goal_xy`` in world coordinates.

    Returns:
        ``(n, 2)`` array: the exact start, the centres of the intermediate cells, the exact
        goal.

    Raises:
        OffMapError, InObstacleError, UnreachableError (all PlanningError/ValueError).
    """
    start_xy = np.asarray(start_xy, dtype=float).reshape(-1)[:2]
    goal_xy = np.asarray(goal_xy, dtype=float).reshape(-1)[:2]
    start = _endpoint_cell(grid, start_xy, 'start')
    goal = _endpoint_cell(grid, goal_xy, 'goal')
    cells, _ = astar_cells(grid, start, goal)
    points = [start_xy] + [grid.cell_to_world(c) for c in cells[1:-1]] + [goal_xy]
    if len(cells) == 1:
        points = [start_xy, goal_xy]
    return np.array(points)


def line_is_free(grid: OccupancyGrid, a, b) -> bool:
    """Whether the segment a-b crosses only free cells (sampled at resolution / 4)."""
    ax, ay = float(a[0]) - grid.origin[0], float(a[1]) - grid.origin[1]
    dx, dy = float(b[0]) - float(a[0]), float(b[1]) - float(a[1])
    res = grid.resolution
    n = max(2, int(math.ceil(math.hypot(dx, dy) / (res / 4.0))) + 1)
    t = np.linspace(0.0, 1.0, n)
    ix = np.floor((ax + t * dx) / res).astype(np.intp)
    iy = np.floor((ay + t * dy) / res).astype(np.intp)
    h, w = grid.occupied.shape
    # The map is a rectangle: a segment whose ends are on it stays on it.
    if not (0 <= ix[0] < w and 0 <= iy[0] < h and 0 <= ix[-1] < w and 0 <= iy[-1] < h):
        return False
    return not grid.occupied[iy, ix].any()


def smooth_path(grid: OccupancyGrid, path, horizon: float = math.inf) -> np.ndarray:
    """Shortcut a grid path by line of sight (string pulling): drops the 45-degree zigzags
    of 8-connected paths, so that the waypoint points where the robot should really go.

    From each kept point the next kept point is found by galloping along the path (1, 2, 4,
    ... points ahead while the line stays free) then bisecting: O(log n) line checks per
    kept point instead of O(n), which keeps a step in milliseconds on paths of thousands of
    cells. Every segment returned is checked free (the first one, to the adjacent cell of an
    8-connected path, is free by construction).

    Smoothing is greedy from the start, so stopping once the smoothed part is ``horizon``
    metres long (the rest of the path kept as it is) changes nothing before that point: a
    waypoint taken within the horizon is the one full smoothing gives.
    """
    path = np.asarray(path, dtype=float)
    n = len(path)
    if n <= 2:
        return path
    out = [path[0]]
    i, length = 0, 0.0
    while i < n - 1:
        good, step = i + 1, 1
        while good < n - 1:
            ahead = min(good + step, n - 1)
            if not line_is_free(grid, path[i], path[ahead]):
                while ahead - good > 1:  # bisect: good is visible, ahead is not
                    mid = (good + ahead) // 2
                    if line_is_free(grid, path[i], path[mid]):
                        good = mid
                    else:
                        ahead = mid
                break
            good, step = ahead, step * 2
        out.append(path[good])
        length += math.dist(path[i], path[good])
        i = good
        if length >= horizon:
            return np.vstack([np.array(out), path[i + 1:]])
    return np.array(out)


def next_waypoint(path, pose_xy, lookahead: float) -> np.ndarray:
    """The point ``lookahead`` metres along ``path`` from the robot (the goal if closer).

    The robot is projected onto the closest point of the path; the waypoint is measured
    along the path from there.
    """
    path = np.asarray(path, dtype=float)
    if path.ndim != 2 or path.shape[1] != 2 or len(path) < 1:
        raise ValueError(f'path must have shape (n, 2) with n >= 1, got {path.shape}')
    if not np.isfinite(lookahead) or lookahead <= 0:
        raise ValueError(f'lookahead must be a finite number > 0, got {lookahead!r}')
    p = np.asarray(pose_xy, dtype=float).reshape(-1)[:2]
    if len(path) == 1:
        return path[0].copy()
    a, b = path[:-1], path[1:]
    seg = b - a
    seg_len2 = np.maximum(np.sum(seg * seg, axis=1), 1e-18)
    t = np.clip(np.sum((p - a) * seg, axis=1) / seg_len2, 0.0, 1.0)
    proj = a + t[:, None] * seg
    k = int(np.argmin(np.sum((proj - p) ** 2, axis=1)))
    remaining = lookahead
    point = proj[k]
    for i in range(k, len(path) - 1):
        end = path[i + 1]
        d = float(np.linalg.norm(end - point))
        if d >= remaining:
            return point + (end - point) * (remaining / d)
        remaining -= d
        point = end
    return path[-1].copy()


class AStarPlanner:
    """Planner callable ``(start_xy, goal_xy) -> path (n, 2)``: A* on a grid, then smoothed.

    Paths keep ``inflation`` metres away from obstacles (the search and the smoothing run on
    the inflated grid). A robot that has strayed into an obstacle or its margin is not
    stuck: the path leaves from there to the nearest free cell. A goal inside an obstacle is
    refused (:class:`InObstacleError`); a goal within the margin is reached through the
    nearest free cell.

    This one runs A* from scratch at every call (seconds on a million cells): it is the
    reference :class:`GridPlanner` is tested and benchmarked against.

    Args:
        grid: the occupancy grid.
        smooth: shortcut the grid path by line of sight (default True).
        inflation: clearance from obstacles in metres (default 0).
    """

    def __init__(self, grid: OccupancyGrid, smooth: bool = True, inflation: float = 0.0):
        self.grid = grid
        self.smooth = smooth
        self.inflation = float(inflation)
        self.planning_grid = inflate(grid, self.inflation)
        self.smooth_horizon = math.inf

    def __call__(self, start_xy, goal_xy) -> np.ndarray:
        start_xy = np.asarray(start_xy, dtype=float).reshape(-1)[:2]
        goal_xy = np.asarray(goal_xy, dtype=float).reshape(-1)[:2]
        if not np.all(np.isfinite(start_xy)):
            raise PlanningError(f'start ({start_xy[0]:g}, {start_xy[1]:g}) is not finite')
        goal = _endpoint_cell(self.grid, goal_xy, 'goal')  # in a real obstacle: refused
        # A robot off the map (it walked off, or started there) is led back onto it, from
        # the map's cell nearest to it, as a robot in an obstacle is led out of it.
        on_map = self.grid.in_map(start_xy)
        start = (_endpoint_cell(self.grid, start_xy, 'start', in_obstacle_ok=True) if on_map
                 else self.grid.nearest_cell(start_xy))
        free_start, free_goal, cells = self._cells(start, goal)
        grid = self.planning_grid
        middle = grid.cell_to_world(np.asarray(cells[1:-1], dtype=float).reshape(-1, 2))
        points = [start_xy[None]]
        leave = free_start != start or not on_map
        if leave:
            points.append(grid.cell_to_world(free_start)[None])  # onto free space first
        points.append(middle)
        if free_goal != goal and len(cells) > 1:
            points.append(grid.cell_to_world(free_goal)[None])
        points.append(goal_xy[None])
        path = np.vstack(points)
        if not self.smooth:
            return path
        # Smooth the part that lies in free space; the way out of an obstacle stays as is.
        k = 1 if leave else 0
        return np.vstack([path[:k], smooth_path(grid, path[k:], self.smooth_horizon)])

    def _no_free_cell(self):
        return UnreachableError(f'no free cell on the map {self.grid.bounds_text()} '
                                f'(inflation {self.inflation} m)')

    def _cells(self, start, goal):
        """``(free start cell, free goal cell, optimal cell path between them)``."""
        grid = self.planning_grid
        free_start, free_goal = nearest_free_cell(grid, start), nearest_free_cell(grid, goal)
        if free_start is None or free_goal is None:
            raise self._no_free_cell()
        return free_start, free_goal, astar_cells(grid, free_start, free_goal)[0]


class GridPlanner(AStarPlanner):
    """The reward selection layer at navigation scale: A*'s paths, read off a field.

    Same paths' cost, same inflation, same way out of an obstacle as :class:`AStarPlanner`,
    but the shortest paths come from a :class:`~sela_ros.core.planning.costfield.CostField`
    computed once per goal (Dijkstra from the goal over the whole map, in compiled code) and kept
    for the next calls: a call then follows the field from the robot's cell, smooths and
    returns, in milliseconds on a 1000 x 1000 map. A robot that strays into an obstacle or
    its margin is led to the nearest cell (Euclidean) from which the goal can be reached.

    Args:
        grid: the occupancy grid.
        smooth: shortcut the grid path by line of sight (default True).
        inflation: clearance from obstacles in metres (default 0).
        smooth_horizon: metres of the path smoothed (the rest is the optimal grid path as it
            is; default 5 m, well beyond any lookahead, None: all of it). Smoothing a long
            path whole costs tens of milliseconds; the waypoint only needs its start.
        cache_size: fields kept (one per goal cell, least recently used dropped first).
    """

    def __init__(self, grid: OccupancyGrid, smooth: bool = True, inflation: float = 0.0,
                 smooth_horizon: float | None = DEFAULT_SMOOTH_HORIZON, cache_size: int = 4):
        super().__init__(grid, smooth=smooth, inflation=inflation)
        self.smooth_horizon = math.inf if smooth_horizon is None else float(smooth_horizon)
        self.cache_size = max(1, int(cache_size))
        self._graph = None
        self._fields = OrderedDict()

    def field(self, goal_xy) -> CostField:
        """The cost-to-go field toward ``goal_xy`` (computed now unless already kept).

        A node may call this when a goal arrives, so that the first step does not pay for
        it. Raises the errors a plan to that goal would raise.
        """
        goal_xy = np.asarray(goal_xy, dtype=float).reshape(-1)[:2]
        return self._field(_endpoint_cell(self.grid, goal_xy, 'goal'))[1]

    def _field(self, goal):
        free_goal = nearest_free_cell(self.planning_grid, goal)
        if free_goal is None:
            raise self._no_free_cell()
        field = self._fields.get(free_goal)
        if field is None:
            free = ~self.planning_grid.occupied
            if self._graph is None:
                self._graph = grid_graph(free)
            field = CostField(free, free_goal, self._graph)
            self._fields[free_goal] = field
            # At most FIELD_CELLS_KEPT cells of fields: on a large map only the current one.
            kept = max(1, min(self.cache_size, FIELD_CELLS_KEPT // free.size))
            while len(self._fields) > kept:
                self._fields.popitem(last=False)
        self._fields.move_to_end(free_goal)
        return free_goal, field

    def _cells(self, start, goal):
        free_goal, field = self._field(goal)
        if self.planning_grid.is_free(start):
            if not field.reachable(start):
                raise UnreachableError(f'goal cell {free_goal} is unreachable from start cell '
                                       f'{start} (map {self.grid.bounds_text()}, inflation '
                                       f'{self.inflation} m)')
            free_start = start
        else:
            free_start = field.nearest_reachable(start)
        return free_start, free_goal, field.cells_from(free_start)


def straight_line_planner(start_xy, goal_xy) -> np.ndarray:
    """Planner for an empty world with no map: the straight segment to the goal."""
    return np.array([np.asarray(start_xy, dtype=float).reshape(-1)[:2],
                     np.asarray(goal_xy, dtype=float).reshape(-1)[:2]])
