"""Plausibility limits on outcomes: what one gait can do to the robot. ROS-free.

An observed outcome is learnt by the GPs and saved for the rest of the robot's life, and its
end pose is where the next step starts. So an outcome that says one 3 s gait moved the robot
a kilometre (a sensor glitch, a simulator gone wrong, someone publishing on the topic) must
be refused with the reason, never learnt: one such observation drags the GP's mean of every
nearby gait, and a pose off the map ends the mission. The shipped archive's gaits move the
intact robot at most 0.45 m; the default limit, ``outcome.max_displacement`` = 2 m, leaves
room for other robots and archives while refusing what no gait can do.
"""
import math
from dataclasses import dataclass

DEFAULT_MAX_DISPLACEMENT = 2.0  # m in one gait


class ImplausibleOutcome(ValueError):
    """An outcome that no gait can produce: refused, not learnt."""


@dataclass(frozen=True)
class OutcomeLimits:
    """``outcome.*`` parameters: what one gait can plausibly do."""

    max_displacement: float = DEFAULT_MAX_DISPLACEMENT  # m between the start and end poses

    def __post_init__(self):
        value = self.max_displacement
        if isinstance(value, bool) or not isinstance(value, (int, float)) \
                or not math.isfinite(value) or value <= 0:
            raise ValueError('outcome.max_displacement must be a finite number > 0 (m), got '
                             f'{value!r}')


def _finite(name, values):
    values = [float(v) for v in values]
    if not all(math.isfinite(v) for v in values):
        raise ImplausibleOutcome(f'{name} has a non-finite value: {values}')
    return values


def _distance(a, b):
    # Halved first: two finite coordinates can be further apart than the largest float.
    return 2.0 * math.hypot(a[0] / 2 - b[0] / 2, a[1] / 2 - b[1] / 2)


def check_outcome(generic_reward, start_pose=None, end_pose=None, limits=None,
                  expected_start=None):
    """Raise :class:`ImplausibleOutcome` when an outcome cannot come from one gait.

    Args:
        generic_reward: observed (dx, dy[, dyaw]) in the robot's frame at the start.
        start_pose, end_pose: observed (x, y[, yaw]) before and after the gait, if known.
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
