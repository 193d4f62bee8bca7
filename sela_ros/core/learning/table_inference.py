"""A damage's table of the whole map from some of its gaits simulated.

A table of every gait of the map on a damage costs a simulation per gait (0.05 core-seconds
on the hexapod: 12,442 gaits, ten core-minutes). The damage library and the self-model
(:mod:`sela_ros.core.learning.self_model`) simulate a subset instead: gaits chosen to cover
the behaviour space (farthest-point sampling over the normalised descriptors), then those
that take the intact robot farthest, which a mission picks most (:func:`gait_subset`); the
others are inferred by a GP over the same descriptors whose prior mean is the intact map
and whose data are the damage's deviations from it and its falls (:func:`infer`).

ROS-free; numpy and scipy only.
"""
from __future__ import annotations

import numpy as np

from sela_ros.core.learning.gp import exponential_kernel


def gait_subset(descriptors, count, speed=None, covering=None, first=0):
    """``count`` gait indices, deterministic (a build resumes the same plan): the first
    ``covering`` (None: all ``count``) cover the descriptors (farthest-point sampling from
    gait ``first``, so that every gait is near a chosen one), then, with ``speed`` (each
    gait's distance on the intact robot), the fastest gaits not chosen yet."""
    descriptors = np.asarray(descriptors, dtype=float)
    count = min(int(count), len(descriptors))
    spread = count if speed is None or covering is None else min(count, int(covering))
    chosen = [int(first)]
    gap = np.sum((descriptors - descriptors[first]) ** 2, axis=1)
    for _ in range(spread - 1):
        nxt = int(np.argmax(gap))
        chosen.append(nxt)
        np.minimum(gap, np.sum((descriptors - descriptors[nxt]) ** 2, axis=1), out=gap)
    if count > spread:
        taken = np.zeros(len(descriptors), bool)
        taken[chosen] = True
        fastest = [int(g) for g in np.argsort(-np.asarray(speed), kind='stable')
                   if not taken[g]]
        chosen += fastest[:count - spread]
    return np.array(chosen, dtype=int)


def infer(descriptors, base, gaits, gr, fallen, sigma, noise_ratio=0.1, rows=2000):
    """Every gait's generic reward and fall flag on one damage from the gaits simulated:
    the GP posterior mean of the deviation from the intact map ``base`` and of the fall
    label (prior 0), exponential kernel of length ``sigma`` over the descriptors.

    Args:
        descriptors: ``(M, d)`` the map's normalised descriptors.
        base: ``(M, k)`` the intact map's generic rewards.
        gaits: ``(n,)`` the gaits simulated; ``gr`` ``(n, k)`` and ``fallen`` ``(n,)`` theirs.
        sigma: the kernel's length; ``noise_ratio``: its noise, a share of the signal's.

    Returns ``(gr (M, k), fallen (M,))``, the simulated gaits as they were."""
    from scipy.linalg import cho_factor, cho_solve

    descriptors = np.asarray(descriptors, dtype=float)
    base = np.asarray(base, dtype=float)
    gaits = np.asarray(gaits, dtype=int)
    gr = np.asarray(gr, dtype=float)
    fallen = np.asarray(fallen, dtype=bool)
    k = base.shape[1]
    x = descriptors[gaits]
    targets = np.column_stack([gr - base[gaits], fallen.astype(float)])
    scale = targets.std(axis=0)
    scale[scale == 0] = 1.0
    kernel = exponential_kernel(x, x, sigma) + noise_ratio * np.eye(len(gaits))
    alpha = cho_solve(cho_factor(kernel), targets / scale)
    mean = np.empty((len(descriptors), targets.shape[1]))
    for i in range(0, len(descriptors), rows):
        mean[i:i + rows] = exponential_kernel(descriptors[i:i + rows], x, sigma) @ alpha
    mean *= scale
    out_gr = base + mean[:, :k]
    out_fallen = mean[:, k] > 0.5
    out_gr[gaits], out_fallen[gaits] = gr, fallen  # the simulated ones as they are
    return out_gr, out_fallen
