"""A mission of several goals, visited in order with all that was learned (ROS-free).

Functions over a :class:`~sela_ros.core.stepper.MissionStepper`, like
:mod:`sela_ros.core.mission_state`: the stepper calls them when goals arrive and when one of
them is reached.
"""
import numpy as np

from sela_ros.core.mission_status import goal_status
from sela_ros.core.stepper_io import Level, Report, SaveState, State


def take_goals(stepper, goals):
    """The mission is now ``goals`` in order (one goal: a plain goal)."""
    goal = np.asarray(goals[0], dtype=float).reshape(-1)[:2]
    rest = [np.asarray(g, dtype=float).reshape(-1)[:2] for g in goals[1:]]
    # A restored mission not yet checked against odometry may still be dropped: the same
    # goal then starts afresh from where the robot is, so that 'taken' stays true (a gait
    # in flight at the restart is still awaited; if it never answers, the new mission goes
    # on without it: MissionStepper._on_tick).
    unchecked = stepper.resume is not None and stepper.state is not State.EXECUTING
    if (stepper.goal is not None and np.array_equal(goal, stepper.goal)
            and stepper.state not in (State.IDLE, State.DONE) and stepper.resume is None):
        stepper.goals_left, stepper.goal_count = rest, stepper.goal_index + len(rest)
        return [goal_status(stepper, 'goal already in progress')]  # it goes on
    stepper.goals_left, stepper.goal_index, stepper.goal_count = rest, 1, len(goals)
    stepper.sela.set_goal(goal)
    stepper.goal = goal
    stepper._plan = None
    if unchecked:
        stepper.resume = stepper.pose = None  # a new mission, from where the robot is
    stepper.steps = 0
    stepper.result = None
    stepper.mission_id += 1
    if stepper.state in (State.IDLE, State.DONE):
        stepper.state = State.READY
    # The goal is announced as taken once its save is on disk (acknowledged means durable).
    out = [Report(Level.OK, f'new goal ({goal[0]:.2f}, {goal[1]:.2f})'),
           SaveState(stepper.snapshot()), goal_status(stepper, 'new goal')]
    if stepper.hold:
        out.append(Report(Level.ERROR, stepper.hold))
    return out


def next_goal(stepper, pose):
    """A goal of the mission is reached: on to the next, with all that was learned."""
    reached, steps = stepper.goal, stepper.steps
    stepper.goal = stepper.goals_left.pop(0)
    stepper.sela.set_goal(stepper.goal)
    stepper.goal_index += 1
    stepper.steps = 0
    stepper._plan = None
    message = (f'goal {stepper.goal_index - 1}/{stepper.goal_count} reached after {steps} steps')
    return [Report(Level.OK, f'{message}, pose ({pose[0]:.2f}, {pose[1]:.2f}); next goal '
                   f'({stepper.goal[0]:.2f}, {stepper.goal[1]:.2f})'),
            SaveState(stepper.snapshot()),
            goal_status(stepper, message, reached=reached, reached_steps=steps)]
