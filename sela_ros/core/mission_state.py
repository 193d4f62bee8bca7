"""What of a mission goes to the state file. ROS-free.

:func:`mission_snapshot` is the ``sela`` (what was learned) and ``mission`` (where the
mission stands) sections of the adapter's state file (:mod:`sela_ros.core.persistence`
writes it); :meth:`MissionStepper.restore <sela_ros.core.stepper.MissionStepper.restore>`
takes them back, with :func:`pending_from_snapshot` for a gait that was in flight.
"""
import numpy as np

from sela_ros.core.sela import Decision
from sela_ros.core.stepper_io import PendingStep, State


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


def pending_from_snapshot(pending, step, now, outcome_timeout):
    """The gait in flight that a snapshot saved (its ``pending``), as a
    :class:`~sela_ros.core.stepper_io.PendingStep` waiting for its outcome from ``now``."""
    d = Decision(index=int(pending['index']), waypoint=np.array(pending['waypoint']),
                 predicted_gr=np.array(pending['predicted_gr']),
                 predicted_pose=np.array(pending['predicted_pose']),
                 reward=float(pending['reward']), sigma=float(pending['sigma']))
    return PendingStep(step=step, pose=np.array(pending['pose']), t_start=now,
                       deadline=now + outcome_timeout, waypoint=d.waypoint, decision=d,
                       behavior_id=int(pending['id']), t_sent=now)


def _list(values):
    return np.asarray(values, dtype=float).tolist()
