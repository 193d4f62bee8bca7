"""UCB picks the argmax of reward + alpha * sigma, lowest index on ties."""
import numpy as np
import pytest

from sela_ros.core.learning.acquisition import ucb, ucb_scores


def test_ucb_is_argmax():
    rng = np.random.default_rng(0)
    mu, sigma = rng.normal(size=1000), rng.random(1000)
    i = ucb(mu, sigma, alpha=0.05)
    assert i == int(np.argmax(mu + 0.05 * sigma))
    assert ucb(mu, sigma, alpha=0.0) == int(np.argmax(mu))


def test_sigma_can_win():
    assert ucb([0.0, -0.1], [0.0, 1.0], alpha=0.05) == 0
    assert ucb([0.0, -0.1], [0.0, 1.0], alpha=0.2) == 1


def test_ties_pick_lowest_index():
    assert ucb([1.0, 2.0, 2.0, 2.0], [0.0, 0.0, 0.0, 0.0]) == 1


def test_scores_and_errors():
    np.testing.assert_allclose(ucb_scores([1.0, 2.0], [2.0, 0.0], 0.5), [2.0, 2.0])
    with pytest.raises(ValueError):
        ucb([1.0, 2.0], [1.0])
    with pytest.raises(ValueError):
        ucb([1.0], [1.0], alpha=-1.0)
    with pytest.raises(ValueError):
        ucb([np.nan], [1.0])


def test_the_learnt_error_starts_from_its_prior_and_follows_the_steps():
    from sela_ros.core.learning.acquisition import CAUTION_PRIOR_ERROR, learnt_error

    assert learnt_error([]) == pytest.approx(CAUTION_PRIOR_ERROR)
    # Planar squared errors of 0.18 m^2 are 0.3 m per axis; the prior counts as one step.
    assert learnt_error([0.18] * 99) == pytest.approx(
        np.sqrt((2 * CAUTION_PRIOR_ERROR ** 2 + 99 * 0.18) / 200))
    assert learnt_error([0.18] * 99) > learnt_error([0.18])


def test_a_gait_tried_lands_surer_than_one_far_from_any_tried():
    from sela_ros.core.learning.acquisition import (
        CAUTION_SPREAD,
        expected_distance,
        landing_variance,
    )

    var = landing_variance(np.array([0.0, 0.5, 1.0, 3.0]), 0.2)
    np.testing.assert_allclose(var, CAUTION_SPREAD ** 2 + np.array([0.0, 0.02, 0.04, 0.04]))
    # On the target: the expected distance is the spread's; far off: about the distance.
    assert expected_distance(0.0, var[2]) == pytest.approx(np.sqrt(2 * var[2]))
    assert expected_distance(4.0, var[0]) == pytest.approx(2.0, rel=1e-3)
