"""Fall-aware adaptation: the fall GP and the acquisition that keeps away from risky gaits."""
import numpy as np
import pytest

from sela_ros.core.learning import SELA, SE2Motion, SELAConfig
from sela_ros.core.learning.fall_risk import FallRisk, safe_choice


def _grid(n=21):
    g = np.linspace(0.0, 1.0, n)
    return np.array([[x, y] for x in g for y in g])


def test_prior_is_trusted_until_a_fall_is_seen():
    risk = FallRisk(_grid())
    assert np.all(risk.risk() == 0.0)
    risk.tell(0, False)
    assert risk.risk().max() < 1e-6 and risk.falls == 0


def test_one_fall_raises_the_risk_of_similar_gaits_only():
    c = _grid()
    risk = FallRisk(c, sigma=0.1)
    fell = int(np.argmin(np.linalg.norm(c - [0.5, 0.5], axis=1)))
    risk.tell(fell, True)
    r = risk.risk()
    near = np.linalg.norm(c - c[fell], axis=1)
    assert r[fell] > 0.95
    assert np.all(r[(near > 0) & (near < 0.06)] > 0.5)
    # Far from it, the robot's fall rate so far (1 fall in 1 step, 3 safe steps assumed):
    # below a threshold of 0.3, so those gaits are still tried there.
    assert risk.base_rate == pytest.approx(0.25)
    np.testing.assert_allclose(r[near > 0.4], 0.25, atol=0.01)
    # A gait that did not fall lowers the risk around it again.
    other = int(np.argmin(np.linalg.norm(c - [0.55, 0.5], axis=1)))
    before = r[other]
    risk.tell(other, False)
    assert risk.risk()[other] < before


def test_a_robot_that_keeps_falling_keeps_to_the_gaits_seen_upright():
    c = _grid()
    risk = FallRisk(c, sigma=0.1)
    safe = int(np.argmin(np.linalg.norm(c - [0.2, 0.2], axis=1)))
    risk.tell(safe, False)
    for corner in ([1.0, 1.0], [0.0, 1.0], [1.0, 0.0]):  # three new gaits, three falls
        risk.tell(int(np.argmin(np.linalg.norm(c - corner, axis=1))), True)
    assert risk.base_rate == pytest.approx(3 / 7)
    r = risk.risk()
    near_safe = np.linalg.norm(c - c[safe], axis=1) < 0.05
    untried = np.linalg.norm(c - [0.6, 0.5], axis=1) < 0.05
    assert np.all(r[near_safe] < 0.3) and r[safe] < 0.01
    assert np.all(r[untried] > 0.3)  # not tried any more at a threshold of 0.3
    chosen = np.argmax(safe_choice(c[:, 0], r, 0.3))  # the score pulls toward x = 1
    assert np.linalg.norm(c[chosen] - c[safe]) < 0.2  # within the kernel's reach of it


def test_prior_fall_rates_are_checked():
    with pytest.raises(ValueError, match='shape'):
        FallRisk(_grid(3), prior=np.zeros(2))
    with pytest.raises(ValueError, match=r'\[0, 1\]'):
        FallRisk(_grid(3), prior=np.full(9, 2.0))


def test_safe_choice_rules_out_risky_gaits_and_keeps_the_least_risky_when_all_are():
    scores = np.array([3.0, 2.0, 1.0])
    assert np.argmax(safe_choice(scores, [0.9, 0.1, 0.0], 0.3)) == 1
    masked = safe_choice(scores, [0.9, 0.8, 0.95], 0.3)
    assert np.isneginf(masked[0]) and masked[1] == 2.0 and np.isneginf(masked[2])


def _sela(threshold, cost=0.0):
    c = _grid()
    # Every gait moves 0.3 m forward on the intact robot; the goal is straight ahead.
    prior = np.tile([0.3, 0.0, 0.0], (len(c), 1))
    prior[:, 0] += 0.1 * c[:, 0]  # the gaits with a large first descriptor go furthest
    return SELA(c, prior, SE2Motion(), goal=(5.0, 0.0),
                config=SELAConfig(planner_lookahead=0.5, fall_risk_threshold=threshold,
                                  fall_risk_cost=cost))


def test_sela_stops_choosing_gaits_like_one_that_fell():
    sela = _sela(0.3)
    first = sela.ask(np.zeros(3))
    assert first.fall_risk == 0.0
    sela.tell_fall(first.index, True)
    second = sela.ask(np.zeros(3))
    c = _grid()
    assert np.linalg.norm(c[second.index] - c[first.index]) > 0.1
    assert second.fall_risk <= 0.3
    # With the risk accepted at 1 and no cost the fall changes nothing (the GR GP learnt
    # nothing); with a cost it does.
    blind = _sela(1.0)
    index = blind.ask(np.zeros(3)).index
    blind.tell_fall(index, True)
    assert blind.ask(np.zeros(3)).index == index
    costly = _sela(1.0, cost=1.0)
    costly.tell_fall(index, True)
    assert costly.ask(np.zeros(3)).index != index


def test_falls_survive_a_restart_of_adaptation_and_a_state_round_trip():
    sela = _sela(0.3)
    sela.tell(3, [0.1, 0.0, 0.0])
    sela.tell_fall(3, True)
    sela.tell_fall(7, False)
    sela.reset_learning()
    assert sela.observations[0].size == 0 and sela.fall_risk.falls == 1
    sela.tell(5, [0.2, 0.0, 0.0])
    state = sela.state_dict()
    assert state['fall_indices'] == [3, 7] and state['fallen'] == [True, False]
    copy = _sela(0.3)
    copy.load_state_dict(state)
    np.testing.assert_allclose(copy.fall_risk.risk(), sela.fall_risk.risk())
    np.testing.assert_allclose(copy.predict()[0], sela.predict()[0])
    # A state saved before falls were learnt still loads.
    del state['fall_indices'], state['fallen']
    copy.load_state_dict(state)
    assert copy.fall_risk.falls == 0
    sela.forget_falls()
    assert np.all(sela.fall_risk.risk() == 0.0)


def _supported(n=400, seed=3):
    """Gaits in 2-D with a support feature unrelated to where they are."""
    rng = np.random.default_rng(seed)
    return rng.random((n, 2)), rng.uniform(1.5, 4.5, n)


def test_support_orders_the_risk_before_any_fall_and_falls_rule_out_the_least_supported():
    c, support = _supported()
    risk = FallRisk(c, sigma=0.05, stability=support)
    r0 = risk.risk()
    low, high = support < 2.0, support > 4.0
    assert r0[low].min() > r0[high].max()  # less support, more risk, with no evidence yet
    assert r0[high].max() < 0.05 and r0.max() < 0.5
    # Three falls on poorly supported gaits, eight steps upright on well supported ones.
    fell = np.flatnonzero(support < 1.9)[:3]
    upright = np.flatnonzero(support > 3.5)[:8]
    for i in upright[:4]:
        risk.tell(i, False)
    for i in fell:
        risk.tell(i, True)
    for i in upright[4:]:
        risk.tell(i, False)
    theta, beta = risk.support_model
    r = risk.risk()
    far = np.min(np.linalg.norm(c[:, None] - c[np.r_[fell, upright]][None], axis=2), axis=1) > 0.2
    # Far from every gait tried: the poorly supported ones are now out at 0.3,
    # the well supported ones still in.
    assert np.all(r[far & (support < 2.0)] > 0.3)
    assert np.all(r[far & (support > 4.0)] < 0.3)
    assert np.all(r[fell] > 0.9)
    assert beta > 1.0 and theta > -4.0
    risk.reset()
    np.testing.assert_allclose(risk.risk(), r0)


def test_falls_that_support_does_not_explain_teach_a_flat_model():
    c, support = _supported()
    risk = FallRisk(c, sigma=0.05, stability=support)
    prior_beta = risk.support_model[1]
    # The best supported gaits fall as often as the worst: support says nothing here.
    order = np.argsort(support)
    for k in range(12):
        risk.tell(order[k], k % 2 == 0)
        risk.tell(order[-1 - k], k % 2 == 0)
    assert risk.support_model[1] < prior_beta - 0.5


def test_a_table_sets_the_support_prior_of_its_damage_and_the_robot_still_moves_it():
    """The support model's prior on a foreseen damage comes from that damage's table: a
    damage whose gaits never fall makes even poorly supported gaits safe, one whose poorly
    supported gaits fall keeps them risky; the spreads stay the generic prior's, so the
    robot's own falls move it as fast."""
    from sela_ros.core.learning.fall_risk import BETA_PRIOR, THETA_PRIOR

    c, support = _supported()
    risk = FallRisk(c, sigma=0.05, stability=support)
    low = support < 2.0
    benign = risk.table_support(np.zeros(len(c), bool))
    harsh = risk.table_support(support < np.quantile(support, 0.2))
    assert benign[1] == harsh[1] == THETA_PRIOR[1] and benign[3] == BETA_PRIOR[1]
    assert benign[0] < THETA_PRIOR[0] - 2.0 and harsh[2] > BETA_PRIOR[0] + 1.0
    generic, r_benign, r_harsh = risk.risk(), risk.risk(support=benign), \
        risk.risk(support=harsh)
    assert r_benign[low].max() < 0.1 < 0.3 < generic[low].min()
    assert r_harsh[low].min() > generic[low].min()
    # The same robot falling three times on poorly supported gaits: under the benign prior
    # the poorly supported gaits far from those are ruled out at 0.3 all the same.
    fell = np.flatnonzero(support < 1.9)[:3]
    for i in fell:
        risk.tell(i, True)
    far = np.min(np.linalg.norm(c[:, None] - c[fell][None], axis=2), axis=1) > 0.2
    assert (far & low).sum() >= 5
    assert np.all(risk.risk(support=benign)[far & low] > 0.3)
    assert FallRisk(c).table_support(np.zeros(len(c), bool)) is None  # no stability
    with pytest.raises(ValueError, match='fallen must have shape'):
        risk.table_support(np.zeros(3, bool))


def test_stability_is_checked():
    with pytest.raises(ValueError, match='stability'):
        FallRisk(_grid(3), stability=np.ones(4))
    with pytest.raises(ValueError, match='stability'):
        FallRisk(_grid(3), stability=np.full(9, np.nan))


def test_sela_uses_the_fall_kernel_of_its_config():
    c = _grid()
    prior = np.tile([0.3, 0.0, 0.0], (len(c), 1))
    wide = SELA(c, prior, SE2Motion(), config=SELAConfig(gp_kernel_sigma=0.3))
    narrow = SELA(c, prior, SE2Motion(), config=SELAConfig(gp_kernel_sigma=0.3,
                                                            fall_kernel_sigma=0.05))
    for s in (wide, narrow):
        s.tell_fall(0, True)
    near = np.linalg.norm(c - c[0], axis=1)
    ring = (near > 0.1) & (near < 0.2)
    assert narrow.fall_risk.risk()[ring].max() < wide.fall_risk.risk()[ring].min()


def test_a_fall_cost_trades_progress_for_safety_below_the_threshold():
    c = _grid()
    prior = np.tile([0.3, 0.0, 0.0], (len(c), 1))
    prior[:, 0] += 0.1 * c[:, 0]  # large first descriptor: furthest
    support = 1.0 + 3.0 * (1.0 - c[:, 0])  # ... and least supported
    def sela(cost):
        return SELA(c, prior, SE2Motion(), goal=(5.0, 0.0), stability=support,
                    config=SELAConfig(planner_lookahead=0.5, fall_risk_threshold=0.5,
                                      fall_risk_cost=cost))
    free, careful = sela(0.0), sela(1.0)
    fast = free.ask(np.zeros(3))
    safe = careful.ask(np.zeros(3))
    assert support[safe.index] > support[fast.index]  # the cost moved the choice
    assert safe.fall_risk < fast.fall_risk <= 0.5
    assert safe.reward < fast.reward  # progress given up for it
