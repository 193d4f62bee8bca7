"""The paper's outer loop: walk to the goal, trust the map until damage is detected, then
adapt with SELA while walking. ROS-free.

:class:`MissionLogic` holds the decisions of one mission; the ``sela_adapter`` node drives it
from DDS messages and :func:`run_mission` drives it in process against the simulator, so
that, for the same seed, both take the same gaits in the same order (a test checks it).

One step:

1. the reward selection layer gives the waypoint (A* path, ``lookahead`` metres along it);
2. ``SELA.ask`` picks the behaviour whose predicted end is closest to the waypoint (UCB);
3. the robot executes it; the observed generic reward comes back;
4. if adapting, ``SELA.tell`` learns it;
5. the damage detector compares it with the prediction; when it fires, adaptation starts
   (from this observation) or, if it was running, restarts from scratch (new damage).
"""
import math
from dataclasses import asdict, dataclass

import numpy as np

from sela_ros.core.damage_detection import DamageDetector, DetectorConfig
from sela_ros.core.planning import next_waypoint
from sela_ros.core.sela import SELA, SE2Motion, SELAConfig

# SELA receives the waypoint itself (a two-point path) and must not shorten it.
_NO_LOOKAHEAD = 1e9


@dataclass
class StepRecord:
    """One mission step, as printed by the demo and stored in its summary."""

    step: int
    behavior_index: int
    pose: list
    waypoint: list
    predicted_gr: list
    observed_gr: list
    reward: float
    sigma: float
    adapting: bool
    error: float = float('nan')
    detected: bool = False
    fallen: bool = False
    true_pose: list = None

    def to_dict(self):
        return asdict(self)


def make_sela(archive, config=None):
    """A SE(2) SELA over the archive's behaviours (prior mean: the intact robot's GR)."""
    values = dict(config or {})
    values['planner.lookahead'] = _NO_LOOKAHEAD
    return SELA(archive.normalised_descriptors(), archive.generic_reward, SE2Motion(),
                config=SELAConfig.from_dict(values))


class MissionLogic:
    """The decisions of one mission; fed poses, waypoints and outcomes by its driver.

    Args:
        sela: the SELA learner over the archive.
        adapt_on_start: learn from the first step instead of waiting for the detector.
        reset_on_fall: a step that ends fallen is followed by a reset to the start, so the
            gait took the robot nowhere: it is learnt as a zero displacement (learning the
            tumble's displacement instead would make a gait that falls toward the goal look
            good, and the robot would try it again and again from the start).
    """

    def __init__(self, sela, adapt_on_start=False, reset_on_fall=False):
        self.sela = sela
        self.reset_on_fall = bool(reset_on_fall)
        self.adapting = bool(adapt_on_start)
        self.adaptations = 1 if adapt_on_start else 0
        self.last = None  # (index, observed_gr) of the latest outcome
        self.records = []

    def decide(self, pose, waypoint):
        """Step 2: the behaviour to execute from ``pose`` toward ``waypoint``."""
        pose = np.asarray(pose, dtype=float)
        waypoint = np.asarray(waypoint, dtype=float)
        self.sela.planner = lambda start, goal: np.array([pose[:2], waypoint])
        return self.sela.ask(pose)

    def outcome(self, decision, pose, observed_gr, fallen=False, true_pose=None):
        """Step 4: record the outcome of ``decision`` and learn from it when adapting."""
        observed_gr = np.asarray(observed_gr, dtype=float)
        learnt = np.zeros_like(observed_gr) if fallen and self.reset_on_fall else observed_gr
        self.sela.tell_fall(decision.index, bool(fallen))
        if self.adapting:
            self.sela.tell(decision.index, learnt)
        self.last = (decision.index, learnt)
        record = StepRecord(
            step=len(self.records) + 1, behavior_index=int(decision.index),
            pose=np.asarray(pose, float).tolist(), waypoint=decision.waypoint.tolist(),
            predicted_gr=decision.predicted_gr.tolist(), observed_gr=observed_gr.tolist(),
            reward=float(decision.reward), sigma=float(decision.sigma),
            adapting=self.adapting, fallen=bool(fallen),
            true_pose=None if true_pose is None else np.asarray(true_pose, float).tolist())
        self.records.append(record)
        return record

    def prediction_sigma(self, decision):
        """How unsure the prediction of ``decision`` is: 0 while the map is trusted."""
        return float(decision.sigma) if self.adapting else 0.0

    def adapt(self):
        """Step 5: start adaptation, or restart it from scratch if it was running."""
        if self.adapting:
            self.sela.reset_learning()
        self.adapting = True
        self.adaptations += 1
        if self.last is not None:
            self.sela.tell(*self.last)
        if self.records:
            self.records[-1].detected = True


def waypoint_for(planner, pose, goal, lookahead):
    """The reward selection layer: A* path from ``pose`` to ``goal``, then the waypoint."""
    path = planner(np.asarray(pose, float)[:2], np.asarray(goal, float))
    return next_waypoint(path, np.asarray(pose, float)[:2], lookahead), path


def as_seen_in_odometry(pose):
    """The pose after a trip through nav_msgs/Odometry (yaw -> quaternion -> yaw)."""
    x, y, yaw = (float(v) for v in pose)
    qz, qw = math.sin(yaw / 2.0), math.cos(yaw / 2.0)
    return np.array([x, y, math.atan2(2.0 * (qw * qz), 1.0 - 2.0 * (qz * qz))])


def run_mission(env, archive, goal, planner, lookahead=0.5, sela_config=None,
                detector_config=None, max_steps=100, adapt_on_start=False, on_step=None,
                reset_on_fall=False):
    """Run the whole mission in process against ``env`` (an ObservedHexapod-like object).

    The first step starts from the robot's odometry, later ones from the observed pose after
    each gait, exactly as the ``sela_adapter`` node does. With ``reset_on_fall``, a step that
    ends fallen is followed by ``env.reset()`` (the robot back at the start) and the next
    step starts from the odometry, as the node does through ``/sim_bridge/reset``.
    Returns ``(success, logic)``; success is judged on the observed pose within ``goal.eps``,
    as the adapter judges it.
    """
    sela = make_sela(archive, sela_config)
    sela.set_goal(goal)
    logic = MissionLogic(sela, adapt_on_start=adapt_on_start, reset_on_fall=reset_on_fall)
    detector = DamageDetector(detector_config or DetectorConfig())
    pose = as_seen_in_odometry(env.true_pose())
    for _ in range(max_steps):
        if sela.goal_reached(pose):
            return True, logic
        waypoint, _ = waypoint_for(planner, pose, goal, lookahead)
        decision = logic.decide(pose, waypoint)
        execution = env.execute(archive.params[decision.index])
        sigma = logic.prediction_sigma(decision)
        record = logic.outcome(decision, pose, execution.observed_generic_reward,
                               fallen=execution.fallen, true_pose=execution.true_end)
        verdict = detector.observe(decision.predicted_gr, execution.observed_generic_reward,
                                   sigma)
        record.error = verdict.error
        if verdict.fire:
            logic.adapt()
        pose = execution.observed_end
        if execution.fallen and reset_on_fall:
            env.reset()
            pose = as_seen_in_odometry(env.true_pose())
        if on_step is not None:
            on_step(record)
    return bool(sela.goal_reached(pose)), logic

