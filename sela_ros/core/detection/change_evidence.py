"""Has the robot changed? The evidence a restart of learning needs. ROS-free.

A detection while adapting says that recent outcomes were off their predictions. That
alone is no reason to throw away what was learned: one gait chained after another can end
half a metre from where the same gait went from a standing start, a gait tried once is
predicted from its neighbours, and noise does the rest. What a new damage does, and an
ordinary surprise does not, is make *several* gaits the robot has learnt well go far from
what they did, at once.

:func:`change_evidence` weighs the latest ``window`` observations against a Gaussian
process fitted to the observations before them (the same kernel and prior as SELA's, over
the gaits observed only, so it is cheap), with the predictive standard deviation widened
by the spread the robot's own repeated gaits show (at least ``noise``). A gait is *learnt*
when those earlier observations leave its predictive standard deviation at most
``max_sigma``; it is *far off* when its new outcome misses the prediction by more than
``threshold`` and by more than ``sigmas`` standard deviations. The robot changed when at
least ``min_gaits`` distinct learnt gaits are far off and they are at least ``share`` of the
learnt gaits of the window. Steps that ended in a fall learnt as no displacement (exact
zeros, ``reset_on_fall``) are not weighed: falls have their own model.

Measured with ``benchmarks/bench_restarts.py`` (docs in its docstring).
"""
from dataclasses import dataclass

import numpy as np

from sela_ros.core.validation import check_number


@dataclass(frozen=True)
class EvidenceConfig:
    """``adaptation.evidence.*``: what a restart of learning needs."""

    window: int = 8  # latest observations weighed against those before them
    min_gaits: int = 3  # distinct learnt gaits far off, at least
    share: float = 0.5  # of the learnt gaits of the window, at least
    threshold: float = 0.25  # m: far off means more than this ...
    sigmas: float = 3.0  # ... and more than this many predictive standard deviations
    noise: float = 0.1  # m: the least spread of a gait's outcomes (chained starts)
    max_sigma: float = 0.1  # a gait is learnt when its predictive std is at most this

    def __post_init__(self):
        check_number('adaptation.evidence.window', self.window, low=1, integer=True)
        check_number('adaptation.evidence.min_gaits', self.min_gaits, low=1, integer=True)
        check_number('adaptation.evidence.share', self.share, low=0.0, high=1.0)
        for name in ('threshold', 'sigmas', 'noise', 'max_sigma'):
            check_number(f'adaptation.evidence.{name}', getattr(self, name), low=0.0)


@dataclass(frozen=True)
class Evidence:
    """What :func:`change_evidence` found."""

    changed: bool
    learnt: int  # distinct learnt gaits in the window
    far_off: int  # of them, far from what was learned
    first: int | None  # position (in all observations) of the first far-off one
    noise: float  # m: the spread used (the robot's repeated gaits, at least ``noise``)
    errors: tuple = ()  # (index, error m, allowed m) of each learnt observation weighed

    def describe(self):
        return (f'{self.far_off} of {self.learnt} learnt gait(s) of the latest steps far from '
                f'what they did (noise {self.noise:.3f} m)')


def repeat_spread(indices, observed):
    """Pooled standard deviation (m, per coordinate of x and y) of the outcomes of gaits
    observed more than once; 0 when none was."""
    indices = np.asarray(indices, dtype=int)
    if not len(indices):
        return 0.0
    observed = np.asarray(observed, dtype=float).reshape(len(indices), -1)[:, :2]
    total, dof = 0.0, 0
    for index in np.unique(indices):
        group = observed[indices == index]
        if len(group) > 1:
            total += float(np.sum((group - group.mean(axis=0)) ** 2))
            dof += 2 * (len(group) - 1)
    return float(np.sqrt(total / dof)) if dof else 0.0


def _posterior(candidates, prior, train, targets, query, sigma, variance, noise):
    """GP posterior mean ``(q, 2)`` and variance ``(q,)`` of candidates ``query`` given the
    observations ``targets`` of candidates ``train`` (exponential kernel, as SELA's)."""
    def kernel(a, b):
        xa, xb = candidates[a], candidates[b]
        sq = np.sum(xa * xa, 1)[:, None] + np.sum(xb * xb, 1)[None, :] - 2.0 * xa @ xb.T
        return variance * np.exp(-0.5 * np.maximum(sq, 0.0) / (sigma * sigma))
    k_tt = kernel(train, train) + noise * np.eye(len(train))
    k_qt = kernel(query, train)
    chol = np.linalg.cholesky(k_tt)
    alpha = np.linalg.solve(chol.T, np.linalg.solve(chol, targets - prior[train]))
    v = np.linalg.solve(chol, k_qt.T)
    mean = prior[query] + k_qt @ alpha
    var = np.maximum(variance - np.sum(v * v, axis=0), 0.0)
    return mean, var


def change_evidence(candidates, prior, indices, observed, sigma, variance, noise,
                    config=None):
    """Does the latest window of observations say that the robot changed?

    Args:
        candidates: ``(M, d)`` normalised behaviour descriptors (SELA's GP inputs).
        prior: ``(M, k)`` the GPs' prior mean (the archive's generic rewards).
        indices, observed: every observation told, oldest first (``SELA.observations``).
        sigma, variance, noise: SELA's kernel length, kernel variance and GP noise.
        config: :class:`EvidenceConfig`.

    Returns:
        :class:`Evidence`.
    """
    config = config or EvidenceConfig()
    candidates = np.asarray(candidates, dtype=float)
    prior = np.asarray(prior, dtype=float)[:, :2]
    indices = np.asarray(indices, dtype=int)
    observed = np.asarray(observed, dtype=float).reshape(len(indices), -1)[:, :2]
    # A fall learnt as no displacement (reset_on_fall) is exactly zero; nothing else is.
    usable = np.any(observed != 0.0, axis=1)
    split = len(indices) - config.window
    earlier = np.flatnonzero(usable[:max(split, 0)])
    spread = max(config.noise, repeat_spread(indices[earlier], observed[earlier]))
    if split <= 0 or not len(earlier):
        return Evidence(False, 0, 0, None, spread)
    recent = split + np.flatnonzero(usable[split:])
    if not len(recent):
        return Evidence(False, 0, 0, None, spread)
    mean, var = _posterior(candidates, prior, indices[earlier], observed[earlier],
                           indices[recent], sigma, variance, noise)
    learnt = np.sqrt(var) <= config.max_sigma
    errors = np.linalg.norm(observed[recent] - mean, axis=1)
    allowed = np.maximum(config.threshold, config.sigmas * np.sqrt(var + spread ** 2))
    far = learnt & (errors > allowed)
    learnt_gaits = set(indices[recent][learnt].tolist())
    far_gaits = set(indices[recent][far].tolist())
    changed = (len(far_gaits) >= config.min_gaits
               and len(far_gaits) >= config.share * len(learnt_gaits))
    first = int(recent[far][0]) if far.any() else None
    weighed = tuple((int(i), float(e), float(a)) for i, e, a, k in
                    zip(indices[recent], errors, allowed, learnt) if k)
    return Evidence(bool(changed), len(learnt_gaits), len(far_gaits), first, spread, weighed)
