"""The paper's outer loop, in process: walk to the goal, trust the map until damage is
detected, then adapt with SELA while walking. ROS-free.

:func:`run_mission` drives a :class:`~sela_ros.core.stepper.MissionStepper` against the
simulator, the planner and the damage detector called directly; the ``sela_adapter`` node
drives the same stepper from DDS messages. For the same seed both take the same gaits in
the same order: they are the same code, fed the same observations.

One step:

1. the reward selection layer gives the waypoint (A* path, ``lookahead`` metres along it);
2. ``SELA.ask`` picks the behaviour whose predicted end is closest to the waypoint (UCB);
3. the robot executes it; the observed generic reward comes back;
4. if adapting, ``SELA.tell`` learns it;
5. the damage detector compares it with the prediction; when it fires, adaptation starts
   (from this observation) or, if it was running, restarts from scratch (new damage).
"""
import time
from collections import deque

import numpy as np

from sela_ros.core.damage_detection import DamageDetector, DetectorConfig
from sela_ros.core.geometry import quaternion_to_yaw, yaw_to_quaternion
from sela_ros.core.learning import make_sela
from sela_ros.core.planning import PlanningError, next_waypoint
from sela_ros.core.stepper import MissionStepper
from sela_ros.core.stepper_io import (
    GoalReceived,
    OutcomeReceived,
    PlanReceived,
    PoseObserved,
    RequestPlan,
    RequestReset,
    ResetDone,
    SendGait,
    StepperConfig,
    VerdictReceived,
)


def waypoint_for(planner, pose, goal, lookahead):
    """The reward selection layer: A* path from ``pose`` to ``goal``, then the waypoint."""
    path = planner(np.asarray(pose, float)[:2], np.asarray(goal, float))
    return next_waypoint(path, np.asarray(pose, float)[:2], lookahead), path


def as_seen_in_odometry(pose):
    """The pose after a trip through nav_msgs/Odometry (yaw -> quaternion -> yaw)."""
    x, y, yaw = (float(v) for v in pose)
    return np.array([x, y, quaternion_to_yaw(*yaw_to_quaternion(yaw))])


def run_mission(env, archive, goal, planner, lookahead=0.5, sela_config=None,
                detector_config=None, max_steps=100, adapt_on_start=False, on_step=None,
                reset_on_fall=False, on_detection='reset', priors=None):
    """Run the whole mission in process against ``env`` (an ObservedHexapod-like object).

    The first step starts from the robot's odometry, later ones from the observed pose after
    each gait, exactly as the ``sela_adapter`` node does. With ``reset_on_fall``, a step that
    ends fallen is followed by ``env.reset()`` (the robot back at the start) and the next
    step starts from the odometry, as the node does through ``/sim_bridge/reset``.
    Returns ``(success, logic)``; success is judged on the observed pose within ``goal.eps``,
    as the adapter judges it; ``logic.records`` lists the steps. ``priors``: SELA's damage
    priors (:func:`~sela_ros.core.damage_priors.resolve_priors`), as the adapter's.
    """
    stepper = MissionStepper(make_sela(archive, sela_config, priors=priors), StepperConfig(
        max_steps=max_steps, adapt_on_start=adapt_on_start, reset_on_fall=reset_on_fall,
        on_detection=on_detection))
    detector = DamageDetector(detector_config or DetectorConfig())

    def odometry():
        return PoseObserved(as_seen_in_odometry(env.true_pose()))

    commands = deque(stepper.handle(odometry(), time.monotonic()))
    commands += stepper.handle(GoalReceived(tuple(goal)), time.monotonic())
    while commands:
        command = commands.popleft()
        events = []
        if isinstance(command, RequestPlan):
            try:
                waypoint, _ = waypoint_for(planner, command.start, command.goal, lookahead)
                events.append(PlanReceived(command.step, command.start, waypoint))
            except PlanningError as exc:
                events.append(PlanReceived(command.step, command.start, None, str(exc)))
        elif isinstance(command, SendGait):
            execution = env.execute(archive.params[command.index])
            observed = execution.observed_generic_reward
            standing = getattr(execution, 'standing_start', None)  # None: not said
            events.append(OutcomeReceived(command.behavior_id, observed, execution.observed_end,
                                          execution.fallen, true_pose=execution.true_end,
                                          standing_start=standing))
            verdict = detector.observe(command.predicted_gr, observed, command.sigma)
            events.append(VerdictReceived(command.behavior_id, verdict.fire, verdict.error,
                                          detector.config.threshold))
        elif isinstance(command, RequestReset):
            env.reset()
            events += [ResetDone(True, 'robot back at the start'), odometry()]
        for event in events:
            commands += stepper.handle(event, time.monotonic())
        if isinstance(command, SendGait):
            record = stepper.logic.records[-1]
            record.error = verdict.error
            if on_step is not None:
                on_step(record)
    return bool(stepper.result), stepper.logic
