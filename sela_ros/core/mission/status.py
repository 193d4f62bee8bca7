"""The mission status, written once: what the stepper says about each step, as text.

The ``sela_adapter`` node publishes these values on ``diagnostics`` (name ``sela_adapter:
mission``) and :class:`sela_ros.tools.mission_client.MissionClient` reads them back: a
status with ``step`` is a step, with ``adapt`` a detection, with ``goal`` the goal taken
(and with ``goal_reached`` too: a goal of a mission of several was reached, on to the next),
with ``success`` the end of the mission (repeated every second while the adapter is idle,
as diagnostics are: a client that was not listening at the end still hears it). ``mission``
numbers the missions: the status of a goal and its result carry the same number.
``goal_index`` of ``goals`` says where a mission of several goals stands. Vectors are
space-separated numbers. ROS-free.
"""
import math

from sela_ros.core.mission.stepper_io import Level, PublishStatus


def mission_status(stepper, reward=None):
    """The status of ``stepper``; with ``reward``, the step that has just ended."""
    values = {'mission': stepper.mission_id, 'state': stepper.state.value,
              'steps': stepper.steps,
              'adapting': stepper.logic.adapting, 'adaptations': stepper.logic.adaptations,
              'observations': len(stepper.sela.observations[0]),
              'failed_steps': stepper.failed_steps,
              'goal_index': stepper.goal_index, 'goals': stepper.goal_count}
    p = stepper.pending
    if reward is not None:
        r = p.record
        values.update(step=r.step, behavior_id=p.behavior_id,
                      behavior_index=r.behavior_index, pose=vector_text(r.pose),
                      waypoint=vector_text(r.waypoint),
                      predicted_gr=vector_text(r.predicted_gr),
                      observed_gr=vector_text(r.observed_gr), reward=f'{reward:.6f}',
                      end_pose=vector_text(stepper.pose), fallen=r.fallen,
                      # wall time of the step: choosing, and the gait's round trip
                      decide_ms=_ms(p.t_start, p.t_sent),
                      execute_ms=_ms(p.t_sent, p.t_outcome),
                      # the prior mean the step was chosen on
                      prior=stepper.prior)
        if stepper.self_model is not None:
            values['self_model'] = stepper.self_model.status()
    if stepper.result is not None:
        values['success'] = stepper.result
    return {k: str(v) for k, v in values.items()}


def goal_status(stepper, message, reached=None, reached_steps=None):
    """Says which goal the mission now has (a client waits for it); with ``reached``, the
    goal of the mission just reached, in ``reached_steps`` steps."""
    values = dict(mission_status(stepper), goal=vector_text(stepper.goal))
    if reached is not None:
        values.update(goal_reached=vector_text(reached), goal_reached_steps=str(reached_steps))
    return PublishStatus(Level.OK, message, values)


def detection_status(stepper, verdict, message):
    """The status after a detection: the verdict that fired and what the adapter did."""
    return PublishStatus(Level.WARN, 'damage detected', dict(
        mission_status(stepper), behavior_id=str(verdict.behavior_id), adapt=message,
        error=f'{verdict.error:.6f}', threshold=str(verdict.threshold)))


def vector_text(values):
    return ' '.join(f'{float(v):.6f}' if math.isfinite(float(v)) else 'nan' for v in values)


def vector_from_text(text):
    return [float(v) for v in text.split()]


def _ms(start, end):
    return 'nan' if start is None or end is None else f'{(end - start) * 1e3:.1f}'
