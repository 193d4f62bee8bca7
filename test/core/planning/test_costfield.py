"""The cost-to-go field planner against the reference A*: same path costs, same rules."""
import math

import numpy as np
import pytest

from sela_ros.core.planning import (
    AStarPlanner,
    GridPlanner,
    OccupancyGrid,
    UnreachableError,
    next_waypoint,
)
from sela_ros.core.planning.costfield import CostField, grid_graph
from sela_ros.core.planning.grid import inflate
from sela_ros.core.planning.planner import astar_cells, line_is_free, smooth_path


def _random_grid(rng, size, density):
    occ = rng.random(size) < density
    # A few walls too, so that paths must go around long obstacles, not only specks.
    for _ in range(rng.integers(0, 4)):
        y, x = rng.integers(0, size[0]), rng.integers(0, size[1])
        if rng.random() < 0.5:
            occ[y, x:x + rng.integers(2, size[1])] = True
        else:
            occ[y:y + rng.integers(2, size[0]), x] = True
    return occ


def _path_cost(cells):
    """Cost of a cell path, checking each move is an allowed 8-connected move."""
    cost = 0.0
    for (x0, y0), (x1, y1) in zip(cells, cells[1:]):
        dx, dy = abs(x1 - x0), abs(y1 - y0)
        assert max(dx, dy) == 1, (cells, x0, y0, x1, y1)
        cost += math.sqrt(2.0) if dx and dy else 1.0
    return cost


@pytest.mark.parametrize('seed', range(40))
def test_field_costs_equal_astar_costs_on_random_grids(seed):
    rng = np.random.default_rng(seed)
    size = (int(rng.integers(3, 30)), int(rng.integers(3, 30)))
    occ = _random_grid(rng, size, rng.uniform(0.0, 0.4))
    grid = OccupancyGrid(occ, 0.1)
    free_cells = np.argwhere(~occ)
    assert len(free_cells) >= 2  # the seeds give grids with room (never skipped)
    graph = grid_graph(~occ)
    for _ in range(4):
        gy, gx = free_cells[rng.integers(len(free_cells))]
        field = CostField(~occ, (gx, gy), graph)
        for _ in range(5):
            sy, sx = free_cells[rng.integers(len(free_cells))]
            try:
                _, a_cost = astar_cells(grid, (sx, sy), (gx, gy))
            except UnreachableError:
                assert not field.reachable((sx, sy))
                continue
            assert field.cost[sy, sx] == pytest.approx(a_cost, abs=1e-9)
            cells = field.cells_from((sx, sy))
            assert cells[0] == (sx, sy) and cells[-1] == (gx, gy)
            assert _path_cost(cells) == pytest.approx(a_cost, abs=1e-9)
            for (x0, y0), (x1, y1) in zip(cells, cells[1:]):
                assert not occ[y1, x1]
                if x0 != x1 and y0 != y1:  # no corner cutting
                    assert not occ[y0, x1] and not occ[y1, x0]


def test_planners_agree_on_the_grid_path_cost_with_inflation():
    rng = np.random.default_rng(7)
    occ = _random_grid(rng, (60, 80), 0.03)
    grid = OccupancyGrid(occ, 0.05)
    fast, ref = GridPlanner(grid, inflation=0.1), AStarPlanner(grid, inflation=0.1)
    assert np.array_equal(fast.planning_grid.occupied, ref.planning_grid.occupied)
    free = np.argwhere(~fast.planning_grid.occupied)
    checked = 0
    for _ in range(20):
        (sy, sx), (gy, gx) = free[rng.integers(len(free), size=2)]
        start, goal = (sx, sy), (gx, gy)
        try:
            _, _, ref_cells = ref._cells(start, goal)
        except UnreachableError:
            with pytest.raises(UnreachableError):
                fast._cells(start, goal)
            continue
        _, _, fast_cells = fast._cells(start, goal)
        assert _path_cost(fast_cells) == pytest.approx(_path_cost(ref_cells), abs=1e-9)
        checked += 1
    assert checked >= 10


def test_inflation_is_a_disc_around_every_obstacle():
    rng = np.random.default_rng(3)
    occ = rng.random((25, 30)) < 0.04
    grid = OccupancyGrid(occ, 0.1)
    got = inflate(grid, 0.25).occupied
    r = 2  # floor(0.25 / 0.1)
    want = occ.copy()
    for y, x in np.argwhere(occ):
        for dy in range(-r, r + 1):
            for dx in range(-r, r + 1):
                if dx * dx + dy * dy <= r * r and 0 <= y + dy < 25 and 0 <= x + dx < 30:
                    want[y + dy, x + dx] = True
    assert np.array_equal(got, want)


def _walled_grid():
    """A 6 m x 6 m field at 5 cm with a wall x in [2.5, 3] for y < 4.5, open above."""
    occ = np.zeros((120, 120), dtype=bool)
    occ[:90, 50:60] = True
    return OccupancyGrid(occ, 0.05)


def test_smoothed_path_segments_are_free_and_the_horizon_keeps_the_waypoint():
    grid = _walled_grid()
    full = GridPlanner(grid, inflation=0.25, smooth_horizon=None)
    short = GridPlanner(grid, inflation=0.25, smooth_horizon=1.0)
    start, goal = (0.5, 0.5), (5.5, 0.5)
    path_full, path_short = full(start, goal), short(start, goal)
    for a, b in zip(path_full, path_full[1:]):
        assert line_is_free(full.planning_grid, a, b)
    assert len(path_full) <= 6  # up, over the wall's end, down: a few corners
    assert len(path_short) > len(path_full)  # the tail beyond 1 m left as grid cells
    for lookahead in (0.3, 0.6, 0.9):
        np.testing.assert_allclose(next_waypoint(path_short, start, lookahead),
                                   next_waypoint(path_full, start, lookahead))


def test_smoothing_reaches_the_end_in_free_space():
    grid = OccupancyGrid.empty(0, 5, 0, 5, 0.05)
    path = np.array([[0.1, 0.1], [0.125, 0.125], [0.175, 0.125], [4.0, 3.0]])
    assert smooth_path(grid, path).tolist() == [[0.1, 0.1], [4.0, 3.0]]


def test_field_is_kept_per_goal_and_reused():
    planner = GridPlanner(_walled_grid(), inflation=0.25)
    field = planner.field((5.5, 0.5))
    planner((0.5, 0.5), (5.5, 0.5))
    planner((1.0, 0.5), (5.51, 0.51))  # same goal cell
    assert planner.field((5.5, 0.5)) is field and len(planner._fields) == 1
    for k in range(6):
        planner((0.5, 0.5), (5.5, 1.0 + 0.5 * k))
    assert len(planner._fields) == planner.cache_size


def test_a_robot_in_an_obstacle_is_led_to_a_cell_that_reaches_the_goal():
    # A pocket of free cells closed on every side sits next to where the robot strayed:
    # the nearest free cell cannot reach the goal, the path must leave by the other side.
    occ = np.zeros((40, 40), dtype=bool)
    occ[10:30, 10:30] = True
    occ[18:22, 6:10] = True
    occ[19:21, 9:10] = False  # the pocket, walled in
    grid = OccupancyGrid(occ, 0.1)
    planner = GridPlanner(grid)
    start = (1.05, 2.05)  # cell (10, 20): in the block, next to the pocket
    path = planner(start, (0.2, 0.2))
    exit_cell = grid.world_to_cell(path[1])
    assert planner.planning_grid.is_free(exit_cell)
    assert not (9 <= exit_cell[0] <= 9 and 19 <= exit_cell[1] <= 20)
    np.testing.assert_allclose(path[0], start)
    np.testing.assert_allclose(path[-1], (0.2, 0.2))


def test_unreachable_goal_is_an_error_from_a_free_start():
    occ = np.zeros((20, 20), dtype=bool)
    occ[:, 10] = True
    planner = GridPlanner(OccupancyGrid(occ, 0.1))
    with pytest.raises(UnreachableError, match='unreachable'):
        planner((0.2, 0.2), (1.8, 0.2))


def test_on_a_large_map_only_the_current_goals_field_is_kept(monkeypatch):
    from sela_ros.core.planning import planner as planner_module

    grid = _walled_grid()
    # As if the map were larger than FIELD_CELLS_KEPT allows two fields of.
    monkeypatch.setattr(planner_module, 'FIELD_CELLS_KEPT', grid.occupied.size * 3 // 2)
    planner = GridPlanner(grid, inflation=0.25)
    for k in range(4):
        planner((0.5, 0.5), (5.5, 1.0 + 0.5 * k))
        assert len(planner._fields) == 1
