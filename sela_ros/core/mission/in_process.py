"""The mission in process: the ``sela_adapter`` node's decision loop, driven directly. ROS-free.

:func:`run_mission` drives a :class:`~sela_ros.core.mission.MissionStepper` (the object the
``sela_adapter`` node drives from DDS messages) against an environment, a planner and the
damage detector called directly: every experiment that reports SELA's figures goes through
it, so a figure is what a user of the nodes gets. For the same seed the node and this loop
take the same gaits in the same order: they are the same code, fed the same observations.

One step:

1. the reward selection layer (``planner``) gives the whole path to the goal; the stepper
   takes the waypoint ``planner.lookahead`` along it (and, looking two steps ahead, the next);
2. ``SELA.ask`` picks the behaviour whose predicted end is closest to the waypoint (UCB);
3. the robot executes it; the observed generic reward comes back;
4. while adapting, ``SELA.tell`` learns it;
5. the damage detector compares it with the prediction; when it fires, adaptation starts.

A fall is got up from where the robot lies (the environment rights it); with
``reset_on_fall`` the robot is put back at the start instead, as the node does through
``/sim_bridge/reset``. An implausible outcome (``outcome.max_displacement``, e.g. under a
large observation noise) is refused as the node refuses it: never learnt nor judged by the
damage detector; once ``outcome_timeout`` has passed the step is over and the next one is
planned from odometry, and after ``max_refused_steps`` such steps in a row the mission fails
with the reason.
"""
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from sela_ros.core.detection import DamageDetector, DetectorConfig
from sela_ros.core.geometry import quaternion_to_yaw, yaw_to_quaternion
from sela_ros.core.learning.self_model import choose
from sela_ros.core.mission.stepper import MissionStepper
from sela_ros.core.mission.stepper_io import (
    DamageSimulated,
    GoalsReceived,
    MissionEnded,
    OutcomeReceived,
    PlanReceived,
    PoseObserved,
    PublishStatus,
    RequestPlan,
    RequestReset,
    ResetDone,
    SendGait,
    SimulateDamage,
    StepperConfig,
    Tick,
    VerdictReceived,
)
from sela_ros.core.planning import PlanningError


def as_seen_in_odometry(pose):
    """The pose after a trip through nav_msgs/Odometry (yaw -> quaternion -> yaw); a point
    robot's (x, y) as it is."""
    pose = np.asarray(pose, dtype=float).reshape(-1)
    if len(pose) != 3:
        return pose.copy()
    x, y, yaw = (float(v) for v in pose)
    return np.array([x, y, quaternion_to_yaw(*yaw_to_quaternion(yaw))])


@dataclass
class MissionRun:
    """What a mission did.

    Attributes:
        success: every goal reached (judged on the observed pose, as the adapter judges).
        end: the stepper's :class:`~sela_ros.core.mission.stepper_io.MissionEnded`.
        logic: the stepper's :class:`~sela_ros.core.mission.MissionLogic` (``records``: the
            steps).
        goal_steps: gaits executed when each goal of the mission was reached.
        falls: steps that ended fallen.
        refused: gaits executed whose outcome was refused (implausible): never learnt.
    """

    success: bool
    end: MissionEnded
    logic: object
    goal_steps: list = field(default_factory=list)
    falls: int = 0
    refused: int = 0

    @property
    def steps(self) -> int:
        """Gaits executed over the whole mission (those whose outcome was refused too)."""
        return self.logic.steps + self.refused


def run_mission(env, sela, goals, planner, detector_config=None, stepper_config=None,
                on_step=None, detect=True, self_model=None, simulate=None) -> MissionRun:
    """Run one mission in process, through the node's stepper, from wherever ``env`` stands.

    Args:
        env: the robot: ``observed_pose()`` (the latest observation), ``true_pose()``,
            ``execute(index)`` (runs the archive's gait ``index``, returns the observed pose
            after it; a fallen robot is righted where it lies), ``reset()`` (back at the
            start: only with ``stepper_config.reset_on_fall``); optionally ``falls`` (a
            count) and ``standing`` (the next gait starts from the settled standing state).
        sela: the :class:`~sela_ros.core.learning.SELA` learner (e.g.
            :func:`~sela_ros.core.mission.make_sela`).
        goals: ``[(x, y), ...]`` visited in order (one goal: a plain mission).
        planner: ``(start_xy, goal_xy) -> path (n, 2)``, the reward selection layer.
        detector_config: the damage detector's (:class:`DetectorConfig`, the node's
            defaults if None).
        stepper_config: :class:`StepperConfig` (the node's defaults if None).
        on_step: called with each step's record once the step is judged.
        detect: run the damage detector (False: adaptation only as ``adapt_on_start``).
        self_model: a :class:`~sela_ros.core.learning.self_model.SelfModel` that reads each
            step's feet (``env.last_execution.duty_factors``); None: none.
        simulate: ``(damage, gaits) -> (generic rewards (n, k), fallen (n,), duty factors
            (n, legs))``, the robot's simulator, for the self-model's hypotheses
            (:func:`answer_request`): run here at once, its answer given to the stepper
            ``self_model.config.delay(gaits asked)`` gaits later (the time it takes a robot
            beside its mission).
    """
    config = stepper_config or StepperConfig()
    stepper = MissionStepper(sela, config, self_model=self_model)
    simulated = []  # (the gaits sent when it is answered, DamageSimulated)
    detector = DamageDetector(detector_config or DetectorConfig())
    now = 0.0  # the stepper's time: one second per event, so no time-out fires unless waited
    goals = [tuple(float(v) for v in np.asarray(g, dtype=float).reshape(-1)[:2])
             for g in goals]

    def handle(event, wait=0.0):
        nonlocal now
        now += 1.0 + wait
        return stepper.handle(event, now)

    def odometry():
        return PoseObserved(as_seen_in_odometry(env.true_pose()))

    commands = deque(handle(odometry()))
    commands += handle(GoalsReceived(tuple(goals)))
    end, goal_steps, falls, refused = None, [], 0, 0
    while commands:
        command = commands.popleft()
        events = []
        if isinstance(command, RequestPlan):
            try:
                path = planner(np.asarray(command.start, float)[:2], command.goal)
                events.append(PlanReceived(command.step, command.start,
                                           path=tuple(map(tuple, np.asarray(path, float)))))
            except PlanningError as exc:
                events.append(PlanReceived(command.step, command.start, None, str(exc)))
        elif isinstance(command, SimulateDamage):
            answer = DamageSimulated(command.damage, command.gaits, error='no simulator') \
                if simulate is None else answer_request(command, simulate)
            simulated.append((stepper.logic.steps + self_model.config.delay(len(command.gaits)),
                              answer))
        elif isinstance(command, SendGait):
            for due, answer in [s for s in simulated if s[0] <= stepper.logic.steps]:
                simulated.remove((due, answer))
                commands += handle(answer)
            before = np.asarray(env.observed_pose(), dtype=float).copy()
            standing = bool(getattr(env, 'standing', False))
            fell = getattr(env, 'falls', 0)
            after = np.asarray(env.execute(command.index), dtype=float).copy()
            fallen = getattr(env, 'falls', 0) > fell
            falls += int(fallen)
            observed = sela.motion.generic_reward(before, after)
            learnt = stepper.logic.steps
            execution = getattr(env, 'last_execution', None)
            duty = None if execution is None else tuple(map(float, execution.duty_factors))
            commands += handle(OutcomeReceived(
                command.behavior_id, tuple(observed), tuple(after), fallen,
                true_pose=tuple(env.true_pose()), standing_start=standing,
                start_pose=tuple(before), duty_factors=duty))
            if stepper.logic.steps == learnt:
                # Refused, as the node refuses it: the detector does not judge it either, and
                # once outcome_timeout has passed with no other outcome the step is over; the
                # next one starts from odometry (or the mission fails, max_refused_steps).
                refused += 1
                commands += handle(odometry())
                commands += handle(Tick(), wait=config.outcome_timeout)
                continue
            if detect:
                verdict = detector.observe(command.predicted_gr, observed, command.sigma)
                events.append(VerdictReceived(command.behavior_id, verdict.fire, verdict.error,
                                              detector.config.threshold))
            else:
                events.append(VerdictReceived(command.behavior_id, False))
        elif isinstance(command, RequestReset):
            env.reset()
            events += [ResetDone(True, 'robot back at the start'), odometry()]
        elif isinstance(command, PublishStatus) and 'goal_reached' in command.values:
            goal_steps.append(stepper.logic.steps + refused)
        elif isinstance(command, MissionEnded):
            end = command
            if command.success:
                goal_steps.append(stepper.logic.steps + refused)
        for event in events:
            commands += handle(event)
        if isinstance(command, SendGait) and on_step is not None:
            on_step(stepper.logic.records[-1])
    if end is None:  # the stepper stopped without a result: a bug, said as one
        raise RuntimeError(f'the mission stopped in state {stepper.state.value} without a '
                           'result')
    return MissionRun(bool(end.success), end, stepper.logic, goal_steps, falls, refused)


def settle_request(command: SimulateDamage, simulate) -> str:
    """The damage a self-model's :class:`SimulateDamage` settles on: the one asked for, or a
    smaller one that explains the feet as well
    (:func:`~sela_ros.core.learning.self_model.choose`), from the gaits the robot ran
    simulated on each (``simulate(damage, gaits) -> (gr, fallen, duty)``)."""
    return command.damage if command.feet is None else choose(command.feet, command.damage,
                                                              simulate)


def simulated_answer(command: SimulateDamage, damage, gr, fallen) -> DamageSimulated:
    """The answer to ``command``: ``damage`` (:func:`settle_request`'s) simulated on its
    gaits, ``gr`` ``(n, k)`` and ``fallen`` ``(n,)``."""
    return DamageSimulated(damage, command.gaits, tuple(map(tuple, np.asarray(gr, float))),
                           tuple(map(bool, fallen)),
                           asked=command.damage if damage != command.damage else '')


def answer_request(command: SimulateDamage, simulate) -> DamageSimulated:
    """The answer to a self-model's :class:`SimulateDamage`, in one go: the damage it
    settles on (:func:`settle_request`) simulated on the gaits asked for. The node runs the
    same two parts in its worker processes, :func:`run_mission` here."""
    damage = settle_request(command, simulate)
    gr, fallen, _ = simulate(damage, np.asarray(command.gaits, dtype=int))
    return simulated_answer(command, damage, gr, fallen)
