"""GP kernel length and signal variance learnt from the steps (gp.hyper.sd)."""
import json

import numpy as np
import pytest

from sela_ros.core.learning import SELA, CandidateSetGP, SE2Motion, exponential_kernel, hyper
from sela_ros.core.learning.sela_config import SELAConfig

SIGMA0, VARIANCE0, NOISE = 0.3, 1.0, 0.001


def sq_distances(x):
    return np.sum((x[:, None, :] - x[None, :, :]) ** 2, axis=2)


def draw(rng, n, sigma, variance, outputs=3, dims=8):
    """``n`` inputs in [0, 1]^dims and residuals drawn from a GP of that kernel."""
    x = rng.random((n, dims))
    k = exponential_kernel(x, x, sigma, variance) + NOISE * np.eye(n)
    return x, np.linalg.cholesky(k) @ rng.normal(size=(n, outputs))


@pytest.mark.parametrize('seed', range(3))
def test_residuals_of_a_long_kernel_learn_a_long_length(seed):
    x, r = draw(np.random.default_rng(seed), 40, sigma=1.2, variance=0.1)
    sigma, variance = hyper.choose(sq_distances(x), r, NOISE, SIGMA0, VARIANCE0, sd=1.0)
    assert sigma >= 0.8 and variance < VARIANCE0


@pytest.mark.parametrize('seed', range(3))
def test_residuals_of_the_configured_kernel_keep_it(seed):
    x, r = draw(np.random.default_rng(seed), 40, sigma=SIGMA0, variance=VARIANCE0)
    assert hyper.choose(sq_distances(x), r, NOISE, SIGMA0, VARIANCE0, sd=1.0) == \
        (SIGMA0, VARIANCE0)


@pytest.mark.parametrize('seed', range(10))
@pytest.mark.parametrize('variance', [1.0, 0.1, 0.01])
def test_three_steps_leave_the_kernel_at_the_prior(seed, variance):
    """With the prior's log sd 0.5, three steps of a long kernel, whatever their scale, do
    not move it; ten do."""
    x, r = draw(np.random.default_rng(seed), 3, sigma=1.2, variance=variance)
    assert hyper.choose(sq_distances(x), r, NOISE, SIGMA0, VARIANCE0, sd=0.5) == \
        (SIGMA0, VARIANCE0)
    x, r = draw(np.random.default_rng(seed), 10, sigma=1.2, variance=variance)
    assert hyper.choose(sq_distances(x), r, NOISE, SIGMA0, VARIANCE0, sd=0.5)[0] > SIGMA0


def test_a_setting_in_use_is_kept_unless_another_beats_it_by_the_margin():
    x, r = draw(np.random.default_rng(7), 40, sigma=1.2, variance=0.1)
    sq = sq_distances(x)
    best = hyper.choose(sq, r, NOISE, SIGMA0, VARIANCE0, sd=1.0)
    scores = {s: hyper.score(sq, r, *s, NOISE, SIGMA0, VARIANCE0, 1.0)
              for s in hyper.grid(SIGMA0, VARIANCE0)}
    assert scores[best] == max(scores.values())
    near = max((s for s in scores if s != best), key=scores.get)
    gap = scores[best] - scores[near]
    assert hyper.choose(sq, r, NOISE, SIGMA0, VARIANCE0, 1.0, current=near,
                        margin=gap + 0.1) == near
    assert hyper.choose(sq, r, NOISE, SIGMA0, VARIANCE0, 1.0, current=near,
                        margin=gap - 0.1) == best


def test_the_marginal_likelihood_is_the_gaussian_density():
    x, r = draw(np.random.default_rng(2), 6, sigma=0.5, variance=0.3, outputs=2)
    k = exponential_kernel(x, x, 0.5, 0.3) + NOISE * np.eye(6)
    expected = sum(-0.5 * r[:, j] @ np.linalg.solve(k, r[:, j])
                   - 0.5 * np.linalg.slogdet(k)[1] - 3 * np.log(2 * np.pi) for j in range(2))
    assert hyper.log_marginal_likelihood(sq_distances(x), r, 0.5, 0.3, NOISE) == \
        pytest.approx(expected, rel=1e-10)


def test_gp_after_a_change_is_the_gp_built_with_the_new_values():
    rng = np.random.default_rng(3)
    candidates, prior = rng.random((200, 8)), rng.normal(size=(200, 3))
    steps = rng.choice(200, 15, replace=False)
    ys = rng.normal(size=(15, 3))
    changed = CandidateSetGP(candidates, prior, sigma=0.3, variance=1.0, noise=NOISE)
    for i, y in zip(steps[:10], ys[:10]):
        changed.add_sample(int(i), y)
    changed.set_hyper(0.8, 0.1)
    for i, y in zip(steps[10:], ys[10:]):  # and it grows on from there
        changed.add_sample(int(i), y)
    scratch = CandidateSetGP(candidates, prior, sigma=0.8, variance=0.1, noise=NOISE)
    for i, y in zip(steps, ys):
        scratch.add_sample(int(i), y)
    for a, b in zip(changed.query(), scratch.query()):
        np.testing.assert_allclose(a, b, atol=1e-9)
    other = rng.normal(size=(200, 3))
    np.testing.assert_allclose(changed.mean_columns_with_prior(other),
                               scratch.mean_columns_with_prior(other), atol=1e-9)
    np.testing.assert_allclose(changed.sq_distances, sq_distances(candidates[steps]),
                               atol=1e-12)
    with pytest.raises(ValueError, match='kernel sigma'):
        changed.set_hyper(0.0, 1.0)


def slow_robot(seed, hyper_sd):
    """A SELA on 8-D gaits whose robot does a third of what every gait did on the intact
    one, told 25 steps of random gaits."""
    rng = np.random.default_rng(seed)
    candidates = rng.random((600, 8))
    prior = np.column_stack([candidates[:, 0] - 0.5, candidates[:, 1] - 0.5,
                             candidates[:, 2] - 0.5])
    config = SELAConfig(gp_kernel_sigma=SIGMA0, gp_hyper_sd=hyper_sd, acquisition_caution=None)
    sela = SELA(candidates, prior, SE2Motion(), config=config, goal=(2.0, 2.0))
    tried = rng.choice(600, 25, replace=False)
    for i in tried:
        sela.tell(int(i), prior[i] / 3.0 + rng.normal(0.0, 0.01, 3))
    untried = np.setdiff1d(np.arange(600), tried)
    return sela, prior, untried


def test_a_robot_slow_everywhere_is_predicted_slow_on_the_gaits_it_has_not_tried():
    fixed, prior, untried = slow_robot(0, None)
    learnt, _, _ = slow_robot(0, 1.0)

    def error(sela):
        return np.sqrt(np.mean((sela.predict()[0][untried] - prior[untried] / 3.0) ** 2))

    assert fixed.hyper == (SIGMA0, VARIANCE0)
    assert error(learnt) < 0.5 * error(fixed)
    sigma, variance = learnt.hyper
    assert sigma > SIGMA0 and variance < VARIANCE0
    # The choice reads the posterior variance as a share of the configured signal variance.
    np.testing.assert_allclose(learnt.predict()[1] ** 2,
                               learnt.gp.query()[1] / variance * VARIANCE0, rtol=1e-12)


def test_state_round_trip_keeps_the_learnt_kernel():
    sela, _, _ = slow_robot(1, 1.0)
    mu, sd = sela.predict()
    state = json.loads(json.dumps(sela.state_dict()))
    assert state['hyper'] == list(sela.hyper) and sela.hyper != (SIGMA0, VARIANCE0)
    other = SELA(sela._candidates, sela._prior, SE2Motion(), config=sela.config)
    other.load_state_dict(state)
    assert other.hyper == sela.hyper
    mu2, sd2 = other.predict()
    np.testing.assert_allclose(mu2, mu, atol=1e-9)
    np.testing.assert_allclose(sd2, sd, atol=1e-9)
    kept = sela.hyper
    sela.keep_latest(20)
    assert sela.hyper == kept
    sela.reset_learning()
    assert sela.hyper == (SIGMA0, VARIANCE0)


def test_the_choice_can_read_the_configured_kernels_variance(monkeypatch):
    """With HYPER_VARIANCE_LEARNT False the learnt kernel sets the means, and the variance
    the choice reads is that of a GP of the configured kernel on the same steps."""
    import sela_ros.core.learning.sela as sela_module

    monkeypatch.setattr(sela_module, 'HYPER_VARIANCE_LEARNT', False)
    learnt, _, _ = slow_robot(0, 1.0)
    mu, sd = learnt.predict()
    assert learnt.hyper != (SIGMA0, VARIANCE0)
    idx, grs = learnt.observations
    configured = CandidateSetGP(learnt._candidates, learnt._prior, sigma=SIGMA0,
                                variance=VARIANCE0, noise=NOISE)
    configured.fit(idx, grs)
    np.testing.assert_allclose(sd ** 2, configured.query()[1], atol=1e-9)
    np.testing.assert_allclose(mu, learnt.gp.query()[0], atol=1e-12)
    learnt.tell(int(np.setdiff1d(np.arange(600), idx)[0]), np.zeros(3))  # kept beside
    configured.add_sample(learnt.observations[0][-1], np.zeros(3))
    np.testing.assert_allclose(learnt.predict()[1] ** 2, configured.query()[1], atol=1e-9)
