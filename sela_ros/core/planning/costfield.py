"""Cost-to-go fields: the reward selection layer's shortest paths at navigation scale.

A* from scratch at every SELA step costs seconds on a map of a million cells. The goal only
changes once per mission leg and the map rarely, so this module computes, once per (map,
goal), the cost of the shortest 8-connected path from EVERY cell to the goal (Dijkstra
from the goal, in compiled code: :func:`scipy.sparse.csgraph.dijkstra`) together with the
next cell toward the goal from every cell. A step then only follows those pointers from the
robot's cell: milliseconds, whatever the map size.

Why scipy's csgraph: it is already a dependency (the GPs use scipy), it runs Dijkstra in
compiled code over a sparse graph that numpy builds in a few vectorised lines, and it
returns the shortest-path tree (predecessors) with the distances. A dedicated grid planner
package would add a dependency for what a dozen lines of numpy and one scipy call give.

The graph is the one :func:`sela_ros.core.planning.planner.astar_cells` searches: straight moves
cost 1 cell, diagonal moves sqrt 2, and a diagonal may not cut the corner of an occupied
cell. So the field's cost at the start is exactly A*'s path cost (tested on random grids).
"""
from __future__ import annotations

import numpy as np
from scipy import ndimage
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from sela_ros.core.planning.grid import MOVES


def grid_graph(free) -> csr_matrix:
    """The 8-connected graph over the cells of a ``(height, width)`` free-space mask.

    Node ``iy * width + ix`` is cell ``(ix, iy)``. A straight move joins two free
    neighbours (weight 1); a diagonal move needs the two cells it passes between free too
    (weight sqrt 2): the no-corner-cutting rule. The CSR arrays are written directly, node
    by node and move by move, so no sort of millions of edges is needed.
    """
    free = np.asarray(free, dtype=bool)
    h, w = free.shape
    pad = np.pad(free, 1)

    def at(dx, dy):  # free[y + dy, x + dx] for every cell, False off the grid
        return pad[1 + dy:1 + dy + h, 1 + dx:1 + dx + w]

    valid = np.empty((h, w, len(MOVES)), dtype=bool)
    for k, (dx, dy, _) in enumerate(MOVES):
        ok = free & at(dx, dy)
        if dx and dy:
            ok &= at(dx, 0) & at(0, dy)
        valid[..., k] = ok
    ids = np.arange(h * w, dtype=np.int32).reshape(h, w, 1)
    step = np.array([dy * w + dx for dx, dy, _ in MOVES], dtype=np.int32)
    indices = (ids + step)[valid]
    data = np.broadcast_to(np.array([c for _, _, c in MOVES]), valid.shape)[valid]
    indptr = np.zeros(h * w + 1, dtype=np.int32)
    np.cumsum(valid.reshape(h * w, -1).sum(axis=1), out=indptr[1:])
    return csr_matrix((data, indices, indptr), shape=(h * w, h * w))


class CostField:
    """Cost-to-go from every cell to one goal cell, and the way down it.

    Args:
        free: ``(height, width)`` boolean mask of the cells a path may use.
        goal_cell: ``(ix, iy)`` of the goal; must be free.
        graph: :func:`grid_graph` of ``free`` (built here if None; pass it to share it
            between the goals of one map).

    Attributes:
        cost: ``(height, width)`` cost of the shortest path to the goal in cells (straight
            1, diagonal sqrt 2); ``inf`` where the goal cannot be reached.
    """

    def __init__(self, free, goal_cell, graph=None):
        free = np.asarray(free, dtype=bool)
        h, w = free.shape
        gx, gy = (int(v) for v in goal_cell)
        if not (0 <= gx < w and 0 <= gy < h) or not free[gy, gx]:
            raise ValueError(f'goal cell {(gx, gy)} must be a free cell of the '
                             f'{w} x {h} grid')
        if graph is None:
            graph = grid_graph(free)
        self.goal_cell = (gx, gy)
        self.shape = (h, w)
        # The graph is symmetric, so the predecessor of a node on the tree rooted at the
        # goal is its next node toward the goal.
        dist, pred = dijkstra(graph, directed=True, indices=gy * w + gx,
                              return_predecessors=True)
        self.cost = dist.reshape(h, w)
        self._next = pred.tolist()  # Python ints: pointer chasing in a loop is faster
        self._nearest = None

    def reachable(self, cell) -> bool:
        ix, iy = cell
        h, w = self.shape
        return 0 <= ix < w and 0 <= iy < h and bool(np.isfinite(self.cost[iy, ix]))

    def cells_from(self, start_cell) -> list:
        """The cells of an optimal path from ``start_cell`` (reachable) to the goal."""
        h, w = self.shape
        ix, iy = start_cell
        if not self.reachable(start_cell):
            raise ValueError(f'cell {tuple(start_cell)} cannot reach the goal')
        node = iy * w + ix
        nodes = [node]
        nxt = self._next
        while node >= 0:  # scipy marks the root (and unreachable nodes) with -9999
            node = nxt[node]
            nodes.append(node)
        nodes.pop()
        nodes = np.asarray(nodes)
        return list(zip((nodes % w).tolist(), (nodes // w).tolist()))

    def nearest_reachable(self, cell):
        """The cell closest (Euclidean) to ``cell`` from which the goal can be reached."""
        if self._nearest is None:
            # Computed once per field, only if the robot ever strays off reachable cells.
            self._nearest = ndimage.distance_transform_edt(
                ~np.isfinite(self.cost), return_distances=False, return_indices=True)
        ix, iy = cell
        return int(self._nearest[1][iy, ix]), int(self._nearest[0][iy, ix])
