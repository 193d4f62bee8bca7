"""A prior mean mixed from the damage priors' tables, fitted to the steps seen.

A damage nobody foresaw is rarely one of the tables (:mod:`sela_ros.core.learning.damage_priors`),
but it is often close to a mixture of them: two legs removed move the robot roughly as the
two single-leg tables' deviations from the intact map added up, a shortened leg as part of
that leg's removal. So instead of picking one table, the prior mean is

    m(x) = intact(x) + sum_k w_k (table_k(x) - intact(x)),

with the weights ``w`` fitted to the observed generic rewards by Bayesian linear regression
(a Gaussian prior on ``w`` truncated at 0, its posterior mode by NNLS: a damage never
undoes another; Gaussian errors of :data:`~sela_ros.core.learning.damage_priors.
RESIDUAL_SCALE` per step: what a gait chained from the last one differs from the same gait
from a standing start; not the GP's noise, which is the spread of one gait repeated from the
same posture and would make the weights chase every chaining error). Without the
truncation this is a GP kernel learnt from the library, ``k_w(x, y) = sum_k s^2 d_k(x)
d_k(y)``, added to the exponential one, with the steps taken as independent; the GPs'
posterior mean is the mixture's mean plus their usual correction near the gaits tried.
As :meth:`DamagePriors.select` does, the fit ignores gaits that fell
(their displacement is the tumble's), counts steps from a standing start (the tables' own
experiment) :data:`~sela_ros.core.learning.damage_priors.STANDING_PRECISION` times more precisely,
and is robust to a share of chained steps far off any prior (a few reweighting passes of the
same two-component error model).

The errors' variance is learnt too (never below the chaining error's): the tables mixed
rarely explain a damage none of them holds to 0.1 m, and weights fitted as if they did chase
every error. And the mixture is averaged with the intact map by their evidence (Bayesian model
averaging: the marginal likelihood of the regression against that of all weights zero), so
that weights the steps barely support count for little: on a single leg whose own table is
left out the other legs' tables predict the untried gaits no better than the intact map
(docs/priors_combination.md).

The weights also mix the tables' falls: a gait's prior risk is the chance that any damage in
the mixture makes it fall, each table counted with its weight clipped to [0, 1] (a noisy OR:
``1 - prod_k (1 - c_k fallen_k)``), so two legs removed fear the falls of both tables and a
shortened leg part of its removal's.

SELA (:meth:`~sela_ros.core.learning.SELA.select_prior`) uses the mixture only while no table
reproduced the robot's standing starts, and only while it has predicted the steps, each
before it was learnt, better than the one-table choice (a prequential score: the fit alone
always prefers K weights to one table). :func:`step_log_likelihood` is that score's term.

ROS-free; numpy and scipy only. One fit (20 steps, the six shipped tables) takes 1.1-1.4 ms
and the mixed mean and falls 0.5-0.6 ms on the shipped map (measured on this machine under
load).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import cholesky, solve_triangular
from scipy.optimize import nnls

from sela_ros.core.learning.damage_priors import (
    OUTLIER_FRACTION,
    OUTLIER_SCALE,
    RESIDUAL_SCALE,
    STANDING_PRECISION,
)

#: Prior standard deviation of each table's weight (``priors.weights.sd``): 1 lets one step
#: set a weight anywhere between none and the whole table; 0 turns the mixture off.
DEFAULT_WEIGHT_SD = 1.0
#: Reweighting passes of the robust fit (the errors' two-component model and their variance).
ROBUST_PASSES = 4
#: Rows of error variance 1 (the chaining error) assumed before any step, in the estimate of
#: the errors' variance.
NOISE_PSEUDO_ROWS = 3.0


@dataclass(frozen=True)
class Mixture:
    """A fitted mixture of damage tables.

    Attributes:
        weights: ``(K,)`` posterior mean of each table's weight.
        covariance: ``(K, K)`` their posterior covariance.
        misfit: median squared error per output of the fitted mean over the steps used
            (units of RESIDUAL_SCALE), as :meth:`DamagePriors.select` reports a table's.
        steps: how many steps the fit used (fallen gaits left out).
        probability: the posterior probability of the mixture against the intact map; the
            ``weights`` are the fitted ones times this (the two models averaged).
        noise: the errors' variance learnt, in units of the chaining error's (>= 1).
    """

    weights: np.ndarray
    covariance: np.ndarray
    misfit: float
    steps: int
    probability: float = 1.0
    noise: float = 1.0

    def mean(self, base_gr, tables) -> np.ndarray:
        """``(M, k)`` the mixed prior mean: ``base + sum_k w_k (tables[k] - base)``.

        ``base_gr``: ``(M, k)`` the intact map; ``tables``: ``(K, M, >= k)``."""
        base_gr = np.asarray(base_gr, dtype=float)
        k = base_gr.shape[1]
        w = self.weights
        used = np.flatnonzero(w)  # the weights' fit is sparse: most tables weigh nothing
        mixed = np.tensordot(w[used], np.asarray(tables)[used, :, :k], axes=1) if used.size \
            else np.zeros_like(base_gr)
        mixed += (1.0 - float(w.sum())) * base_gr
        return mixed

    def fall_rates(self, fallen) -> np.ndarray:
        """``(M,)`` the prior risk of each gait: a noisy OR of the tables' falls ``(K, M)``,
        each weighed by its weight clipped to [0, 1]."""
        fallen = np.asarray(fallen, dtype=bool)
        c = np.clip(self.weights, 0.0, 1.0)
        used = np.flatnonzero(c > 0)
        if not used.size:
            return np.zeros(fallen.shape[1])
        # prod_k (1 - c_k f_k) as one product over the tables used: a table of weight 1
        # stands for no gait it tips over.
        sure = c[used] >= 1.0
        stand = np.exp(np.log1p(-np.where(sure, 0.0, c[used])) @ fallen[used])
        if sure.any():
            stand[fallen[used[sure]].any(axis=0)] = 0.0
        return 1.0 - stand


def fit_mixture(base_gr, tables, indices, observed, fall_indices=(), fallen=(), standing=(),
                weight_sd=DEFAULT_WEIGHT_SD, prior_weights=None,
                nonnegative=True) -> Mixture:
    """The weights of the tables that best explain the steps seen (Bayesian regression).

    Args:
        base_gr: ``(M, k)`` the intact map's generic rewards.
        tables: ``(K, M, >= k)`` the damage priors' generic rewards.
        indices, observed: the gaits learnt ``(N,)`` and their generic rewards ``(N, k)``.
        fall_indices, fallen: every step's gait and whether it fell; gaits seen falling are
            left out of the fit.
        standing: ``(N,)`` which learnt steps started standing (empty: none).
        weight_sd: prior standard deviation of each weight (> 0).
        prior_weights: ``(K,)`` prior mean of the weights; None: zeros (the intact map).
        nonnegative: weights >= 0 (a truncated normal prior; the weights are its posterior
            mode): a damage never undoes another, and a negative weight predicts gaits
            better than on the intact robot.

    Raises:
        ValueError: shapes that do not match, indices outside the map, values not finite,
            a ``weight_sd`` that is not a positive number.
    """
    base_gr = np.asarray(base_gr, dtype=float)
    tables = np.asarray(tables)
    if base_gr.ndim != 2:
        raise ValueError(f'base_gr must have shape (M, k), got {base_gr.shape}')
    m, k = base_gr.shape
    if tables.ndim != 3 or tables.shape[1] != m or tables.shape[2] < k:
        raise ValueError(f'tables must have shape (K, {m}, >= {k}), got {tables.shape}')
    n_tables = tables.shape[0]
    if not (np.isfinite(weight_sd) and weight_sd > 0):
        raise ValueError(f'weight_sd must be a positive number, got {weight_sd!r}')
    prior = np.zeros(n_tables) if prior_weights is None else \
        np.asarray(prior_weights, dtype=float).reshape(-1)
    if prior.shape != (n_tables,) or not np.all(np.isfinite(prior)):
        raise ValueError(f'prior_weights must be {n_tables} finite numbers, got {prior!r}')
    indices = np.asarray(indices).reshape(-1)
    if indices.size and (not np.issubdtype(indices.dtype, np.integer)
                         or indices.min() < 0 or indices.max() >= m):
        raise ValueError(f'indices must be integers in [0, {m}), got {indices!r}')
    observed = np.asarray(observed, dtype=float)
    if observed.shape != (indices.size, k):
        raise ValueError(f'observed must have shape ({indices.size}, {k}), got '
                         f'{observed.shape}')
    if not np.all(np.isfinite(observed)):
        raise ValueError('observed generic rewards must be finite')
    standing = np.asarray(standing, dtype=bool).reshape(-1)
    if standing.size not in (0, indices.size):
        raise ValueError(f'standing has {standing.size} flags for {indices.size} steps')
    fall_indices = np.asarray(fall_indices, dtype=int).reshape(-1)
    fallen = np.asarray(fallen, dtype=bool).reshape(-1)
    if fallen.shape != fall_indices.shape:
        raise ValueError(f'{fall_indices.size} fall indices but {fallen.size} fallen flags')

    keep = ~np.isin(indices, fall_indices[fallen])
    seen = indices[keep].astype(int)
    precision_w = np.full(n_tables, 1.0 / weight_sd ** 2)
    if not seen.size:
        return Mixture(prior.copy(), np.diag(1.0 / precision_w), 0.0, 0)
    scale = RESIDUAL_SCALE[:k] if k <= RESIDUAL_SCALE.size else np.full(k, 0.1)
    base = base_gr[seen]
    # Rows: one per step and output, in units of the chaining error.
    target = ((observed[keep] - base) / scale).reshape(-1)
    design = ((tables[:, seen, :k] - base[None]) / scale).reshape(n_tables, -1).T
    step_precision = (np.where(standing[keep], STANDING_PRECISION ** 2, 1.0)
                      if standing.size else np.ones(seen.size))
    wide = OUTLIER_SCALE ** 2
    robust = np.ones(seen.size)
    tau2 = 1.0  # the errors' variance, in units of the chaining error's
    for _ in range(ROBUST_PASSES):
        row_w = np.repeat(step_precision * robust, k) / tau2
        a = design.T @ (design * row_w[:, None]) + np.diag(precision_w)
        b = design.T @ (target * row_w) + precision_w * prior
        cov = np.linalg.inv(a)
        w = _nonnegative_solve(a, b) if nonnegative else cov @ b
        res2 = (target - design @ w) ** 2
        q = res2.reshape(seen.size, k).sum(axis=1) * step_precision
        # The tables mixed rarely explain a damage they do not hold to the chaining error:
        # the errors' variance is learnt (inverse-gamma, NOISE_PSEUDO_ROWS rows at 1), never
        # below 1, so that a poor fit does not make its weights look sure.
        tau2 = max(1.0, (NOISE_PSEUDO_ROWS + float(row_w @ res2) * tau2)
                   / (NOISE_PSEUDO_ROWS + row_w.size))
        # Responsibility of the "explained" component of each step's error, and the
        # precision the step gets: its mean over the two components.
        qt = q / tau2
        log_in = np.log1p(-OUTLIER_FRACTION) - 0.5 * qt
        log_out = np.log(OUTLIER_FRACTION) - 0.5 * k * np.log(wide) - 0.5 * qt / wide
        resp = np.exp(log_in - np.logaddexp(log_in, log_out))
        robust = resp + (1.0 - resp) / wide
    # Bayesian model averaging of the mixture with the intact map (all weights 0): the
    # mixture's evidence against the map's (a Gaussian linear model's marginal likelihood
    # ratio, its K weights paid for by the log-determinant), equal prior odds.
    # At the (constrained) mode, by Laplace's approximation over the weights not at zero;
    # a half-normal prior is twice as dense as the normal one.
    b0 = design.T @ (target * row_w)
    active = w > 0 if nonnegative else np.ones(n_tables, bool)
    aa = a[np.ix_(active, active)] / precision_w[active]
    log_bf = float(b0 @ w - 0.5 * w @ (a @ w)) - 0.5 * float(np.linalg.slogdet(aa)[1]) \
        + (np.log(2.0) * int(active.sum()) if nonnegative else 0.0)
    if prior_weights is not None:
        log_bf = np.inf  # the prior's own weights: no comparison with the intact map
    probability = 1.0 / (1.0 + np.exp(-min(log_bf, 700.0)))
    r = ((target - design @ w) ** 2).reshape(seen.size, k).sum(axis=1)
    misfit = float(np.sort(r)[(r.size - 1) // 2] / k)
    return Mixture(probability * w, 0.5 * (cov + cov.T), misfit, int(seen.size),
                   float(probability), float(tau2))


def _nonnegative_solve(a, b):
    """``argmin 0.5 w^T a w - b^T w`` over ``w >= 0`` (a positive definite): NNLS on the
    Cholesky factor, ``||R w - R^-T b||^2``."""
    upper = cholesky(a, lower=False)
    return nnls(upper, solve_triangular(upper, b, trans='T'))[0]


def step_log_likelihood(residual, standing=False) -> float:
    """Log-likelihood of one step's prediction error ``(k,)`` under the damage priors' error
    model (:meth:`DamagePriors.select`'s): Gaussian of RESIDUAL_SCALE (STANDING_PRECISION
    times narrower from a standing start), robust to a share of steps far off."""
    residual = np.asarray(residual, dtype=float).reshape(-1)
    k = residual.size
    scale = RESIDUAL_SCALE[:k] if k <= RESIDUAL_SCALE.size else np.full(k, 0.1)
    q = float(np.sum((residual / scale) ** 2)) * (STANDING_PRECISION ** 2 if standing else 1.0)
    wide = OUTLIER_SCALE ** 2
    return float(np.logaddexp(np.log1p(-OUTLIER_FRACTION) - 0.5 * q,
                              np.log(OUTLIER_FRACTION) - 0.5 * k * np.log(wide)
                              - 0.5 * q / wide))

