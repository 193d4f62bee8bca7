"""The GPs' kernel length and signal variance learnt from the steps (``gp.hyper.sd``).

At a fixed kernel length a step informs only the gaits near it; when the residuals of the
steps (what they did less the prior mean in use) are large and alike over the whole map, a
longer length carries them to the gaits not tried. The length and the signal variance are
chosen on a small grid around the configured ones by the log marginal likelihood of the
residuals plus a log-normal prior centred on the configured values, so that a few steps cannot
move them far, and a new setting is taken only when it beats the one in use by a margin: each
change refactorises the GP over the whole archive.
"""
from __future__ import annotations

import numpy as np
from scipy.linalg import cholesky, solve_triangular

#: Kernel lengths tried, as multiples of the configured one (0.3 on the 8-D map: 0.3 to 1.2).
LENGTH_FACTORS = (1.0, 5.0 / 3.0, 8.0 / 3.0, 4.0)
#: Signal variances tried, as multiples of the configured one.
VARIANCE_FACTORS = (0.01, 0.1, 1.0)
#: How much more (nats) a setting must score than the one in use to replace it.
MARGIN = 2.0


def log_marginal_likelihood(sq, residuals, sigma, variance, noise) -> float:
    """``log p(residuals)`` under a zero-mean GP of exponential kernel (length ``sigma``,
    signal ``variance``) and ``noise`` variance, the D outputs independent and sharing the
    kernel: ``sq`` (N, N) squared distances between the inputs, ``residuals`` (N, D)."""
    residuals = np.asarray(residuals, dtype=float)
    residuals = residuals.reshape(len(residuals), -1)
    n, d = residuals.shape
    if not n:
        return 0.0
    k = variance * np.exp((-0.5 / (sigma * sigma)) * np.asarray(sq, dtype=float))
    k[np.diag_indices(n)] += noise
    low = cholesky(k, lower=True, check_finite=False)
    alpha = solve_triangular(low, residuals, lower=True, check_finite=False)
    return float(-0.5 * np.sum(alpha * alpha) - d * np.sum(np.log(np.diag(low)))
                 - 0.5 * n * d * np.log(2.0 * np.pi))


def log_prior(sigma, variance, sigma0, variance0, sd) -> float:
    """Log-normal prior of the length and the variance, centred on ``sigma0`` and
    ``variance0``, ``sd`` the standard deviation of their logs (constants left out)."""
    return float(-0.5 * (np.log(sigma / sigma0) / sd) ** 2
                 - 0.5 * (np.log(variance / variance0) / sd) ** 2)


def score(sq, residuals, sigma, variance, noise, sigma0, variance0, sd) -> float:
    """The log posterior (up to a constant) of a setting: evidence plus prior."""
    return log_marginal_likelihood(sq, residuals, sigma, variance, noise) \
        + log_prior(sigma, variance, sigma0, variance0, sd)


def grid(sigma0, variance0):
    """The settings tried: ``(sigma, variance)`` pairs around the configured ones."""
    return [(sigma0 * a, variance0 * b) for a in LENGTH_FACTORS for b in VARIANCE_FACTORS]


def choose(sq, residuals, noise, sigma0, variance0, sd, current=None, margin=MARGIN):
    """The ``(sigma, variance)`` to use given the residuals of the steps: the grid's best by
    :func:`score`, or ``current`` (default: the configured values) unless the best beats it
    by ``margin`` nats. ``sq`` (N, N): squared distances between the steps' inputs."""
    current = (float(sigma0), float(variance0)) if current is None else \
        (float(current[0]), float(current[1]))
    residuals = np.asarray(residuals, dtype=float)
    if not len(residuals):
        return current
    args = (noise, sigma0, variance0, sd)
    best, best_score = current, score(sq, residuals, *current, *args)
    kept = best_score
    for setting in grid(sigma0, variance0):
        value = score(sq, residuals, *setting, *args)
        if value > best_score:
            best, best_score = setting, value
    return best if best_score > kept + margin else current
