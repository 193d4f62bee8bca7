"""An affine map of the prior mean, learnt from the steps: what a damage does to the whole map.

The GPs link a step only to gaits near it in the descriptor space; a damage that makes the
robot slower, or turn as it walks, changes every gait's outcome alike. A map of the prior's
prediction ``m`` of every gait (the intact map, a damage table or their mixture) to the
robot's outcome::

    dx'   = a11 dx + a12 dy + bx
    dy'   = a21 dx + a22 dy + by
    dyaw' = c dyaw + e dx + byaw

is learnt from every step by Bayesian linear regression, its prior centred on the identity
(scale and rotation terms ``~ N(identity, scale_sd^2)``, offsets ``~ N(0, offset_sd^2)``) and
each output's noise the chaining error, so that a few steps move it only as far as they show;
the GP then models what is left. Planar outputs share their features ``(dx, dy, 1)``; the
turn takes ``(dyaw, dx, 1)`` (a robot that drifts as it walks forward). The fit is a 3x3
solve per output: O(N) per step, then O(M) to apply it to the whole map.

With ``descriptor_sd``, the scale of each output also varies with the gait: ``a11`` (dx),
``a22`` (dy) and ``e`` (the drift of the turn) each gain a term linear in the gait's
normalised descriptor, centred on the middle of the map (``u . (d - 0.5)``), its weights
``~ N(0, descriptor_sd^2)``. On the 8-D map the descriptor holds each leg's duty factor: a
robot that lost a leg slows the gaits that lean on that leg more than the others, which one
scale for the whole map cannot say. A solve of ``3 + d`` unknowns per output.
"""
from __future__ import annotations

import numpy as np

#: Prior standard deviation of the offsets: m per gait for dx, dy; rad per gait for dyaw.
OFFSET_SD = np.array([0.05, 0.05, 0.1])
#: Noise standard deviation of each output around the map (the chaining error: a gait
#: chained from the last differs from its standing start by this much).
NOISE_SD = np.array([0.1, 0.1, 0.25])
#: Default prior standard deviation of the scale and rotation terms around the identity.
DEFAULT_SCALE_SD = 0.5


def _features(prior, output, descriptors=None):
    """``(N, 3 [+ d])`` features of ``output`` from the prior's predictions ``(N, k)`` (and
    the gaits' normalised descriptors ``(N, d)``), and the prior mean of their weights."""
    ones = np.ones(len(prior))
    if output < 2:
        centre = np.zeros(3)
        centre[output] = 1.0
        design = np.column_stack([prior[:, 0], prior[:, 1], ones])
    else:
        design, centre = np.column_stack([prior[:, 2], prior[:, 0], ones]), np.array(
            [1.0, 0.0, 0.0])
    if descriptors is None:
        return design, centre
    # The scale term the descriptor modulates: dx for dx, dy for dy, the drift (dx) for dyaw.
    scaled = prior[:, 1 if output == 1 else 0]
    varying = scaled[:, None] * (np.asarray(descriptors, dtype=float) - 0.5)
    return np.column_stack([design, varying]), np.concatenate(
        [centre, np.zeros(varying.shape[1])])


def fit_affine(prior_observed, observed, scale_sd=DEFAULT_SCALE_SD, descriptors=None,
               descriptor_sd=None) -> np.ndarray:
    """The posterior mean weights ``(k, 3 [+ d])`` of the affine map, given the prior's
    predictions ``(N, k)`` at the gaits run and their outcomes ``(N, k)`` (k is 2 or 3:
    dx, dy[, dyaw]); with ``descriptor_sd``, the gaits' normalised descriptors ``(N, d)``
    make its scale vary across the map."""
    prior_observed = np.asarray(prior_observed, dtype=float)
    observed = np.asarray(observed, dtype=float)
    k = prior_observed.shape[1]
    if descriptor_sd is None:
        descriptors = None
    elif descriptors is None:
        raise ValueError('descriptor_sd needs the descriptors of the gaits run')
    extra = 0 if descriptors is None else np.asarray(descriptors).shape[1]
    weights = np.zeros((k, 3 + extra))
    for output in range(k):
        design, centre = _features(prior_observed, output, descriptors)
        sd = np.concatenate([[scale_sd, scale_sd, OFFSET_SD[output]],
                             np.full(extra, descriptor_sd or 1.0)])
        precision = np.diag(1.0 / sd ** 2)
        noise = NOISE_SD[output] ** 2
        a = precision + design.T @ design / noise
        b = precision @ centre + design.T @ observed[:, output] / noise
        weights[output] = np.linalg.solve(a, b)
    return weights


def apply_affine(weights, prior, descriptors=None) -> np.ndarray:
    """The map ``weights`` (:func:`fit_affine`) applied to every gait's prediction
    ``(M, k)`` (and, for a map fitted with descriptors, the gaits' normalised descriptors
    ``(M, d)``); returns ``(M, k)``."""
    prior = np.asarray(prior, dtype=float)
    weights = np.asarray(weights, dtype=float)
    extra = weights.shape[1] - 3
    if extra and (descriptors is None or np.shape(descriptors)[1] != extra):
        raise ValueError(f'a map fitted with {extra} descriptor dimensions needs the '
                         'descriptors of the gaits it is applied to')
    if extra:
        # (M, k) the descriptor's part of each output's scale: one matrix product.
        modulation = (np.asarray(descriptors, dtype=float) - 0.5) @ weights[:, 3:].T
    out = np.empty_like(prior)
    for output in range(prior.shape[1]):
        w = weights[output]
        if output < 2:
            out[:, output] = w[0] * prior[:, 0] + w[1] * prior[:, 1] + w[2]
        else:
            out[:, output] = w[0] * prior[:, 2] + w[1] * prior[:, 0] + w[2]
        if extra:
            out[:, output] += modulation[:, output] * prior[:, 1 if output == 1 else 0]
    return out
