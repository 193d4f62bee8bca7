"""The mission's step cycle as plain Python: events in, commands out. ROS-free.

One step: plan (the waypoint) -> ask (SELA picks a gait) -> command (gait and prediction
out) -> outcome (learnt while adapting) -> verdict (a detection starts or restarts
adaptation) -> the next step; falls, resets, time-outs, early or late adaptation requests and
resuming after a restart are part of it. :class:`MissionStepper` never waits and never reads
a clock: its driver (the ``sela_adapter`` node, :func:`sela_ros.core.mission.run_mission`, a
test) passes the time with each event and carries out the commands it returns (see
:mod:`sela_ros.core.mission.stepper_io`), so the DDS mission takes the in-process mission's gaits.
Steps start from the latest outcome's observed pose, or from odometry when there is none
(start, reset, restart), between missions, or after the simulator restarted.
"""
import math
from dataclasses import replace

import numpy as np

from sela_ros.core.geometry import planar_distance
from sela_ros.core.learning.sela import Decision, prior_reason
from sela_ros.core.mission import stepper_io as io
from sela_ros.core.mission.logic import MissionLogic
from sela_ros.core.mission.reach import sela_lookahead
from sela_ros.core.mission.status import (
    detection_status,
    goal_status,
    mission_status,
    vector_text,
)
from sela_ros.core.mission.stepper_io import (
    AskedPlan,
    Level,
    MissionEnded,
    PendingStep,
    PublishReward,
    PublishStatus,
    Reply,
    Report,
    RequestPlan,
    RequestReset,
    SaveState,
    SendGait,
    State,
    StepperConfig,
)
from sela_ros.core.planning import next_waypoint
from sela_ros.core.validation import ImplausibleOutcome, OutcomeLimits, check_outcome

#: Ends of a mission its client asked for: said as WARN, not as a failure.
USER_ENDS = ('canceled', 'preempted')


class MissionStepper:
    """The step cycle of one robot: feed it events, carry out the commands it returns.

    Args:
        sela: the SELA learner (its goal is set by a ``GoalReceived`` event).
        config: :class:`StepperConfig`.
        next_id: the id of the first command (a node that replaces its stepper goes on with
            its ids, so that no latched outcome of an old command pairs with a new one).
    """

    def __init__(self, sela, config=None, next_id=1, self_model=None):
        self.config = config or StepperConfig()
        # SelfModel (sela_ros.core.learning.self_model) or None: reads each outcome's feet
        self.self_model = self_model
        self.logic = MissionLogic(sela, self.config.adapt_on_start, self.config.reset_on_fall,
                                  self.config.on_detection)
        self.state = State.IDLE
        self.goal = None
        self.goals_left = []  # a mission's goals after the current one, in order
        self.goal_index = self.goal_count = 0  # the current goal's rank (from 1), how many
        self.steps = 0
        self.failed_steps = 0
        self.result = None  # True / False once DONE
        self.ended = None  # (code, reason) of the result, once DONE
        # Counts the missions taken (saved with them): a result names its mission, so a
        # client can tell the result of its own goal from a repeat of an earlier one.
        self.mission_id = 0
        self.next_id = int(next_id)  # of the next command (unique across steppers of a node)
        self.pending = None  # PendingStep
        self.pose = self.pose_stamp = None  # the latest outcome's end pose, and its time
        self.odom = self.odom_stamp = None
        self.hold = None  # why no gait may be sent ('' : silently), None: go
        self.reset_needed = False
        self.adapt_after_outcome = False
        self.resume = None  # a restored mission waiting to see where the robot is
        self.restored_mission = None  # the mission id the state file held
        self._plan = None  # AskedPlan
        self._verdicts = {}  # behaviour id -> verdict heard before the outcome
        self.last_id = None  # id of the latest outcome processed
        self._deadline = None  # of the reset
        self.cancel = None  # why the mission ends after the running gait (a cancel)
        self._attempts = 1  # of the next plan request (the planner did not answer before)
        self.refused_steps = 0  # steps in a row whose outcomes were all refused
        self.prior = 'intact'  # the GPs' prior mean: the intact map or a damage prior
        self._handlers = {
            io.GoalReceived: self._on_goal, io.GoalsReceived: self._on_goals,
            io.PoseObserved: self._on_pose, io.PlanReceived: self._on_plan,
            io.OutcomeReceived: self._on_outcome, io.VerdictReceived: self._on_verdict,
            io.AdaptRequested: self._on_adapt, io.ClearRequested: self._on_clear,
            io.ResetDone: self._on_reset_done, io.HoldChanged: self._on_hold,
            io.CancelRequested: self._on_cancel, io.Tick: self._on_tick,
            io.DamageSimulated: self._on_damage_simulated}

    @property
    def sela(self):
        return self.logic.sela

    def configure(self, **changes):
        """Change timings or ``max_steps`` (the rest is fixed at construction)."""
        self.config = replace(self.config, **changes)

    def current_pose(self):
        return self.pose if self.pose is not None else self.odom

    # --- events --------------------------------------------------------------------------

    def handle(self, event, now):
        """Apply ``event`` observed at time ``now`` (s); returns the commands, in order."""
        handler = self._handlers.get(type(event))
        if handler is None:
            raise TypeError(f'not a stepper event: {event!r}')
        out = handler(event, now)
        if self.state is State.READY:
            out += self._start_step(now)
        return out

    def _on_goal(self, event, now):
        return self._take(event.goal, [event.goal])

    def _on_goals(self, event, now):
        if not event.goals:
            return [Report(Level.ERROR, 'goal path rejected: it has no poses')]
        return self._take(event.goals[0], list(event.goals))

    def _take(self, first, goals):
        """A new mission: one that was running ends first (preempted), unless the new one
        starts with the goal it is walking to (it goes on, with the new goals after)."""
        out = []
        if self.running():
            same = (np.array_equal(np.asarray(first, dtype=float).reshape(-1)[:2], self.goal)
                    and self.resume is None)
            if not same:
                out += self._end(False, 'preempted', 'preempted by a new goal',
                                 self.current_pose())
                if self.state is State.PLANNING:
                    self.state = State.READY  # the new goal's plan is asked at once
        self.cancel = None
        return out + self._take_goals(goals)

    def _take_goals(self, goals):
        """The mission is now ``goals`` in order (one goal: a plain goal)."""
        goal = np.asarray(goals[0], dtype=float).reshape(-1)[:2]
        rest = [np.asarray(g, dtype=float).reshape(-1)[:2] for g in goals[1:]]
        # A restored mission not yet checked against odometry may still be dropped: the same
        # goal then starts afresh from where the robot is, so that 'taken' stays true (a gait
        # in flight at the restart is still awaited; if it never answers, the new mission
        # goes on without it: _on_tick).
        unchecked = self.resume is not None and self.state is not State.EXECUTING
        if (self.goal is not None and np.array_equal(goal, self.goal)
                and self.state not in (State.IDLE, State.DONE) and self.resume is None):
            self.goals_left, self.goal_count = rest, self.goal_index + len(rest)
            return [goal_status(self, 'goal already in progress')]  # it goes on
        self.goals_left, self.goal_index, self.goal_count = rest, 1, len(goals)
        self.sela.set_goal(goal)
        self.goal = goal
        self._plan = None
        if unchecked:
            self.resume = self.pose = None  # a new mission, from where the robot is
        self.steps = 0
        self.result = self.ended = None
        self.mission_id += 1
        if self.state in (State.IDLE, State.DONE):
            self.state = State.READY
        # The goal is announced as taken once its save is on disk (acknowledged means
        # durable).
        out = [Report(Level.OK, f'new goal ({goal[0]:.2f}, {goal[1]:.2f})'), self._save(),
               goal_status(self, 'new goal')]
        if self.hold:
            out.append(Report(Level.ERROR, self.hold))
        return out

    def running(self):
        """Whether a mission is under way (a goal, and not ended)."""
        return self.goal is not None and self.state not in (State.IDLE, State.DONE)

    def _on_cancel(self, event, now):
        if not self.running():
            return [Reply(False, 'no mission to cancel')]
        if self.state is State.EXECUTING:
            self.cancel = event.reason
            message = (f'mission {self.mission_id} ends after the outcome of command '
                       f'{self.pending.behavior_id}')
            return [Report(Level.WARN, message), Reply(True, message)]
        if self.state is State.PLANNING:
            self.steps -= 1  # planned, never sent
        self.state = State.READY
        return self._end(False, 'canceled', event.reason, self.current_pose()) + [
            Reply(True, f'mission {self.mission_id} canceled')]

    def _on_pose(self, event, now):
        pose = np.asarray(event.pose, dtype=float)
        if (event.stamp is not None and self.odom_stamp is not None
                and event.stamp < self.odom_stamp and self.pose_stamp is not None):
            self.pose_stamp = -math.inf  # the simulator's clock went back: it restarted
        self.odom, self.odom_stamp = pose, event.stamp
        if self.resume is not None and self.state is not State.EXECUTING:
            return self._check_resume(pose)
        # Within a mission steps start from the outcome's observed pose, as in process; between
        # missions, or once the simulator restarted, odometry putting the robot elsewhere wins.
        moved = (self.pose is not None and event.stamp is not None
                 and self.pose_stamp is not None and event.stamp >= self.pose_stamp
                 and (self.state in (State.IDLE, State.DONE) or (
                     self.pose_stamp == -math.inf
                     and self.state in (State.READY, State.VERDICT, State.PLANNING)))
                 and planar_distance(pose, self.pose) > self.config.pose_tolerance)
        if not moved:
            return []
        distance = planar_distance(pose, self.pose)
        self.pose = None
        return [Report(Level.WARN, f'odometry puts the robot {distance:.2f} m from its '
                       'last observed pose: the next step starts from odometry')]

    def _on_plan(self, event, now):
        plan = self._plan
        if plan is None or plan.step != event.step or not np.array_equal(
                plan.start, np.asarray(event.start, dtype=float)):
            return []  # an answer to an older request
        path = None if event.path is None else np.asarray(event.path, dtype=float)
        if path is not None and path.size:
            plan.path = path.reshape(-1, 2)
        elif event.waypoint is None:
            plan.refused = event.reason or 'no path'
        else:
            plan.waypoint = np.asarray(event.waypoint, dtype=float).reshape(-1)[:2]
        if self.state is State.PLANNING and self.pending.step == plan.step:
            return self._plan_ready(now)
        return []

    def _on_outcome(self, event, now):
        p = self.pending
        if self.state is not State.EXECUTING or event.behavior_id != p.behavior_id:
            if event.behavior_id >= self.next_id:
                return [Report(Level.WARN, f'ignored outcome {event.behavior_id}: it pairs '
                               'with no command of this adapter')]
            return []
        try:
            start = p.pose if event.start_pose is None else event.start_pose
            check_outcome(event.generic_reward, start, event.end_pose,
                          OutcomeLimits(self.config.max_displacement), expected_start=p.pose)
        except ImplausibleOutcome as exc:
            # Never learnt, never a pose to start from. A plausible outcome may still come
            # (a forged one may overtake the real one); if none has by outcome_timeout, the
            # gait ran from somewhere else than planned: the step starts again, from
            # odometry (_on_tick), never the same gait resent.
            p.refused = str(exc)
            return [Report(Level.ERROR, f'outcome of command {event.behavior_id} refused, not '
                           f'learnt: {exc}')]
        self.resume = None
        self.refused_steps = 0
        p.t_outcome = now
        self.pose = np.asarray(event.end_pose, dtype=float)
        self.pose_stamp = event.stamp
        self.last_id = p.behavior_id
        self.reset_needed = bool(event.fallen) and self.config.reset_on_fall
        out = []
        # The next step's plan depends only on the pose: ask now, the planner works while
        # this step is learnt and judged.
        if (self.goal is not None and not self.sela.goal_reached(self.pose)
                and self.steps < self.config.max_steps and not self.reset_needed
                and self.cancel is None):
            out.append(self._ask_plan(self.steps + 1, self.pose, now))
        p.record = self.logic.outcome(p.decision, p.pose, event.generic_reward,
                                      fallen=event.fallen, true_pose=event.true_pose,
                                      standing_start=event.standing_start)
        out += self._bound_learning()
        out += self._read_feet(p, event)
        if event.fallen:
            self.failed_steps += 1
            out.append(Report(Level.ERROR, f'step {self.steps} failed: the robot fell or '
                              'flipped' + ('; resetting it through /sim_bridge/reset'
                                           if self.reset_needed else '')))
        reward = -float(np.linalg.norm(p.waypoint - self.pose[:2]))
        announce = [PublishReward(reward), PublishStatus(Level.OK, 'step', self.status(reward))]
        self.state = State.VERDICT
        p.deadline = now + self.config.detector_timeout
        # Acknowledged means durable: the save comes first, the step is announced after it
        # (the driver releases the announcement once the save is on disk).
        if self.adapt_after_outcome:
            self.adapt_after_outcome = False
            out += self._adapt()[1]
        else:
            out.append(self._save())
        out += announce
        if p.behavior_id in self._verdicts:
            out += self._verdict(self._verdicts.pop(p.behavior_id))
        return out

    def _read_feet(self, pending, event):
        """The self-model reads the step's feet; while adapting, a hypothesis no table holds
        is simulated beside the mission (:class:`~sela_ros.core.mission.stepper_io.
        SimulateDamage`)."""
        model = self.self_model
        if model is None or event.duty_factors is None:
            return []
        model.observe(pending.decision.index, event.duty_factors, event.fallen)
        wanted = model.request(self.sela.priors) if self.logic.adapting else None
        if wanted is None:
            return []
        damage, gaits, feet = wanted
        said = f'the feet say {damage}; simulating it on {len(gaits)} gaits' \
            if feet is not None else \
            f'simulating {len(gaits)} more gaits of {damage}, those its table infers go farthest'
        return [Report(Level.OK, f'self-model: {said} beside the mission'),
                io.SimulateDamage(damage, tuple(int(g) for g in gaits), feet)]

    def _on_damage_simulated(self, event, now):
        model = self.self_model
        if model is None:
            return []
        asked = event.asked or event.damage
        if event.error:
            model.failed(asked)
            return [Report(Level.WARN, f'self-model: {asked} not simulated: {event.error}')]
        try:
            priors = model.install(self.sela.priors, event.damage, event.gaits,
                                   event.generic_reward, event.fallen, asked)
        except ValueError as exc:
            model.failed(asked)
            return [Report(Level.WARN, str(exc))]
        if priors is self.sela.priors:
            return []
        self.sela.priors = priors
        instead = f' (the feet said {asked}: a leg the others tilt off the ground)' \
            if asked != event.damage else ''
        return [Report(Level.OK, f'self-model: the table of {event.damage} is a damage prior '
                       f'({len(event.gaits)} gaits simulated, the others inferred){instead}')]

    def _on_verdict(self, event, now):
        if self.state is State.VERDICT and event.behavior_id == self.pending.behavior_id:
            return self._verdict(event)
        if self.state is State.EXECUTING and event.behavior_id == self.pending.behavior_id:
            self._verdicts[event.behavior_id] = event  # heard before the outcome
            return []
        if event.behavior_id == self.last_id and event.fire:
            # Late: the step went on without it. Adapt as an early call would.
            self.last_id = None
            out = self._on_adapt(io.AdaptRequested(), now)
            return out[:-1] + [detection_status(self, event, out[-1].message)]
        return []  # judged already, or an older command (a restarted detector's replay)

    def _verdict(self, event):
        self.last_id = None  # judged: a replay of this verdict changes nothing
        self.state = State.READY
        self.logic.judged(event.error)
        if not event.fire:
            return []
        message, out = self._adapt()
        return out + [detection_status(self, event, message)]

    def _on_adapt(self, event, now):
        if self.state is State.EXECUTING:
            # Adapt from the outcome on its way, as soon as it is processed.
            self.adapt_after_outcome = True
            message = ('adaptation will ' + ('restart' if self.logic.adapting else 'start')
                       + f' from the outcome of command {self.pending.behavior_id}')
            return [Report(Level.WARN, message), Reply(True, message)]
        message, out = self._adapt()
        return out + [Reply(True, message)]

    def _adapt(self):
        restarting = self.logic.adapting
        kept = self.logic.adapt()
        message = (('adaptation started' if not restarting
                    else 'adaptation goes on with what it learned' if kept
                    else 'adaptation restarted, what was learned before set aside')
                   + f' ({len(self.sela.observations[0])} observation(s))')
        return message, [Report(Level.WARN, message), self._save()]

    def _on_clear(self, event, now):
        forgotten = len(self.sela.observations[0])
        self.logic.forget(self.config.adapt_on_start)
        if self.self_model is not None:
            self.sela.priors = self.self_model.forget(self.sela.priors)
        message = f'forgot {forgotten} observation(s): back to the intact map'
        return [self._save(), Report(Level.WARN, message), Reply(True, message)]

    def _on_reset_done(self, event, now):
        if self.state is not State.RESETTING:
            return []
        self.reset_needed = False
        self.state = State.READY
        if not event.success:
            return [Report(Level.ERROR, f'reset refused: {event.message or "no answer"}; '
                           'going on from where the robot lies'), self._save()]
        # The next step starts from the pose odometry reports after the reset.
        self.pose = self.odom = None
        self._plan = None
        return [Report(Level.WARN, f'reset: {event.message}'), self._save()]

    def _on_hold(self, event, now):
        self.hold = event.reason
        return [Report(Level.ERROR, event.reason)] if event.reason else []

    def _on_tick(self, event, now):
        p = self.pending
        if self.state is State.PLANNING and now > p.deadline:
            self.steps -= 1
            self.state = State.READY
            attempts, self._plan = self._plan.attempts, None
            if attempts >= self.config.plan_attempts:
                return self._end(False, 'no_plan', f'the planner did not answer {attempts} '
                                 f'plan request(s) of {self.config.plan_timeout:g} s each',
                                 self.current_pose())
            self._attempts = attempts + 1
            return [Report(Level.ERROR, f'planner did not answer; asking again '
                           f'({attempts + 1}/{self.config.plan_attempts})')]
        if self.state is State.EXECUTING and now > p.deadline:
            if self.resume is not None and self.odom is not None and planar_distance(
                    self.odom, p.pose) > self.config.pose_tolerance:
                if self.mission_id != self.restored_mission:  # a goal came since
                    return self._abandon_restored_gait(self.odom, p.pose) + \
                        self._start_step(now)
                return self._drop_mission(self.odom, p.pose)
            if p.refused is not None:
                return self._refused_step(p)
            if p.sends >= self.config.outcome_attempts:
                return self._lost_command(p)
            p.deadline = now + self.config.outcome_timeout
            p.sends += 1
            return [Report(Level.ERROR, f'no outcome for command {p.behavior_id} within '
                           f'{self.config.outcome_timeout} s; sending it again '
                           f'({p.sends}/{self.config.outcome_attempts})'),
                    SendGait(p.behavior_id, p.decision.index, p.decision.predicted_gr,
                             self.logic.prediction_sigma(p.decision), resend=True)]
        if self.state is State.VERDICT and now > p.deadline:
            self.state = State.READY
            return [Report(Level.WARN, f'no verdict on command {p.behavior_id} within '
                           f'{self.config.detector_timeout} s: going on')]
        if self.state is State.RESETTING and now > self._deadline:
            self.reset_needed = False
            self.state = State.READY
            return [Report(Level.ERROR, '/sim_bridge/reset did not answer: going on from '
                           'where the robot lies')]
        return []

    def _refused_step(self, p):
        """Only refused outcomes came for the step in flight: the gait ran, from elsewhere
        than the step was planned from (or it says what cannot be). The step is over, not
        learnt; the next one is planned from odometry, or, after ``max_refused_steps`` such
        steps in a row, the mission fails with the reason."""
        self.refused_steps += 1
        self.pose = None  # one rule: no outcome to start from, so odometry
        self.pending = None
        self.state = State.DONE if self.ended is not None else State.READY
        if self.refused_steps >= self.config.max_refused_steps and self.running():
            self.state = State.READY
            return self._end(False, 'failed', f'{self.refused_steps} outcome(s) in a row '
                             f'refused, the latest: {p.refused}', self.current_pose())
        return [Report(Level.ERROR, f'command {p.behavior_id} only had refused outcomes: '
                       'the next step is planned from where odometry puts the robot')]

    def _lost_command(self, p):
        """No outcome came for ``outcome_attempts`` sends of the command: the mission fails
        (the simulator or the robot does not answer), and the command is no longer awaited."""
        self.pending = None
        self.pose = None
        self.state = State.DONE if self.ended is not None else State.READY
        if not self.running():
            return [Report(Level.ERROR, f'no outcome for command {p.behavior_id} after '
                           f'{p.sends} send(s): no longer awaited')]
        return self._end(False, 'failed', f'no outcome for command {p.behavior_id} after '
                         f'{p.sends} send(s) of {self.config.outcome_timeout:g} s each',
                         self.current_pose())

    # --- the cycle -----------------------------------------------------------------------

    def _start_step(self, now):
        if self.hold is not None or self.resume is not None or self.goal is None:
            return []
        if self.cancel is not None:
            return self._end(False, 'canceled', self.cancel, self.current_pose())
        if self.reset_needed:
            self.state = State.RESETTING
            self._deadline = now + self.config.outcome_timeout
            return [Report(Level.WARN, 'robot fell: calling /sim_bridge/reset'), RequestReset()]
        pose = self.current_pose()
        if pose is None:
            return []
        if self.sela.goal_reached(pose):
            if not self.goals_left:
                return self._finish(True, pose)
            return self._next_goal(pose) + self._start_step(now)
        if self.steps >= self.config.max_steps:
            return self._finish(False, pose)
        out = []
        plan = self._plan
        if plan is None or plan.step != self.steps + 1 or not np.array_equal(
                plan.start, pose) or plan.refused:
            out.append(self._ask_plan(self.steps + 1, pose, now))
        self.steps += 1
        self.pending = PendingStep(step=self.steps, pose=pose.copy(), t_start=self._plan.t,
                                   deadline=now + self.config.plan_timeout)
        self.state = State.PLANNING
        return out + self._plan_ready(now)

    def _ask_plan(self, step, pose, now):
        attempts, self._attempts = self._attempts, 1
        self._plan = AskedPlan(step, np.array(pose, dtype=float), now, attempts=attempts)
        return RequestPlan(step, self._plan.start.copy(), self.goal.copy())

    def _plan_ready(self, now):
        plan, p = self._plan, self.pending
        if plan.refused:
            self.steps -= 1
            self._plan = None
            # A goal that cannot be planned is not retried: the mission ends, saying why.
            return self._end(False, 'no_plan', f'no plan to the goal: {plan.refused}', p.pose)
        if not plan.answered():
            return []
        self._plan = None
        if plan.path is not None:
            self._take_waypoints(plan)
        p.waypoint = plan.waypoint
        p.decision = self.logic.decide(p.pose, p.waypoint, self.goal, following=plan.following)
        p.behavior_id = self.next_id
        self.next_id += 1
        p.t_sent = now
        p.deadline = now + self.config.outcome_timeout
        self.state = State.EXECUTING
        d = p.decision
        said = []
        if d.prior != self.prior:
            said.append(Report(Level.OK, f'prior: {d.prior} (was {self.prior}), '
                               f'{prior_reason(d.prior)}'))
            self.prior = d.prior
        # Write-ahead: the gait in flight is recorded before it is sent, so that a restarted
        # adapter knows it and waits for its (latched) outcome instead of losing it.
        return [*said, self._save(), SendGait(p.behavior_id, int(d.index), d.predicted_gr,
                                       self.logic.prediction_sigma(d), pose=tuple(p.pose),
                                       waypoint=tuple(p.waypoint), candidates=d.candidates)]

    def _take_waypoints(self, plan):
        """The waypoints the reward is built on, taken off the planner's path here and only
        here, as the step starts: what the steps before it taught (``planner.reach``) is
        learnt by then, whichever of the plan and the detector's verdict came first."""
        start, lookahead = plan.start[:2], sela_lookahead(self.sela)
        plan.waypoint = next_waypoint(plan.path, start, lookahead)
        if self.sela.config.planner_horizon > 1:
            second = next_waypoint(plan.path, start, 2 * lookahead)
            if np.linalg.norm(second - plan.waypoint) > 1e-6:
                plan.following = second

    def _next_goal(self, pose):
        """A goal of the mission is reached: on to the next, with all that was learned."""
        reached, steps = self.goal, self.steps
        self.goal = self.goals_left.pop(0)
        self.sela.set_goal(self.goal)
        self.goal_index += 1
        self.steps = 0
        self._plan = None
        message = f'goal {self.goal_index - 1}/{self.goal_count} reached after {steps} steps'
        return [Report(Level.OK, f'{message}, pose ({pose[0]:.2f}, {pose[1]:.2f}); next goal '
                       f'({self.goal[0]:.2f}, {self.goal[1]:.2f})'),
                self._save(), goal_status(self, message, reached=reached, reached_steps=steps)]

    def _finish(self, success, pose):
        if success:
            return self._end(True, 'succeeded', 'goal reached', pose)
        return self._end(False, 'max_steps', 'goal not reached: the mission took its '
                         f'max_steps ({self.config.max_steps})', pose)

    def _end(self, success, code, reason, pose):
        """End the mission (said once, whatever ended it): the result, after its save.

        A gait in flight (a mission preempted by a new one) is still awaited and learnt."""
        if self.state not in (State.EXECUTING, State.VERDICT, State.RESETTING):
            self.state = State.DONE
        self.result = success
        self.ended = (code, reason)
        self.cancel = None
        where = '' if pose is None else f', pose ({pose[0]:.2f}, {pose[1]:.2f})'
        reached = self.goal_index - (0 if success else 1)
        # Acknowledged means durable: the result is announced once its save is on disk (a
        # client that heard it and stops the adapter at once finds the mission done after a
        # restart, not half done).
        return [Report(self._end_level(), f'{reason} after {self.steps} steps{where}'),
                self._save(), self._result_status(),
                MissionEnded(self.mission_id, success, code, reason, self.steps,
                             None if pose is None else tuple(float(v) for v in pose),
                             max(0, reached), max(1, self.goal_count))]

    # --- status and persistence ----------------------------------------------------------

    def status(self, reward=None):
        """The mission status as text values (see :mod:`sela_ros.core.mission.status`)."""
        return mission_status(self, reward)

    def _end_level(self):
        """How the mission's end is said: OK reached, WARN ended by its client (canceled, or
        preempted by a new goal: what the user asked for), ERROR failed."""
        if self.result:
            return Level.OK
        return Level.WARN if self.ended[0] in USER_ENDS else Level.ERROR

    def _result_status(self):
        """The result, with the goal it ended at: repeated while idle, it tells a client that
        matched late (or missed the goal's own status) which goal it answers."""
        code, reason = self.ended
        values = dict(self.status(), code=code)
        if self.goal is not None:
            values['goal'] = vector_text(self.goal)
        return PublishStatus(self._end_level(), reason, values)

    def _bound_learning(self):
        """Over a robot's life, learning keeps the latest ``max_observations`` observations
        (forgotten by the batch: a tenth more at most, then back to the cap)."""
        cap = self.config.max_observations
        told = max(len(self.sela.observations[0]), self.sela.fall_observations)
        if told <= cap + max(1, cap // 10):
            return []
        forgotten = self.sela.keep_latest(cap)
        return [Report(Level.OK, f'learning bounded: the {forgotten} oldest observation(s) '
                       f'forgotten, the latest {cap} kept (max_observations)')]

    def _save(self):
        return SaveState(self.snapshot())

    def snapshot(self):
        """What was learned and where the mission stands, as JSON-able values: the ``sela``
        and ``mission`` sections of the adapter's state file."""
        p = self.pending
        pending = None
        if p is not None and p.decision is not None and self.state in (State.EXECUTING,
                                                                          State.VERDICT):
            d = p.decision
            pending = {'id': p.behavior_id, 'step': p.step, 'index': int(d.index),
                       'pose': _list(p.pose), 'waypoint': _list(d.waypoint),
                       'predicted_gr': _list(d.predicted_gr),
                       'predicted_pose': _list(d.predicted_pose), 'reward': d.reward,
                       'sigma': d.sigma}
        last = self.logic.last
        pose = self.current_pose()
        return {'sela': self.sela.state_dict(), 'mission': {
            'state': self.state.value, 'steps': self.steps, 'mission_id': self.mission_id,
            'failed_steps': self.failed_steps,
            'goal': None if self.goal is None else _list(self.goal),
            'goals_left': [_list(g) for g in self.goals_left],
            'goal_index': self.goal_index, 'goal_count': self.goal_count,
            'pose': None if pose is None else _list(pose),
            'adapting': self.logic.adapting, 'adaptations': self.logic.adaptations,
            'last': None if last is None else [int(last[0]), _list(last[1])],
            'next_id': self.next_id, 'pending': pending, 'reset_needed': self.reset_needed,
            'result': None if self.result is None or self.ended is None else {
                'success': bool(self.result), 'code': self.ended[0],
                'reason': self.ended[1]}}}

    def restore(self, snapshot, now):
        """Take back what :meth:`snapshot` saved; returns the commands (reports) it gives.
        Raises KeyError, TypeError or ValueError on a bad one.

        What was learned always comes back. A mission in progress comes back only if the
        robot turns out to be where it was (the first odometry decides); a gait in flight
        waits for its outcome. A mission that had ended says its result again: a client
        that had not heard it when the adapter stopped hears it now.
        """
        self.sela.load_state_dict(snapshot['sela'], keep=self.config.max_observations)
        m = snapshot['mission']
        self.logic.restore(bool(m['adapting']), int(m['adaptations']), m['last'])
        self.next_id = int(m['next_id'])
        self.failed_steps = int(m.get('failed_steps', 0))
        self.mission_id = self.restored_mission = int(m.get('mission_id', 0))
        state = State(m['state'])
        result = m.get('result')
        if state is State.DONE and result is not None:
            self.state, self.steps = State.DONE, int(m['steps'])
            self.goal_index = int(m.get('goal_index', 1))
            self.goal_count = int(m.get('goal_count', 1))
            self.result = bool(result['success'])
            self.ended = (str(result['code']), str(result['reason']))
            return [self._result_status()]
        if m['goal'] is None or state in (State.IDLE, State.DONE):
            return []
        self.goal = np.array(m['goal'], dtype=float)
        self.sela.set_goal(self.goal)
        self.goals_left = [np.array(g, dtype=float) for g in m.get('goals_left', [])]
        self.goal_index = int(m.get('goal_index', 1))
        self.goal_count = int(m.get('goal_count', 1 + len(self.goals_left)))
        self.steps = int(m['steps'])
        self.reset_needed = bool(m.get('reset_needed', False))
        pending = m.get('pending')
        if pending is not None and state is State.EXECUTING:
            self.pending = pending_from_snapshot(pending, self.steps, now,
                                                 self.config.outcome_timeout)
            self.resume = self.pending.pose
            self.state = State.EXECUTING  # the outcome may be waiting (it is latched)
            return [Report(Level.WARN, f'resuming: waiting for the outcome of command '
                           f"{pending['id']}")]
        if m['pose'] is None:
            return self._end(False, 'failed', 'mission dropped: the state file has no pose '
                             'to check the robot against; send the goal again', None)
        if pending is not None:
            self.last_id = int(pending['id'])  # a late verdict on it still counts
        self.resume = np.array(m['pose'], dtype=float)
        self.state = State.READY
        return [Report(Level.WARN, f'mission to ({self.goal[0]:.2f}, {self.goal[1]:.2f}) '
                       'restored: checking that the robot is where it was')]

    def _drop_mission(self, pose, saved):
        """The robot is not where the state file puts it: the mission ends, failed (what
        was learned stays)."""
        message = (f'mission to ({self.goal[0]:.2f}, {self.goal[1]:.2f}) dropped: the robot '
                   f'is {planar_distance(pose, saved):.2f} m from where the state file puts '
                   f'it (tolerance {self.config.pose_tolerance} m); send the goal again')
        self.resume = self.pending = None
        self.reset_needed = False
        self.state = State.DONE
        return self._end(False, 'failed', message, pose)

    def _abandon_restored_gait(self, pose, saved):
        """The gait in flight at a restart never answered and the robot is elsewhere, but a
        goal came since: that mission goes on from where the robot is, without the gait."""
        behavior_id = self.pending.behavior_id
        self.resume = self.pending = self.pose = None
        self.state = State.READY
        self.steps = max(self.steps - 1, 0)  # the step never happened
        return [Report(Level.WARN, f'command {behavior_id}, in flight at the restart, never '
                       f'answered and the robot is {planar_distance(pose, saved):.2f} m from '
                       'where it was sent: going on with the new goal from here')]

    def _check_resume(self, pose):
        """The first odometry after a restore: go on from there, or drop the mission."""
        saved = self.resume
        if planar_distance(pose, saved) > self.config.pose_tolerance:
            return self._drop_mission(pose, saved)
        self.resume = None
        self.pose = None  # plan from where the robot is
        return [Report(Level.WARN, f'mission resumed at step {self.steps}: the robot is '
                       f'{planar_distance(pose, saved):.3f} m from where the state file puts '
                       'it')]


def pending_from_snapshot(pending, step, now, outcome_timeout):
    """The gait in flight that a snapshot saved (its ``pending``), as a
    :class:`~sela_ros.core.mission.stepper_io.PendingStep` waiting for its outcome from ``now``."""
    d = Decision(index=int(pending['index']), waypoint=np.array(pending['waypoint']),
                 predicted_gr=np.array(pending['predicted_gr']),
                 predicted_pose=np.array(pending['predicted_pose']),
                 reward=float(pending['reward']), sigma=float(pending['sigma']))
    return PendingStep(step=step, pose=np.array(pending['pose']), t_start=now,
                       deadline=now + outcome_timeout, waypoint=d.waypoint, decision=d,
                       behavior_id=int(pending['id']), t_sent=now)


def _list(values):
    return np.asarray(values, dtype=float).tolist()
