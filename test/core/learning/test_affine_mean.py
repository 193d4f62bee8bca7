"""The affine map of the prior mean learnt from the steps (gp.mean.affine)."""
import numpy as np
import pytest

from sela_ros.core.learning import SELA, SE2Motion, SELAConfig
from sela_ros.core.learning.affine_mean import apply_affine, fit_affine

IDENTITY = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])


def _map(rng, m=400):
    """A map of gaits moving up to 0.5 m and turning up to 1 rad."""
    return np.column_stack([rng.uniform(-0.5, 0.5, m), rng.uniform(-0.3, 0.3, m),
                            rng.uniform(-1.0, 1.0, m)])


def test_no_step_is_the_identity():
    np.testing.assert_allclose(fit_affine(np.zeros((0, 3)), np.zeros((0, 3))), IDENTITY)
    prior = _map(np.random.default_rng(0))
    np.testing.assert_allclose(apply_affine(IDENTITY, prior), prior)


def test_many_steps_find_the_map_of_a_slow_robot_that_drifts():
    rng = np.random.default_rng(1)
    prior = _map(rng)
    # The damaged robot: a third as fast, its walk rotated by 0.3 rad, turning 0.2 rad per
    # metre forward.
    c, s = np.cos(0.3), np.sin(0.3)
    truth = np.column_stack([0.33 * (c * prior[:, 0] - s * prior[:, 1]),
                             0.33 * (s * prior[:, 0] + c * prior[:, 1]),
                             0.8 * prior[:, 2] + 0.2 * prior[:, 0]])
    noisy = truth + rng.normal(0, [0.02, 0.02, 0.05], truth.shape)
    weights = fit_affine(prior, noisy)
    np.testing.assert_allclose(apply_affine(weights, prior), truth, atol=0.03)


def test_three_steps_move_the_map_only_as_far_as_they_show():
    rng = np.random.default_rng(2)
    prior = _map(rng)
    slow = prior * [0.3, 0.3, 1.0]
    rows = [0, 1, 2]
    weights = fit_affine(prior[rows], slow[rows])
    scale = weights[0, 0]
    # Towards the truth, not all the way: three steps of a chaining error's noise.
    assert 0.3 < scale < 1.0
    many = fit_affine(prior, slow)
    assert abs(many[0, 0] - 0.3) < abs(scale - 0.3)


@pytest.mark.parametrize('affine, far', [(0.5, True), (None, False)])
def test_sela_generalises_a_few_steps_to_gaits_far_from_them(affine, far):
    """Three steps of a robot half as fast as the map: with the affine map, a gait far from
    them in the descriptor space is predicted slower too; without it, it keeps the map's."""
    rng = np.random.default_rng(3)
    m = 200
    candidates = rng.random((m, 4))
    prior = _map(rng, m)
    sela = SELA(candidates, prior, SE2Motion(), goal=[2.0, 0.0],
                config=SELAConfig(gp_kernel_sigma=0.05, gp_mean_affine=affine))
    tried = [0, 1, 2]
    for i in tried:
        sela.tell(i, prior[i] * [0.5, 0.5, 1.0])
    mu, _ = sela.predict()
    distance = np.min(np.linalg.norm(candidates[:, None] - candidates[tried][None], axis=2),
                      axis=1)
    untried = np.flatnonzero(distance > 0.4)
    assert untried.size
    ratio = np.abs(mu[untried, 0]).sum() / np.abs(prior[untried, 0]).sum()
    assert (ratio < 0.9) == far
    # The gaits tried are predicted as they landed, either way.
    np.testing.assert_allclose(mu[tried, 0], prior[tried, 0] * 0.5, atol=0.01)


def test_a_fall_is_left_out_of_the_map():
    rng = np.random.default_rng(4)
    prior = _map(rng, 50)
    sela = SELA(rng.random((50, 3)), prior, SE2Motion(), goal=[2.0, 0.0],
                config=SELAConfig(gp_kernel_sigma=0.05))
    sela.tell(0, prior[0])
    sela.tell(1, [-0.5, 0.4, 2.5])  # where a fall threw it
    sela.tell_fall(1, True)
    mu, _ = sela.predict()
    far = np.flatnonzero(np.linalg.norm(sela._candidates - sela._candidates[[0, 1]][:, None],
                                        axis=2).min(axis=0) > 0.3)
    np.testing.assert_allclose(mu[far], prior[far], atol=1e-6)


def test_the_map_stays_off_while_the_prior_predicts_the_steps_as_well():
    """On a robot the prior mean predicts (within the chaining error), the affine map is not
    used: gaits far from the steps keep the prior's predictions."""
    rng = np.random.default_rng(5)
    m = 200
    candidates = rng.random((m, 4))
    prior = _map(rng, m)
    sela = SELA(candidates, prior, SE2Motion(), goal=[2.0, 0.0],
                config=SELAConfig(gp_kernel_sigma=0.05, gp_mean_affine=0.5))
    for i in range(6):
        sela.tell(i, prior[i] + rng.normal(0, [0.03, 0.03, 0.05]))
    assert sela._affine_score <= 0.0
    mu, _ = sela.predict()
    far = np.flatnonzero(np.linalg.norm(candidates[:, None] - candidates[:6][None],
                                        axis=2).min(axis=1) > 0.4)
    np.testing.assert_allclose(mu[far], prior[far], atol=1e-6)


def _lost_leg(rng, m=400, d=4):
    """A map and descriptors in [0, 1]^d; the robot: gaits slowed in proportion to how much
    they lean on descriptor dimension 1 (a leg's duty factor), unslowed where it is 0."""
    prior = _map(rng, m)
    descriptors = rng.random((m, d))
    scale = 1.0 - 0.8 * descriptors[:, 1]
    truth = np.column_stack([scale * prior[:, 0], scale * prior[:, 1], prior[:, 2]])
    return prior, descriptors, truth


def test_no_step_with_descriptors_is_the_identity():
    prior, descriptors, _ = _lost_leg(np.random.default_rng(6))
    weights = fit_affine(np.zeros((0, 3)), np.zeros((0, 3)), descriptors=np.zeros((0, 4)),
                         descriptor_sd=1.0)
    assert weights.shape == (3, 7)
    np.testing.assert_allclose(apply_affine(weights, prior, descriptors), prior)


def test_a_scale_that_varies_with_the_descriptor_finds_a_lost_leg():
    """Gaits that lean on one leg slowed more than others: the map with descriptor terms
    predicts gaits it never saw within the noise; one scale for all cannot."""
    rng = np.random.default_rng(7)
    prior, descriptors, truth = _lost_leg(rng)
    seen = np.arange(60)
    noisy = truth[seen] + rng.normal(0, [0.02, 0.02, 0.05], (60, 3))
    varying = fit_affine(prior[seen], noisy, descriptors=descriptors[seen], descriptor_sd=1.0)
    uniform = fit_affine(prior[seen], noisy)
    unseen = np.arange(60, len(prior))
    err_varying = np.abs(apply_affine(varying, prior, descriptors)[unseen, :2]
                         - truth[unseen, :2]).mean()
    err_uniform = np.abs(apply_affine(uniform, prior)[unseen, :2] - truth[unseen, :2]).mean()
    assert err_varying < 0.02
    assert err_uniform > 2 * err_varying
    # The weight on the leg's dimension says the gaits leaning on it are slower.
    assert varying[0, 3 + 1] < -0.5


def test_descriptor_terms_need_the_descriptors():
    prior, descriptors, truth = _lost_leg(np.random.default_rng(8), m=20)
    with pytest.raises(ValueError, match='descriptors'):
        fit_affine(prior, truth, descriptor_sd=1.0)
    weights = fit_affine(prior, truth, descriptors=descriptors, descriptor_sd=1.0)
    with pytest.raises(ValueError, match='descriptors'):
        apply_affine(weights, prior)


@pytest.mark.parametrize('descriptor_sd', [1.0, None])
def test_sela_slows_the_untried_gaits_that_lean_on_the_lost_leg(descriptor_sd):
    """After a dozen steps of a robot that lost what descriptor dimension 1 stands for,
    SELA with gp.mean.descriptor predicts far, untried gaits that lean on it slower than
    those that do not; with one scale it slows both alike."""
    rng = np.random.default_rng(9)
    m = 300
    prior, candidates, truth = _lost_leg(rng, m)
    sela = SELA(candidates, prior, SE2Motion(), goal=[2.0, 0.0],
                config=SELAConfig(gp_kernel_sigma=0.05, gp_mean_affine=0.5,
                                  gp_mean_descriptor=descriptor_sd))
    tried = np.arange(12)
    for i in tried:
        sela.tell(int(i), truth[i])
    assert sela._affine_score > 0.0
    mu, _ = sela.predict()
    far = np.linalg.norm(candidates[:, None] - candidates[tried][None], axis=2).min(axis=1) \
        > 0.2
    leaning, free = far & (candidates[:, 1] > 0.8), far & (candidates[:, 1] < 0.2)
    assert leaning.any() and free.any()

    def ratio(rows):
        return np.abs(mu[rows, 0]).sum() / np.abs(prior[rows, 0]).sum()

    assert (ratio(leaning) < ratio(free) - 0.3) == (descriptor_sd is not None)


def test_a_table_that_reproduced_the_standing_starts_is_used_without_the_map():
    """The robot's own damage foreseen: its table reproduced every step from a standing
    start. Even where the map would predict the steps a little better (a robot 10 % slower
    than the table), far gaits keep the table's predictions: what is left of its error is
    the GPs' to learn gait by gait."""
    from sela_ros.core.learning import DamagePriors

    rng = np.random.default_rng(10)
    m = 300
    candidates = rng.random((m, 4))
    intact = _map(rng, m)
    table = intact * [0.5, 0.5, 1.0]
    priors = DamagePriors(('remove:front_left',), table[None], np.zeros((1, m), bool), 'x')
    sela = SELA(candidates, intact, SE2Motion(), goal=[2.0, 0.0], priors=priors,
                config=SELAConfig(gp_kernel_sigma=0.05, gp_mean_affine=0.5,
                                  priors_weights_sd=None))
    tried = np.argsort(-np.abs(table[:, 0]))[:10]
    for i in tried:
        sela.tell(int(i), table[i] * [0.9, 0.9, 1.0], standing_start=True)
    selection = sela.select_prior()
    assert selection.name == 'remove:front_left' and selection.reproduced
    assert sela._affine_score > 0.0
    assert sela._fit_affine(table)[0, 0] < 0.97  # the map would slow every gait
    mu, _ = sela.predict()
    far = np.linalg.norm(candidates[:, None] - candidates[tried][None], axis=2).min(axis=1) \
        > 0.3
    assert far.any()
    np.testing.assert_allclose(mu[far], table[far], atol=1e-6)
