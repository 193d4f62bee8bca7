"""Simulator settings that make gait outcomes comparable: archives are stamped with them.

No PyBullet here: reading or checking settings does not load the simulator.
"""
from __future__ import annotations

import json
import math
import os

import numpy as np

from sim_bridge import controller

MODEL_VERSION = 'sela-hexapod-v1'
CONTROLLER_VERSION = controller.CONTROLLER_VERSION

# What an archive that predates a key was built with: a missing key means this value.
SIM_DEFAULTS = {
    'dt': 1.0 / 240.0,
    'gait_duration': 3.0,
    'controller_version': CONTROLLER_VERSION,
    'model_version': MODEL_VERSION,
    'solver_iterations': 50,
}

#: Physics of the 8-D map, chosen with benchmarks/bench_physics.py: over twice the
#: evaluations/s of the defaults, gaits ending a few cm from where the defaults put them.
FAST_SETTINGS = {'dt': 1.0 / 120.0, 'solver_iterations': 30}


def simulator_settings(dt: float = SIM_DEFAULTS['dt'],
                       gait_duration: float = SIM_DEFAULTS['gait_duration'],
                       solver_iterations: int = SIM_DEFAULTS['solver_iterations'],
                       robot=None) -> dict:
    """Settings that make gait outcomes comparable; stamp archives with them.

    A longer dt and fewer solver iterations make evaluations cheaper but move where gaits
    end by centimetres, so an archive is only valid in a simulator with its own settings.
    ``robot`` (a :class:`sim_bridge.robots.RobotDescription`; None: the hexapod) adds its
    stamp: its controller and model versions, and its name.
    """
    dt = float(dt)
    gait_duration = float(gait_duration)
    if not (math.isfinite(dt) and 0.0 < dt <= 0.01):
        raise ValueError(f'dt must be in (0, 0.01] s, got {dt}')
    if not (math.isfinite(gait_duration) and gait_duration > 0.0):
        raise ValueError(f'gait_duration must be > 0 s, got {gait_duration}')
    if isinstance(solver_iterations, bool) or not float(solver_iterations).is_integer() \
            or not 1 <= solver_iterations <= 1000:
        raise ValueError(f'solver_iterations must be an integer in [1, 1000], got '
                         f'{solver_iterations!r}')
    settings = {'dt': dt, 'gait_duration': gait_duration,
                'controller_version': CONTROLLER_VERSION, 'model_version': MODEL_VERSION,
                'solver_iterations': int(solver_iterations)}
    if robot is not None:
        settings.update(robot.stamp())
    return settings


def physics_settings(metadata: dict) -> dict:
    """Keyword arguments of :class:`Hexapod` for an archive's metadata (or settings dict).

    A key the archive predates takes the value it was built with (:data:`SIM_DEFAULTS`),
    so the shipped 2-D archive keeps running with 50 solver iterations.
    """
    return {key: metadata.get(key, SIM_DEFAULTS[key])
            for key in ('dt', 'gait_duration', 'solver_iterations')}


def read_archive_settings(path: str | os.PathLike) -> dict:
    """:func:`physics_settings` of the archive file at ``path`` (from its JSON metadata).

    sim_bridge reads the stamp itself rather than through sela_ros, which sits above it.

    Raises:
        ValueError: no such file, or no readable metadata in it.
    """
    return physics_settings(read_archive_metadata(path))


def read_archive_metadata(path: str | os.PathLike) -> dict:
    """The JSON metadata of the archive file at ``path`` (its stamp: physics, robot).

    Raises:
        ValueError: no such file, or no readable metadata in it.
    """
    try:
        with np.load(path, allow_pickle=False) as npz:
            metadata = json.loads(str(npz['metadata']))
    except Exception as exc:
        raise ValueError(f'cannot read the simulator settings of archive {path}: '
                         f'{type(exc).__name__}: {exc}') from None
    if not isinstance(metadata, dict):
        raise ValueError(f'archive {path}: metadata is not a JSON object')
    return metadata
