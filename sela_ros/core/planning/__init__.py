"""The reward selection layer: occupancy grids and the map files they come from, paths to the
goal, the waypoint of each step."""
from sela_ros.core.planning.grid import (
    InObstacleError,
    OccupancyGrid,
    OffMapError,
    PlanningError,
    UnreachableError,
)
from sela_ros.core.planning.maps import (
    DEFAULT_INFLATION,
    DEFAULT_MAP,
    ORIGIN_LIMIT,
    RESOLUTION_RANGE,
    SIDE_RANGE,
    MapError,
    check_geometry,
    default_grid,
    grid_from_description,
    grid_from_ros,
    load_map_file,
)
from sela_ros.core.planning.planner import (
    AStarPlanner,
    GridPlanner,
    next_waypoint,
    straight_line_planner,
)

__all__ = ['DEFAULT_INFLATION', 'DEFAULT_MAP', 'ORIGIN_LIMIT', 'RESOLUTION_RANGE', 'SIDE_RANGE',
           'AStarPlanner', 'GridPlanner', 'InObstacleError', 'MapError', 'OccupancyGrid',
           'OffMapError', 'PlanningError', 'UnreachableError', 'check_geometry', 'default_grid',
           'grid_from_description', 'grid_from_ros', 'load_map_file', 'next_waypoint',
           'straight_line_planner']
