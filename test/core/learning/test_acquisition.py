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


def test_path_coordinates_project_on_the_nearest_segment():
    from sela_ros.core.learning.acquisition import path_coordinates

    path = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 2.0]])
    s, off = path_coordinates(path, [0.5, 1.2, -0.5, 1.0, 3.0], [0.1, 1.0, 0.0, 3.0, 0.0])
    np.testing.assert_allclose(s, [0.5, 2.0, 0.0, 3.0, 1.0])
    np.testing.assert_allclose(off, [0.1, 0.2, 0.5, 1.0, 2.0])
    s, off = path_coordinates(np.array([[1.0, 1.0]]), [1.0], [2.0])
    assert s.tolist() == [0.0] and off.tolist() == [1.0]
    with pytest.raises(ValueError, match='path'):
        path_coordinates(np.array([[0.0, np.nan], [1.0, 0.0]]), [0.0], [0.0])


def test_progress_reward_counts_what_is_gained_along_the_path():
    from sela_ros.core.learning.acquisition import progress_reward

    path = np.array([[0.0, 0.0], [0.6, 0.0], [2.0, 0.0]])
    # Short of the waypoint on the path, beyond it, on it, and as far along but aside.
    x, y = np.array([0.2, 1.0, 0.6, 0.2]), np.array([0.0, 0.0, 0.0, 0.3])
    reward = progress_reward(path, x, y, [0.6, 0.0], 1.0)
    np.testing.assert_allclose(reward, [-0.4, 0.4, 0.0, -0.7])
    # By the distance to the waypoint, the landing beyond it would score as the one 0.4 m
    # short; along the path it is the best.
    assert int(np.argmax(reward)) == 1
    # Uncertain landings: the distance off the path in root mean square, the progress its
    # mean.
    np.testing.assert_allclose(progress_reward(path, x, y, [0.6, 0.0], 2.0,
                                               np.array([0.04, 0.04, 0.04, 0.09])),
                               [-0.8, 0.0, -0.4, -0.4 - 2.0 * np.sqrt(0.18)])
    with pytest.raises(ValueError, match='off_weight'):
        progress_reward(path, x, y, [0.6, 0.0], -1.0)


def test_progress_from_poses_is_the_progress_of_each_landing():
    """The (K, M) rank-2 form gives what projecting each of the K M landings gives."""
    from sela_ros.core.learning.acquisition import progress_reward, progress_reward_from

    rng = np.random.default_rng(0)
    ends, g = rng.normal(size=(4, 3)), 0.3 * rng.normal(size=(3, 50))
    c, s = np.cos(ends[:, 2]), np.sin(ends[:, 2])
    x = ends[:, :1] + c[:, None] * g[0] - s[:, None] * g[1]
    y = ends[:, 1:2] + s[:, None] * g[0] + c[:, None] * g[1]
    var = 0.01 * rng.random((4, 50))
    for path in ([[0.0, 0.0], [0.6, 0.6], [2.0, 2.0]], [[0.0, 0.0], [0.6, 0.0], [1.0, 2.0],
                                                       [1.0, 2.0], [-1.0, 3.0]], [[1.0, 1.0]]):
        path = np.array(path)
        expected = progress_reward(path, x.reshape(-1), y.reshape(-1), [0.6, 0.6], 1.5,
                                   var.reshape(-1)).reshape(4, 50)
        np.testing.assert_allclose(progress_reward_from(path, ends, c, s, g, [0.6, 0.6], 1.5,
                                                        var), expected, atol=1e-12)


def test_path_from_cuts_the_track_ahead_of_a_point():
    from sela_ros.core.learning.acquisition import path_from

    path = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 2.0]])
    np.testing.assert_allclose(path_from(path, [0.5, 0.1], 1.0), [[0.5, 0.0], [1.0, 0.0],
                                                                  [1.0, 0.5]])
    np.testing.assert_allclose(path_from(path, [0.5, 0.1], 10.0), [[0.5, 0.0], [1.0, 0.0],
                                                                   [1.0, 2.0]])
    np.testing.assert_allclose(path_from(path, [3.0, 3.0], 1.0), [[1.0, 2.0], [1.0, 2.0]])


def test_reach_probability_matches_monte_carlo():
    from sela_ros.core.learning.acquisition import reach_probability

    rng = np.random.default_rng(3)
    for distance, sd, reach in ((0.0, 0.1, 0.3), (0.3, 0.1, 0.3), (0.5, 0.2, 0.3),
                                (0.1, 0.05, 0.15), (0.6, 0.05, 0.3), (1.0, 0.4, 0.45),
                                (0.2, 0.3, 0.1)):
        landings = rng.normal([distance, 0.0], sd, size=(200_000, 2))
        sampled = np.mean(np.hypot(landings[:, 0], landings[:, 1]) <= reach)
        assert reach_probability(distance ** 2, sd ** 2, reach) == pytest.approx(sampled,
                                                                                 abs=0.02)


def test_reach_probability_falls_with_distance_and_spread_out_of_reach():
    from sela_ros.core.learning.acquisition import reach_probability

    near = reach_probability(np.array([0.0, 0.1, 0.2, 0.3, 0.4]) ** 2, 0.05 ** 2, 0.3)
    assert np.all(np.diff(near) < 0) and near[0] > 0.99 and near[-1] < 0.03
    # Within reach, a wider spread only loses chance; far out of reach it gains some.
    spread = reach_probability(0.1 ** 2, np.array([0.05, 0.1, 0.2, 0.4]) ** 2, 0.3)
    assert np.all(np.diff(spread) < 0)
    far = reach_probability(0.8 ** 2, np.array([0.05, 0.4]) ** 2, 0.3)
    assert far[0] < 1e-6 < far[1]
    with pytest.raises(ValueError, match='reach'):
        reach_probability(0.1, 0.01, 0.0)
    with pytest.raises(ValueError, match='landing_var'):
        reach_probability(0.1, 0.0, 0.3)
