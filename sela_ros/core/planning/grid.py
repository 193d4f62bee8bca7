"""The occupancy grid the reward selection layer plans on, its errors and its clearance.

Cells are ``occupied[iy, ix]``; :func:`inflate` grows obstacles for clearance and
:func:`nearest_free_cell` finds the way out of an obstacle the robot strayed into.
"""
from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

SQRT2 = math.sqrt(2.0)
#: The 8-connected moves (dx, dy, cost in cells).
MOVES = ((1, 0, 1.0), (-1, 0, 1.0), (0, 1, 1.0), (0, -1, 1.0),
         (1, 1, SQRT2), (1, -1, SQRT2), (-1, 1, SQRT2), (-1, -1, SQRT2))


class PlanningError(ValueError):
    """No path can be planned."""


class OffMapError(PlanningError):
    """The start or the goal lies outside the map."""


class InObstacleError(PlanningError):
    """The start or the goal lies in an occupied cell."""


class UnreachableError(PlanningError):
    """No obstacle-free path joins the start and the goal."""


class OccupancyGrid:
    """A 2-D occupancy grid in the ``odom`` frame (like nav_msgs/OccupancyGrid).

    Args:
        occupancy: ``(height, width)`` array, row = y cell, column = x cell; nonzero (or
            True) means occupied. Integer grids in ROS's convention (-1 unknown, 0..100)
            count values >= ``occupied_threshold`` and unknown (< 0) as occupied.
        resolution: cell size in metres.
        origin: world ``(x, y)`` of the corner of cell (0, 0).
        occupied_threshold: for integer grids, the value from which a cell is occupied.
        unknown_is_occupied: for integer grids, whether unknown (< 0) cells are occupied.
    """

    def __init__(self, occupancy, resolution: float, origin=(0.0, 0.0),
                 occupied_threshold: int = 50, unknown_is_occupied: bool = True):
        occ = np.asarray(occupancy)
        if occ.ndim != 2 or occ.shape[0] < 1 or occ.shape[1] < 1:
            raise ValueError(f'occupancy must be a non-empty 2-D array, got shape {occ.shape}')
        if not np.isfinite(resolution) or resolution <= 0:
            raise ValueError(f'resolution must be a finite number > 0, got {resolution!r}')
        origin = np.asarray(origin, dtype=float).reshape(-1)
        if origin.shape != (2,) or not np.all(np.isfinite(origin)):
            raise ValueError(f'origin must be a finite (x, y), got {origin!r}')
        if occ.dtype == bool:
            self.occupied = occ.copy()
        else:
            self.occupied = (occ >= occupied_threshold) | ((occ < 0) & bool(unknown_is_occupied))
        self.resolution = float(resolution)
        self.origin = origin

    @classmethod
    def empty(cls, xmin, xmax, ymin, ymax, resolution):
        """An obstacle-free grid covering ``[xmin, xmax] x [ymin, ymax]``."""
        width = int(math.ceil((xmax - xmin) / resolution))
        height = int(math.ceil((ymax - ymin) / resolution))
        if width < 1 or height < 1:
            raise ValueError('empty grid needs xmax > xmin and ymax > ymin')
        return cls(np.zeros((height, width), dtype=bool), resolution, (xmin, ymin))

    @property
    def width(self) -> int:
        return self.occupied.shape[1]

    @property
    def height(self) -> int:
        return self.occupied.shape[0]

    @property
    def bounds(self):
        """``(xmin, xmax, ymin, ymax)`` in metres."""
        x0, y0 = self.origin
        return (x0, x0 + self.width * self.resolution, y0, y0 + self.height * self.resolution)

    def bounds_text(self) -> str:
        xmin, xmax, ymin, ymax = self.bounds
        return f'x in [{xmin:g}, {xmax:g}), y in [{ymin:g}, {ymax:g})'

    def world_to_cell(self, xy):
        """Cell ``(ix, iy)`` holding the world point ``xy``; raises OffMapError outside."""
        xy = np.asarray(xy, dtype=float).reshape(-1)[:2]
        ix, iy = np.floor((xy - self.origin) / self.resolution).astype(int)
        if not (0 <= ix < self.width and 0 <= iy < self.height):
            raise OffMapError(f'point ({xy[0]:g}, {xy[1]:g}) is off the map '
                              f'({self.bounds_text()})')
        return int(ix), int(iy)

    def nearest_cell(self, xy):
        """The map's cell nearest to ``xy`` (its own cell when on the map)."""
        xy = np.asarray(xy, dtype=float).reshape(-1)[:2]
        ix, iy = np.floor((xy - self.origin) / self.resolution)
        return (int(np.clip(ix, 0, self.width - 1)), int(np.clip(iy, 0, self.height - 1)))

    def cell_to_world(self, cell):
        """World ``(x, y)`` of the centre of cell ``(ix, iy)``."""
        return self.origin + (np.asarray(cell, dtype=float) + 0.5) * self.resolution

    def in_map(self, xy) -> bool:
        try:
            self.world_to_cell(xy)
        except OffMapError:
            return False
        return True

    def goal_problem(self, xy):
        """Why the goal ``xy`` cannot be planned to (off the map, inside an obstacle), or
        None: the one rule the planner, the adapter and the experiments apply."""
        if not self.in_map(xy):
            return f'off the map ({self.bounds_text()})'
        if not self.is_free(self.world_to_cell(xy)):
            return 'inside an obstacle'
        return None

    def is_free(self, cell) -> bool:
        ix, iy = cell
        return (0 <= ix < self.width and 0 <= iy < self.height
                and not self.occupied[iy, ix])


def inflate(grid: OccupancyGrid, radius: float) -> OccupancyGrid:
    """The grid with every obstacle grown by ``radius`` metres (a disc), for clearance."""
    radius = float(radius)
    if not (math.isfinite(radius) and radius >= 0.0):
        raise ValueError(f'inflation radius must be a finite number >= 0, got {radius!r}')
    r = int(math.floor(radius / grid.resolution + 1e-9))
    if r == 0 or not grid.occupied.any():
        return grid
    # A cell is in the margin when an occupied cell lies within r cells (a disc): the exact
    # Euclidean distance transform does it in one pass whatever r is.
    distance = ndimage.distance_transform_edt(~grid.occupied)
    return OccupancyGrid(distance <= r + 1e-9, grid.resolution, grid.origin)


def nearest_free_cell(grid: OccupancyGrid, cell):
    """The free cell closest to ``cell`` (breadth-first, 8-connected), or None."""
    start = tuple(cell)
    if grid.is_free(start):
        return start
    seen = {start}
    frontier = [start]
    while frontier:
        nxt = []
        for c in frontier:
            for dx, dy, _ in MOVES:
                n = (c[0] + dx, c[1] + dy)
                if n in seen or not (0 <= n[0] < grid.width and 0 <= n[1] < grid.height):
                    continue
                if grid.is_free(n):
                    return n
                seen.add(n)
                nxt.append(n)
        frontier = nxt
    return None
