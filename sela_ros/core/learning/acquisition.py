"""Acquisition: Upper Confidence Bound over all candidates at once."""
from __future__ import annotations

import numpy as np
from scipy import special

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


# Progress along the path (``acquisition.progress``): a gait is scored by where its landing
# puts the robot on the planned path, not by its distance to one waypoint on it. A robot whose
# gaits all fall short of the waypoint then still takes the one that goes furthest along the
# path, and a gait that lands beyond the waypoint is not punished for it.


def path_coordinates(path, x, y):
    """Arc length along ``path`` (n, 2) of the nearest point of the path to each ``(x, y)``,
    and the distance to it: ``(s (M,), off (M,))``; a point beyond either end projects on it."""
    path = np.asarray(path, dtype=float)
    x = np.asarray(x, dtype=float).reshape(-1)
    y = np.asarray(y, dtype=float).reshape(-1)
    if path.ndim != 2 or path.shape[1] != 2 or len(path) < 1 or not np.all(np.isfinite(path)):
        raise ValueError(f'path must be a finite (n, 2) array with n >= 1, got {path.shape}')
    if len(path) == 1:
        return np.zeros(x.size), np.hypot(x - path[0, 0], y - path[0, 1])
    a, seg = path[:-1], np.diff(path, axis=0)
    length = np.hypot(seg[:, 0], seg[:, 1])
    start = np.concatenate([[0.0], np.cumsum(length)[:-1]])
    # (M, n-1): each point's projection on each segment, clipped to it.
    dx, dy = x[:, None] - a[None, :, 0], y[:, None] - a[None, :, 1]
    t = np.clip((dx * seg[:, 0] + dy * seg[:, 1]) / np.maximum(length ** 2, 1e-18), 0.0, 1.0)
    ox, oy = dx - t * seg[:, 0], dy - t * seg[:, 1]
    sq = ox * ox + oy * oy
    k = np.argmin(sq, axis=1)
    rows = np.arange(x.size)
    return start[k] + t[rows, k] * length[k], np.sqrt(sq[rows, k])


def progress_reward(path, x, y, waypoint, off_weight, landing_var=None) -> np.ndarray:
    """Specialised reward of landing at each ``(x, y)``: how far along ``path`` beyond
    ``waypoint`` its nearest point on the path lies (negative: short of it), less
    ``off_weight`` times its distance off the path (with ``landing_var``, the variance per
    axis of each landing: that distance's root mean square; the progress is its mean: one
    standard deviation less keeps a robot on the gait it knows that stays put,
    docs/learning_the_damage.md). A landing on the waypoint scores 0, as it does by the
    distance to it."""
    if not np.isfinite(off_weight) or off_weight < 0:
        raise ValueError(f'off_weight must be a finite number >= 0, got {off_weight!r}')
    s, off = path_coordinates(path, x, y)
    s_waypoint, _ = path_coordinates(path, [waypoint[0]], [waypoint[1]])
    if landing_var is not None:
        off = np.sqrt(off * off + np.asarray(landing_var, dtype=float))
    return s - s_waypoint[0] - off_weight * off


def progress_reward_from(path, origins, cos, sin, displacement, waypoint, off_weight,
                         landing_var=None) -> np.ndarray:
    """:func:`progress_reward` of every landing ``origins[k] + R_k displacement[:, m]``
    (``R_k`` the rotation by the angle whose cosine and sine are ``cos[k]``, ``sin[k]``):
    ``(K, M)``, from rank-2 products per segment of ``path`` rather than K M projections
    (``landing_var``: ``(K, M)`` or None)."""
    path = np.asarray(path, dtype=float)
    origins = np.asarray(origins, dtype=float)[:, :2]
    g = np.asarray(displacement, dtype=float)[:2]
    seg = np.diff(path, axis=0)
    length = np.hypot(seg[:, 0], seg[:, 1]) if len(path) > 1 else np.zeros(0)
    if not (length > 1e-12).any():
        x = origins[:, 0, None] + cos[:, None] * g[0] - sin[:, None] * g[1]
        y = origins[:, 1, None] + sin[:, None] * g[0] + cos[:, None] * g[1]
        var = None if landing_var is None else np.asarray(landing_var).reshape(-1)
        return progress_reward(path, x.reshape(-1), y.reshape(-1), waypoint, off_weight,
                               var).reshape(x.shape)
    if not np.isfinite(off_weight) or off_weight < 0:
        raise ValueError(f'off_weight must be a finite number >= 0, got {off_weight!r}')
    start = np.concatenate([[0.0], np.cumsum(length)[:-1]])
    ones = np.vstack([g, np.ones((1, g.shape[1]))])  # (3, M): a row's offset in the product
    best_sq = best_s = None
    for a, d, n, s0 in zip(path[:-1], seg, length, start):
        if n <= 1e-12:
            continue
        u, v = d / n, np.array([-d[1], d[0]]) / n
        # The landing's along- and across-track coordinates: (R_k^T u) . g + (o_k - a) . u,
        # one (K, 3) @ (3, M) product each.
        rel = origins - a
        along = np.column_stack([cos * u[0] + sin * u[1], cos * u[1] - sin * u[0],
                                 rel @ u]) @ ones
        cross = np.column_stack([cos * v[0] + sin * v[1], cos * v[1] - sin * v[0],
                                 rel @ v]) @ ones
        t = np.clip(along, 0.0, n)
        along -= t
        along *= along
        cross *= cross
        along += cross
        t += s0
        if best_sq is None:
            best_sq, best_s = along, t
        else:
            nearer = along < best_sq
            np.copyto(best_sq, along, where=nearer)
            np.copyto(best_s, t, where=nearer)
    s_waypoint, _ = path_coordinates(path, [waypoint[0]], [waypoint[1]])
    best_s -= s_waypoint[0]
    if landing_var is not None:
        best_sq += landing_var
    np.sqrt(best_sq, out=best_sq)
    best_sq *= off_weight
    best_s -= best_sq
    return best_s


def path_from(path, point, length):
    """The part of ``path`` from the projection of ``point`` on it, ``length`` metres long
    (shorter where the path ends): the track the second of two steps is scored along."""
    path = np.asarray(path, dtype=float)
    s, _ = path_coordinates(path, [point[0]], [point[1]])
    if len(path) < 2:
        return path.copy()
    seg = np.diff(path, axis=0)
    cum = np.concatenate([[0.0], np.cumsum(np.hypot(seg[:, 0], seg[:, 1]))])
    first, last = s[0], min(s[0] + length, cum[-1])

    def at(arc):
        k = int(np.clip(np.searchsorted(cum, arc, side='right') - 1, 0, len(seg) - 1))
        span = cum[k + 1] - cum[k]
        return path[k] + seg[k] * ((arc - cum[k]) / span if span > 0 else 0.0)

    inner = path[(cum > first) & (cum < last)]
    return np.vstack([at(first), inner, at(last)])


# The chance of landing within reach (``acquisition.reach``): while caution is on, a gait is
# scored by the probability that its landing, N(predicted, landing_var I_2), falls within the
# reach of the waypoint. A gait that surely stays put then has no chance, however sure, and a
# gait whose landing is uncertain loses what its spread puts out of reach.
#: Below this chance for every gait allowed, no gait is likely to reach: the gaits are scored
#: by their expected distance to the waypoint (caution's). Lower, a robot that lost its speed
#: keeps trying untried gaits, whose spread alone gives them some chance, and stays put
#: (docs/learning_the_damage.md).
REACH_MIN_CHANCE = 0.5
#: Metres of reward per metre of expected distance added to the chance (times the reach):
#: among gaits about as likely to reach, the one expected nearer the waypoint.
REACH_TIE_BREAK = 0.01


def reach_probability(sq_distance, landing_var, reach) -> np.ndarray:
    """Probability that a landing ``N(mu, landing_var I_2)`` whose mean is ``sq_distance``
    (squared) from a target falls within ``reach`` of it: the CDF of a non-central
    chi-square with 2 degrees of freedom at ``reach^2 / landing_var``, noncentrality
    ``sq_distance / landing_var``, by Sankaran's normal approximation (within 0.02 of the
    exact one, at half the cost of its series)."""
    if not np.isfinite(reach) or reach <= 0:
        raise ValueError(f'reach must be a finite number > 0, got {reach!r}')
    var = np.asarray(landing_var, dtype=float)
    if (var <= 0).any():
        raise ValueError('landing_var must be > 0')
    lam = np.maximum(np.asarray(sq_distance, dtype=float), 0.0) / var
    k = 2.0
    kl = k + lam
    k2l = kl + lam
    h = 1.0 - (2.0 / 3.0) * kl * (k2l + lam) / (k2l * k2l)
    p = k2l / (kl * kl)
    m = (h - 1.0) * (1.0 - 3.0 * h)
    z = ((reach * reach / var / kl) ** h - (1.0 + h * p * (h - 1.0 - 0.5 * (2.0 - h) * m * p))) \
        / (h * np.sqrt(2.0 * p) * (1.0 + 0.5 * m * p))
    return special.ndtr(z)


def reach_reward(chance, expected, reach) -> np.ndarray:
    """Specialised reward (m) of gaits with ``chance`` of landing within ``reach`` of the
    waypoint and ``expected`` distance to it: ``reach x chance``, so that UCB's bonus and
    the fall cost keep their units, less :data:`REACH_TIE_BREAK` times the expected
    distance."""
    return reach * np.asarray(chance, dtype=float) \
        - REACH_TIE_BREAK * np.asarray(expected, dtype=float)
