"""Mission logic, persistence and the planner's map description."""
import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from sela_ros.core.learning import SELA, SE2Motion, SELAConfig
from sela_ros.core.mission import MissionLogic, as_seen_in_odometry
from sela_ros.core.storage.persistence import StateError, atomic_write_json, load_state, set_aside
from sela_ros.nodes.planner_node import grid_from_description, load_map_file


def _sela():
    rng = np.random.default_rng(0)
    candidates = rng.random((50, 2))
    prior = np.column_stack([candidates * 0.6 - 0.3, np.zeros(50)])
    return SELA(candidates, prior, SE2Motion(), goal=(1.0, 0.0),
                config=SELAConfig(planner_lookahead=1e9))


def test_mission_trusts_the_map_until_adapt_then_learns_and_restarts():
    logic = MissionLogic(_sela(), on_detection='reset')
    pose = np.zeros(3)
    d1 = logic.decide(pose, np.array([0.3, 0.0]))
    assert logic.prediction_sigma(d1) == 0.0  # the intact map is trusted
    logic.outcome(d1, pose, [0.05, 0.1, 0.2])
    assert len(logic.sela.observations[0]) == 0  # not adapting: nothing learned
    logic.adapt()
    assert logic.adapting and logic.records[-1].detected
    assert logic.sela.observations[0].tolist() == [d1.index]  # learns the triggering step
    d2 = logic.decide(pose, np.array([0.3, 0.0]))
    logic.outcome(d2, pose, [0.1, 0.0, 0.0])
    assert len(logic.sela.observations[0]) == 2
    logic.adapt()  # a second detection: restart from scratch with the latest outcome
    assert logic.sela.observations[0].tolist() == [d2.index] and logic.adaptations == 2


@pytest.mark.parametrize('reset_on_fall', [False, True])
def test_a_step_that_ends_fallen_is_learnt_as_going_nowhere_when_the_robot_is_reset(
        reset_on_fall):
    logic = MissionLogic(_sela(), adapt_on_start=True, reset_on_fall=reset_on_fall)
    pose = np.zeros(3)
    decision = logic.decide(pose, np.array([0.3, 0.0]))
    tumble = [0.3, 0.05, -2.0]
    record = logic.outcome(decision, pose, tumble, fallen=True)
    assert record.fallen and record.observed_gr == tumble  # reported as it happened
    learnt = logic.sela.observations[1][0].tolist()
    assert learnt == ([0.0, 0.0, 0.0] if reset_on_fall else tumble)
    # Reset after the fall, the robot starts the next step standing: the damage priors'
    # tables ran every gait from there (SELA.tell(..., standing_start=True)).
    logic.outcome(logic.decide(pose, np.array([0.3, 0.0])), pose, [0.1, 0.0, 0.0])
    logic.outcome(logic.decide(pose, np.array([0.3, 0.0])), pose, [0.1, 0.0, 0.0])
    assert logic.sela.state_dict()['standing_starts'] == [False, reset_on_fall, False]


def test_odometry_round_trip_of_the_first_pose():
    pose = as_seen_in_odometry([0.1, -0.2, 0.3])
    assert pose[0] == 0.1 and pose[1] == -0.2 and abs(pose[2] - 0.3) < 1e-12


def test_state_file_round_trip_and_bad_files(tmp_path):
    path = tmp_path / 'state.json'
    assert load_state(path, 10) is None
    state = {'format': 1, 'archive_size': 10, 'mission': {},
             'sela': {'num_candidates': 10, 'indices': [1], 'generic_rewards': [[0.1, 0, 0]]}}
    atomic_write_json(path, state)
    assert load_state(path, 10) == state
    with pytest.raises(StateError, match='archive of 10 behaviours, the loaded archive has 11'):
        load_state(path, 11)
    path.write_text('{"format": 1, "archive_')
    with pytest.raises(StateError, match='unreadable'):
        load_state(path, 10)
    kept = set_aside(path)
    assert kept.exists() and not path.exists()
    with pytest.raises(ValueError):
        atomic_write_json(path, {'x': float('nan')})  # never a file JSON cannot read back
    assert not path.exists()


def test_atomic_write_survives_sigkill(tmp_path):
    """A writer killed mid-loop leaves a complete file: the last one it wrote."""
    path = tmp_path / 'state.json'
    code = ('import sys\nfrom sela_ros.core.storage.persistence import atomic_write_json\ni = 0\n'
            'while True:\n    atomic_write_json(sys.argv[1], {"i": i, "pad": "x" * 200000})\n'
            '    i += 1\n')
    proc = subprocess.Popen([sys.executable, '-c', code, str(path)],
                            env=dict(os.environ, PYTHONPATH=os.getcwd()))
    try:
        # Let it rewrite the file several times (a condition, not a time: a loaded machine
        # may take seconds), then kill it mid-loop.
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and _written(path) < 5:
            time.sleep(0.02)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=10)
    data = json.loads(path.read_text())
    assert data['i'] >= 5 and len(data['pad']) == 200000


def _written(path):
    try:
        return json.loads(path.read_text())['i']
    except (OSError, ValueError):
        return -1


def test_map_description_with_obstacles():
    grid = grid_from_description(0.1, [0.0, 0.0], 2.0, 1.0, [0.5, 0.0, 0.7, 0.6])
    assert grid.occupied.shape == (10, 20)
    assert grid.occupied[2, 6] and not grid.occupied[8, 6] and not grid.occupied[2, 2]


@pytest.mark.parametrize('args, match', [
    ((0.0, [0, 0], 1, 1, []), 'map.resolution'),
    ((0.1, [0, 0], 1, 1, [1, 2, 3]), 'rectangles'),
    ((0.1, [0, 0], 1, 1, [1, 1, 0, 0]), 'empty'),
    ((0.1, [0], 1, 1, []), 'map.origin'),
])
def test_bad_map_description_is_a_clear_error(args, match):
    with pytest.raises(ValueError, match=match):
        grid_from_description(*args)


def test_map_file_errors(tmp_path):
    bad = tmp_path / 'bad.yaml'
    bad.write_text('resolution: [0.1\n  origin')
    with pytest.raises(ValueError, match='not valid YAML'):
        load_map_file(bad)
    partial = tmp_path / 'partial.yaml'
    partial.write_text('resolution: 0.1\n')
    with pytest.raises(ValueError, match='missing key'):
        load_map_file(partial)
    with pytest.raises(ValueError, match='No such file'):
        load_map_file(tmp_path / 'absent.yaml')
    good = tmp_path / 'good.yaml'
    good.write_text('resolution: 0.1\norigin: [-1, -1]\nwidth: 2\nheight: 2\n'
                    'obstacles: [0, 0, 0.5, 0.5]\n')
    assert load_map_file(good).occupied.sum() > 0


class _FakeRobot:
    """Gait i moves the robot by ``grs[i]`` in its frame; gait ``tips`` tips it over (it
    gets up where it lies)."""

    def __init__(self, grs, tips=None):
        self.grs, self.tips, self.pose, self.resets, self.falls = grs, tips, np.zeros(3), 0, 0

    def true_pose(self):
        return self.pose.copy()

    observed_pose = true_pose

    def reset(self):
        self.pose, self.resets = np.zeros(3), self.resets + 1

    def execute(self, index):
        from sela_ros.core.geometry import se2_compose

        self.pose = se2_compose(self.pose, self.grs[index])
        self.falls += int(index == self.tips)
        return self.pose.copy()


@pytest.mark.parametrize('reset_on_fall', [False, True])
def test_run_mission_drives_the_stepper_to_the_goal_after_a_fall(reset_on_fall):
    from types import SimpleNamespace

    from sela_ros.core.mission import StepperConfig, make_sela, run_mission
    from sela_ros.core.planning import straight_line_planner

    rng = np.random.default_rng(3)
    descriptors = rng.random((40, 2))
    grs = np.column_stack([descriptors * 0.4 - 0.1, np.zeros(40)])
    # The gait that lands nearest the first waypoint (0.3, 0) tips the robot over.
    tips = int(np.argmin(np.hypot(grs[:, 0] - 0.3, grs[:, 1])))
    archive = SimpleNamespace(params=np.zeros((40, 36)), generic_reward=grs, kernel_sigma=0.1,
                              normalised_descriptors=lambda: descriptors)
    robot = _FakeRobot(grs, tips)
    steps = []
    run = run_mission(robot, make_sela(archive, {'planner.lookahead': 0.3}), [(1.0, 0.0)],
                      straight_line_planner, on_step=steps.append,
                      stepper_config=StepperConfig(max_steps=30, adapt_on_start=True,
                                                   reset_on_fall=reset_on_fall))
    assert run.success and run.end.code == 'succeeded' and steps == list(run.logic.records)
    first = run.logic.records[0]
    assert first.behavior_index == tips and first.fallen and run.falls >= 1
    if reset_on_fall:  # episodic: back at the start
        assert robot.resets >= 1 and run.logic.records[1].pose == [0.0, 0.0, 0.0]
    else:  # got up where it lay: the next step starts where the first one ended
        assert robot.resets == 0
        np.testing.assert_allclose(run.logic.records[1].pose, grs[tips], atol=1e-12)
    assert np.hypot(*(robot.pose[:2] - (1.0, 0.0))) < 0.1
    assert run.goal_steps == [run.steps]


def test_run_mission_ends_at_once_with_the_reason_when_the_goal_cannot_be_planned():
    from types import SimpleNamespace

    from sela_ros.core.mission import make_sela, run_mission
    from sela_ros.core.planning import GridPlanner, default_grid

    descriptors = np.random.default_rng(0).random((10, 2))
    archive = SimpleNamespace(params=np.zeros((10, 36)), kernel_sigma=0.1,
                              generic_reward=np.column_stack([descriptors, np.zeros(10)]),
                              normalised_descriptors=lambda: descriptors)
    robot = _FakeRobot(archive.generic_reward)
    run = run_mission(robot, make_sela(archive), [(40.0, 0.0)], GridPlanner(default_grid()))
    assert not run.success and run.steps == 0
    assert run.end.code == 'no_plan' and 'off the map' in run.end.reason


class _GlitchyRobot(_FakeRobot):
    """A :class:`_FakeRobot` whose gaits numbered in ``glitches`` (1, 2, ... in the order
    executed) report an end pose ``jump`` metres off in x: an implausible outcome."""

    def __init__(self, grs, glitches, jump=5.0):
        super().__init__(grs)
        self.glitches, self.jump, self.executed = set(glitches), jump, 0
        self.gaits = []

    def execute(self, index):
        self.executed += 1
        self.gaits.append(index)
        pose = super().execute(index)
        if self.executed in self.glitches:
            pose[0] += self.jump
        return pose


def _glitch_archive(seed=3):
    from types import SimpleNamespace

    descriptors = np.random.default_rng(seed).random((40, 2))
    grs = np.column_stack([descriptors * 0.4 - 0.1, np.zeros(40)])
    return SimpleNamespace(params=np.zeros((40, 36)), generic_reward=grs, kernel_sigma=0.1,
                           normalised_descriptors=lambda: descriptors)


def test_run_mission_refuses_an_implausible_outcome_as_the_node_and_goes_on_from_odometry():
    from sela_ros.core.mission import StepperConfig, make_sela, run_mission
    from sela_ros.core.planning import straight_line_planner

    archive = _glitch_archive()
    robot = _GlitchyRobot(archive.generic_reward, glitches=[1])
    run = run_mission(robot, make_sela(archive, {'planner.lookahead': 0.3}), [(1.0, 0.0)],
                      straight_line_planner,
                      stepper_config=StepperConfig(max_steps=30, adapt_on_start=True))
    assert run.success and run.end.code == 'succeeded', run.end
    assert run.refused == 1 and run.steps == robot.executed == len(run.logic.records) + 1
    # Never learnt; the next step starts from odometry (the true pose), not the glitch.
    assert len(run.logic.sela.observations[0]) == len(run.logic.records)
    np.testing.assert_allclose(run.logic.records[0].pose,
                               as_seen_in_odometry(archive.generic_reward[robot.gaits[0]]),
                               atol=1e-12)
    assert run.goal_steps == [run.steps]


def test_run_mission_fails_with_the_reason_after_max_refused_steps_in_a_row():
    from sela_ros.core.mission import StepperConfig, make_sela, run_mission
    from sela_ros.core.planning import straight_line_planner

    archive = _glitch_archive()
    robot = _GlitchyRobot(archive.generic_reward, glitches=range(1, 100))
    run = run_mission(robot, make_sela(archive, {'planner.lookahead': 0.3}), [(1.0, 0.0)],
                      straight_line_planner,
                      stepper_config=StepperConfig(max_steps=30, max_refused_steps=4))
    assert not run.success and run.end.code == 'failed'
    assert '4 outcome(s) in a row refused' in run.end.reason, run.end.reason
    assert run.refused == run.steps == robot.executed == 4 and not run.logic.records


def test_a_robot_that_starts_off_the_planners_map_is_led_onto_it_and_reaches_the_goal():
    from types import SimpleNamespace

    from sela_ros.core.mission import StepperConfig, make_sela, run_mission
    from sela_ros.core.planning import GridPlanner, OccupancyGrid

    rng = np.random.default_rng(5)
    descriptors = rng.random((60, 2))
    grs = np.column_stack([descriptors * 0.5 - 0.25, np.zeros(60)])
    archive = SimpleNamespace(params=np.zeros((60, 36)), generic_reward=grs, kernel_sigma=0.1,
                              normalised_descriptors=lambda: descriptors)
    grid = OccupancyGrid.empty(0.5, 2.5, 0.5, 2.5, 0.05)  # the start (0, 0) is off it
    assert not grid.in_map((0.0, 0.0))
    robot = _FakeRobot(grs)
    run = run_mission(robot, make_sela(archive, {'planner.lookahead': 0.3}), [(1.5, 1.2)],
                      GridPlanner(grid), stepper_config=StepperConfig(max_steps=40,
                                                                      adapt_on_start=True))
    assert run.success and run.end.code == 'succeeded', run.end
    assert np.hypot(*(robot.pose[:2] - (1.5, 1.2))) < 0.1


def test_a_long_life_keeps_the_latest_records_only_and_counts_every_step():
    logic = MissionLogic(_sela(), adapt_on_start=True, keep_records=5)
    pose = np.zeros(3)
    for _ in range(12):
        decision = logic.decide(pose, np.array([0.3, 0.0]))
        logic.outcome(decision, pose, [0.1, 0.0, 0.0])
    assert logic.steps == 12 and len(logic.records) == 5
    assert [r.step for r in logic.records] == [8, 9, 10, 11, 12]
    assert len(logic.sela.observations[0]) == 12  # what was learnt is not the records
