"""Waypoints this robot can reach (``planner.reach``): the lookahead from the steps shown."""
import dataclasses

import numpy as np
import pytest
from stepper_driver import Driver, of, only

from sela_ros.core.learning import SELAConfig
from sela_ros.core.mission.reach import (
    REACH_FLOOR,
    reach_lookahead,
    sela_lookahead,
    standing_displacements,
)
from sela_ros.core.mission.stepper_io import (
    PlanReceived,
    RequestPlan,
    SendGait,
    VerdictReceived,
)


def test_the_lookahead_follows_the_fast_steps_shown_within_the_floor_and_the_lookahead():
    slow = np.array([[0.1, 0.0], [0.0, 0.12], [0.05, 0.0], [0.2, 0.1]])
    reach = np.quantile(np.linalg.norm(slow, axis=1), 0.9)
    assert reach_lookahead(slow, 0.6, 1.0) == pytest.approx(reach)
    assert reach_lookahead(slow, 0.6, 1.5) == pytest.approx(1.5 * reach)
    # A robot that walks as fast as the lookahead, or faster, keeps it.
    assert reach_lookahead(slow * 10, 0.6, 1.0) == 0.6
    # One that barely moves gets a waypoint no nearer than the floor.
    assert reach_lookahead(slow / 100, 0.6, 1.0) == REACH_FLOOR
    # A lookahead below the floor is never raised.
    assert reach_lookahead(slow / 100, 0.1, 1.0) == 0.1


def test_the_lookahead_stays_until_enough_steps_are_shown_or_when_off():
    slow = np.array([[0.1, 0.0], [0.1, 0.0]])
    assert reach_lookahead(slow, 0.6, 1.0) == 0.6  # two steps: not yet
    assert reach_lookahead(np.vstack([slow, slow]), 0.6, 1.0) == pytest.approx(0.15)
    assert reach_lookahead(np.vstack([slow, slow]), 0.6, None) == 0.6
    assert reach_lookahead(np.zeros((0, 2)), 0.6, 1.0) == 0.6


def test_bad_settings_are_refused_with_the_reason():
    with pytest.raises(ValueError, match='planner.reach'):
        reach_lookahead(np.ones((4, 2)), 0.6, 0.0)
    with pytest.raises(ValueError, match='lookahead'):
        reach_lookahead(np.ones((4, 2)), float('nan'), 1.0)
    with pytest.raises(ValueError, match='planner.reach'):
        SELAConfig(planner_reach=-1.0)
    assert SELAConfig().planner_reach is None
    assert SELAConfig().to_dict()['planner.reach'] == 'none'
    assert SELAConfig.from_dict({'planner.reach': 1.5}).planner_reach == 1.5


def test_steps_of_gaits_that_fell_show_no_reach():
    indices = np.array([3, 5, 3, 7])
    rewards = np.array([[0.5, 0.0, 0.0], [0.1, 0.0, 0.0], [0.4, 0.1, 0.0], [0.0, 0.2, 0.3]])
    kept = standing_displacements(indices, rewards, np.array([3, 5, 3]),
                                  np.array([False, False, True]))
    np.testing.assert_allclose(kept, [[0.1, 0.0], [0.0, 0.2]])


def _reach_driver(reach):
    d = Driver(adapt_on_start=True)
    sela = d.stepper.sela
    sela.set_config(dataclasses.replace(sela.config, planner_reach=reach))
    return d


def _walk(d, request, gr, steps):
    """``steps`` steps along a straight path to the goal, each moving ``gr``; returns each
    gait sent and the last plan request."""
    gaits = []
    for _ in range(steps):
        start = tuple(request.start)
        path = (start[:2], tuple(request.goal))
        gait = only(d(PlanReceived(request.step, start, path=path)), SendGait)
        gaits.append(gait)
        out = d.outcome(gait, gr)
        out += d(VerdictReceived(gait.behavior_id, False))
        request = only(of(out, RequestPlan), RequestPlan)
    return gaits, request


@pytest.mark.parametrize('reach, expected', [(None, 0.6), (1.0, 0.2), (2.0, 0.4)])
def test_the_stepper_sets_the_waypoint_where_the_steps_shown_reach(reach, expected):
    d = _reach_driver(reach)
    gaits, _ = _walk(d, d.start(goal=(3.0, 0.0)), (0.2, 0.0, 0.0), 4)
    distances = [np.linalg.norm(np.subtract(g.waypoint, g.pose[:2])) for g in gaits]
    # Until three steps are learnt the waypoint is planner.lookahead along the path.
    np.testing.assert_allclose(distances[:3], 0.6)
    assert distances[3] == pytest.approx(expected)
    assert sela_lookahead(d.stepper.sela) == pytest.approx(expected)


def test_looking_two_steps_ahead_the_second_waypoint_is_as_far_again(monkeypatch):
    d = _reach_driver(1.0)
    sela = d.stepper.sela
    sela.set_config(dataclasses.replace(sela.config, planner_horizon=2))
    asked = []
    ask = sela.ask

    def spy(pose, waypoint=None, next_waypoint_xy=None, map_trusted=False):
        asked.append((np.array(pose[:2]), waypoint, next_waypoint_xy))
        return ask(pose, waypoint, next_waypoint_xy, map_trusted)

    monkeypatch.setattr(sela, 'ask', spy)
    _walk(d, d.start(goal=(3.0, 0.0)), (0.2, 0.0, 0.0), 4)
    pose, first, second = asked[-1]
    assert np.linalg.norm(first - pose) == pytest.approx(0.2)
    assert np.linalg.norm(second - pose) == pytest.approx(0.4)
    pose, first, second = asked[0]
    assert np.linalg.norm(second - pose) == pytest.approx(1.2)


def test_the_waypoint_is_taken_as_the_step_starts_after_the_verdict():
    # A plan answered before the detector's verdict on the step before: the waypoint uses
    # what that step taught once it is learnt, as when the verdict comes first.
    d = _reach_driver(1.0)
    gaits, request = _walk(d, d.start(goal=(3.0, 0.0)), (0.2, 0.0, 0.0), 2)
    start = tuple(request.start)
    gait = only(d(PlanReceived(request.step, start, path=(start[:2], (3.0, 0.0)))), SendGait)
    out = d.outcome(gait, (0.2, 0.0, 0.0))
    early = only(out, RequestPlan)
    start = tuple(early.start)
    assert d(PlanReceived(early.step, start, path=(start[:2], (3.0, 0.0)))) == []
    gait = only(d(VerdictReceived(gait.behavior_id, False)), SendGait)
    assert np.linalg.norm(np.subtract(gait.waypoint, gait.pose[:2])) == pytest.approx(0.2)
