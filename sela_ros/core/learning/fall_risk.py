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

A map can say more than "nothing falls" about gaits nobody has tried yet. On the hexapod's 8-D
map the six duty factors give each gait's *support*, the mean number of feet on the ground:
with a leg (or two) removed, gaits with little support tip the robot over far more often
(front left leg removed, 1,000 gaits of the shipped 8-D map from a standing start: 31 % of
the least supported tenth fall, 1 % of the best supported tenth; front left and rear right
removed: 83 % and 4 %; ``scripts/fall_analysis.py``, ``docs/notebook.md``). Given such a
``stability`` feature, the risk of an untried gait is a Bayesian logistic model instead of
one rate for all, ``P(fall) = s(theta - beta z)`` with ``z`` the gait's standardised
stability: ``theta`` (how badly this robot falls) and ``beta`` (how much support protects
it) are learnt from every step on a grid posterior, from a prior where a gait of average
support rarely tips the robot over (5 %) and support helps (``beta`` about 1.5 per standard
deviation, what the measurements above give). One fall then rules out the least supported
gaits at once, everywhere in the map, not only near the gait that fell; a robot whose falls
have nothing to do with support learns a smaller ``beta``.

Falls are more local than displacements: on the 8-D map a gait 0.15-0.25 away from one seen
upright still falls 6.5 % of the time against 9 % for any gait (front left removed), so the
fall GP has its own, shorter kernel (``fall.kernel.sigma``, 0.12 on the 8-D map).
"""
from __future__ import annotations

import numpy as np

from sela_ros.core.learning.gp import CandidateSetGP

#: Risk accepted by default: gaits predicted to fall more often than this are never tried.
#: Below it, SELA's ``fall.risk.cost`` weighs the risk against the progress (docs/notebook.md).
DEFAULT_THRESHOLD = 0.3
#: What a fall costs by default in SELA's choice, in metres of predicted progress (measured on
#: the 8-D map against 0, 0.5 and 2: docs/notebook.md).
DEFAULT_COST = 1.0
#: Steps without a fall assumed before any is seen, in the fall rate of untried gaits without
#: a stability feature: one fall in the first step gives them 0.25, two in a row 0.4.
SAFE_PSEUDO_STEPS = 3
#: Prior of the logistic model over the stability feature: ``theta ~ N(mean, sd)`` (a gait of
#: average support tips the robot over with probability ``s(-3)`` = 5 % before any evidence:
#: SELA adapts a robot that is damaged; -4 and -3.5 measured worse, docs/notebook.md) and
#: ``beta ~ N(mean, sd)``, ``beta >= 0`` (per standard deviation of the feature).
THETA_PRIOR = (-3.0, 1.5)
BETA_PRIOR = (1.5, 1.0)
#: How many gaits a damage prior's table counts for in the logistic model's prior on that
#: damage (:meth:`FallRisk.table_support`): its falls are from a standing start, not chained
#: as on the robot, so they set where the model starts, not how sure it is (docs/notebook.md).
TABLE_EVIDENCE = 600
#: What the support model's risk of a gait counts for, in chained runs, against the chained
#: runs of that gait a damage prior holds (:meth:`FallRisk.risk`, ``chained``).
CHAINED_PRIOR_RUNS = 1.0
_THETA_GRID = np.linspace(-9.0, 5.0, 57)
_BETA_GRID = np.linspace(0.0, 5.0, 41)
_Z_GRID = np.linspace(-4.0, 4.0, 161)


class FallRisk:
    """Per-gait risk of falling over a fixed archive, learnt from every step.

    Args:
        candidates: ``(M, d)`` normalised behaviour descriptors (the GPs' inputs).
        prior: ``(M,)`` prior fall rate per gait in ``[0, 1]``; None: zeros (intact map).
        sigma, variance, noise: kernel parameters (those of the generic-reward GPs).
        stability: ``(M,)`` a feature of each gait that makes falls less likely (the 8-D
            map's support, :attr:`~sela_ros.core.storage.Archive.stability`); None: every
            untried gait has the robot's fall rate so far.
    """

    def __init__(self, candidates, prior=None, sigma=0.1, variance=1.0, noise=0.001,
                 stability=None):
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
        self._z = None
        self._log_lik_grid = None  # table_support's, computed on its first call
        if stability is not None:
            stability = np.asarray(stability, dtype=float).reshape(-1)
            if stability.shape != (candidates.shape[0],) or not np.all(np.isfinite(stability)):
                raise ValueError(f'stability must be {candidates.shape[0]} finite numbers, got '
                                 f'shape {stability.shape}')
            spread = stability.std()
            self._z = np.clip((stability - stability.mean()) / (spread if spread > 0 else 1.0),
                              _Z_GRID[0], _Z_GRID[-1])
            theta, beta = np.meshgrid(_THETA_GRID, _BETA_GRID, indexing='ij')
            self._theta, self._beta = theta.ravel(), beta.ravel()
            # P(fall) at every grid point of (theta, beta) and of z, once: (2337, 161).
            self._p_grid = 1.0 / (1.0 + np.exp(-(self._theta[:, None]
                                                 - self._beta[:, None] * _Z_GRID[None, :])))
            self._log_prior = _log_support_prior(self._theta, self._beta,
                                                 (*THETA_PRIOR, *BETA_PRIOR))
        self.reset()

    def reset(self) -> None:
        """Forget every observed fall: back to the prior."""
        candidates, prior, sigma, variance, noise = self._args
        # Outputs: the fall (prior: the map's rate) and a constant 1 (prior 0), whose mean
        # k^T K^-1 1 says how much each gait is covered by what was observed.
        self._gp = CandidateSetGP(candidates, np.column_stack([prior, np.zeros_like(prior)]),
                                  sigma=sigma, variance=variance, noise=noise)
        self.falls = 0
        self._untried = {}  # untried_risk() per support prior, emptied by each tell
        if self._z is not None:
            self._log_lik = np.zeros_like(self._theta)  # of the steps seen, on the grid

    def tell(self, index: int, fallen: bool) -> None:
        """Learn whether gait ``index`` ended with the robot fallen."""
        self._gp.add_sample(index, [1.0 if fallen else 0.0, 1.0])
        self.falls += bool(fallen)
        self._untried = {}
        if self._z is not None:
            self._log_lik += _log_likelihood(self._theta, self._beta, self._z[int(index)],
                                             fallen)

    @property
    def num_observations(self) -> int:
        return self._gp.num_samples

    def tell_many(self, indices, fallen) -> None:
        """:meth:`tell` each ``(index, fallen)`` in turn; into an empty model at once."""
        indices = [int(i) for i in indices]
        fallen = [bool(f) for f in fallen]
        if self._gp.num_samples:
            for i, f in zip(indices, fallen):
                self.tell(i, f)
            return
        self._gp.fit(indices, [[1.0 if f else 0.0, 1.0] for f in fallen])
        self.falls += sum(fallen)
        self._untried = {}
        if self._z is not None:
            for i, f in zip(indices, fallen):
                self._log_lik += _log_likelihood(self._theta, self._beta, self._z[i], f)

    @property
    def support_model(self):
        """Posterior means ``(theta, beta)`` of the logistic model; None without stability."""
        if self._z is None:
            return None
        w = self._weights()
        return float(w @ self._theta), float(w @ self._beta)

    def _weights(self, support=None):
        log_post = self._log_lik + (self._log_prior if support is None
                                    else _log_support_prior(self._theta, self._beta, support))
        w = np.exp(log_post - log_post.max())
        return w / w.sum()

    def table_support(self, fallen) -> tuple | None:
        """The logistic model's prior on a foreseen damage, from its table's falls.

        ``fallen``: ``(M,)`` which gaits fall from a standing start on that damage (a damage
        prior's table), or the rate at which each falls (a mixture of tables). Returns
        ``(theta mean, theta sd, beta mean, beta sd)``: the means are the posterior of
        :data:`THETA_PRIOR` and :data:`BETA_PRIOR` given the table's falls, weighed as
        :data:`TABLE_EVIDENCE` gaits (a table whose gaits never fall says that this damage
        rarely tips the robot over, whatever the support); the spreads stay the generic
        prior's, so the robot's own steps move it as fast as they move that one. None without
        a stability feature."""
        if self._z is None:
            return None
        fallen = np.asarray(fallen, dtype=float).reshape(-1)
        if fallen.shape != self._z.shape:
            raise ValueError(f'fallen must have shape {self._z.shape}, got {fallen.shape}')
        if not np.all((fallen >= 0) & (fallen <= 1)):
            raise ValueError('fallen must be flags or fall rates in [0, 1]')
        # The gaits binned on the grid of z: one likelihood term per bin, not per gait.
        step = _Z_GRID[1] - _Z_GRID[0]
        bins = np.rint((self._z - _Z_GRID[0]) / step).astype(int)  # z is within the grid
        weight = TABLE_EVIDENCE / fallen.size
        if self._log_lik_grid is None:
            # log P(fall) and log P(stand) at every grid point of (theta, beta) and of z, once:
            # a mixture of tables asks for a new support prior at every step.
            self._log_lik_grid = tuple(
                _log_likelihood(self._theta[:, None], self._beta[:, None], _Z_GRID[None, :],
                                flag) for flag in (True, False))
        log_post = self._log_prior.copy()
        for grid, share in zip(self._log_lik_grid, (fallen, 1.0 - fallen)):
            counts = np.bincount(bins, weights=share, minlength=_Z_GRID.size) * weight
            log_post += grid @ counts
        w = np.exp(log_post - log_post.max())
        w /= w.sum()
        return (float(w @ self._theta), THETA_PRIOR[1], float(w @ self._beta), BETA_PRIOR[1])

    def untried_risk(self, support=None) -> np.ndarray:
        """``(M,)`` risk of each gait before anything near it was observed: the robot's fall
        rate so far, or, with a stability feature, the logistic model's posterior predictive
        probability for the gait's stability.

        ``support``: the logistic model's prior for a foreseen damage
        (:meth:`table_support`) in place of :data:`THETA_PRIOR` and :data:`BETA_PRIOR`; the
        robot's own steps update it all the same."""
        key = None if support is None or self._z is None else tuple(map(float, support))
        if key not in self._untried:
            if self._z is None:
                self._untried[key] = np.full(self._args[0].shape[0], self.base_rate)
            else:
                self._untried[key] = np.interp(self._z, _Z_GRID,
                                               self._weights(key) @ self._p_grid)
        return self._untried[key]

    @property
    def base_rate(self) -> float:
        """The robot's fall rate so far, the risk of a gait far from every observed one."""
        return self.falls / (len(self._gp.indices) + SAFE_PSEUDO_STEPS)

    def risk(self, prior_falls=None, support=None, chained=None) -> np.ndarray:
        """Predicted risk of falling of every gait, ``(M,)`` in ``[0, 1]``.

        ``prior_falls``: ``(M,)`` what a damage prior says of each gait (1: it falls from a
        standing start on that damage); where nothing near a gait was observed, its risk is
        at least that (measured against the table's own rates: docs/notebook.md).
        ``support``: the logistic model's prior on that damage (:meth:`table_support`).
        ``chained``: ``(gaits, runs, falls)``, gaits that damage prior ran chained after
        others, how often and how often they fell: their untried risk is the support
        model's, counted as :data:`CHAINED_PRIOR_RUNS` runs, pooled with those.
        """
        mu, _ = self._gp.query_columns()
        untried = self.untried_risk(support)
        if chained is not None and len(chained[0]):
            gaits, runs, falls = chained
            untried = untried.copy()
            untried[gaits] = ((CHAINED_PRIOR_RUNS * untried[gaits] + falls)
                              / (CHAINED_PRIOR_RUNS + runs))
        if prior_falls is not None:
            untried = np.maximum(untried, prior_falls)
        return np.clip(mu[0] + untried * (1.0 - mu[1]), 0.0, 1.0)

    @property
    def observations(self):
        """``(indices (N,), fallen (N,) bool)`` told so far."""
        return (np.array(self._gp.indices, dtype=int),
                self._gp.observed[:, 0] > 0.5)


def _log_likelihood(theta, beta, z, fallen):
    """Log-likelihood of a gait of standardised stability ``z`` falling (or not) under the
    logistic model ``P(fall) = s(theta - beta z)``, at every ``(theta, beta)``."""
    logit = theta - beta * z
    # log s(l) = -log(1 + e^-l); log(1 - s(l)) = -log(1 + e^l)
    return -np.logaddexp(0.0, -logit if fallen else logit)


def _log_support_prior(theta, beta, support):
    theta_mean, theta_sd, beta_mean, beta_sd = support
    return (-0.5 * ((theta - theta_mean) / theta_sd) ** 2
            - 0.5 * ((beta - beta_mean) / beta_sd) ** 2)


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
