"""Fall-aware adaptation: the risk that each gait of the archive tips the damaged robot over.

A fall is an outcome like any other, so it is learnt like one: a GP over the same normalised
behaviour descriptors and kernel as the generic-reward GPs, whose observation for a gait is 1
when it ended fallen and 0 when it did not. Its prior mean is the archive's own fall rate
(zero for a map built on the intact robot, where no elite falls), so before any evidence every
gait is trusted. One fall raises the risk of every gait whose descriptor is close to the one
that fell, which is the point of the paper's 8-D descriptor: gaits that lean on the same leg
(similar duty factors) share the risk, and SELA stops trying them one at a time.

What is learnt near one gait says nothing about gaits far from every observed one; for those
the risk is the robot's own fall rate so far, ``falls / (steps + SAFE_PSEUDO_STEPS)``, not
zero. On a robot that falls at almost every new gait (two legs removed: about 4 random gaits
in 10 flip it over) the untried gaits then soon count as too risky and SELA keeps to the gaits
it has seen stay upright and to their neighbours; on a robot that rarely falls the rate stays
low and nothing changes. In the GP this is a prior mean ``c`` that moves with the evidence:
the posterior mean is linear in the prior, ``mu_c = mu_0 + c (1 - k^T K^-1 1)``, so a second
output observed as 1 everywhere gives ``k^T K^-1 1`` at no extra solve.

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
#: Steps without a fall assumed before any is seen, in the fall rate of untried gaits: one fall
#: in the first step gives them 0.25 (still tried at the default threshold), two in a row 0.4.
SAFE_PSEUDO_STEPS = 3


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
        # Outputs: the fall (prior: the map's rate) and a constant 1 (prior 0), whose mean
        # k^T K^-1 1 says how much each gait is covered by what was observed.
        self._gp = CandidateSetGP(candidates, np.column_stack([prior, np.zeros_like(prior)]),
                                  sigma=sigma, variance=variance, noise=noise)
        self.falls = 0

    def tell(self, index: int, fallen: bool) -> None:
        """Learn whether gait ``index`` ended with the robot fallen."""
        self._gp.add_sample(index, [1.0 if fallen else 0.0, 1.0])
        self.falls += bool(fallen)

    @property
    def base_rate(self) -> float:
        """The robot's fall rate so far, the risk of a gait far from every observed one."""
        return self.falls / (len(self._gp.indices) + SAFE_PSEUDO_STEPS)

    def risk(self) -> np.ndarray:
        """Predicted risk of falling of every gait, ``(M,)`` in ``[0, 1]``."""
        mu, _ = self._gp.query_columns()
        return np.clip(mu[0] + self.base_rate * (1.0 - mu[1]), 0.0, 1.0)

    @property
    def observations(self):
        """``(indices (N,), fallen (N,) bool)`` told so far."""
        return (np.array(self._gp.indices, dtype=int),
                self._gp.observed[:, 0] > 0.5)


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
