"""Gaussian processes for SELA: exponential kernel, multi-output GP, candidate-set cache.

The kernel follows limbo's ``Exp`` kernel, ``k(x, y) = variance * exp(-0.5 ||x - y||^2 /
sigma^2)``, over inputs normalised to ``[0, 1]^d``. Means follow M-BOA: the GP models the
difference between the observations and a prior mean (the archive's prediction).
"""
from __future__ import annotations

import numpy as np
from scipy.linalg import cholesky, solve_triangular

from sela_ros.core.validation import check_number, finite_array

DEFAULT_SIGMA = 0.1
DEFAULT_VARIANCE = 1.0
DEFAULT_NOISE = 0.001
#: The kernel lengths (on normalised descriptors) a GP is given: a shorter one underflows.
MIN_SIGMA, MAX_SIGMA = 1e-3, 100.0


def exponential_kernel(a, b, sigma=DEFAULT_SIGMA, variance=DEFAULT_VARIANCE):
    """Exponential kernel matrix between the rows of ``a`` (n, d) and ``b`` (m, d).

    Returns:
        ``(n, m)`` array of ``variance * exp(-0.5 * ||a_i - b_j||^2 / sigma^2)``.
    """
    a = np.atleast_2d(np.asarray(a, dtype=float))
    b = np.atleast_2d(np.asarray(b, dtype=float))
    sq = (np.sum(a * a, axis=1)[:, None] + np.sum(b * b, axis=1)[None, :] - 2.0 * a @ b.T)
    np.maximum(sq, 0.0, out=sq)
    return variance * np.exp(-0.5 * sq / (sigma * sigma))


def _check_hyper(sigma, variance, noise):
    check_number('kernel sigma', float(sigma), low=0.0, low_open=True)
    check_number('kernel variance', float(variance), low=0.0, low_open=True)
    check_number('GP noise', float(noise), low=0.0)


def _check_finite(name, array):
    finite_array(array, name)


class _GrowingCholesky:
    """Lower Cholesky factor L of K + noise I, grown one row at a time (rank-one extension).

    Also keeps ``beta = L^{-1} (Y - prior(X))``: appending a row to L appends one row to
    beta (forward substitution) and leaves the earlier rows unchanged.
    """

    def __init__(self, output_dim, capacity=32):
        self.n = 0
        self._L = np.zeros((capacity, capacity))
        self._beta = np.zeros((capacity, output_dim))

    @property
    def L(self):
        return self._L[:self.n, :self.n]

    @property
    def beta(self):
        return self._beta[:self.n]

    def _grow(self):
        cap = 2 * self._L.shape[0]
        L = np.zeros((cap, cap))
        L[:self.n, :self.n] = self.L
        beta = np.zeros((cap, self._beta.shape[1]))
        beta[:self.n] = self.beta
        self._L, self._beta = L, beta

    def append(self, k_vec, k_self, residual):
        """Append one observation; returns the new row ``(l, d)`` of L (l: (n,), d scalar)."""
        if self.n == self._L.shape[0]:
            self._grow()
        n = self.n
        if n:
            row = solve_triangular(self.L, k_vec, lower=True, check_finite=False)
        else:
            row = np.zeros(0)
        d2 = k_self - float(row @ row)
        if d2 <= 1e-12:
            raise ValueError(
                'GP covariance is no longer positive definite (duplicate input with zero '
                'noise?); use a noise > 0')
        d = np.sqrt(d2)
        self._L[n, :n] = row
        self._L[n, n] = d
        self._beta[n] = (residual - row @ self.beta) / d
        self.n = n + 1
        return row, d


class CandidateSetGP:
    """A multi-output GP restricted to a FIXED set of M candidate inputs (the archive).

    Keeps, for every candidate, the rows ``V = L^{-1} k(X_obs, X*)`` (N, M) plus the
    posterior mean (M, D) and variance (M,) up to date. A new observation appends one
    row of V: O(M N) work and memory per observation; reading the posterior of all M
    candidates is then O(M D) (no triangular solve at query time). All outputs are observed
    at the same inputs with the same kernel and noise, so they share ONE Cholesky factor and
    differ only in their targets; a sample extends it by one row, never refactorises it.

    Args:
        candidates: ``(M, d)`` inputs, normalised to ``[0, 1]^d``.
        prior_mean: ``(M, D)`` prior mean value per candidate (the archive's GR).
        sigma, variance, noise: kernel and noise parameters.
    """

    def __init__(self, candidates, prior_mean, sigma: float = DEFAULT_SIGMA,
                 variance: float = DEFAULT_VARIANCE, noise: float = DEFAULT_NOISE):
        candidates = np.asarray(candidates, dtype=float)
        prior_mean = np.asarray(prior_mean, dtype=float)
        if candidates.ndim != 2 or candidates.shape[0] < 1:
            raise ValueError(f'candidates must have shape (M, d), got {candidates.shape}')
        if prior_mean.ndim == 1:
            prior_mean = prior_mean[:, None]
        if prior_mean.ndim != 2 or prior_mean.shape[0] != candidates.shape[0]:
            raise ValueError(
                f'prior_mean must have shape ({candidates.shape[0]}, D) to match the '
                f'candidates, got {prior_mean.shape}')
        _check_finite('candidates', candidates)
        _check_finite('prior_mean', prior_mean)
        _check_hyper(sigma, variance, noise)
        self.sigma, self.variance, self.noise = float(sigma), float(variance), float(noise)
        self.candidates = candidates
        self.prior = prior_mean
        self._sq_norms = np.sum(candidates * candidates, axis=1)
        self._chol = _GrowingCholesky(prior_mean.shape[1])
        self._V = np.zeros((8, candidates.shape[0]))
        # Outputs stored as rows (D, M): per-output updates are contiguous axpy's, much
        # faster than broadcasting over an (M, D) array with a small D.
        self._mu_t = np.ascontiguousarray(prior_mean.T)
        self._var = np.full(candidates.shape[0], self.variance)
        self._indices: list[int] = []
        self._Y: list[np.ndarray] = []

    @property
    def num_candidates(self) -> int:
        return self.candidates.shape[0]

    @property
    def output_dim(self) -> int:
        return self.prior.shape[1]

    @property
    def num_samples(self) -> int:
        return self._chol.n

    @property
    def indices(self) -> list:
        return list(self._indices)

    @property
    def observed(self) -> np.ndarray:
        return np.array(self._Y).reshape(-1, self.output_dim)

    def _kernel_row(self, index):
        x = self.candidates[index]
        sq = self._sq_norms + self._sq_norms[index] - 2.0 * (self.candidates @ x)
        np.maximum(sq, 0.0, out=sq)
        return self.variance * np.exp((-0.5 / (self.sigma * self.sigma)) * sq)

    def _sq_rows(self, idx):
        """``(N, M)`` squared distances of the candidates ``idx`` to every candidate."""
        sq = self._sq_norms[idx][:, None] + self._sq_norms[None, :] \
            - 2.0 * (self.candidates[idx] @ self.candidates.T)
        np.maximum(sq, 0.0, out=sq)
        return sq

    @property
    def sq_distances(self) -> np.ndarray:
        """``(N, N)`` squared distances between the observed inputs."""
        x = self.candidates[self._indices]
        norms = self._sq_norms[self._indices]
        return np.maximum(norms[:, None] + norms[None, :] - 2.0 * (x @ x.T), 0.0)

    def add_sample(self, index: int, y) -> None:
        """Add the observation ``y`` (D,) of candidate ``index``; O(M N)."""
        if isinstance(index, (bool, np.bool_)) or not isinstance(index, (int, np.integer)):
            raise ValueError(f'index must be an integer, got {index!r}')
        index = int(index)
        if not 0 <= index < self.num_candidates:
            raise ValueError(f'index must be in [0, {self.num_candidates}), got {index}')
        y = np.asarray(y, dtype=float).reshape(-1)
        if y.shape != (self.output_dim,):
            raise ValueError(f'y must have shape ({self.output_dim},), got {y.shape}')
        _check_finite('y', y)
        n = self._chol.n
        krow = self._kernel_row(index)
        k_vec = krow[self._indices] if n else np.zeros(0)
        row, d = self._chol.append(k_vec, self.variance + self.noise, y - self.prior[index])
        if n == self._V.shape[0]:
            V = np.zeros((2 * n, self.num_candidates))
            V[:n] = self._V[:n]
            self._V = V
        v = krow - row @ self._V[:n] if n else krow
        v /= d
        self._V[n] = v
        for j, b in enumerate(self._chol.beta[n]):
            self._mu_t[j] += b * v
        self._var -= v * v
        self._indices.append(index)
        self._Y.append(y)

    def fit(self, indices, ys) -> None:
        """Learn the observations ``ys`` (N, D) of candidates ``indices`` into an empty GP, as
        N :meth:`add_sample` calls would, in matrix products: one Cholesky factorisation and
        one triangular solve over the archive instead of N passes over it (a state file of
        many observations is taken back in a fraction of the time)."""
        if self.num_samples:
            raise ValueError('fit is for a GP with no observation yet')
        idx = np.asarray([int(i) for i in indices], dtype=int)
        if np.any((idx < 0) | (idx >= self.num_candidates)):
            raise ValueError(f'indices must be in [0, {self.num_candidates})')
        ys = np.asarray(ys, dtype=float).reshape(len(idx), self.output_dim)
        _check_finite('y', ys)
        if not len(idx):
            return
        self._factorise(idx, ys, self._sq_rows(idx))

    def set_hyper(self, sigma: float, variance: float) -> None:
        """Go on with the kernel length ``sigma`` and signal variance ``variance``: the
        observations are learnt again under them, as a GP built with them would have learnt
        them (one Cholesky factorisation and one triangular solve over the archive,
        O(M N^2))."""
        _check_hyper(sigma, variance, self.noise)
        sigma, variance = float(sigma), float(variance)
        if sigma == self.sigma and variance == self.variance:
            return
        self.sigma, self.variance = sigma, variance
        n = self.num_samples
        if not n:
            self._var = np.full(self.num_candidates, self.variance)
            return
        idx = np.asarray(self._indices, dtype=int)
        self._factorise(idx, np.array(self._Y), self._sq_rows(idx))

    def _factorise(self, idx, ys, sq):
        """Learn ``ys`` (N, D) at ``idx`` from scratch, ``sq`` (N, M) their squared
        distances to every candidate (overwritten)."""
        n = len(idx)
        k = np.exp((-0.5 / (self.sigma * self.sigma)) * sq, out=sq)
        k *= self.variance  # (N, M): k(X_obs, X*)
        k_nn = k[:, idx] + self.noise * np.eye(n)
        try:
            low = cholesky(k_nn, lower=True, check_finite=False)
        except np.linalg.LinAlgError as exc:
            raise ValueError('GP covariance is not positive definite (duplicate input with '
                             'zero noise?); use a noise > 0') from exc
        beta = solve_triangular(low, ys - self.prior[idx], lower=True, check_finite=False)
        v = solve_triangular(low, k, lower=True, check_finite=False, overwrite_b=True)
        chol = _GrowingCholesky(self.output_dim, capacity=max(32, 2 * n))
        chol._L[:n, :n], chol._beta[:n], chol.n = low, beta, n
        self._chol, self._V = chol, v
        self._mu_t = np.ascontiguousarray(self.prior.T + beta.T @ v)
        self._var = self.variance - np.einsum('ij,ij->j', v, v)
        self._indices = idx.tolist()
        self._Y = list(ys)

    def query(self):
        """Posterior of all candidates: ``(mu (M, D), var (M,))`` (views: do not modify)."""
        np.maximum(self._var, 0.0, out=self._var)
        return self._mu_t.T, self._var

    def query_columns(self):
        """Like :meth:`query` with the means as rows, ``(mu (D, M), var (M,))``: the
        layout to use for fast per-output arithmetic over a large archive."""
        np.maximum(self._var, 0.0, out=self._var)
        return self._mu_t, self._var

    def mean_columns_with_prior(self, prior_mean) -> np.ndarray:
        """The posterior mean ``(D, M)`` the same observations give under another prior
        mean ``(M, D)`` (the variance does not depend on it): ``m + V^T L^-1 (Y - m(X))``,
        O(M N D), nothing refactorised."""
        prior_mean = np.asarray(prior_mean, dtype=float)
        if prior_mean.shape != self.prior.shape:
            raise ValueError(f'prior_mean must have shape {self.prior.shape}, got '
                             f'{prior_mean.shape}')
        n = self._chol.n
        if not n:
            return np.ascontiguousarray(prior_mean.T)
        residual = self.observed - prior_mean[self._indices]
        beta = solve_triangular(self._chol.L, residual, lower=True, check_finite=False)
        return prior_mean.T + beta.T @ self._V[:n]

    def mean_at_with_prior(self, index: int, prior_observed, prior_index) -> np.ndarray:
        """The posterior mean ``(D,)`` of candidate ``index`` under another prior mean, given
        only where it is needed: ``prior_observed`` ``(N, D)`` at the observed inputs (in
        :attr:`indices` order) and ``prior_index`` ``(D,)`` at ``index``; O(N^2 D)."""
        prior_index = np.asarray(prior_index, dtype=float).reshape(-1)
        n = self._chol.n
        if not n:
            return prior_index.copy()
        residual = self.observed - np.asarray(prior_observed, dtype=float).reshape(n, -1)
        beta = solve_triangular(self._chol.L, residual, lower=True, check_finite=False)
        return prior_index + beta.T @ self._V[:n, int(index)]

