"""The mission stepper without DDS: events in, commands out, on a fake clock.

Every state and transition of the step cycle: plan, ask, command, outcome, verdict, learn;
falls and resets, time-outs, a detector that answers late or before the outcome, an
adaptation asked mid-gait, holds, restarts (resume or drop), odometry that moves the robot.
"""
import numpy as np
import pytest
from stepper_driver import FORWARD, Driver, of, only, small_sela

from sela_ros.core.mission import MissionStepper
from sela_ros.core.mission.stepper_io import (
    AdaptRequested,
    CancelRequested,
    ClearRequested,
    GoalReceived,
    GoalsReceived,
    HoldChanged,
    Level,
    MissionEnded,
    OutcomeReceived,
    PlanReceived,
    PoseObserved,
    PublishReward,
    PublishStatus,
    Reply,
    Report,
    RequestPlan,
    RequestReset,
    ResetDone,
    SaveState,
    SendGait,
    State,
    StepperConfig,
    Tick,
    VerdictReceived,
)


def test_a_step_goes_plan_ask_command_outcome_verdict_and_the_next_plan_is_asked_early():
    d = Driver()
    request = d.start()
    assert d.state is State.PLANNING and request.step == 1 and np.allclose(request.goal, (1, 0))
    out = d.plan(request)
    gait = only(out, SendGait)
    assert d.state is State.EXECUTING and gait.behavior_id == 1 and gait.sigma == 0.0
    assert of(out, SaveState)  # the command is on disk before its outcome can come
    out = d.outcome(gait)
    assert d.state is State.VERDICT
    early = only(out, RequestPlan)  # asked before the verdict: the planner works meanwhile
    assert early.step == 2 and np.allclose(early.start[:2], (0.2, 0.0))
    status = only(out, PublishStatus).values
    assert status['step'] == '1' and status['behavior_id'] == '1'
    assert only(out, PublishReward).value == pytest.approx(-0.1)
    assert len(d.stepper.sela.observations[0]) == 0  # the map is trusted: nothing learnt
    assert d(VerdictReceived(1, False)) == []  # waits for the plan already asked
    assert d.state is State.PLANNING
    assert only(d.plan(early), SendGait).behavior_id == 2


def test_goal_reached_when_the_current_pose_is_within_eps_and_max_steps_ends_a_mission():
    d = Driver()
    request = d.start(goal=(0.25, 0.0))
    out = []
    gait = only(d.plan(request), SendGait)
    out = d.outcome(gait) + d(VerdictReceived(gait.behavior_id, False))
    assert not of(out, RequestPlan)  # within 0.1 m of the goal: no next step
    final = [s for s in of(out, PublishStatus) if 'success' in s.values]
    assert d.state is State.DONE and final[0].values['success'] == 'True'
    d = Driver(max_steps=2)
    request = d.start(goal=(5.0, 0.0))
    request = d.step(d.step(request))
    assert request is None and d.state is State.DONE and d.stepper.result is False
    assert d.stepper.steps == 2
    assert d.stepper.ended == ('max_steps', 'goal not reached: the mission took its '
                               'max_steps (2)')


def test_a_fall_is_a_failed_step_learnt_as_going_nowhere_and_the_robot_is_reset():
    d = Driver(reset_on_fall=True, adapt_on_start=True)
    gait = only(d.plan(d.start()), SendGait)
    out = d.outcome(gait, gr=(0.3, 0.1, -2.0), fallen=True)
    assert not of(out, RequestPlan)  # no plan from where it lies
    assert any('failed: the robot fell' in r.message for r in of(out, Report)
               if r.level is Level.ERROR)
    assert d.stepper.sela.observations[1].tolist() == [[0.0, 0.0, 0.0]]
    out = d(VerdictReceived(gait.behavior_id, False))
    only(out, RequestReset)
    assert d.state is State.RESETTING
    assert d(ResetDone(True, 'robot back at the start')) and d.state is State.READY
    assert d.stepper.current_pose() is None  # waits for odometry after the reset
    request = only(d(PoseObserved((0.0, 0.0, 0.0), stamp=3.0)), RequestPlan)
    assert np.allclose(request.start, 0.0) and d.stepper.failed_steps == 1


def test_a_reset_refused_or_unanswered_goes_on_from_where_the_robot_lies():
    for finish in ('refused', 'timeout'):
        d = Driver(reset_on_fall=True, outcome_timeout=5.0)
        gait = only(d.plan(d.start()), SendGait)
        d.outcome(gait, fallen=True)
        d(VerdictReceived(gait.behavior_id, False))
        assert d.state is State.RESETTING
        if finish == 'refused':
            out = d(ResetDone(False, 'not available'))
        else:
            assert d(Tick(), dt=4.0) == []
            out = d(Tick(), dt=2.0)
        assert any(r.level is Level.ERROR for r in of(out, Report))
        request = only(out, RequestPlan)  # from the pose the fall ended at
        assert np.allclose(request.start[:2], (0.2, 0.0))


def test_an_outcome_that_never_comes_resends_the_same_command_without_a_new_prediction():
    d = Driver(outcome_timeout=10.0)
    gait = only(d.plan(d.start()), SendGait)
    assert d(Tick(), dt=9.0) == []
    again = only(d(Tick(), dt=2.0), SendGait)
    assert again.resend and again.behavior_id == gait.behavior_id and again.index == gait.index
    assert d.state is State.EXECUTING
    d.outcome(gait)
    assert d.state is State.VERDICT


def test_a_planner_that_does_not_answer_is_asked_again_and_a_stale_answer_is_ignored():
    d = Driver(plan_timeout=10.0)
    first = d.start()
    again = only(d(Tick(), dt=11.0), RequestPlan)
    assert again.step == first.step == 1 and d.stepper.steps == 1
    assert d(PlanReceived(7, tuple(first.start), (0.3, 0.0))) == []  # no such request
    assert only(d.plan(again), SendGait)


def test_a_goal_that_cannot_be_planned_is_refused_and_not_retried_after_a_restart():
    d = Driver()
    request = d.start()
    out = d(PlanReceived(request.step, tuple(request.start), None, 'goal in an obstacle'))
    # The mission ends at once, with a result that says why.
    assert d.state is State.DONE and not of(out, SendGait) and d.stepper.steps == 0
    assert 'goal in an obstacle' in only(out, Report).message
    end = only(out, MissionEnded)
    assert (end.success, end.code, end.mission_id) == (False, 'no_plan', 1)
    assert 'goal in an obstacle' in end.reason
    assert of(out, PublishStatus)[-1].values['success'] == 'False'
    restarted = Driver()
    restarted.stepper.restore(of(out, SaveState)[-1].snapshot, 0.0)
    assert not of(restarted(PoseObserved((0.0, 0.0, 0.0))), SendGait)
    assert restarted.state in (State.IDLE, State.DONE)


def test_a_late_verdict_still_adapts():
    d = Driver(detector_timeout=2.0)
    gait = only(d.plan(d.start()), SendGait)
    d.outcome(gait)
    out = d(Tick(), dt=2.5)  # no verdict: the next step goes on
    assert d.state is State.PLANNING and 'no verdict' in of(out, Report)[0].message
    out = d(VerdictReceived(gait.behavior_id, True))  # late, while planning: adapt now
    assert d.stepper.logic.adapting and d.stepper.sela.observations[0].tolist() == [
        gait.index]
    assert of(out, PublishStatus)[0].values['adapt'].startswith('adaptation started')
    assert d(VerdictReceived(gait.behavior_id, True)) == []  # a replay changes nothing
    assert d.stepper.logic.adaptations == 1


def test_a_late_verdict_during_the_next_gait_adapts_from_that_gait():
    d = Driver(detector_timeout=2.0)
    gait = only(d.plan(d.start()), SendGait)
    request = only(d.outcome(gait), RequestPlan)
    d(Tick(), dt=2.5)
    second = only(d.plan(request), SendGait)
    d(VerdictReceived(gait.behavior_id, True))
    assert not d.stepper.logic.adapting  # not yet: the gait in flight comes first
    d.outcome(second)
    assert d.stepper.logic.adapting
    assert d.stepper.sela.observations[0].tolist() == [second.index]


def test_a_verdict_heard_before_its_outcome_is_applied_with_it():
    d = Driver()
    gait = only(d.plan(d.start()), SendGait)
    assert d(VerdictReceived(gait.behavior_id, True)) == []
    out = d.outcome(gait)
    assert d.state is State.PLANNING and d.stepper.logic.adapting
    assert of(out, PublishStatus)[-1].values['adapt'].startswith('adaptation started')


def test_adapt_asked_mid_gait_starts_from_that_gait_and_again_restarts_from_scratch():
    d = Driver(on_detection='reset')
    gait = only(d.plan(d.start()), SendGait)
    reply = only(d(AdaptRequested()), Reply)
    assert reply.success and 'from the outcome of command 1' in reply.message
    request = only(d.outcome(gait), RequestPlan)
    assert d.stepper.logic.adapting and len(d.stepper.sela.observations[0]) == 1
    d(VerdictReceived(gait.behavior_id, False))
    second = only(d.plan(request), SendGait)
    assert second.sigma > 0.0  # the prediction now says how unsure it is
    d.outcome(second)
    assert len(d.stepper.sela.observations[0]) == 2
    reply = only(d(AdaptRequested()), Reply)  # a new damage: restart from the latest
    assert 'adaptation restarted' in reply.message
    assert d.stepper.sela.observations[0].tolist() == [second.index]
    reply = only(d(ClearRequested()), Reply)
    assert 'forgot 1 observation' in reply.message and not d.stepper.logic.adapting


def test_a_hold_stops_gaits_until_it_is_lifted():
    d = Driver()
    out = d(HoldChanged('archive built for another simulator'))
    assert only(out, Report).level is Level.ERROR
    d(PoseObserved((0.0, 0.0, 0.0)))
    out = d(GoalReceived((1.0, 0.0)))
    assert not of(out, RequestPlan) and d.state is State.READY
    assert any('another simulator' in r.message for r in of(out, Report))
    assert d(HoldChanged('')) == []  # asking again: silent
    only(d(HoldChanged(None)), RequestPlan)


def test_the_same_goal_again_goes_on_and_a_new_one_starts_over():
    d = Driver()
    request = d.start()
    out = d(GoalReceived((1.0, 0.0)))
    assert only(out, PublishStatus).message == 'goal already in progress'
    assert d.stepper.steps == 1
    gait = only(d.plan(request), SendGait)
    out = d(GoalReceived((0.0, 1.0)))
    assert only(out, MissionEnded).code == 'preempted'  # the old mission's result
    assert of(out, PublishStatus)[-1].values['goal'] == '0.000000 1.000000'
    assert d.stepper.steps == 0 and d.state is State.EXECUTING  # the gait in flight ends
    assert only(d.outcome(gait), RequestPlan).goal.tolist() == [0.0, 1.0]


def test_each_mission_is_numbered_and_its_result_names_it_also_after_a_restart():
    d = Driver()
    request = d.start(goal=(0.25, 0.0))
    taken = only(d.log, PublishStatus).values
    assert taken['mission'] == '1'
    assert d(GoalReceived((0.25, 0.0)))[0].values['mission'] == '1'  # in progress: the same
    gait = only(d.plan(request), SendGait)
    out = d.outcome(gait) + d(VerdictReceived(gait.behavior_id, False))
    final = [s.values for s in of(out, PublishStatus) if 'success' in s.values]
    assert final[0]['mission'] == '1' and final[0]['success'] == 'True'
    assert final[0]['goal'] == '0.250000 0.000000'  # a client that missed the goal's status
    # The same goal again is a new mission: a client can tell its result from the last one.
    out = d(GoalReceived((0.25, 0.0)))
    assert {s.values['mission'] for s in of(out, PublishStatus)} == {'2'}  # taken (and done)
    snapshot = d.stepper.snapshot()
    restarted = Driver()
    restarted.stepper.restore(snapshot, 0.0)
    assert restarted.stepper.mission_id == 2
    restarted(PoseObserved((0.25, 0.0, 0.0), stamp=0.0))
    assert of(restarted(GoalReceived((3.0, 0.0))), PublishStatus)[0].values['mission'] == '3'


def test_a_mission_that_ended_before_a_restart_says_its_result_again():
    """The adapter stopped just after a mission ended, before its client heard the result:
    the restarted adapter says that result again, naming the mission, and goes on idle."""
    d = Driver()
    request = d.start(goal=(0.25, 0.0))
    gait = only(d.plan(request), SendGait)
    d.outcome(gait)
    d(VerdictReceived(gait.behavior_id, False))
    assert d.state is State.DONE
    restarted = Driver()
    out = restarted.stepper.restore(of(d.log, SaveState)[-1].snapshot, 0.0)
    result = only(out, PublishStatus)
    assert result.level is Level.OK and result.message == 'goal reached'
    assert (result.values['mission'], result.values['success'], result.values['code'],
            result.values['steps']) == ('1', 'True', 'succeeded', '1')
    assert restarted.state is State.DONE and not of(out, MissionEnded)  # no action to end
    out = restarted(GoalReceived((1.0, 0.0)))
    assert of(out, PublishStatus)[0].values['mission'] == '2'
    assert 'success' not in of(out, PublishStatus)[0].values


def test_outcomes_of_other_commands_are_ignored():
    d = Driver()
    gait = only(d.plan(d.start()), SendGait)
    out = d(OutcomeReceived(999, FORWARD, (0.2, 0.0, 0.0)))
    assert 'pairs with no command' in only(out, Report).message
    assert d(OutcomeReceived(0, FORWARD, (0.2, 0.0, 0.0))) == []  # older: silently
    assert d.state is State.EXECUTING and d.stepper.pending.behavior_id == gait.behavior_id


def test_odometry_replaces_the_pose_between_missions_and_after_a_simulator_restart():
    d = Driver()
    gait = only(d.plan(d.start(goal=(0.25, 0.0))), SendGait)
    d.outcome(gait, stamp=3.0)
    d(VerdictReceived(gait.behavior_id, False))
    assert d.state is State.DONE
    assert d(PoseObserved((0.1, 0.0, 0.0), stamp=2.0)) == []  # older (mid-gait): ignored
    assert d(PoseObserved((0.21, 0.0, 0.0), stamp=3.0)) == []  # the same place: noise
    out = d(PoseObserved((0.8, 0.5, 0.0), stamp=3.0))  # moved between missions
    assert 'starts from odometry' in only(out, Report).message
    request = only(d(GoalReceived((2.0, 0.5))), RequestPlan)
    assert np.allclose(request.start[:2], (0.8, 0.5))  # not from the stale outcome pose
    # Within a mission odometry does not override the observed pose (as in process)...
    gait = only(d.plan(request), SendGait)
    d.outcome(gait, stamp=6.0)
    assert d(PoseObserved((1.5, 1.5, 0.0), stamp=6.0)) == []
    # ... unless the simulator restarted (its clock went back): then it is the truth.
    d(PoseObserved((0.0, 0.0, 0.0), stamp=0.5))
    request = only(d(VerdictReceived(gait.behavior_id, False)), RequestPlan)
    assert np.allclose(request.start, 0.0)


def _saved_mid_mission(at_verdict=False):
    d = Driver(adapt_on_start=True)
    request = d.step(d.start())
    gait = only(d.plan(request), SendGait)
    if at_verdict:
        d.outcome(gait)
    snapshot = of(d.log, SaveState)[-1].snapshot
    return d, gait, snapshot


@pytest.mark.parametrize('where, resumed', [((0.45, 0.0, 0.0), True),
                                            ((1.0, 1.0, 0.0), False)])
def test_a_restored_mission_goes_on_only_if_the_robot_is_where_it_was(where, resumed):
    before, gait, snapshot = _saved_mid_mission(at_verdict=True)
    d = Driver(adapt_on_start=True)
    out = d.stepper.restore(snapshot, 0.0)
    assert 'restored' in only(out, Report).message
    assert len(d.stepper.sela.observations[0]) == 2  # what was learned always comes back
    out = d(PoseObserved(where, stamp=0.0))
    if resumed:
        assert 'mission resumed at step 2' in only(out, Report).message
        request = only(out, RequestPlan)
        assert request.step == 3 and np.allclose(request.start, where)  # where it is now
        assert d.stepper.next_id == 3  # ids go on: no clash with latched outcomes
    else:
        assert 'dropped' in of(out, Report)[0].message and d.state is State.DONE
        end = only(out, MissionEnded)  # the restored mission ends, and says why
        assert (end.success, end.code) == (False, 'failed') and 'dropped' in end.reason
        assert not of(out, RequestPlan)
    # A late verdict on the step before the restart still counts.
    d(VerdictReceived(gait.behavior_id, True))
    assert d.stepper.logic.adaptations == 2


def test_the_same_goal_sent_before_a_restored_mission_is_checked_is_a_new_mission():
    """After a relaunch the client sends its goal again, before the first odometry has said
    whether the restored mission to that goal can go on. 'Already in progress' would be a
    promise the check may break (the robot elsewhere: the mission dropped, and the client,
    told its goal was taken, waits for ever): the goal is taken as a new mission instead."""
    before, gait, snapshot = _saved_mid_mission(at_verdict=True)
    d = Driver(adapt_on_start=True)
    d.stepper.restore(snapshot, 0.0)
    out = d(GoalReceived((1.0, 0.0)))  # the mission's own goal
    assert of(out, PublishStatus)[-1].message == 'new goal'
    out = d(PoseObserved((1.0, 1.0, 0.0), stamp=0.0))  # far from where the state file says
    assert not any('dropped' in r.message for r in of(out, Report))
    request = only(out, RequestPlan)
    assert request.step == 1 and np.allclose(request.start, (1.0, 1.0, 0.0))
    assert len(d.stepper.sela.observations[0]) == 2  # what was learned stays


@pytest.mark.parametrize('goal', [(1.0, 0.0), (0.0, 1.5)])
def test_a_goal_sent_while_a_restored_gait_is_in_flight_survives_the_gait_never_answering(goal):
    before, gait, snapshot = _saved_mid_mission()
    d = Driver(outcome_timeout=5.0)
    d.stepper.restore(snapshot, 0.0)
    assert of(d(GoalReceived(goal)), PublishStatus)[-1].message == 'new goal'
    assert d.state is State.EXECUTING  # the gait in flight is still awaited
    d(PoseObserved((2.0, 2.0, 0.0)))
    out = d(Tick(), dt=6.0)  # it never answers, and the robot is elsewhere
    assert not any('dropped' in r.message for r in of(out, Report))
    assert 'going on with the new goal from here' in of(out, Report)[0].message
    request = only(out, RequestPlan)
    assert request.step == 1 and np.allclose(request.start, (2.0, 2.0, 0.0))
    assert np.allclose(request.goal, goal)


def test_a_gait_in_flight_at_restart_waits_for_its_outcome_or_resends_it_from_there():
    before, gait, snapshot = _saved_mid_mission()
    d = Driver(adapt_on_start=True, outcome_timeout=5.0)
    d.stepper.restore(snapshot, 0.0)
    assert d.state is State.EXECUTING and d.stepper.pending.behavior_id == gait.behavior_id
    d(PoseObserved((0.3, 0.0, 0.0)))  # mid-gait: no verdict on it yet
    out = d(OutcomeReceived(gait.behavior_id, FORWARD, (0.6, 0.0, 0.0)))  # latched
    assert only(out, RequestPlan).start[0] == 0.6 and d.state is State.VERDICT
    assert len(d.stepper.sela.observations[0]) == 2
    # The outcome never comes and the robot is elsewhere: the mission is dropped.
    d = Driver(outcome_timeout=5.0)
    d.stepper.restore(snapshot, 0.0)
    d(PoseObserved((2.0, 2.0, 0.0)))
    out = d(Tick(), dt=6.0)
    assert not of(out, SendGait) and d.state is State.DONE
    assert only(out, MissionEnded).code == 'failed'


def test_every_state_is_visited():
    visited = set()
    d = Driver(reset_on_fall=True)
    d(PoseObserved((0.0, 0.0, 0.0)))
    d(HoldChanged(''))
    d(GoalReceived((0.45, 0.0)))
    d(HoldChanged(None))
    request = of(d.log, RequestPlan)[0]
    gait = only(d.plan(request), SendGait)
    d.outcome(gait, fallen=True)
    d(VerdictReceived(gait.behavior_id, False))
    d(ResetDone(True, 'back'))
    request = only(d(PoseObserved((0.0, 0.0, 0.0), stamp=4.0)), RequestPlan)
    request = d.step(request)
    d.step(request)
    visited |= d.states
    assert visited == set(State), visited


def test_a_mission_of_several_goals_visits_them_in_order_and_keeps_learning():
    d = Driver(adapt_on_start=True)
    d(PoseObserved((0.0, 0.0, 0.0), stamp=0.0))
    out = d(GoalsReceived(((0.4, 0.0), (0.4, 0.4), (0.0, 0.4))))
    request = only(out, RequestPlan)
    assert np.allclose(request.goal, (0.4, 0.0)) and d.stepper.goal_count == 3
    taken = only(out, PublishStatus).values
    assert taken['goal'].split()[:2] == ['0.400000', '0.000000'] and taken['goals'] == '3'
    reached, requests = [], [request]
    for _ in range(12):  # each gait lands on its goal: one step per goal
        gait = only(d.plan(requests[-1], waypoint=requests[-1].goal), SendGait)
        end = np.append(requests[-1].goal, 0.0)  # the gait lands on the goal exactly
        gr = d.stepper.sela.motion.generic_reward(d.stepper.pending.pose, end)
        out = d(OutcomeReceived(gait.behavior_id, tuple(gr), tuple(end)), dt=3.0)
        out += d(VerdictReceived(gait.behavior_id, False))
        reached += [s.values for s in of(out, PublishStatus) if 'goal_reached' in s.values]
        if d.state is State.DONE:
            break
        requests.append(only(out, RequestPlan))
    assert [r['goal_reached'].split()[:2] for r in reached] == [
        ['0.400000', '0.000000'], ['0.400000', '0.400000']]
    assert [r['goal_index'] for r in reached] == ['2', '3']
    assert [tuple(np.round(r.goal, 3)) for r in requests] == [(0.4, 0.0), (0.4, 0.4),
                                                              (0.0, 0.4)]
    final = [s for s in of(d.log, PublishStatus) if 'success' in s.values][-1].values
    assert final['success'] == 'True' and final['goal_index'] == '3'
    assert len(d.stepper.sela.observations[0]) == 3  # learnt on every leg, never forgotten
    # A plain goal afterwards is a mission of one.
    d(GoalReceived((1.0, 1.0)))
    assert d.stepper.goal_count == 1 and d.stepper.goals_left == []
    assert d(GoalsReceived(())) and d.stepper.goal_count == 1  # an empty path: refused


def test_a_mission_comes_back_with_its_remaining_goals_after_a_restart():
    d = Driver()
    d(PoseObserved((0.0, 0.0, 0.0), stamp=0.0))
    d(GoalsReceived(((2.0, 0.0), (2.0, 2.0))))
    snapshot = d.stepper.snapshot()
    back = Driver()
    back.stepper.restore(snapshot, 0.0)
    assert [g.tolist() for g in back.stepper.goals_left] == [[2.0, 2.0]]
    assert back.stepper.goal_count == 2 and back.stepper.goal_index == 1


def test_an_implausible_outcome_is_refused_not_learnt_and_the_step_planned_again_from_odometry():
    d = Driver(adapt_on_start=True, outcome_timeout=5.0)
    gait = only(d.plan(d.start()), SendGait)
    out = d(OutcomeReceived(gait.behavior_id, (1e9, 0.0, 0.0), (1e9, 0.0, 0.0)), dt=3.0)
    report = only(out, Report)
    assert report.level is Level.ERROR and 'refused, not learnt' in report.message
    assert 'outcome.max_displacement 2 m' in report.message
    assert d.state is State.EXECUTING and not len(d.stepper.sela.observations[0])
    assert d.stepper.current_pose()[0] == 0.0  # never a pose to start from
    d(PoseObserved((0.25, 0.0, 0.0), stamp=3.0))  # where the gait really took the robot
    out = d(Tick(), dt=3.0)
    assert not of(out, SendGait)  # the gait ran: never sent again
    request = only(out, RequestPlan)
    assert request.step == 2 and np.allclose(request.start, (0.25, 0.0, 0.0))


def test_a_plausible_outcome_after_a_refused_one_is_learnt():
    d = Driver(adapt_on_start=True, outcome_timeout=5.0)
    gait = only(d.plan(d.start()), SendGait)
    d(OutcomeReceived(gait.behavior_id, (0.2, 0.0, 0.0), (0.2, 0.0, 0.0), start_pose=(
        -2.0, 0.5, 0.0)), dt=1.0)  # forged: from elsewhere
    d.outcome(gait)
    assert d.state is State.VERDICT and len(d.stepper.sela.observations[0]) == 1


def test_odometry_that_lies_about_the_start_cannot_wedge_the_mission():
    """Odometry puts the robot elsewhere than every outcome does: each step is planned from
    it, each outcome refused, no gait sent twice, and the mission ends with the reason."""
    d = Driver(adapt_on_start=True, outcome_timeout=5.0, max_refused_steps=3)
    d.start(goal=(2.0, 0.0), pose=(-2.0, 0.5, 0.0))
    sent, ended = [], []
    for _ in range(10):
        d(PoseObserved((-2.0, 0.5, 0.0), stamp=0.0))
        requests = of(d.log, RequestPlan)
        gait = only(d.plan(requests[-1]), SendGait)
        sent.append(gait.behavior_id)
        d(OutcomeReceived(gait.behavior_id, FORWARD, (0.2, 0.0, 0.0),
                          start_pose=(0.0, 0.0, 0.0)), dt=1.0)
        out = d(Tick(), dt=5.0)
        ended = of(out, MissionEnded)
        if ended:
            break
    assert len(sent) == 3 and len(set(sent)) == 3
    assert not any(c.resend for c in of(d.log, SendGait))
    assert ended[0].code == 'failed' and '3 outcome(s) in a row refused' in ended[0].reason
    assert 'started the gait away from the pose it was planned from' in ended[0].reason
    assert d.state is State.DONE
    # The next goal is taken, from odometry.
    d(PoseObserved((0.2, 0.0, 0.0), stamp=9.0))
    assert only(d(GoalReceived((1.0, 0.0))), RequestPlan).start[0] == 0.2


def test_an_outcome_that_never_comes_is_sent_a_bounded_number_of_times_then_the_mission_fails():
    d = Driver(outcome_timeout=5.0, outcome_attempts=3)
    gait = only(d.plan(d.start()), SendGait)
    resends = [only(d(Tick(), dt=6.0), SendGait) for _ in range(2)]
    assert all(r.resend and r.behavior_id == gait.behavior_id for r in resends)
    out = d(Tick(), dt=6.0)
    assert not of(out, SendGait)
    ended = only(out, MissionEnded)
    assert ended.code == 'failed' and 'after 3 send(s)' in ended.reason
    assert d.state is State.DONE and d.stepper.snapshot()['mission']['pending'] is None
    assert d(OutcomeReceived(gait.behavior_id, FORWARD, (0.2, 0.0, 0.0)), dt=1.0) == []


def test_a_step_is_saved_before_it_is_announced():
    d = Driver(adapt_on_start=True)
    out = d.outcome(only(d.plan(d.start()), SendGait))
    kinds = [type(c) for c in out]
    assert kinds.index(SaveState) < kinds.index(PublishReward) < kinds.index(PublishStatus)
    assert only(out, SaveState).snapshot['sela']['indices'] == [
        int(d.stepper.pending.decision.index)]


@pytest.mark.parametrize('policy, same_gait_elsewhere, kept', [
    ('evidence', False, True), ('evidence', True, True), ('keep', True, True),
    ('reset', False, False)])
def test_a_new_detection_while_adapting_keeps_what_was_learned_unless_the_evidence_says(
        policy, same_gait_elsewhere, kept):
    from sela_ros.core.mission import MissionLogic

    logic = MissionLogic(small_sela(), adapt_on_start=True, on_detection=policy)
    pose = np.zeros(3)
    decisions = [logic.decide(pose, np.array([0.3, 0.0])) for _ in range(3)]
    for d in decisions:
        logic.outcome(d, pose, [0.2, 0.0, 0.0])
    if same_gait_elsewhere:  # one gait 0.5 m off: a surprise, no evidence of a new damage
        logic.outcome(decisions[0], pose, [-0.3, 0.0, 0.0])
    else:
        logic.outcome(logic.decide(pose, np.array([0.0, 0.3])), pose, [0.0, 0.1, 0.0])
    learned = len(logic.sela.observations[0])
    assert logic.adapt() is kept
    assert len(logic.sela.observations[0]) == (learned if kept else 1)


def test_the_prior_in_use_is_reported_when_a_damage_prior_takes_over():
    from sela_ros.core.learning import DamagePriors

    sela = small_sela()
    table = np.tile(FORWARD, (sela.num_candidates, 1))  # on this damage every gait goes 0.2 m
    sela.priors = DamagePriors(('remove:front_left',), table[None], np.zeros((1, 50), bool),
                               'unchecked')
    d = Driver(adapt_on_start=True)
    d.stepper = MissionStepper(sela, StepperConfig(adapt_on_start=True))
    request = d.start(goal=(3.0, 0.0))
    request = d.step(request)  # the outcome is the table's, not the intact map's
    # The first step, before any outcome, is hedged over the intact map and the table.
    said = [r.message for r in of(d.log, Report) if r.message.startswith('prior:')]
    assert said == ['prior: intact and damage priors (was intact), no step has shown the '
                    'damage yet: the first step is hedged over them'], said
    d.log = []
    only(d.plan(request), SendGait)
    said = [r.message for r in of(d.log, Report)]
    assert any(m.startswith('prior: remove:front_left (was intact and damage priors)')
               for m in said), said


def test_a_result_and_a_goal_taken_are_announced_after_their_saves():
    """Acknowledged means durable: the driver releases a status once the saves before it
    are on disk, so a status must come after the save of what it announces (a client that
    hears 'goal reached' and stops the adapter at once must find the mission done)."""
    d = Driver()
    d(PoseObserved((0.0, 0.0, 0.0), stamp=0.0))
    out = d(GoalReceived((0.3, 0.0)))
    kinds = [type(c) for c in out]
    assert kinds.index(SaveState) < kinds.index(PublishStatus), kinds
    request = of(out, RequestPlan)[0]
    gait = only(d.plan(request), SendGait)
    out = d.outcome(gait, gr=(0.3, 0.0, 0.0)) + d(VerdictReceived(gait.behavior_id, False))
    finals = [i for i, c in enumerate(out)
              if isinstance(c, PublishStatus) and 'success' in c.values]
    assert finals, out
    saves = [i for i, c in enumerate(out) if isinstance(c, SaveState)
             and c.snapshot['mission']['state'] == 'done']
    assert saves and saves[0] < finals[0], out


def test_the_waypoints_are_taken_off_the_whole_path_lookahead_along_it():
    d = Driver()
    request = d.start(goal=(2.0, 0.0))
    lookahead = d.stepper.sela.config.planner_lookahead
    # An L-shaped path: the waypoint is measured along it, not as the crow flies.
    path = ((0.0, 0.0), (0.2, 0.0), (0.2, 1.0), (2.0, 1.0), (2.0, 0.0))
    gait = only(d(PlanReceived(request.step, tuple(request.start), path=path)), SendGait)
    np.testing.assert_allclose(gait.waypoint, (0.2, lookahead - 0.2))
    assert d.stepper.pending.decision.waypoint.tolist() == list(gait.waypoint)


def test_a_cancel_ends_the_mission_after_the_running_gait_and_no_gait_follows():
    d = Driver()
    gait = only(d.plan(d.start()), SendGait)
    out = d(CancelRequested())
    assert only(out, Reply).success and not of(out, MissionEnded)
    out = d.outcome(gait) + d(VerdictReceived(gait.behavior_id, False))
    end = only(out, MissionEnded)
    assert (end.success, end.code, end.steps) == (False, 'canceled', 1)
    assert not of(out, SendGait) and not of(out, RequestPlan) and d.state is State.DONE
    # What the user asked for is no failure: said as a warning, the result too.
    ended = [s for s in of(out, PublishStatus) if 'success' in s.values]
    assert [s.level for s in ended] == [Level.WARN]
    assert all(r.level is Level.WARN for r in of(out, Report) if 'canceled' in r.message)
    assert of(d(Tick(), dt=100.0), SendGait) == []
    assert not only(d(CancelRequested()), Reply).success  # nothing left to cancel


def test_a_new_goal_preempts_the_mission_and_the_gait_in_flight_is_still_learnt():
    d = Driver(adapt_on_start=True)
    gait = only(d.plan(d.start(goal=(1.0, 0.0))), SendGait)
    out = d(GoalReceived((0.0, 1.0)))
    end = only(out, MissionEnded)
    assert (end.success, end.code, end.mission_id) == (False, 'preempted', 1)
    assert d.stepper.mission_id == 2 and d.state is State.EXECUTING
    d.outcome(gait)  # the old command's outcome is still taken and learnt
    assert d.stepper.sela.observations[0].tolist() == [gait.index]
    # The same goal again is no preemption: the mission goes on.
    assert not of(d(GoalReceived((0.0, 1.0))), MissionEnded)


def test_a_planner_that_never_answers_ends_the_mission_with_the_reason():
    d = Driver(plan_timeout=1.0, plan_attempts=3)
    d.start()
    ends = []
    for _ in range(10):
        ends += of(d(Tick(), dt=1.5), MissionEnded)
    end = only(ends, MissionEnded)
    assert end.code == 'no_plan' and 'did not answer 3' in end.reason
    assert d.state is State.DONE and d.stepper.steps == 0


def test_learning_keeps_the_latest_observations_over_a_long_life_and_so_do_its_saves():
    d = Driver(adapt_on_start=True, max_observations=10, max_steps=100)
    request = d.start(goal=(50.0, 0.0))
    sizes = []
    for _ in range(25):
        request = d.step(request)
        sizes.append((len(d.stepper.sela.observations[0]), d.stepper.sela.fall_observations))
    assert max(max(s) for s in sizes) <= 11  # a tenth more at most, then back to 10
    assert (10, 10) in sizes
    said = [r.message for r in of(d.log, Report) if 'learning bounded' in r.message]
    assert said and 'the latest 10 kept' in said[0]
    snapshot = d.stepper.snapshot()['sela']
    assert len(snapshot['indices']) <= 11 and len(snapshot['fall_indices']) <= 11
    # A state file of a longer life (another cap) is taken back with the latest only.
    restored = Driver(adapt_on_start=True, max_observations=4)
    restored.stepper.restore(d.stepper.snapshot(), 0.0)
    assert restored.stepper.sela.observations[0].tolist() == snapshot['indices'][-4:]
    assert restored.stepper.sela.fall_observations == 4
