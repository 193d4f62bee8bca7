"""GP over the archive: closed-form posterior, incremental == batch, input checks."""
import numpy as np
import pytest

from sela_ros.core.learning import CandidateSetGP, exponential_kernel


def closed_form(X, Y, Xs, prior, sigma=0.1, variance=1.0, noise=0.001):
    K = exponential_kernel(X, X, sigma, variance) + noise * np.eye(len(X))
    Ks = exponential_kernel(X, Xs, sigma, variance)
    mu = prior(Xs) + Ks.T @ np.linalg.solve(K, Y - prior(X))
    var = variance - np.sum(Ks * np.linalg.solve(K, Ks), axis=0)
    return mu, var


def prior(X):
    return np.stack([np.sin(3 * X[:, 0]), X.sum(axis=1)], axis=1)


def test_kernel_values():
    k = exponential_kernel([[0.0, 0.0]], [[0.1, 0.0], [0.0, 0.0]], sigma=0.1, variance=2.0)
    assert k[0, 0] == pytest.approx(2.0 * np.exp(-0.5))
    assert k[0, 1] == pytest.approx(2.0)


def test_posterior_matches_closed_form():
    rng = np.random.default_rng(1)
    X, Xs = rng.random((12, 2)), rng.random((50, 2))
    Y = rng.normal(size=(12, 2))
    C = np.vstack([X, Xs])  # the observed inputs are candidates too
    gp = CandidateSetGP(C, prior(C), sigma=0.3)
    for i, y in enumerate(Y):
        gp.add_sample(i, y)
    mu, var = gp.query()
    mu_ref, var_ref = closed_form(X, Y, Xs, prior, sigma=0.3)
    np.testing.assert_allclose(mu[len(X):], mu_ref, atol=1e-9)
    np.testing.assert_allclose(var[len(X):], var_ref, atol=1e-9)


def test_prior_only_without_samples():
    Xs = np.random.default_rng(0).random((5, 2))
    mu, var = CandidateSetGP(Xs, prior(Xs)).query()
    np.testing.assert_allclose(mu, prior(Xs))
    np.testing.assert_allclose(var, 1.0)


def test_candidate_cache_matches_closed_form_incrementally():
    rng = np.random.default_rng(2)
    C = rng.random((300, 3))
    P = prior(C)
    cache = CandidateSetGP(C, P, sigma=0.2)
    idx = rng.integers(0, 300, size=20)
    idx[5] = idx[4]  # a repeated input: fine thanks to the noise
    Y = rng.normal(size=(20, 2))
    for n, (i, y) in enumerate(zip(idx, Y), start=1):
        cache.add_sample(i, y)
        if n in (1, 7, 20):  # incremental == batch at every stage (crosses a regrowth)
            mu_ref, var_ref = closed_form(C[idx[:n]], Y[:n], C, prior, sigma=0.2)
            mu, var = cache.query()
            np.testing.assert_allclose(mu, mu_ref, atol=1e-9)
            np.testing.assert_allclose(var, var_ref, atol=1e-9)
    assert cache.indices == [int(i) for i in idx]


def test_fit_at_once_is_what_the_samples_one_by_one_give_and_it_grows_on():
    rng = np.random.default_rng(3)
    C = rng.random((300, 3))
    P = prior(C)
    idx = rng.integers(0, 300, size=40)
    idx[5] = idx[4]
    Y = rng.normal(size=(40, 2))
    one_by_one, at_once = CandidateSetGP(C, P, sigma=0.2), CandidateSetGP(C, P, sigma=0.2)
    for i, y in zip(idx[:30], Y[:30]):
        one_by_one.add_sample(i, y)
    at_once.fit(idx[:30], Y[:30])
    for i, y in zip(idx[30:], Y[30:]):  # and samples after the fit, past a regrowth
        one_by_one.add_sample(i, y)
        at_once.add_sample(i, y)
    mu_ref, var_ref = closed_form(C[idx], Y, C, prior, sigma=0.2)
    for gp in (one_by_one, at_once):
        mu, var = gp.query()
        np.testing.assert_allclose(mu, mu_ref, atol=1e-9)
        np.testing.assert_allclose(var, var_ref, atol=1e-9)
    assert at_once.indices == [int(i) for i in idx]
    np.testing.assert_allclose(at_once.observed, Y)
    with pytest.raises(ValueError, match='no observation yet'):
        at_once.fit(idx[:2], Y[:2])


def test_observation_reduces_variance_at_that_point():
    cache = CandidateSetGP(np.linspace(0, 1, 11)[:, None], np.zeros((11, 1)))
    cache.add_sample(5, [1.0])
    mu, var = cache.query()
    assert var[5] < 0.01 and var[0] == pytest.approx(1.0)
    assert mu[5, 0] == pytest.approx(1.0 / 1.001)


@pytest.mark.parametrize('bad', [
    lambda: CandidateSetGP(np.zeros((0, 2)), np.zeros((0, 2))),
    lambda: CandidateSetGP(np.zeros((2, 2)), np.zeros((2, 2)), sigma=0.0),
    lambda: CandidateSetGP(np.zeros((2, 2)), np.zeros((2, 2)), noise=float('nan')),
    lambda: CandidateSetGP(np.zeros(5), np.zeros((5, 2))),
    lambda: CandidateSetGP(np.zeros((5, 1)), np.zeros((4, 2))),
    lambda: CandidateSetGP(np.full((5, 1), np.nan), np.zeros((5, 2))),
])
def test_constructors_fail_fast(bad):
    with pytest.raises(ValueError):
        bad()


def test_add_sample_checks():
    cache = CandidateSetGP(np.zeros((3, 1)), np.zeros((3, 2)))
    with pytest.raises(ValueError, match='nan; expected finite'):
        cache.add_sample(0, [np.nan, 0.0])
    with pytest.raises(ValueError, match='index'):
        cache.add_sample(3, [0.0, 0.0])
    with pytest.raises(ValueError, match='shape'):
        cache.add_sample(0, [0.0])
