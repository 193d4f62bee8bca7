"""Plausibility limits on outcomes: what one gait can do to the robot. ROS-free.

An observed outcome is learnt by the GPs and saved for the rest of the robot's life, and its
end pose is where the next step starts. So an outcome that says one 3 s gait moved the robot
a kilometre (a sensor glitch, a simulator gone wrong, someone publishing on the topic) must
be refused with the reason, never learnt: one such observation drags the GP's mean of every
nearby gait, and a pose off the map ends the mission. The adapter's limit follows its archive
by default (``outcome.max_displacement`` auto: :func:`archive_displacement_limit`, twice the
furthest gait of the map: 1.25 m on the shipped 8-D map, whose fastest gait moves the intact
robot 0.63 m; 0.91 m on the 2-D map); :data:`DEFAULT_MAX_DISPLACEMENT`, 2 m, is the limit
where no archive is at hand (the damage detector's default).

The same limits hold for every way generic rewards come in: a live outcome
(:func:`check_outcome`, which also checks that the generic reward is the displacement its own
start and end poses say), a resumed state file, a loaded archive and the damage-prior tables
(:func:`check_generic_rewards`): whatever fails is refused with the reason, never learnt or
saved.
"""
import math
from dataclasses import dataclass

import numpy as np

DEFAULT_MAX_DISPLACEMENT = 2.0  # m in one gait
#: An outcome may move the robot this many times as far as the archive's furthest gait: a
#: damaged robot is slower, not faster, than its map; a tumble adds a few centimetres.
ARCHIVE_MARGIN = 2.0
#: How far (m) a generic reward may be from the displacement its start and end poses give:
#: both come from the same two observations, so they agree up to the position noise of a
#: start pose taken from odometry instead (0.01 m std here); 0.25 m refuses a reward that
#: does not belong to its poses without refusing a noisy start.
DEFAULT_MAX_DISAGREEMENT = 0.25
#: The same for the heading (rad): the yaw is observed exactly.
DEFAULT_MAX_YAW_DISAGREEMENT = 0.5


class ImplausibleOutcome(ValueError):
    """An outcome that no gait can produce: refused, not learnt."""


@dataclass(frozen=True)
class OutcomeLimits:
    """``outcome.*`` parameters: what one gait can plausibly do."""

    max_displacement: float = DEFAULT_MAX_DISPLACEMENT  # m between the start and end poses
    # m, rad: a generic reward against the displacement its own poses give
    max_disagreement: float = DEFAULT_MAX_DISAGREEMENT
    max_yaw_disagreement: float = DEFAULT_MAX_YAW_DISAGREEMENT

    def __post_init__(self):
        for name, unit in (('max_displacement', 'm'), ('max_disagreement', 'm'),
                           ('max_yaw_disagreement', 'rad')):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or not math.isfinite(value) or value <= 0:
                raise ValueError(f'outcome.{name} must be a finite number > 0 ({unit}), got '
                                 f'{value!r}')


def archive_displacement_limit(generic_rewards, margin=ARCHIVE_MARGIN):
    """``outcome.max_displacement`` for an archive of ``generic_rewards`` (N, 3): ``margin``
    times the planar displacement of its furthest gait."""
    gr = np.asarray(generic_rewards, dtype=float).reshape(-1, 3)
    return float(margin * np.max(np.hypot(gr[:, 0], gr[:, 1])))


def _finite(name, values):
    values = [float(v) for v in values]
    if not all(math.isfinite(v) for v in values):
        raise ImplausibleOutcome(f'{name} has a non-finite value: {values}')
    return values


def _distance(a, b):
    # Halved first: two finite coordinates can be further apart than the largest float.
    return 2.0 * math.hypot(a[0] / 2 - b[0] / 2, a[1] / 2 - b[1] / 2)


def _wrap(angle):
    return math.remainder(angle, 2.0 * math.pi)


def _disagreement(gr, start, end):
    """``(position m, heading rad)``: how far ``gr`` is from the displacement ``start`` ->
    ``end`` in the start frame (the heading part 0 without yaws)."""
    yaw0 = start[2] if len(start) > 2 else 0.0
    c, s = math.cos(yaw0), math.sin(yaw0)
    # Halved first, as in _distance: finite poses never overflow.
    dxw, dyw = end[0] / 2 - start[0] / 2, end[1] / 2 - start[1] / 2
    dx, dy = 2.0 * (c * dxw + s * dyw), 2.0 * (-s * dxw + c * dyw)
    position = 2.0 * math.hypot(gr[0] / 2 - dx / 2, gr[1] / 2 - dy / 2)
    heading = 0.0
    if len(gr) > 2 and len(start) > 2 and len(end) > 2:
        heading = abs(_wrap(_wrap(gr[2]) - _wrap(_wrap(end[2]) - _wrap(start[2]))))
    return position, heading


def check_outcome(generic_reward, start_pose=None, end_pose=None, limits=None,
                  expected_start=None):
    """Raise :class:`ImplausibleOutcome` when an outcome cannot come from one gait.

    Args:
        generic_reward: observed (dx, dy[, dyaw]) in the robot's frame at the start.
        start_pose, end_pose: observed (x, y[, yaw]) before and after the gait, if known;
            with both, the generic reward must be the displacement between them (within
            ``limits.max_disagreement`` and ``max_yaw_disagreement``).
        limits: :class:`OutcomeLimits` (default: the defaults).
        expected_start: (x, y[, yaw]) the step was planned from: the robot cannot have
            started the gait further than ``max_displacement`` from it.
    """
    limits = limits or OutcomeLimits()
    limit = limits.max_displacement
    gr = _finite('generic reward', generic_reward)
    moved = math.hypot(gr[0], gr[1])
    if moved > limit:
        raise ImplausibleOutcome(
            f'generic reward ({gr[0]:.4g}, {gr[1]:.4g}) moves the robot {moved:.4g} m in one '
            f'gait, more than outcome.max_displacement {limit:g} m')
    start = None if start_pose is None else _finite('start pose', start_pose)
    end = None if end_pose is None else _finite('end pose', end_pose)
    expected = None if expected_start is None else _finite('expected start', expected_start)
    for a, b, what in ((start, end, 'moved from its start pose to its end pose'),
                       (expected, start, 'started the gait away from the pose it was '
                                         'planned from')):
        if a is not None and b is not None and _distance(a, b) > limit:
            raise ImplausibleOutcome(
                f'the robot {what}: ({a[0]:.4g}, {a[1]:.4g}) -> ({b[0]:.4g}, {b[1]:.4g}), '
                f'{_distance(a, b):.4g} m, more than outcome.max_displacement {limit:g} m')
    if start is not None and end is not None:
        position, heading = _disagreement(gr, start, end)
        if position > limits.max_disagreement or heading > limits.max_yaw_disagreement:
            raise ImplausibleOutcome(
                f'generic reward ({", ".join(f"{v:.4g}" for v in gr)}) does not match its own '
                f'poses ({start[0]:.4g}, {start[1]:.4g}) -> ({end[0]:.4g}, {end[1]:.4g}): '
                f'{position:.3g} m and {heading:.3g} rad apart, more than '
                f'{limits.max_disagreement:g} m or {limits.max_yaw_disagreement:g} rad')


def check_generic_rewards(generic_rewards, limits=None, what='generic rewards'):
    """Raise :class:`ImplausibleOutcome` unless every row of ``generic_rewards`` (``(N, k)``,
    k >= 2: dx, dy[, dyaw]) is finite and moves the robot at most
    ``limits.max_displacement``: the check for stored rewards (a state file, an archive, a
    damage-prior table), which come without poses."""
    limits = limits or OutcomeLimits()
    gr = np.asarray(generic_rewards, dtype=float)
    if gr.size == 0:
        return
    gr = gr.reshape(-1, gr.shape[-1])
    finite = np.isfinite(gr).all(axis=1)
    if not finite.all():
        row = int(np.flatnonzero(~finite)[0])
        raise ImplausibleOutcome(f'{what}: {int((~finite).sum())} row(s) with NaN or inf '
                                 f'(first: row {row}, {gr[row].tolist()})')
    # Halved first: 1e308 squared overflows.
    moved = 2.0 * np.hypot(gr[:, 0] / 2, gr[:, 1] / 2)
    over = moved > limits.max_displacement
    if over.any():
        row = int(np.argmax(moved))
        raise ImplausibleOutcome(
            f'{what}: {int(over.sum())} row(s) move the robot more than '
            f'outcome.max_displacement {limits.max_displacement:g} m in one gait (the largest: '
            f'row {row}, {moved[row]:.4g} m)')
