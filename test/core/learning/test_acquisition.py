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
