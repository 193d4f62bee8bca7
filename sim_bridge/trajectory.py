"""A gait as a joint trajectory, for robots driven through a ``joint_trajectory_controller``.

ROS-free. What is robot-specific comes from its description
(:class:`sim_bridge.robots.RobotDescription`, the hexapod when ``robot`` is None): its
joints, their limits (its URDF's) and the gait controller that turns a parameter vector into
joint targets. The rest is the same for any robot: checking a trajectory before it moves
anything, and playing one in the simulator.

A gait becomes the controller's own samples: the controller's table is piecewise constant at
``n_samples`` samples per ``period`` (the hexapod's: 100 per second), so the trajectory has
one point per sample, each point holding its sample's targets, and a last point at the
gait's end. The simulator plays a trajectory by holding each point's positions until the next
point's time (:func:`hold_targets`): with points at the controller's own rate that is exactly
the direct path's sequence of targets.
"""
from __future__ import annotations

import functools
import math
import xml.etree.ElementTree as ElementTree

import numpy as np

from sim_bridge.robots import get_robot

#: Tolerance (s) on point times, so that t = k/100 falls on its own point despite rounding.
TIME_EPS = 1e-9
#: Tolerance (rad) on joint limits: a target exactly on the limit is allowed.
LIMIT_EPS = 1e-9


class TrajectoryError(ValueError):
    """A trajectory that must not be played: says which joint, point or value and why."""


# --- the robot: joints, limits, gait controller ---------------------------------------------


def joint_names(robot=None) -> tuple[str, ...]:
    """The joints the robot's gait controller drives, in the order of its columns."""
    return tuple(get_robot(robot).joint_names)


def joint_limits(robot=None) -> dict[str, tuple[float, float]]:
    """``{joint: (lower, upper)}`` in rad of the driven joints, from the robot's URDF (the
    limits its ``joint_trajectory_controller`` is configured with)."""
    description = get_robot(robot)
    return _urdf_limits(description)


@functools.lru_cache(maxsize=8)
def _urdf_limits(description):
    found = {}
    for joint in ElementTree.fromstring(description.urdf('intact')).iter('joint'):
        limit = joint.find('limit')
        if limit is not None and 'lower' in limit.attrib and 'upper' in limit.attrib:
            found[joint.get('name')] = (float(limit.get('lower')), float(limit.get('upper')))
    return {n: found[n] for n in description.joint_names if n in found}


def controller_rate(robot=None) -> float:
    """Samples per second of the robot's gait controller."""
    description = get_robot(robot)
    return description.n_samples / description.period


def gait_trajectory(params, duration: float, rate: float | None = None, robot=None):
    """One gait as ``(times, positions)``: points every ``1 / rate`` s from 0 (default: the
    controller's own rate), each with the controller's targets at that time (columns in
    :func:`joint_names` order), then a last point at ``duration`` (the time the gait ends),
    holding the next sample's targets.

    Raises:
        ValueError: bad parameters (the description's ``validate_params``), or a duration or
            rate that is not a positive finite number.
    """
    description = get_robot(robot)
    duration = float(duration)
    rate = controller_rate(description) if rate is None else float(rate)
    if not (math.isfinite(duration) and duration > 0.0):
        raise ValueError(f'gait duration must be > 0 s, got {duration}')
    if not (math.isfinite(rate) and rate > 0.0):
        raise ValueError(f'trajectory rate must be > 0 Hz, got {rate}')
    table = description.target_table(description.validate_params(params))
    n_points = int(math.ceil(duration * rate - TIME_EPS))
    times = np.append(np.arange(n_points) / rate, duration)
    samples = np.floor(times * controller_rate(description) + TIME_EPS)
    return times, table[samples.astype(np.int64) % description.n_samples]


# --- checks, the same for any robot ----------------------------------------------------------


def check_trajectory(names, times, positions, known=None, limits=None, robot=None):
    """Refuse a trajectory that must not move anything; returns nothing when it is fine.

    Args:
        names: its joint names.
        times: (n,) seconds from the start of each point.
        positions: (n, len(names)) targets in rad.
        known: the robot's joint names (default :func:`joint_names` of ``robot``).
        limits: ``{joint: (lower, upper)}`` (default :func:`joint_limits` of ``robot``);
            joints absent from it are not checked.

    Raises:
        TrajectoryError: unknown or repeated joints, no points, times that do not increase,
            non-finite values, or a target beyond its joint's limits (the first one named).
    """
    known = set(joint_names(robot) if known is None else known)
    limits = joint_limits(robot) if limits is None else limits
    names = list(names)
    unknown = [n for n in names if n not in known]
    if unknown:
        raise TrajectoryError(f'unknown joint(s) {", ".join(map(repr, unknown[:5]))}; the '
                              f'robot has {", ".join(sorted(known))}')
    if len(set(names)) != len(names):
        twice = sorted({n for n in names if names.count(n) > 1})
        raise TrajectoryError(f'joint(s) named twice: {", ".join(twice)}')
    times = np.asarray(times, dtype=np.float64)
    positions = np.asarray(positions, dtype=np.float64)
    if times.ndim != 1 or len(times) == 0:
        raise TrajectoryError('the trajectory has no points')
    if positions.shape != (len(times), len(names)):
        raise TrajectoryError(f'every point needs one position per joint ({len(names)}); '
                              f'got positions of shape {positions.shape}')
    if not (np.all(np.isfinite(times)) and np.all(np.isfinite(positions))):
        raise TrajectoryError('times and positions must be finite numbers')
    if times[0] < 0.0 or np.any(np.diff(times) <= 0.0):
        raise TrajectoryError('point times must start at >= 0 s and strictly increase')
    for column, name in enumerate(names):
        if name not in limits:
            continue
        lower, upper = limits[name]
        values = positions[:, column]
        out = np.flatnonzero((values < lower - LIMIT_EPS) | (values > upper + LIMIT_EPS))
        if len(out):
            i = int(out[0])
            raise TrajectoryError(
                f'joint {name} at point {i} (t = {times[i]:.3f} s): {values[i]:.4f} rad is '
                f'beyond its limits [{lower:.4f}, {upper:.4f}] rad '
                f'({len(out)} point(s) out of range)')


# --- playing one in the simulator ----------------------------------------------------------


def hold_targets(names, times, positions, dt: float, columns=None, robot=None) -> np.ndarray:
    """Targets per physics step, each point held until the next point's time.

    The trajectory runs until its last point's time: step ``k`` at ``t = k dt`` takes the
    last point with a time <= t (the first point before it). Returns ``(n_steps,
    len(columns))``, columns in the order of ``columns`` (default :func:`joint_names` of
    ``robot``); a column no joint of the trajectory drives holds its standing target.
    """
    description = get_robot(robot)
    standing = dict(zip(description.joint_names, description.standing_targets()))
    columns = description.joint_names if columns is None else tuple(columns)
    times = np.asarray(times, dtype=np.float64)
    positions = np.asarray(positions, dtype=np.float64)
    n_steps = int(round(times[-1] / dt))
    step_times = np.arange(n_steps, dtype=np.float64) * dt
    point = np.clip(np.searchsorted(times, step_times + TIME_EPS, side='right') - 1, 0, None)
    targets = np.zeros((n_steps, len(columns)))
    index = {name: i for i, name in enumerate(names)}
    for c, name in enumerate(columns):
        if name in index:
            targets[:, c] = positions[point, index[name]]
        else:
            targets[:, c] = standing.get(name, 0.0)
    return targets
