"""Occupancy grid, A* optimality and errors, waypoint selection."""
import math

import numpy as np
import pytest

from sela_ros.core.planning import (
    AStarPlanner,
    GridPlanner,
    InObstacleError,
    OccupancyGrid,
    OffMapError,
    PlanningError,
    UnreachableError,
    next_waypoint,
)
from sela_ros.core.planning.planner import astar, astar_cells


def grid_from(rows, resolution=1.0):
    """Rows written top (high y) to bottom; '#' is an obstacle."""
    occ = np.array([[c == '#' for c in r] for r in rows[::-1]])
    return OccupancyGrid(occ, resolution)


def test_world_cell_conversion_and_bounds():
    g = OccupancyGrid(np.zeros((4, 6), dtype=bool), 0.5, origin=(-1.0, 2.0))
    assert g.bounds == (-1.0, 2.0, 2.0, 4.0)
    assert g.world_to_cell((-0.9, 2.1)) == (0, 0)
    assert g.world_to_cell((1.99, 3.99)) == (5, 3)
    np.testing.assert_allclose(g.cell_to_world((1, 1)), [-0.25, 2.75])
    with pytest.raises(OffMapError, match='off the map'):
        g.world_to_cell((2.0, 3.0))


def test_int_grid_follows_ros_convention():
    g = OccupancyGrid(np.array([[0, 100, -1, 49]]), 1.0)
    assert g.occupied.tolist() == [[False, True, True, False]]


def test_diagonal_costs_sqrt2():
    g = OccupancyGrid.empty(0, 10, 0, 10, 1.0)
    cells, cost = astar_cells(g, (0, 0), (5, 3))
    assert cost == pytest.approx(3 * math.sqrt(2) + 2)
    assert cells[0] == (0, 0) and cells[-1] == (5, 3) and len(cells) == 6


def test_detour_around_wall_is_optimal():
    g = grid_from([
        '.......',
        '...#...',
        '...#...',
        '...#...',
        '.......',
    ])
    cells, cost = astar_cells(g, (0, 2), (6, 2))
    # Over the wall: 2 diagonals up, 2 straight, 2 diagonals down (no corner cutting).
    assert cost == pytest.approx(4 * math.sqrt(2) + 2)
    assert all(not g.occupied[y, x] for x, y in cells)


def test_no_corner_cutting():
    g = grid_from([
        '.#',
        '#.',
    ])
    with pytest.raises(UnreachableError):
        astar_cells(g, (0, 0), (1, 1))


def test_unreachable_message_names_bounds():
    g = grid_from([
        '..#..',
        '..#..',
        '..#..',
    ])
    with pytest.raises(UnreachableError, match=r'unreachable.*x in \[0, 5\)'):
        astar(g, (0.5, 0.5), (4.5, 0.5))


def test_endpoint_errors_say_which():
    g = grid_from(['..#', '...'])
    with pytest.raises(OffMapError, match='^start'):
        astar(g, (-1.0, 0.5), (0.5, 0.5))
    with pytest.raises(OffMapError, match='^goal'):
        astar(g, (0.5, 0.5), (0.5, 7.0))
    with pytest.raises(InObstacleError, match='^goal .* in an obstacle'):
        astar(g, (0.5, 0.5), (2.5, 1.5))
    assert issubclass(InObstacleError, PlanningError) and issubclass(PlanningError, ValueError)


def test_astar_world_path_endpoints_exact():
    g = OccupancyGrid.empty(0, 3, 0, 3, 0.1)
    path = astar(g, (0.02, 0.03), (2.0, 1.0))
    np.testing.assert_allclose(path[0], [0.02, 0.03])
    np.testing.assert_allclose(path[-1], [2.0, 1.0])


def test_grid_planner_smooths_to_straight_line_in_free_space():
    g = OccupancyGrid.empty(-1, 3, -1, 3, 0.05)
    path = GridPlanner(g)((0.0, 0.0), (2.0, 1.0))
    assert len(path) == 2
    blocked = OccupancyGrid.empty(-1, 3, -1, 3, 0.05)
    blocked.occupied[20:60, 40] = True  # a wall at x = 1 between y in [0, 2)
    path = GridPlanner(blocked)((0.0, 1.0), (2.0, 1.0))
    assert len(path) > 2


def test_next_waypoint():
    path = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]])
    np.testing.assert_allclose(next_waypoint(path, (0.0, 0.0), 0.5), [0.5, 0.0])
    np.testing.assert_allclose(next_waypoint(path, (0.8, 0.1), 0.5), [1.0, 0.3])
    np.testing.assert_allclose(next_waypoint(path, (1.0, 0.9), 0.5), [1.0, 1.0])
    with pytest.raises(ValueError):
        next_waypoint(path, (0, 0), 0.0)


def _grid_with_block():
    g = OccupancyGrid.empty(0.0, 4.0, 0.0, 4.0, 0.1)
    occupied = g.occupied.copy()
    occupied[15:25, 15:25] = True  # a 1 m block at [1.5, 2.5]^2
    return OccupancyGrid(occupied, 0.1, (0.0, 0.0))


def test_inflated_paths_keep_their_clearance_from_obstacles():
    grid = _grid_with_block()
    for inflation in (0.0, 0.3):
        path = GridPlanner(grid, inflation=inflation)((0.5, 0.5), (3.5, 3.5))
        # Every segment, sampled finely, keeps `inflation` (minus half a cell) from the block.
        for a, b in zip(path, path[1:]):
            for t in np.linspace(0.0, 1.0, 50):
                x, y = a + t * (b - a)
                dx = max(1.5 - x, 0.0, x - 2.5)
                dy = max(1.5 - y, 0.0, y - 2.5)
                assert math.hypot(dx, dy) >= inflation - 0.1, (inflation, x, y)


def test_a_robot_inside_an_obstacle_is_led_out_not_stuck():
    grid = _grid_with_block()
    planner = GridPlanner(grid, inflation=0.2)
    path = planner((1.6, 2.0), (0.5, 2.0))  # started inside the block
    assert np.allclose(path[0], (1.6, 2.0)) and np.allclose(path[-1], (0.5, 2.0))
    exit_cell = grid.world_to_cell(path[1])
    assert planner.planning_grid.is_free(exit_cell)
    assert path[1][0] < 1.5 - 0.2 + 1e-9  # the nearest free cell, to the left of the block


def test_a_goal_inside_an_obstacle_is_still_refused_with_inflation():
    planner = GridPlanner(_grid_with_block(), inflation=0.2)
    with pytest.raises(InObstacleError, match='goal'):
        planner((0.5, 0.5), (2.0, 2.0))
    # Within the margin but not in the obstacle: reached.
    path = planner((0.5, 0.5), (1.4, 0.5))
    assert np.allclose(path[-1], (1.4, 0.5))


@pytest.mark.parametrize('make', [AStarPlanner, GridPlanner])
@pytest.mark.parametrize('start', [(-1.3, 2.0), (5.5, -2.0), (2.0, 9.0)])
def test_a_robot_off_the_map_is_led_back_onto_it(make, start):
    grid = _grid_with_block()
    planner = make(grid, inflation=0.2)
    path = planner(start, (0.5, 2.0))
    assert np.allclose(path[0], start) and np.allclose(path[-1], (0.5, 2.0))
    entry = grid.world_to_cell(path[1])  # the first point is on the map, in free space
    assert planner.planning_grid.is_free(entry)
    # ... and it is the map's edge nearest to the robot (no free cell is nearer).
    free = np.argwhere(~planner.planning_grid.occupied)[:, ::-1]
    centres = grid.cell_to_world(free)
    nearest = np.min(np.hypot(*(centres - start).T))
    assert np.hypot(*(path[1] - start)) <= nearest + grid.resolution * 1.5
    with pytest.raises(PlanningError, match='not finite'):
        planner((np.nan, 0.0), (0.5, 2.0))
