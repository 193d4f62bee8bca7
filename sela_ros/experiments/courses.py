"""The obstacle courses shipped in ``config/maps`` and what runs on them needs (ROS-free).

A course is a map_server map plus the goals a mission visits in order (``courses.yaml``
beside the maps); the last goal is the experiment's. :class:`CourseEnvironment` wraps an
experiment environment to count collisions (a gait that ends inside an obstacle: the
simulator has no walls, the map is the planner's) and to keep the path walked.
"""
from __future__ import annotations

import os
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

COURSES_FILE = 'courses.yaml'


@dataclass(frozen=True)
class Course:
    name: str
    map_path: Path
    goals: tuple  # ((x, y), ...) visited in order; the last is the experiment's goal
    description: str = ''


def maps_dir() -> Path:
    """``share/sela_ros/config/maps`` of the installed package, else the source tree's."""
    prefixes = [p for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    candidates = [Path(p) / 'share' / 'sela_ros' / 'config' / 'maps' for p in prefixes]
    candidates += [Path(sys.prefix) / 'share' / 'sela_ros' / 'config' / 'maps',
                   Path(__file__).resolve().parents[2] / 'config' / 'maps']
    for candidate in candidates:
        if (candidate / COURSES_FILE).is_file():
            return candidate
    raise FileNotFoundError('no config/maps/courses.yaml found (looked in '
                            + ', '.join(str(c) for c in candidates) + ')')


def load_courses(directory=None) -> dict:
    """``{name: Course}`` from ``courses.yaml`` in ``directory`` (default :func:`maps_dir`)."""
    import yaml

    directory = Path(directory) if directory is not None else maps_dir()
    with open(directory / COURSES_FILE) as handle:
        data = yaml.safe_load(handle)
    courses = {}
    for name, entry in data.items():
        goals = tuple(tuple(float(v) for v in g) for g in entry['goals'])
        courses[name] = Course(name, directory / entry['map'], goals,
                               entry.get('description', ''))
    return courses


def find_course(text) -> tuple:
    """``(map YAML path, Course or None)`` for a course name or a map YAML path.

    A path to one of the shipped courses' maps is recognised, so its goals come with it.

    Raises:
        ValueError: neither a known course nor an existing file.
    """
    try:
        courses = load_courses()
    except FileNotFoundError:
        courses = {}
    if text in courses:
        return courses[text].map_path, courses[text]
    path = Path(text)
    if not path.is_file():
        raise ValueError(f'{text!r} is neither a course ({", ".join(courses) or "none found"})'
                         ' nor a map file')
    for course in courses.values():
        if course.map_path.name == path.name and (
                course.map_path.resolve() == path.resolve()
                or course.map_path.read_bytes() == path.read_bytes()):
            return path, course
    return path, None


class CourseEnvironment:
    """An experiment environment on a course map: counts collisions, keeps the path walked.

    Args:
        env: the environment (``reset``, ``observed_pose``, ``true_pose``, ``execute``).
        grid: the course's :class:`~sela_ros.core.planning.OccupancyGrid` (not inflated).

    Attributes:
        collisions: gaits since ``reset`` that ended (true pose) inside an obstacle.
        path: true ``(x, y)`` since ``reset``: the start, then after every gait.
    """

    def __init__(self, env, grid):
        self.env = env
        self.grid = grid
        self.collisions = 0
        self.path = []

    def __getattr__(self, name):  # falls, sim_seconds, ... of the wrapped environment
        return getattr(self.env, name)

    def reset(self) -> None:
        self.env.reset()
        self.collisions = 0
        self.path = [self._xy()]

    def observed_pose(self):
        return self.env.observed_pose()

    def true_pose(self):
        return self.env.true_pose()

    def execute(self, index):
        observed = self.env.execute(index)
        xy = self._xy()
        self.path.append(xy)
        if self.grid.in_map(xy) and not self.grid.is_free(self.grid.world_to_cell(xy)):
            self.collisions += 1
        return observed

    def _xy(self):
        return [round(float(v), 4) for v in np.asarray(self.env.true_pose())[:2]]
