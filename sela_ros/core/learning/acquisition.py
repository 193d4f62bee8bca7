"""Acquisition: Upper Confidence Bound over all candidates at once."""
from __future__ import annotations

import numpy as np

DEFAULT_ALPHA = 0.05


def ucb_scores(reward_mu, sigma, alpha: float = DEFAULT_ALPHA) -> np.ndarray:
    """UCB value ``reward_mu + alpha * sigma`` of every candidate.

    Args:
        reward_mu: ``(M,)`` predicted (specialised) reward of each candidate.
        sigma: ``(M,)`` posterior standard deviation of each candidate.
        alpha: exploration weight (``acquisition.ucb.alpha``).
    """
    reward_mu = np.asarray(reward_mu, dtype=float)
    sigma = np.asarray(sigma, dtype=float)
    if reward_mu.ndim != 1 or reward_mu.shape != sigma.shape or reward_mu.size == 0:
        raise ValueError(
            f'reward_mu and sigma must be non-empty 1-D arrays of the same length, got '
            f'{reward_mu.shape} and {sigma.shape}')
    if not np.isfinite(alpha) or alpha < 0:
        raise ValueError(f'alpha must be a finite number >= 0, got {alpha!r}')
    return reward_mu + alpha * sigma


def ucb(reward_mu, sigma, alpha: float = DEFAULT_ALPHA) -> int:
    """Index of the candidate that maximises UCB (ties: the lowest index)."""
    scores = ucb_scores(reward_mu, sigma, alpha)
    if np.isnan(scores).any():
        raise ValueError('UCB scores contain NaN; check the rewards and variances')
    return int(np.argmax(scores))


# Caution (``acquisition.caution``): on a robot whose untried gaits land far from where the
# map and priors say, a gait is scored by its expected distance to the waypoint instead of
# its predicted one, so that gaits already tried, whose landing is known, are preferred.
#: The default ``acquisition.caution`` (m): measured on 102 damages, 20 seeds each
#: (docs/damage_library.md).
DEFAULT_CAUTION = 0.15
#: Error (m, per axis) of an untried gait's predicted landing before any step has shown it;
#: it counts as one step's worth in :func:`learnt_error`.
CAUTION_PRIOR_ERROR = 0.1
#: Spread (m, per axis) of where a gait already tried lands again: a gait chained from the
#: last one differs from a standing start by 0.07 m rms in the plane (docs/notebook.md).
CAUTION_SPREAD = 0.05
#: Posterior variance (a share of the kernel's) above which a gait counts as untried: its
#: landing error then measures how wrong the prior is for this robot.
UNTRIED_VARIANCE = 0.5


def learnt_error(surprises) -> float:
    """Root mean squared error per axis (m) of untried gaits' predicted landings, from the
    squared planar errors ``surprises`` seen so far, starting from
    :data:`CAUTION_PRIOR_ERROR` worth one step."""
    surprises = np.asarray(surprises, dtype=float).reshape(-1)
    return float(np.sqrt((2.0 * CAUTION_PRIOR_ERROR ** 2 + surprises.sum())
                         / (2.0 * (1 + surprises.size))))


def landing_variance(variance, error) -> np.ndarray:
    """Per axis, the variance (m^2) of where each gait lands: :data:`CAUTION_SPREAD` for a
    gait tried, up to ``error`` squared for one far from every gait tried (``variance``: the
    GP's posterior variance, a share of the kernel's)."""
    return CAUTION_SPREAD ** 2 + np.clip(np.asarray(variance, dtype=float), 0.0, 1.0) * error ** 2


def expected_distance(sq_distance, landing_var) -> np.ndarray:
    """Approximate expected distance from a target of a landing ``N(mu, landing_var I_2)``
    whose mean is ``sq_distance`` (squared) away: ``sqrt(d^2 + 2 s^2)``, its root mean square."""
    return np.sqrt(np.maximum(sq_distance, 0.0) + 2.0 * landing_var)
