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
