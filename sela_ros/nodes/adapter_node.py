"""The ``sela_adapter`` node: the archive, the GPs and UCB; chooses gaits and learns.

A thin layer around :class:`sela_ros.core.mission.MissionStepper` (plan -> ask -> command ->
outcome -> verdict -> learn): each message or service answer becomes a stepper event, each
command it returns a message, a service call or a file write; no callback waits. Outcomes
and verdicts (``damage_detector/verdict``) pair with the command by id. ``~/adapt`` starts
(or restarts) adaptation, ``~/clear`` forgets what was learned. Missions come as goals on
``goal_pose`` / ``goal_path`` or as nav2's actions ``navigate_to_pose`` / ``follow_waypoints``
(:mod:`sela_ros.nodes.adapter_actions`), one at a time. What was learned and where
the mission stands go to ``state_file`` after every step and come back at start-up
(``resume``); archive and state file handling is in :mod:`sela_ros.nodes.adapter_support`.
"""
import math
import time
from collections import deque

from nav_msgs.srv import GetPlan
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

from sela_ros.core.mission import stepper_io as io
from sela_ros.core.planning import OccupancyGrid
from sela_ros.core.storage import ArchiveError, load_archive, persistence, resolve_archive_path
from sela_ros.core.validation import OutcomeLimits
from sela_ros.nodes import adapter_params as params
from sela_ros.nodes import adapter_support, markers
from sela_ros.nodes import conversions as conv
from sela_ros.nodes import grid_conversions as grids
from sela_ros.nodes import interface as ifc
from sela_ros.nodes.adapter_actions import MissionActions
from sela_ros.nodes.guard import guard, guard_parameters, guard_service
from sela_ros.nodes.heartbeat import LivenessMonitor, add_heartbeat
from sela_ros.nodes.node_main import run_node
from sela_ros.nodes.params import declare
from sela_ros.nodes.self_model_runner import SelfModelSimulations
from sela_ros.nodes.sim_check import SimulatorCheck

TICK_PERIOD = 0.25  # s (wall): time-outs only, steps advance on events
RESULT_PERIOD = 1.0  # s (wall): a mission's result is said again this often while idle
# s (wall) a lost planner has to come back (restarted) before the mission waiting on its plan
# ends: a restart is not the end of a mission, a dead planner ends it within seconds.
PLANNER_RETURN = 5.0


class SelaAdapter(Node):
    def __init__(self):
        super().__init__(ifc.SELA_ADAPTER)
        self.values = declare(self, params.PARAMETERS, on_change=self.parameters_callback)
        self.frame_id = self.values['frame_id']
        self.goal_frames = conv.goal_frames(self.frame_id, self.values['map_frame'])
        # The planner's map (latched) rules out goals off it at once.
        self.archive = self.archive_path = self.stepper = self.map = self.priors = None
        self.simulations = None  # SelfModelSimulations of the archive in use (None: none)
        self.wall = Clock(clock_type=ClockType.STEADY_TIME)
        # Saves are written off the executor's thread; what announces a step waits for the
        # save before it (acknowledged means durable) and is released on the executor's
        # thread through this guard condition.
        self._saved = self.create_guard_condition(self._release_saved)
        self.store = persistence.StateStore(self.values['state_file'] or str(
            persistence.default_state_file(self.get_fully_qualified_name())),
            on_released=self._saved.trigger)
        # The state file is this adapter's alone: a second adapter on the same file would
        # resume the other's learning and erase it at every save.
        self._store_busy = self.store.claim()
        self._events, self._feeding, self._reply = deque(), False, None
        self._deferred_plan = None  # a plan request waiting for the planner to come up
        self._asked_plan = None  # the latest plan request sent to the planner
        self._result = None  # the last mission's result status, and when it was said
        self.pubs = {kind: ifc.publisher(self, topic) for kind, topic in (
            ('behavior', ifc.BEHAVIOR), ('prediction', ifc.PREDICTION),
            ('reward', ifc.REWARD), ('diagnostics', ifc.DIAGNOSTICS), ('markers', ifc.MARKERS),
            ('target', ifc.TARGET))}
        self.markers = markers.MarkerPublisher(self, self.pubs['markers'], self.frame_id)
        # Each input message becomes one stepper event; a malformed one is logged, dropped.
        for topic, what, event in (
                (ifc.GOAL, 'goal rejected', lambda m: conv.goal_event(m, self.goal_frames)),
                (ifc.GOAL_PATH, 'goal path rejected',
                 lambda m: conv.goals_event(m, self.goal_frames)),
                (ifc.ODOM, 'ignored odometry', conv.odometry_event),
                (ifc.OUTCOME, 'ignored outcome', conv.outcome_event),
                (ifc.VERDICT, 'ignored verdict', conv.verdict_event)):
            ifc.subscription(self, topic, lambda m, e=event, w=what: self._translate(m, e, w))
        self.plan_client = ifc.client(self, ifc.MAKE_PLAN)
        self.reset_client = ifc.client(self, ifc.RESET)
        self.sim_check = SimulatorCheck(self, self.values['simulator_node'],
                                        lambda reason: self.feed(io.HoldChanged(reason)))
        ifc.subscription(self, ifc.MAP, self.map_callback)
        ifc.server(self, ifc.ADAPT, lambda q, a: self._ask(
            io.AdaptRequested(), 'no archive loaded: set the archive parameter first', a))
        ifc.server(self, ifc.CLEAR, lambda q, a: self._ask(
            io.ClearRequested(), 'no archive loaded: nothing to clear', a))
        # navigate_to_pose and follow_waypoints: the same missions, as nav2's actions.
        self.actions = MissionActions(self)
        # The planner and the detector, watched through their own liveliness writers: a lost
        # planner ends the mission (no plan can come), a lost detector is reported and
        # adaptation runs without its verdicts.
        self.liveness = LivenessMonitor(self, (ifc.PLANNER, ifc.DAMAGE_DETECTOR), math.inf,
                                        self._liveness_changed)
        add_heartbeat(self)
        try:
            self._use_archive(self.values['archive'])
        except ArchiveError as exc:
            self.report(io.Level.ERROR, f'no archive loaded: {exc}')
        else:
            if self.values['resume'] and not self._store_busy:
                self._resume()
        if self._store_busy:
            self.report(io.Level.ERROR, self._store_busy)
        self.create_timer(TICK_PERIOD, self.tick, clock=self.wall)
        self.create_timer(RESULT_PERIOD, self._say_liveness, clock=self.wall)

    # --- inputs -> events ----------------------------------------------------------------

    @guard(what='input')
    def _translate(self, msg, make_event, what):
        goal = isinstance(msg, (ifc.GOAL.type, ifc.GOAL_PATH.type))
        if goal:
            self.sim_check.poll()  # first: a mismatch found now holds this goal's first gait
        try:
            event = make_event(msg)
        except conv.MessageError as exc:
            if goal:  # the user who sent it looks on /diagnostics
                self.report(io.Level.ERROR, f'{what}: {exc}')
            else:  # a stream (odometry, outcomes): the log, at most once a second
                self.get_logger().error(f'{what}: {exc}', throttle_duration_sec=1.0)
            return
        if isinstance(event, io.GoalReceived):
            refusal = adapter_support.goal_refusal(self.map, event.goal, self.stepper)
            if refusal:
                self.report(io.Level.ERROR, refusal)
                return
        if isinstance(event, io.GoalsReceived) and len(event.goals) > self.values[
                'max_waypoints']:
            self.report(io.Level.ERROR, f'goal path refused: {len(event.goals)} poses, more '
                        f"than max_waypoints {self.values['max_waypoints']}")
            return
        self.feed(event)

    @guard
    def map_callback(self, msg):
        try:
            self.map = OccupancyGrid(*grids.occupancy_grid_from_msg(msg))
        except (conv.MessageError, ValueError) as exc:
            self.get_logger().error(f'ignored map: {exc}')

    @guard_service(what='service')
    def _ask(self, event, refusal, response):
        self._reply = io.Reply(False, refusal)
        self.feed(event)
        response.success, response.message = self._reply.success, self._reply.message
        return response

    @guard
    def tick(self):
        self.sim_check.poll()
        self.liveness.poll()
        if self._deferred_plan is not None and self.liveness.lost(ifc.PLANNER):
            self._end_if_planner_gone()
        elif self._deferred_plan is not None and self.plan_client.service_is_ready():
            command, self._deferred_plan = self._deferred_plan, None
            self._request_plan(command)
        if self.simulations is not None:
            for answer in self.simulations.poll():
                self.feed(answer)
        self.feed(io.Tick())
        self._repeat_result()

    def _liveness_changed(self, name, change):
        if change == 'alive':
            self.get_logger().info(f'{name} alive')
            self._say_liveness(name)
            return
        self.get_logger().error(self.liveness.watch.why(name))
        self._say_liveness(name)
        if name == ifc.PLANNER:
            # The plan asked can never come from the lost planner: it is asked again of a
            # restarted one, or the mission ends once none came back in PLANNER_RETURN s,
            # instead of after its plan requests' time-outs.
            if self._asked_plan is not None and self._deferred_plan is None:
                self._deferred_plan = self._asked_plan
            self._asked_plan = None

    def _end_if_planner_gone(self):
        lost_at = self.liveness.watch.lost.get(ifc.PLANNER)
        if (self._deferred_plan is not None and lost_at is not None
                and time.monotonic() - lost_at >= PLANNER_RETURN):
            command, self._deferred_plan = self._deferred_plan, None
            self.feed(self._planner_lost(command))

    def _adapt_without_detector(self):
        """No damage can be detected while the detector is lost: learn from every outcome,
        as a detection would have it (also after a ``~/clear`` meanwhile)."""
        if (self.liveness.lost(ifc.DAMAGE_DETECTOR) and self.stepper is not None
                and not self.stepper.logic.adapting
                and not self.stepper.adapt_after_outcome):
            self.report(io.Level.WARN, f'{ifc.DAMAGE_DETECTOR} lost: no verdicts, adapting '
                        'from every outcome')
            self.feed(io.AdaptRequested())

    def _planner_lost(self, command):
        return io.PlanReceived(command.step, tuple(command.start), reason=(
            f'the planner is lost ({self.liveness.watch.why(ifc.PLANNER)})'))

    @guard
    def _say_liveness(self, only=None):
        """Every second, as diagnostics are read (a monitor that starts late still sees
        it): the detector's state (no one else watches it), and the planner's while it is
        lost (the detector says it too); ``only``: that node's, now."""
        self._adapt_without_detector()
        statuses = []
        for name in (ifc.PLANNER, ifc.DAMAGE_DETECTOR):
            if only not in (None, name) or name not in self.liveness.watch.seen:
                continue
            if self.liveness.lost(name):
                message = self.liveness.watch.why(name)
                if name == ifc.DAMAGE_DETECTOR:
                    message += ': no verdicts, missions adapt from every outcome'
                statuses.append(conv.diagnostic_status(conv.diagnostic_level(io.Level.ERROR),
                                                       f'{name}: liveness', message))
            elif only is not None or name == ifc.DAMAGE_DETECTOR:
                statuses.append(conv.diagnostic_status(conv.diagnostic_level(io.Level.OK),
                                                       f'{name}: liveness',
                                                       f'{name} alive (liveliness)'))
        if statuses:
            self.pubs['diagnostics'].publish(conv.diagnostic_array(
                statuses, self.get_clock().now().to_msg()))

    def _repeat_result(self):
        """While idle after a mission, its result is said again every second, as
        diagnostics are: a client that was not matched when it ended (the adapter had just
        restarted) still hears it. The result names its mission (``mission``)."""
        if self._result is None:
            return
        level, message, values, said = self._result
        if (self.stepper is None or self.stepper.state is not io.State.DONE
                or values.get('mission') != str(self.stepper.mission_id)):
            self._result = None  # a new mission, or a cleared one: nothing to repeat
        elif self.now() - said >= RESULT_PERIOD:
            self._result = (level, message, values, self.now())
            self.say(level, message, values)

    @guard_parameters
    def parameters_callback(self, changes):
        # Called by params.declare with values its check accepted (the rest is read-only).
        for param in changes:
            if param.name == 'archive':
                problem, path, archive = adapter_support.archive_change(
                    param.value, self.archive_path if self.archive is not None else None,
                    self.stepper, self.get_name(), self.sim_check.mismatch)
                if problem:
                    return SetParametersResult(successful=False, reason=problem)
                if archive is None:
                    self.get_logger().info(f'archive {path} is the one in use: kept, with '
                                           'what was learned on it')
                else:
                    self._use_archive(path, archive)
            elif self.stepper is not None:
                self.stepper.configure(**params.stepper_change(param.name, param.value,
                                                               self.archive))
            self.values[param.name] = param.value
        return SetParametersResult(successful=True)

    # --- the archive, and what was learned ------------------------------------------------

    def _use_archive(self, path, archive=None):
        """Load the archive at ``path`` ('': the shipped one; ``8d``, ``2d``: the shipped ones
        by name; ``archive``: already loaded from there) and a stepper over it; a mission in
        progress goes on with the new archive, from where the robot is."""
        path = resolve_archive_path(path)
        archive, old = archive if archive is not None else load_archive(path), self.stepper
        self.archive, self.archive_path = archive, path
        self.priors = adapter_support.load_priors(self.values['priors.tables'], archive, path,
                                                  self.get_logger())
        self._use_self_model(archive)
        self.stepper = adapter_support.new_stepper(
            self.values, archive, self.priors, next_id=1 if old is None else old.next_id,
            self_model=self._self_model())
        self.sim_check.use(archive, path)
        self.get_logger().info(f'archive {path}: {len(archive)} behaviours, '
                               f'{archive.descriptors.shape[1]}-D descriptors, kernel length '
                               f'{self.stepper.sela.config.gp_kernel_sigma:g}')
        for event in adapter_support.carried_over(old):
            self.feed(event)

    def _use_self_model(self, archive):
        """The self-model's simulations for ``archive`` (those under way for another are
        dropped)."""
        if self.simulations is not None:
            self.simulations.close()
            self.simulations = None
        model, robot, why_not = adapter_support.self_model(self.values, archive)
        if why_not:  # a 2-D map, a robot the simulator cannot build: SELA as without it
            self.get_logger().info(why_not)
        if model is not None:
            self.simulations = SelfModelSimulations(archive.params, archive.simulator_settings,
                                                    robot, self.values['self_model.workers'])
            self.get_logger().info(
                f'self-model: the feet of the {robot} are read; a damage they show is '
                f'simulated on {self.values["self_model.gaits"]} gaits beside the mission')

    def _self_model(self):
        """A fresh self-model for a new stepper (None: none)."""
        return None if self.simulations is None else \
            adapter_support.self_model(self.values, self.archive)[0]

    def _resume(self):
        """Take back what the state file holds; an unusable file is set aside with the
        reason."""
        path = self.store.path
        restored = {}

        def restore(state):
            # Into a fresh stepper, swapped in below only once all of it came back.
            stepper = adapter_support.new_stepper(self.values, self.archive, self.priors,
                                                  self_model=self._self_model())
            restored['commands'] = stepper.restore(state, self.now())
            restored['stepper'] = stepper

        limits = OutcomeLimits(self.stepper.config.max_displacement)
        state, problem = persistence.resume_state(
            path, len(self.archive), restore, limits=limits,
            learned_on=persistence.learned_on(self.values['simulator_node']))
        if problem:
            self.report(io.Level.ERROR, problem)
            return
        if state is not None:
            self.stepper = restored['stepper']
            self._dispatch(restored['commands'])
            mode = 'adapting' if self.stepper.logic.adapting else 'trusting the map'
            self.get_logger().warn(f'resumed from {path}: '
                                   f'{len(self.stepper.sela.observations[0])} '
                                   f'observation(s), {mode}')

    # --- the stepper and its commands ----------------------------------------------------

    def now(self):
        return self.wall.now().nanoseconds * 1e-9

    def feed(self, event):
        """Hand ``event`` to the stepper; events raised while dispatching queue behind it."""
        if self.stepper is None:
            return
        self._events.append(event)
        if self._feeding:
            return
        self._feeding = True
        try:
            while self._events:
                self._dispatch(self.stepper.handle(self._events.popleft(), self.now()))
        finally:
            self._feeding = False

    def _dispatch(self, commands):
        for i, c in enumerate(commands):
            if isinstance(c, io.SendGait):
                # Write-ahead: sent once the save recording it is written (see below).
                self.store.after_saves(c)
                self._release_saved()
            elif isinstance(c, io.RequestPlan):
                self._request_plan(c)
            elif isinstance(c, io.RequestReset):
                self._call(self.reset_client, Trigger.Request(), lambda a: io.ResetDone(
                    bool(a and a.success), a.message if a else 'no answer'))
            elif isinstance(c, (io.PublishReward, io.PublishStatus, io.MissionEnded)):
                # Acknowledged means durable: out once the saves before it are on disk.
                self.store.after_saves(c)
                self._release_saved()
            elif isinstance(c, io.SimulateDamage):
                if self.simulations is None:  # a stepper given no self-model never asks
                    self.feed(io.DamageSimulated(c.damage, c.gaits, error='no simulator'))
                else:
                    self.simulations.submit(c)
            elif isinstance(c, io.Report):
                self.report(c.level, c.message)
            elif isinstance(c, io.Reply):
                self._reply = c
            elif isinstance(c, io.SaveState):  # the fsync'ed write is off the step's path
                # The record of a gait about to be sent must only survive a crash of this
                # process (it is written again, fsync'ed, with the outcome): no fsync, ~1 ms.
                ahead = i + 1 < len(commands) and isinstance(commands[i + 1], io.SendGait)
                self.store.save(persistence.state_document(
                    len(self.archive), c.snapshot,
                    persistence.learned_on(self.values['simulator_node'])), sync=not ahead)

    @guard(what='announcement')
    def _release_saved(self):
        for items, error in self.store.released():
            if error:
                self.report(io.Level.ERROR, f'{error}: what was learned since the last '
                             'good save is only in memory')
            for c in items:
                if isinstance(c, io.SendGait):
                    self._send_gait(c)
                elif isinstance(c, io.PublishReward):
                    self.pubs['reward'].publish(Float64(data=c.value))
                elif isinstance(c, io.MissionEnded):
                    self.actions.mission_ended(c)  # its status, just before it, said it too
                else:
                    # goal_id: the action goal that owns the mission ('' : a topic's goal).
                    values = dict(c.values, saved='False' if error else 'True',
                                  goal_id=self.actions.goal_id(c.values.get('mission', '')))
                    self.say(c.level, c.message, values)
                    self.actions.status_released(c.level, c.message, values)
                    if 'success' in values:
                        self._result = (c.level, c.message, values, self.now())
                    if 'end_pose' in c.values and 'step' in c.values:
                        self.markers.outcome(c.values['end_pose'])

    def _send_gait(self, c):
        self.pubs['behavior'].publish(conv.behavior_to_msg(self.archive.params[c.index],
                                                           c.behavior_id))
        if not c.resend:
            self.pubs['prediction'].publish(conv.prediction_to_msg(
                c.behavior_id, c.predicted_gr, c.sigma))
            self.pubs['target'].publish(conv.point_stamped(
                c.waypoint, stamp=self.get_clock().now().to_msg(), frame_id=self.frame_id))
            self.markers.decision(c)

    def _request_plan(self, command):
        if self.liveness.lost(ifc.PLANNER) or not self.plan_client.service_is_ready():
            self._deferred_plan = command  # sent by the timer once the planner is up
            self._end_if_planner_gone()
            return
        request = GetPlan.Request(
            start=conv.pose_stamped(command.start[:2], command.start[2], frame_id=self.frame_id),
            goal=conv.pose_stamped(command.goal, 0.0, frame_id=self.frame_id))
        self._asked_plan = command
        self._call(self.plan_client, request,
                   lambda answer: adapter_support.plan_event(answer, command, self.map))

    def _call(self, client, request, event):
        """Call ``client``; its answer (None: not available) becomes ``event(answer)``."""
        if not client.service_is_ready():
            self.get_logger().error(f'{client.srv_name} is not available')
            self.feed(event(None))
            return
        client.call_async(request).add_done_callback(lambda f: self.feed(event(f.result())))

    def report(self, level, message):
        # One call site per severity: rclpy refuses to log one site at two severities.
        if level is io.Level.ERROR:
            self.get_logger().error(message)
            self.say(level, message, {})
        elif level is io.Level.WARN:
            self.get_logger().warn(message)
        else:
            self.get_logger().info(message)

    def say(self, level, message, values):
        """Publish a mission status (``values``: what it says, as text) on diagnostics."""
        self.pubs['diagnostics'].publish(conv.diagnostic_array(conv.diagnostic_status(
            conv.diagnostic_level(level), ifc.MISSION_STATUS, message, values),
            self.get_clock().now().to_msg()))

    def destroy_node(self):
        self.actions.destroy()
        if self.simulations is not None:
            self.simulations.close()
        self.store.close()  # the last snapshot reaches the disk
        super().destroy_node()


def main(args=None):
    run_node(SelaAdapter, args)


if __name__ == '__main__':
    main()
