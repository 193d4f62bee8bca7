"""The mixture of damage priors: weights fitted to the steps seen, and SELA over it."""
import numpy as np
import pytest

from sela_ros.core.learning import (
    SELA,
    DamagePriors,
    FallRisk,
    SE2Motion,
    SELAConfig,
    params_checksum,
)
from sela_ros.core.learning.prior_mixture import Mixture, fit_mixture
from sela_ros.core.learning.sela import MIXTURE, prior_reason

M = 400


def library(seed=0, tables=4):
    """An intact map and ``tables`` damage tables whose deviations from it differ."""
    rng = np.random.default_rng(seed)
    candidates = rng.random((M, 4))
    intact = np.column_stack([rng.uniform(-0.6, 0.6, (M, 2)), rng.uniform(-0.5, 0.5, M)])
    grs = np.stack([intact * rng.uniform(0.2, 0.9, 3) + rng.normal(0, 0.25, (M, 3))
                    for _ in range(tables)])
    fallen = rng.random((tables, M)) < 0.1
    params = rng.random((M, 36))
    names = tuple(f'remove:{leg}' for leg in
                  ('front_left', 'middle_left', 'rear_left', 'front_right')[:tables])
    return candidates, intact, DamagePriors(names, grs, fallen, params_checksum(params))


def mixed(intact, priors, weights):
    return intact + np.tensordot(weights, priors.generic_reward - intact[None], axes=1)


def test_a_known_mixture_of_tables_is_recovered():
    _, intact, priors = library()
    truth = np.array([0.7, 0.0, 0.4, 0.0])
    rng = np.random.default_rng(1)
    idx = rng.choice(M, 25, replace=False)
    seen = mixed(intact, priors, truth)[idx] + rng.normal(0, 0.02, (25, 3))
    fit = fit_mixture(intact, priors.generic_reward, idx, seen)
    np.testing.assert_allclose(fit.weights, truth, atol=0.05)
    assert fit.steps == 25 and fit.misfit < 0.2
    assert np.all(np.linalg.eigvalsh(fit.covariance) > 0)
    # The mixed mean predicts the gaits never tried.
    untried = np.setdiff1d(np.arange(M), idx)
    err = fit.mean(intact, priors.generic_reward)[untried] - mixed(intact, priors, truth)[untried]
    assert np.abs(err).max() < 0.05


def test_one_table_is_recovered_and_the_intact_map_gives_no_weight():
    _, intact, priors = library(2)
    idx = np.arange(0, M, 40)
    fit = fit_mixture(intact, priors.generic_reward, idx, priors.generic_reward[1][idx])
    np.testing.assert_allclose(fit.weights, [0, 1, 0, 0], atol=0.05)
    none = fit_mixture(intact, priors.generic_reward, idx, intact[idx])
    np.testing.assert_allclose(none.weights, 0.0, atol=0.05)


def test_without_steps_the_prior_weights_hold_and_the_mean_is_the_intact_map():
    _, intact, priors = library()
    fit = fit_mixture(intact, priors.generic_reward, [], np.zeros((0, 3)), weight_sd=0.5)
    assert fit.steps == 0 and np.all(fit.weights == 0)
    np.testing.assert_allclose(np.diag(fit.covariance), 0.25)
    np.testing.assert_allclose(fit.mean(intact, priors.generic_reward), intact)
    primed = fit_mixture(intact, priors.generic_reward, [], np.zeros((0, 3)),
                         prior_weights=[0.5, 0, 0, 0])
    np.testing.assert_allclose(primed.weights, [0.5, 0, 0, 0])


def test_gaits_that_fell_are_left_out_and_a_wild_step_does_not_drag_the_weights():
    _, intact, priors = library(3)
    truth = np.array([0.0, 0.8, 0.0, 0.3])
    idx = np.arange(5, M, 25)
    seen = mixed(intact, priors, truth)[idx]
    tumble = seen.copy()
    tumble[0] = [1.5, -1.5, 3.0]  # where the tumble took it
    fit = fit_mixture(intact, priors.generic_reward, idx, tumble, fall_indices=idx[:1],
                      fallen=[True])
    assert fit.steps == idx.size - 1
    np.testing.assert_allclose(fit.weights, truth, atol=0.05)
    # Not said to have fallen: one step in 16 far off every prior is an outlier.
    robust = fit_mixture(intact, priors.generic_reward, idx, tumble)
    np.testing.assert_allclose(robust.weights, truth, atol=0.1)


def test_standing_starts_weigh_more():
    _, intact, priors = library(4)
    idx = np.array([10, 20])
    # The first step (standing) says table 0, the second (chained) says table 2.
    seen = np.stack([priors.generic_reward[0][10], priors.generic_reward[2][20]])
    even = fit_mixture(intact, priors.generic_reward, idx, seen)
    standing = fit_mixture(intact, priors.generic_reward, idx, seen, standing=[True, False])
    err = [np.abs(f.mean(intact, priors.generic_reward)[10] - seen[0]).sum()
           for f in (even, standing)]
    assert err[1] < err[0]


def test_malformed_input_is_refused():
    _, intact, priors = library()
    tables = priors.generic_reward
    with pytest.raises(ValueError, match='observed must have shape'):
        fit_mixture(intact, tables, [1, 2], np.zeros((3, 3)))
    with pytest.raises(ValueError, match='indices'):
        fit_mixture(intact, tables, [M], np.zeros((1, 3)))
    with pytest.raises(ValueError, match='indices'):
        fit_mixture(intact, tables, [-1], np.zeros((1, 3)))
    with pytest.raises(ValueError, match='indices'):
        fit_mixture(intact, tables, [0.5], np.zeros((1, 3)))
    with pytest.raises(ValueError, match='finite'):
        fit_mixture(intact, tables, [1], [[np.nan, 0, 0]])
    with pytest.raises(ValueError, match='tables'):
        fit_mixture(intact, tables[:, :10], [1], np.zeros((1, 3)))
    with pytest.raises(ValueError, match='weight_sd'):
        fit_mixture(intact, tables, [1], np.zeros((1, 3)), weight_sd=0.0)
    with pytest.raises(ValueError, match='prior_weights'):
        fit_mixture(intact, tables, [1], np.zeros((1, 3)), prior_weights=[1.0])
    with pytest.raises(ValueError, match='standing'):
        fit_mixture(intact, tables, [1], np.zeros((1, 3)), standing=[True, False])
    with pytest.raises(ValueError, match='fallen'):
        fit_mixture(intact, tables, [1], np.zeros((1, 3)), fall_indices=[1], fallen=[])


def test_falls_mix_as_a_noisy_or_of_the_weighed_tables():
    fallen = np.array([[1, 1, 0, 0], [1, 0, 1, 0]], bool)
    mixture = Mixture(np.array([1.0, 0.5]), np.eye(2), 0.0, 3)
    np.testing.assert_allclose(mixture.fall_rates(fallen), [1.0, 1.0, 0.5, 0.0])
    # Weights outside [0, 1] count as none and as the whole table.
    clipped = Mixture(np.array([-0.4, 1.7]), np.eye(2), 0.0, 3)
    np.testing.assert_allclose(clipped.fall_rates(fallen), [1.0, 0.0, 1.0, 0.0])


def test_the_support_prior_reads_fall_rates_as_it_reads_flags():
    rng = np.random.default_rng(0)
    model = FallRisk(rng.random((M, 3)), stability=rng.random(M))
    flags = rng.random(M) < 0.2
    assert model.table_support(flags) == model.table_support(flags.astype(float))
    half = model.table_support(0.5 * flags)
    assert model.table_support(np.zeros(M))[0] < half[0] < model.table_support(flags)[0]
    with pytest.raises(ValueError, match=r'\[0, 1\]'):
        model.table_support(np.full(M, 1.5))


def sela_over(priors, candidates, intact, **config):
    return SELA(candidates, intact, SE2Motion(), goal=(2.0, 0.0), priors=priors,
                config=SELAConfig(**config))


def test_sela_uses_the_mixture_on_a_damage_no_table_holds():
    candidates, intact, priors = library(5)
    truth = mixed(intact, priors, np.array([0.6, 0.0, 0.0, 0.6]))
    sela = sela_over(priors, candidates, intact)
    for i in (3, 50, 97, 150):
        sela.tell(i, truth[i], standing_start=i == 3)
    selection = sela.select_prior()
    assert selection.name == MIXTURE and selection.mixture.steps == 4
    assert 'no table reproduced' in prior_reason(MIXTURE)
    mu, _ = sela.predict()
    far = np.setdiff1d(np.arange(M), (3, 50, 97, 150))
    mixture_error = np.abs(mu[far] - truth[far]).mean()
    # The one-table choice is worse away from the gaits tried.
    one = sela_over(priors, candidates, intact, priors_weights_sd=None)
    for i in (3, 50, 97, 150):
        one.tell(i, truth[i], standing_start=i == 3)
    assert one.select_prior().mixture is None
    mu_one, _ = one.predict()
    assert mixture_error < 0.5 * np.abs(mu_one[far] - truth[far]).mean()
    decision = sela.ask(np.zeros(3))
    assert decision.prior == MIXTURE
    # Its falls: at least the noisy OR of the two weighed tables where nothing was tried.
    rates = selection.mixture.fall_rates(priors.fallen)
    risk = sela.fall_risk.risk(rates)
    assert np.all(risk[far] >= rates[far] - 1e-12) and rates.max() > 0.5


def test_a_table_that_reproduced_the_standing_starts_is_used_as_it_is():
    candidates, intact, priors = library(6)
    sela = sela_over(priors, candidates, intact)
    own = priors.generic_reward[2]
    sela.tell(7, own[7], standing_start=True)
    sela.tell(70, own[70])
    selection = sela.select_prior()
    assert selection.name == priors.names[2] and selection.reproduced
    assert selection.mixture is None


def test_weights_are_nonnegative_unless_asked_otherwise():
    _, intact, priors = library(7)
    idx = np.arange(3, M, 20)
    # A robot that does better than the intact map where table 0 says it does worse.
    seen = mixed(intact, priors, np.array([-0.5, 0.0, 0.6, 0.0]))[idx]
    kept = fit_mixture(intact, priors.generic_reward, idx, seen)
    assert np.all(kept.weights >= 0) and kept.weights[0] == 0 and kept.weights[2] > 0.3
    signed = fit_mixture(intact, priors.generic_reward, idx, seen, nonnegative=False)
    np.testing.assert_allclose(signed.weights, [-0.5, 0.0, 0.6, 0.0], atol=0.05)


def test_the_mixture_counts_for_what_its_evidence_says_against_the_intact_map():
    _, intact, priors = library(8)
    idx = np.arange(11, M, 30)
    rng = np.random.default_rng(2)
    # Steps the intact map explains (chaining-sized errors): the weights are averaged away.
    plain = fit_mixture(intact, priors.generic_reward, idx,
                        intact[idx] + rng.normal(0, 0.05, (idx.size, 3)))
    assert plain.probability < 0.5 and np.abs(plain.weights).max() < 0.1
    # Steps a mixture explains: it holds, and its weights are the fitted ones.
    truth = np.array([0.0, 0.5, 0.5, 0.0])
    held = fit_mixture(intact, priors.generic_reward, idx, mixed(intact, priors, truth)[idx])
    assert held.probability > 0.99 and held.noise == 1.0
    np.testing.assert_allclose(held.weights, truth, atol=0.05)
    # Steps nothing explains well: the errors' variance learnt is above the chaining error's.
    wild = fit_mixture(intact, priors.generic_reward, idx,
                       rng.uniform(-0.8, 0.8, (idx.size, 3)))
    assert wild.noise > 2.0


def test_the_mixture_is_used_only_while_it_predicts_the_steps_better():
    candidates, intact, priors = library(9)
    steps = (3, 50, 97, 150, 222)
    # A robot that moves as the intact map says: the one-table choice (the intact map)
    # predicts every step, the mixture never does better, and is not used.
    plain = sela_over(priors, candidates, intact)
    for i in steps:
        plain.tell(i, intact[i], standing_start=i == 3)
    scores = plain.state_dict()['prior_scores']
    assert scores['table'] >= scores['mixture'] and plain.select_prior().name == 'intact'
    # A robot that two tables add up to: the mixture predicts each step better, and is used.
    truth = mixed(intact, priors, np.array([0.0, 0.7, 0.0, 0.7]))
    both = sela_over(priors, candidates, intact)
    for i in steps:
        both.tell(i, truth[i], standing_start=i == 3)
    scores = both.state_dict()['prior_scores']
    assert scores['mixture'] > scores['table'] and both.select_prior().name == MIXTURE
    # The scores are what was learnt: a restored SELA makes the same choice.
    again = sela_over(priors, candidates, intact)
    again.load_state_dict(both.state_dict())
    assert again.state_dict()['prior_scores'] == scores
    assert again.select_prior().name == MIXTURE
    # Without a mixture (priors.weights.sd 0) nothing is scored.
    off = sela_over(priors, candidates, intact, priors_weights_sd=None)
    for i in steps:
        off.tell(i, truth[i], standing_start=i == 3)
    assert off.state_dict()['prior_scores'] == {'table': 0.0, 'mixture': 0.0}
    assert off.select_prior().name != MIXTURE


def test_the_posterior_mean_of_one_gait_under_another_prior():
    from sela_ros.core.learning import CandidateSetGP

    candidates, intact, priors = library(10)
    gp = CandidateSetGP(candidates, intact, sigma=0.3)
    other = priors.generic_reward[1]
    assert np.allclose(gp.mean_at_with_prior(5, np.zeros((0, 3)), other[5]), other[5])
    rng = np.random.default_rng(3)
    for i in (4, 40, 80, 120):
        gp.add_sample(i, rng.normal(0, 0.3, 3))
    full = gp.mean_columns_with_prior(other)
    rows = other[gp.indices]
    for j in (0, 40, 300):
        np.testing.assert_allclose(gp.mean_at_with_prior(j, rows, other[j]), full[:, j],
                                   atol=1e-12)


def test_the_mixed_falls_are_a_noisy_or_of_the_tables_weighed_by_their_weights():
    rng = np.random.default_rng(4)
    fallen = rng.random((5, 200)) < 0.3
    for weights in ([0.0, 0.3, 1.0, 2.5, 0.7], [0.2, 0.0, 0.0, 0.5, 0.1], [0.0] * 5):
        mixture = Mixture(np.array(weights), np.eye(5), 0.0, 0)
        stand = np.ones(200)
        for c, f in zip(np.clip(weights, 0, 1), fallen):
            stand[f] *= 1.0 - c
        np.testing.assert_allclose(mixture.fall_rates(fallen), 1.0 - stand, atol=1e-12)
