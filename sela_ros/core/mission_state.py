"""What of a mission goes to the state file, and how it comes back. ROS-free.

:func:`mission_snapshot` is the ``sela`` (what was learned) and ``mission`` (where the
mission stands) sections of the adapter's state file (:mod:`sela_ros.core.persistence`
writes it); :func:`restore_mission` takes them back into a fresh stepper: what was learned
always, a mission in progress only if the robot turns out to be where it was.
"""
import numpy as np

from sela_ros.core.geometry import planar_distance
from sela_ros.core.sela import Decision
from sela_ros.core.stepper_io import Level, PendingStep, Report, SaveState, State


def mission_snapshot(stepper):
    """What a :class:`~sela_ros.core.stepper.MissionStepper` learned and where its mission
    stands, as JSON-able values (the ``sela`` and ``mission`` sections of the state file)."""
    p = stepper.pending
    pending = None
    if p is not None and p.decision is not None and stepper.state in (State.EXECUTING,
                                                                      State.VERDICT):
        d = p.decision
        pending = {'id': p.behavior_id, 'step': p.step, 'index': int(d.index),
                   'pose': _list(p.pose), 'waypoint': _list(d.waypoint),
                   'predicted_gr': _list(d.predicted_gr),
                   'predicted_pose': _list(d.predicted_pose), 'reward': d.reward,
                   'sigma': d.sigma}
    last = stepper.logic.last
    pose = stepper.current_pose()
    return {'sela': stepper.sela.state_dict(), 'mission': {
        'state': stepper.state.value, 'steps': stepper.steps, 'mission_id': stepper.mission_id,
        'failed_steps': stepper.failed_steps,
        'goal': None if stepper.goal is None else _list(stepper.goal),
        'goals_left': [_list(g) for g in stepper.goals_left],
        'goal_index': stepper.goal_index, 'goal_count': stepper.goal_count,
        'pose': None if pose is None else _list(pose),
        'adapting': stepper.logic.adapting, 'adaptations': stepper.logic.adaptations,
        'last': None if last is None else [int(last[0]), _list(last[1])],
        'next_id': stepper.next_id, 'pending': pending, 'reset_needed': stepper.reset_needed}}


def restore_mission(stepper, snapshot, now):
    """Take back what :func:`mission_snapshot` saved into ``stepper``; returns the
    commands (reports) it gives. Raises KeyError, TypeError or ValueError on a bad one.

    What was learned always comes back. A mission in progress comes back only if the
    robot turns out to be where it was (the first odometry decides); a gait in flight
    waits for its outcome.
    """
    stepper.sela.load_state_dict(snapshot['sela'])
    m = snapshot['mission']
    stepper.logic.adapting = bool(m['adapting'])
    stepper.logic.adaptations = int(m['adaptations'])
    last = m['last']
    stepper.logic.last = None if last is None else (int(last[0]), np.array(last[1], float))
    stepper.next_id = int(m['next_id'])
    stepper.failed_steps = int(m.get('failed_steps', 0))
    stepper.mission_id = stepper.restored_mission = int(m.get('mission_id', 0))
    state = State(m['state'])
    if m['goal'] is None or state in (State.IDLE, State.DONE):
        return []
    stepper.goal = np.array(m['goal'], dtype=float)
    stepper.sela.set_goal(stepper.goal)
    stepper.goals_left = [np.array(g, dtype=float) for g in m.get('goals_left', [])]
    stepper.goal_index = int(m.get('goal_index', 1))
    stepper.goal_count = int(m.get('goal_count', 1 + len(stepper.goals_left)))
    stepper.steps = int(m['steps'])
    stepper.reset_needed = bool(m.get('reset_needed', False))
    pending = m.get('pending')
    if pending is not None and state is State.EXECUTING:
        d = Decision(index=int(pending['index']), waypoint=np.array(pending['waypoint']),
                     predicted_gr=np.array(pending['predicted_gr']),
                     predicted_pose=np.array(pending['predicted_pose']),
                     reward=float(pending['reward']), sigma=float(pending['sigma']))
        stepper.pending = PendingStep(
            step=stepper.steps, pose=np.array(pending['pose']), t_start=now,
            deadline=now + stepper.config.outcome_timeout, waypoint=d.waypoint, decision=d,
            behavior_id=int(pending['id']), t_sent=now)
        stepper.resume = stepper.pending.pose
        stepper.state = State.EXECUTING  # the outcome may be waiting (it is latched)
        return [Report(Level.WARN, f'resuming: waiting for the outcome of command '
                       f"{pending['id']}")]
    if m['pose'] is None:
        stepper.goal = None
        return [Report(Level.ERROR, 'mission dropped: the state file has no pose to '
                       'check the robot against; send the goal again')]
    if pending is not None:
        stepper.last_id = int(pending['id'])  # a late verdict on it still counts
    stepper.resume = np.array(m['pose'], dtype=float)
    stepper.state = State.READY
    return [Report(Level.WARN, f'mission to ({stepper.goal[0]:.2f}, {stepper.goal[1]:.2f}) '
                   'restored: checking that the robot is where it was')]


def _list(values):
    return np.asarray(values, dtype=float).tolist()


def drop_mission(stepper, pose, saved):
    """The robot is not where the state file puts it: the mission is dropped (what was
    learned stays)."""
    message = (f'mission to ({stepper.goal[0]:.2f}, {stepper.goal[1]:.2f}) dropped: the robot '
               f'is {planar_distance(pose, saved):.2f} m from where the state file puts it '
               f'(tolerance {stepper.config.pose_tolerance} m); send the goal again')
    stepper.resume = stepper.pending = None
    stepper.state = State.IDLE
    stepper.reset_needed = False
    return [Report(Level.ERROR, message), SaveState(mission_snapshot(stepper))]


def abandon_restored_gait(stepper, pose, saved):
    """The gait in flight at a restart never answered and the robot is elsewhere, but a goal
    came since: that mission goes on from where the robot is, without the gait."""
    behavior_id = stepper.pending.behavior_id
    stepper.resume = stepper.pending = stepper.pose = None
    stepper.state = State.READY
    stepper.steps = max(stepper.steps - 1, 0)  # the step never happened
    return [Report(Level.WARN, f'command {behavior_id}, in flight at the restart, never '
                   f'answered and the robot is {planar_distance(pose, saved):.2f} m from '
                   'where it was sent: going on with the new goal from here')]


def check_resume(stepper, pose):
    """The first odometry after a restore: go on from there, or drop the mission."""
    saved = stepper.resume
    if planar_distance(pose, saved) > stepper.config.pose_tolerance:
        return drop_mission(stepper, pose, saved)
    stepper.resume = None
    stepper.pose = None  # plan from where the robot is
    return [Report(Level.WARN, f'mission resumed at step {stepper.steps}: the robot is '
                   f'{planar_distance(pose, saved):.3f} m from where the state file puts it')]
