"""Waypoints this robot can reach: the lookahead from the steps it has shown. ROS-free.

A robot that lost much of its speed lands every gait far short of a waypoint
``planner.lookahead`` ahead; the gait whose landing is nearest such a waypoint is then often
one that brings it little nearer the goal. With ``planner.reach`` the waypoint is set at that
multiple of the robot's shown reach (:data:`REACH_QUANTILE` of the planar displacements of the
steps learnt that stayed up), bounded between :data:`REACH_FLOOR` and ``planner.lookahead``.
Until :data:`REACH_MIN_STEPS` such steps are learnt (the intact map trusted, or a new
adaptation) the waypoint stays ``planner.lookahead`` along the path.

Off by default: on the pairs of removed legs it gets fewer runs home (with caution on, a
waypoint within reach is about as near to a gait tried that barely moves as to an untried
one predicted to land on it, and the gait tried wins; docs/learning_the_damage.md).
"""
import numpy as np

#: The quantile of the steps' planar displacements taken as the robot's reach: high, so that
#: the waypoint follows the fastest gaits shown rather than the slow ones tried on the way
#: (a waypoint set at the typical step would draw slower gaits, and shrink again).
REACH_QUANTILE = 0.9
#: m: the nearest waypoint: a gait that lands nearest a waypoint closer than this may as well
#: be one that stays put.
REACH_FLOOR = 0.15
#: Steps learnt that stayed up before the reach they show sets the waypoint.
REACH_MIN_STEPS = 3


def standing_displacements(indices, generic_rewards, fall_indices, fallen):
    """The ``(n, 2)`` planar displacements of the steps learnt (gaits ``indices``, their
    generic rewards' first two columns) whose gait never ended a step on the ground (a fall
    says nothing of how far the robot walks)."""
    indices = np.asarray(indices, dtype=int).reshape(-1)
    rewards = np.asarray(generic_rewards, dtype=float)
    if not len(indices):
        return np.zeros((0, 2))
    fell = np.asarray(fall_indices, dtype=int).reshape(-1)[np.asarray(fallen, dtype=bool)
                                                          .reshape(-1)]
    return rewards[~np.isin(indices, fell), :2]


def reach_lookahead(displacements, lookahead, gain, floor=REACH_FLOOR,
                    quantile=REACH_QUANTILE, min_steps=REACH_MIN_STEPS) -> float:
    """The distance along the path to the waypoint: ``gain`` times the ``quantile`` of the
    planar lengths of ``displacements`` ``(n, 2)``, within [``floor``, ``lookahead``];
    ``lookahead`` itself when ``gain`` is None or fewer than ``min_steps`` are given."""
    if not np.isfinite(lookahead) or lookahead <= 0:
        raise ValueError(f'lookahead must be a finite number > 0, got {lookahead!r}')
    if gain is None:
        return float(lookahead)
    if not np.isfinite(gain) or gain <= 0:
        raise ValueError(f'planner.reach must be a finite number > 0 or none, got {gain!r}')
    lengths = np.linalg.norm(np.asarray(displacements, dtype=float).reshape(-1, 2), axis=1)
    lengths = lengths[np.isfinite(lengths)]
    if len(lengths) < min_steps:
        return float(lookahead)
    reach = gain * float(np.quantile(lengths, quantile))
    return float(min(lookahead, max(min(floor, lookahead), reach)))


def sela_lookahead(sela) -> float:
    """The lookahead of ``sela``'s next step (``planner.lookahead``, or with ``planner.reach``
    that multiple of the reach its learnt steps show)."""
    config = sela.config
    if config.planner_reach is None:
        return float(config.planner_lookahead)
    indices, rewards = sela.observations
    fall_indices, fallen = sela.fall_risk.observations
    return reach_lookahead(standing_displacements(indices, rewards, fall_indices, fallen),
                           config.planner_lookahead, config.planner_reach, floor=REACH_FLOOR,
                           quantile=REACH_QUANTILE, min_steps=REACH_MIN_STEPS)
