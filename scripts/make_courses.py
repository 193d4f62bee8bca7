#!/usr/bin/env python3
"""Write the obstacle courses shipped in config/maps/ (map_server YAML + PGM each).

``python scripts/make_courses.py [--out config/maps]`` regenerates them; the files are
committed, this script says how they were drawn. Every course is sized for the hexapod (one
gait moves it up to about 0.4 m): 5-6.5 m across, 0.1 m walls, passages at least 1.3 m
wide, so at least 0.8 m stay free after the planner's 0.25 m inflation on both sides. The
robot starts at the origin, facing +x. The goals of each course (the last one is the
experiment's goal; all of them in order are the demo's mission) are in courses.yaml.
"""
import argparse
from pathlib import Path

import numpy as np

RESOLUTION = 0.05
WALL = 0.1
FREE, OCCUPIED = 254, 0  # as map_saver writes them


def raster(bounds, walls):
    """Image (row 0 on top) of a field ``bounds = (xmin, xmax, ymin, ymax)`` with a border
    wall and the rectangles ``walls`` [(xmin, ymin, xmax, ymax), ...] occupied."""
    xmin, xmax, ymin, ymax = bounds
    w = int(round((xmax - xmin) / RESOLUTION))
    h = int(round((ymax - ymin) / RESOLUTION))
    xs = xmin + (np.arange(w) + 0.5) * RESOLUTION
    ys = ymin + (np.arange(h) + 0.5) * RESOLUTION
    border = [(xmin, ymin, xmax, ymin + WALL), (xmin, ymax - WALL, xmax, ymax),
              (xmin, ymin, xmin + WALL, ymax), (xmax - WALL, ymin, xmax, ymax)]
    occupied = np.zeros((h, w), dtype=bool)
    for x0, y0, x1, y1 in border + list(walls):
        occupied[np.ix_((ys >= y0) & (ys <= y1), (xs >= x0) & (xs <= x1))] = True
    return np.where(occupied, OCCUPIED, FREE).astype(np.uint8)[::-1]


def wall_gap():
    """A wall across the field between start and goal, with one 1.4 m gap off to the side."""
    walls = [(1.9, -2.5, 2.1, 1.0), (1.9, 2.4, 2.1, 3.0)]
    return (-1.0, 5.0, -2.5, 3.0), walls


def corridor():
    """A 1.4 m corridor with two turns: east, north, then back west (a U)."""
    bounds = (-1.0, 5.5, -1.0, 4.0)
    # Solid blocks around the free U: x in [-0.7, 5.2] for y in [-0.7, 0.7] and [2.3, 3.7],
    # joined by x in [3.8, 5.2].
    walls = [(-1.0, 0.7, 3.8, 2.3), (-1.0, -1.0, 5.5, -0.7), (-1.0, 3.7, 5.5, 4.0),
             (-1.0, -1.0, -0.7, 4.0), (5.2, -1.0, 5.5, 4.0)]
    return bounds, walls


# The maze: 4 x 4 cells of 1.5 m, cell (i, j) centred on (1.5 i, 1.5 j); open passages
# between cells (a spanning tree: one way between any two cells, with dead ends).
MAZE_CELL = 1.5
MAZE_SIZE = 4
MAZE_PASSAGES = [
    ((0, 0), (1, 0)), ((1, 0), (2, 0)), ((2, 0), (2, 1)), ((2, 1), (1, 1)), ((1, 1), (1, 2)),
    ((1, 2), (2, 2)), ((2, 2), (3, 2)), ((3, 2), (3, 3)),  # the way to the goal
    ((2, 0), (3, 0)), ((3, 0), (3, 1)), ((1, 1), (0, 1)), ((0, 1), (0, 2)),
    ((0, 2), (0, 3)), ((0, 3), (1, 3)), ((1, 3), (2, 3)),  # dead ends
]


def maze():
    c, n, half = MAZE_CELL, MAZE_SIZE, WALL / 2.0
    lo, hi = -c / 2.0, c * n - c / 2.0
    bounds = (lo - half, hi + half, lo - half, hi + half)
    open_edges = {frozenset(p) for p in MAZE_PASSAGES}
    walls = []
    for i in range(n):
        for j in range(n):
            x, y = i * c + c / 2.0, j * c + c / 2.0  # the cell's upper right corner
            if i + 1 < n and frozenset([(i, j), (i + 1, j)]) not in open_edges:
                walls.append((x - half, y - c - half, x + half, y + half))
            if j + 1 < n and frozenset([(i, j), (i, j + 1)]) not in open_edges:
                walls.append((x - c - half, y - half, x + half, y + half))
    return bounds, walls


COURSES = {'wall_gap': wall_gap, 'corridor': corridor, 'maze': maze}


def write_course(out, name, bounds, walls):
    image = raster(bounds, walls)
    h, w = image.shape
    with open(out / f'{name}.pgm', 'wb') as handle:
        handle.write(f'P5\n# sela_ros course {name} (scripts/make_courses.py)\n{w} {h}\n255\n'
                     .encode())
        handle.write(image.tobytes())
    (out / f'{name}.yaml').write_text(
        f'# Obstacle course "{name}" for sela_ros (map_server format; scripts/make_courses.py)\n'
        f'image: {name}.pgm\nmode: trinary\nresolution: {RESOLUTION}\n'
        f'origin: [{bounds[0]}, {bounds[2]}, 0.0]\nnegate: 0\noccupied_thresh: 0.65\n'
        f'free_thresh: 0.25\n')


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--out', default=str(Path(__file__).resolve().parents[1] / 'config'
                                             / 'maps'))
    args = parser.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for name, make in COURSES.items():
        write_course(out, name, *make())
        print(f'wrote {out / name}.yaml and .pgm')


if __name__ == '__main__':
    main()
