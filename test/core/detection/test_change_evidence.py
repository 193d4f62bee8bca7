"""A restart of learning needs evidence that the robot changed; what it sets aside is kept."""
import json
from dataclasses import replace

import numpy as np
import pytest

from sela_ros.core.detection.change_evidence import EvidenceConfig, change_evidence, repeat_spread
from sela_ros.core.learning import SELA, SE2Motion
from sela_ros.core.mission import MissionLogic
from sela_ros.core.storage import persistence

PRIOR_GR = (0.3, 0.0, 0.0)


def _sela(m=60, seed=0):
    rng = np.random.default_rng(seed)
    candidates = rng.random((m, 2))
    prior = np.tile(PRIOR_GR, (m, 1))
    return SELA(candidates, prior, SE2Motion())


def _learn(sela, rng, gaits, times, noise=0.03, gr=(0.2, 0.05, 0.0)):
    for _ in range(times):
        for g in gaits:
            sela.tell(g, np.asarray(gr) + np.r_[rng.normal(0, noise, 2), 0.0])


def test_the_spread_of_repeated_gaits_is_pooled():
    indices = [1, 1, 2, 2, 3]
    observed = [[0.0, 0.0], [0.2, 0.0], [1.0, 1.0], [1.0, 1.2], [5.0, 5.0]]
    # Each pair is 0.2 m apart on one coordinate: squared deviations 0.02 each, 2 dof each.
    assert repeat_spread(indices, observed) == pytest.approx(np.sqrt(0.04 / 4))
    assert repeat_spread([1, 2], [[0, 0], [1, 1]]) == 0.0


def test_one_gait_far_from_what_it_did_is_no_evidence():
    sela, rng = _sela(), np.random.default_rng(1)
    gaits = [3, 7, 11, 19, 23]
    _learn(sela, rng, gaits, 3)
    _learn(sela, rng, [3, 7, 11, 19], 1)
    sela.tell(23, [-0.4, 0.3, 0.0])  # 0.7 m off: a chained start gone wrong, once
    evidence = sela.change_evidence()
    assert not evidence.changed
    assert evidence.far_off == 1 and evidence.learnt == 5, evidence


def test_several_learnt_gaits_far_off_at_once_are_a_new_damage():
    sela, rng = _sela(), np.random.default_rng(2)
    gaits = [3, 7, 11, 19, 23]
    _learn(sela, rng, gaits, 3)
    before = len(sela.observations[0])
    _learn(sela, rng, [3], 1)  # still as it was
    _learn(sela, rng, [7, 11, 19], 1, gr=(-0.2, -0.1, 0.0))  # a leg lost: 0.4 m short
    evidence = sela.change_evidence()
    assert evidence.changed and evidence.far_off == 3, evidence
    assert evidence.first == before + 1  # the first step of the new robot
    assert 'learnt gait(s)' in evidence.describe()


def test_untried_gaits_far_from_the_prior_are_no_evidence():
    # Learning in progress: gaits never tried do what the (intact) prior did not say.
    sela, rng = _sela(), np.random.default_rng(3)
    _learn(sela, rng, [3, 7], 3)
    for g in (30, 31, 32, 33, 34, 35, 36, 37):
        sela.tell(g, [-0.3, 0.2, 0.0])
    evidence = sela.change_evidence(EvidenceConfig(max_sigma=0.05))
    assert not evidence.changed and evidence.learnt == 0, evidence


def test_falls_learnt_as_no_displacement_are_not_weighed():
    sela, rng = _sela(), np.random.default_rng(4)
    gaits = [3, 7, 11, 19, 23]
    _learn(sela, rng, gaits, 3)
    for g in (3, 7, 11, 19):
        sela.tell(g, [0.0, 0.0, 0.0])  # fell and was reset: learnt as no displacement
    assert not sela.change_evidence().changed


def test_the_evidence_config_is_checked():
    with pytest.raises(ValueError, match='adaptation.evidence.window'):
        EvidenceConfig(window=0)
    with pytest.raises(ValueError, match='adaptation.evidence.share'):
        EvidenceConfig(share=1.5)


def test_without_earlier_observations_nothing_is_learnt_enough_to_judge():
    evidence = change_evidence(np.random.default_rng(0).random((5, 2)), np.zeros((5, 3)),
                               [0, 1, 2], np.ones((3, 3)), 0.1, 1.0, 0.001)
    assert not evidence.changed and evidence.learnt == 0


def _adapting_logic():
    logic = MissionLogic(_sela(), adapt_on_start=True, on_detection='evidence')
    rng = np.random.default_rng(5)
    pose = np.zeros(3)
    decisions = {}

    def step(gait, gr):
        d = logic.decide(pose, np.array([0.3, 0.0]))
        d = decisions.setdefault(gait, replace(d, index=gait))
        logic.outcome(d, pose, np.asarray(gr) + np.r_[rng.normal(0, 0.02, 2), 0.0])
    return logic, step


def test_a_detection_on_one_surprise_keeps_everything_and_a_new_damage_sets_aside():
    logic, step = _adapting_logic()
    for _ in range(3):
        for g in (3, 7, 11, 19, 23):
            step(g, (0.2, 0.05, 0.0))
    step(23, (-0.4, 0.3, 0.0))  # one surprise
    learned = len(logic.sela.observations[0])
    assert logic.adapt() is True and logic.restarts == 0
    assert len(logic.sela.observations[0]) == learned
    for g in (7, 11, 19):  # the robot changed
        step(g, (-0.2, -0.1, 0.0))
    assert logic.adapt() is False and logic.restarts == 1
    idx, _ = logic.sela.observations
    assert idx.tolist() == [23, 7, 11, 19]  # from the first step far off: learnt again
    aside = logic.sela.set_aside_learning
    assert len(aside) == 1 and len(aside[0]['indices']) == learned - 1
    assert 'far from what they did' in aside[0]['reason']
    # Kept in the state and recoverable.
    state = json.loads(json.dumps(logic.sela.state_dict()))
    other = _sela()
    other.load_state_dict(state)
    assert other.set_aside_learning == aside
    assert other.recover() == learned - 1
    assert len(other.observations[0]) == learned + 3 and not other.set_aside_learning


def test_a_users_clear_forgets_what_was_set_aside_too():
    logic = MissionLogic(_sela(), adapt_on_start=True, on_detection='reset')
    pose = np.zeros(3)
    for _ in range(2):
        logic.outcome(logic.decide(pose, np.array([0.3, 0.0])), pose, [0.2, 0.0, 0.0])
    logic.adapt()
    assert logic.sela.set_aside_learning
    logic.forget(adapt_on_start=False)
    assert not logic.sela.set_aside_learning and not len(logic.sela.observations[0])
    assert logic.sela.state_dict()['set_aside'] == []


def test_the_reset_policy_sets_aside_too():
    logic = MissionLogic(_sela(), adapt_on_start=True, on_detection='reset')
    pose = np.zeros(3)
    for _ in range(4):
        logic.outcome(logic.decide(pose, np.array([0.3, 0.0])), pose, [0.2, 0.0, 0.0])
    assert logic.adapt() is False
    assert len(logic.sela.observations[0]) == 1
    assert len(logic.sela.set_aside_learning[0]['indices']) == 4


def test_set_aside_learning_is_bounded_and_checked_in_the_state_file(tmp_path):
    sela = _sela()
    for n in range(25):
        sela.tell(n % 60, [0.1, 0.0, 0.0])
        sela.set_aside(f'episode {n}')
    assert len(sela.set_aside_learning) == 20
    assert sela.set_aside_learning[-1]['reason'] == 'episode 24'
    path = tmp_path / 'state.json'
    snapshot = {'sela': sela.state_dict(), 'mission': {}}
    persistence.atomic_write_json(path, persistence.state_document(60, snapshot))
    assert persistence.load_state(path, 60)['sela']['set_aside'][0]['reason'] == 'episode 5'
    snapshot['sela']['set_aside'][3]['generic_rewards'][0][0] = 5.0
    persistence.atomic_write_json(path, persistence.state_document(60, snapshot))
    with pytest.raises(persistence.StateError, match=r'set_aside\[3\]\.generic_rewards: 1 '
                       r'row\(s\) move the robot more than outcome.max_displacement 2 m'):
        persistence.load_state(path, 60)


@pytest.mark.slow
def test_forty_goals_on_a_robot_whose_damage_never_changes_restart_nothing():
    """The in-process product loop (the node's step cycle and defaults), 40 successive goals:
    this damage and seed restarted learning twice under the single-gait rule."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[3] / 'benchmarks'))
    from bench_restarts import false_restarts

    # The map trusted until the detector fires: then it keeps judging while adapting.
    reached, mission = false_restarts('remove:middle_right', 1, 40, adapt_on_start=False)
    assert reached == 40
    assert mission.fires, 'no detection while adapting: nothing was put to the test'
    assert mission.restarts == [] and mission.stepper.logic.restarts == 0
    assert mission.stepper.sela.set_aside_learning == []
    # Every step learnt from the first detection on: nothing erased.
    assert len(mission.stepper.sela.observations[0]) == mission.steps - mission.fires[0] + 1
