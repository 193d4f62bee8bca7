"""Fall-aware adaptation: the risk that each gait of the archive tips the damaged robot over.

A fall is an outcome like any other, so it is learnt like one: a GP over the same normalised
behaviour descriptors and kernel as the generic-reward GPs, whose observation for a gait is 1
when it ended fallen and 0 when it did not. Its prior mean is the archive's own fall rate
(zero for a map built on the intact robot, where no elite falls), so before any evidence every
gait is trusted. One fall raises the risk of every gait whose descriptor is close to the one
that fell, which is the point of the paper's 8-D descriptor: gaits that lean on the same leg
(similar duty factors) share the risk, and SELA stops trying them one at a time.

The acquisition keeps away from gaits whose predicted risk is above ``fall.risk.threshold``
(the risk accepted). The GP is a regression on a 0/1 label, not a classifier: its mean,
clipped to [0, 1], is a smooth, cheap (one rank-one update per step, as the generic-reward
GPs) and monotone stand-in for the probability of falling, which is all the threshold needs.
"""
from __future__ import annotations

import numpy as np

from sela_ros.core.gp import CandidateSetGP

#: Risk accepted by default: gaits predicted to fall more often than this are not tried.
DEFAULT_THRESHOLD = 0.3


class FallRisk:
    """Per-gait risk of falling over a fixed archive, learnt from every step.

    Args:
        candidates: ``(M, d)`` normalised behaviour descriptors (the GPs' inputs).
        prior: ``(M,)`` prior fall rate per gait in ``[0, 1]``; None: zeros (intact map).
        sigma, variance, noise: kernel parameters (those of the generic-reward GPs).
    """

    def __init__(self, candidates, prior=None, sigma=0.1, variance=1.0, noise=0.001):
        candidates = np.asarray(candidates, dtype=float)
        if prior is None:
            prior = np.zeros(candidates.shape[0])
        prior = np.asarray(prior, dtype=float).reshape(-1)
        if prior.shape != (candidates.shape[0],):
            raise ValueError(f'prior must have shape ({candidates.shape[0]},), got '
                             f'{prior.shape}')
        if not np.all(np.isfinite(prior)) or prior.min(initial=0.0) < 0 \
                or prior.max(initial=0.0) > 1:
            raise ValueError('prior fall rates must be finite numbers in [0, 1]')
        self._args = (candidates, prior[:, None], sigma, variance, noise)
        self.reset()

    def reset(self) -> None:
        """Forget every observed fall: back to the prior."""
        candidates, prior, sigma, variance, noise = self._args
        self._gp = CandidateSetGP(candidates, prior, sigma=sigma, variance=variance,
                                  noise=noise)
        self.falls = 0

    def tell(self, index: int, fallen: bool) -> None:
        """Learn whether gait ``index`` ended with the robot fallen."""
        self._gp.add_sample(index, [1.0 if fallen else 0.0])
        self.falls += bool(fallen)

    def risk(self) -> np.ndarray:
        """Predicted risk of falling of every gait, ``(M,)`` in ``[0, 1]``."""
        mu, _ = self._gp.query_columns()
        return np.clip(mu[0], 0.0, 1.0)

    @property
    def observations(self):
        """``(indices (N,), fallen (N,) bool)`` told so far."""
        return (np.array(self._gp.indices, dtype=int),
                self._gp.observed.reshape(-1) > 0.5)


def safe_choice(scores, risk, threshold) -> np.ndarray:
    """Scores with every gait riskier than ``threshold`` ruled out (``-inf``).

    If every gait is ruled out, the least risky ones keep their scores: the robot must move,
    and the gait least likely to tip it over is the best bet.
    """
    scores = np.asarray(scores, dtype=float)
    risk = np.asarray(risk, dtype=float)
    allowed = risk <= threshold
    if not allowed.any():
        allowed = risk <= risk.min() + 1e-12
    return np.where(allowed, scores, -np.inf)
