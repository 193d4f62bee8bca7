"""The ``sela_adapter`` node: the archive, the GPs and UCB; chooses gaits and learns.

A thin layer around :class:`sela_ros.core.stepper.MissionStepper` (the step cycle: plan ->
ask -> command -> outcome -> verdict -> learn): each message or service answer becomes a
stepper event, each command it returns a message, a service call or a file write; no
callback waits. The waypoint is the last pose of ``planner/make_plan``'s answer; outcomes
and verdicts (``damage_detector/verdict``) pair with the command by id. ``~/adapt`` starts
adaptation (or restarts it from scratch), ``~/clear`` forgets what was learned. What was
learned and where the mission stands go to ``state_file`` after every step and come back at
start-up (``resume``). A bad archive is reported and the node stays up: set a good one with
``ros2 param set /sela_adapter archive PATH``.
"""
import os
from collections import deque

from nav_msgs.srv import GetPlan
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

from sela_ros.core import persistence
from sela_ros.core import stepper_io as io
from sela_ros.core.archive import ArchiveError, default_archive_path, load_archive
from sela_ros.core.learning import make_sela
from sela_ros.core.planning import OccupancyGrid
from sela_ros.core.stepper import MissionStepper
from sela_ros.nodes import adapter_params as params
from sela_ros.nodes import conversions as conv
from sela_ros.nodes import interface as ifc
from sela_ros.nodes import markers
from sela_ros.nodes.guard import guard, guard_parameters, guard_service
from sela_ros.nodes.heartbeat import add_heartbeat
from sela_ros.nodes.node_main import run_node
from sela_ros.nodes.params import declare
from sela_ros.nodes.sim_check import SimulatorCheck

TICK_PERIOD = 0.25  # s (wall): time-outs only, steps advance on events


class SelaAdapter(Node):
    def __init__(self):
        super().__init__(ifc.SELA_ADAPTER)
        self.values = declare(self, params.PARAMETERS, on_change=self.parameters_callback)
        self.frame_id = self.values['frame_id']
        self.archive = self.stepper = None
        self.wall = Clock(clock_type=ClockType.STEADY_TIME)
        # Saves are written off the executor's thread; what announces a step waits for the
        # save before it (acknowledged means durable) and is released on the executor's
        # thread through this guard condition.
        self._saved = self.create_guard_condition(self._release_saved)
        self.store = persistence.StateStore(self.values['state_file'] or str(
            persistence.default_state_file()), on_released=self._saved.trigger)
        self.archive_path = None
        self.map = None  # the planner's map (latched): goals off it are refused at once
        self._events, self._feeding, self._reply = deque(), False, None
        self._deferred_plan = None  # a plan request waiting for the planner to come up
        self.pubs = {kind: ifc.publisher(self, topic) for kind, topic in (
            ('behavior', ifc.BEHAVIOR), ('prediction', ifc.PREDICTION),
            ('reward', ifc.REWARD), ('diagnostics', ifc.DIAGNOSTICS), ('markers', ifc.MARKERS))}
        self._trail = deque(maxlen=500)  # where the robot ended each step (the markers' trail)
        # Each input message becomes one stepper event; a malformed one is logged, dropped.
        for topic, what, event in (
                (ifc.GOAL, 'goal rejected', lambda m: conv.goal_event(m, self.frame_id)),
                (ifc.GOAL_PATH, 'goal path rejected',
                 lambda m: conv.goals_event(m, self.frame_id)),
                (ifc.ODOM, 'ignored odometry', conv.odometry_event),
                (ifc.OUTCOME, 'ignored outcome', conv.outcome_event),
                (ifc.VERDICT, 'ignored verdict', conv.verdict_event)):
            ifc.subscription(self, topic, lambda m, e=event, w=what: self._translate(m, e, w))
        self.plan_client = ifc.client(self, ifc.MAKE_PLAN)
        self.reset_client = ifc.client(self, ifc.RESET)
        self.sim_check = SimulatorCheck(self, self.values['simulator_node'],
                                        lambda reason: self._feed(io.HoldChanged(reason)))
        ifc.subscription(self, ifc.MAP, self.map_callback)
        ifc.server(self, ifc.ADAPT, lambda q, a: self._ask(
            io.AdaptRequested(), 'no archive loaded: set the archive parameter first', a))
        ifc.server(self, ifc.CLEAR, lambda q, a: self._ask(
            io.ClearRequested(), 'no archive loaded: nothing to clear', a))
        self.add_on_set_parameters_callback(self.parameters_callback)
        add_heartbeat(self)
        try:
            self._use_archive(self.values['archive'])
        except ArchiveError as exc:
            self._report(io.Level.ERROR, f'no archive loaded: {exc}')
        else:
            if self.values['resume']:
                self._resume()
        self.create_timer(TICK_PERIOD, self.tick, clock=self.wall)

    def _use_archive(self, path):
        path = path or str(default_archive_path())
        archive, old = load_archive(path), self.stepper
        self.archive, self.archive_path = archive, path
        self.stepper = MissionStepper(make_sela(archive, params.sela_config(self.values)),
                                      params.stepper_config(self.values))
        self.sim_check.use(archive, path)
        self.get_logger().info(f'archive {path}: {len(archive)} behaviours')
        if old is not None:
            self.stepper.next_id = old.next_id  # command ids stay unique across archives
        if old is not None and old.goal is not None and old.state is not io.State.DONE:
            if old.odom is not None:  # the new stepper goes on with the goal, from here
                self._feed(io.PoseObserved(tuple(old.odom), old.odom_stamp))
            self._feed(io.GoalsReceived((tuple(old.goal), *map(tuple, old.goals_left))))

    def _archive_change(self, value):
        """Why ``archive`` cannot become ``value`` now, or None (then it is in use).

        The same file again keeps everything (nothing to load). Another file would make what
        was learned meaningless (its indices are the old archive's gaits): refused while
        anything is learned, until ``~/clear``.
        """
        path = value or str(default_archive_path())
        if self.archive is not None and _same_file(path, self.archive_path):
            self.get_logger().info(f'archive {path} is the one in use: kept, with what was '
                                   'learned on it')
            return None
        if self.stepper is not None and self.stepper.state not in (
                io.State.IDLE, io.State.DONE, io.State.READY):
            return 'archive cannot change mid-step'
        learned = 0 if self.stepper is None else len(self.stepper.sela.observations[0])
        if learned:
            return (f'archive {path} refused: {learned} observation(s) were learned on '
                    f'{self.archive_path} and would be lost; call '
                    f'{self.get_name()}/clear first, then set the archive again')
        try:
            self._use_archive(path)
        except ArchiveError as exc:
            return str(exc)
        return None

    def _resume(self):
        path = self.store.path
        restored = []

        def restore(state):
            # Into a fresh stepper, swapped in only once all of it came back.
            stepper = MissionStepper(make_sela(self.archive, params.sela_config(self.values)),
                                     params.stepper_config(self.values))
            restored.extend(stepper.restore(state, self._now()))
            self.stepper = stepper

        state, problem = persistence.resume_state(path, len(self.archive), restore)
        if problem:
            self._report(io.Level.ERROR, problem)
            return
        self._dispatch(restored)
        if state is not None:
            mode = 'adapting' if self.stepper.logic.adapting else 'trusting the map'
            self.get_logger().warn(f'resumed from {path}: '
                                   f'{len(self.stepper.sela.observations[0])} observation(s), '
                                   f'{mode}')

    # --- inputs -> events ----------------------------------------------------------------

    @guard(what='input')
    def _translate(self, msg, make_event, what):
        if isinstance(msg, (ifc.GOAL.type, ifc.GOAL_PATH.type)):
            self.sim_check.poll()  # first: a mismatch found now holds this goal's first gait
        try:
            event = make_event(msg)
        except conv.MessageError as exc:
            self.get_logger().error(f'{what}: {exc}')
            return
        if isinstance(event, io.GoalReceived) and self._goal_refused(event.goal):
            return
        self._feed(event)

    @guard
    def map_callback(self, msg):
        try:
            self.map = OccupancyGrid(*conv.occupancy_grid_from_msg(msg))
        except (conv.MessageError, ValueError) as exc:
            self.get_logger().error(f'ignored map: {exc}')

    def _goal_refused(self, goal):
        """A goal off the planner's map or inside an obstacle cannot be planned: refused
        here, and a mission in progress goes on (without a map: the planner decides)."""
        if self.map is None:
            return False
        if not self.map.in_map(goal):
            problem = f'off the map {self.map.bounds_text()}'
        elif not self.map.is_free(self.map.world_to_cell(goal)):
            problem = 'inside an obstacle'
        else:
            return False
        running = self.stepper is not None and self.stepper.goal is not None and \
            self.stepper.state not in (io.State.IDLE, io.State.DONE)
        self._report(io.Level.ERROR, f'goal ({goal[0]:.2f}, {goal[1]:.2f}) refused: {problem}'
                     + (f'; the mission to ({self.stepper.goal[0]:.2f}, '
                        f'{self.stepper.goal[1]:.2f}) goes on' if running else ''))
        return True

    @guard_service(what='service')
    def _ask(self, event, refusal, response):
        self._reply = io.Reply(False, refusal)
        self._feed(event)
        response.success, response.message = self._reply.success, self._reply.message
        return response

    @guard
    def tick(self):
        self.sim_check.poll()
        if self._deferred_plan is not None and self.plan_client.service_is_ready():
            command, self._deferred_plan = self._deferred_plan, None
            self._request_plan(command)
        self._feed(io.Tick())

    @guard_parameters
    def parameters_callback(self, changes):
        # Called by params.declare with values its check accepted (the rest is read-only).
        for param in changes:
            if param.name == 'archive':
                problem = self._archive_change(param.value)
                if problem:
                    return SetParametersResult(successful=False, reason=problem)
            elif self.stepper is not None:
                self.stepper.configure(**params.stepper_change(param.name, param.value))
            self.values[param.name] = param.value
        return SetParametersResult(successful=True)

    # --- the stepper and its commands ----------------------------------------------------

    def _now(self):
        return self.wall.now().nanoseconds * 1e-9

    def _feed(self, event):
        """Hand ``event`` to the stepper; events raised while dispatching queue behind it."""
        if self.stepper is None:
            return
        self._events.append(event)
        if self._feeding:
            return
        self._feeding = True
        try:
            while self._events:
                self._dispatch(self.stepper.handle(self._events.popleft(), self._now()))
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
            elif isinstance(c, (io.PublishReward, io.PublishStatus)):
                # Acknowledged means durable: out once the saves before it are on disk.
                self.store.after_saves(c)
                self._release_saved()
            elif isinstance(c, io.Report):
                self._report(c.level, c.message)
            elif isinstance(c, io.Reply):
                self._reply = c
            elif isinstance(c, io.SaveState):  # the fsync'ed write is off the step's path
                # The record of a gait about to be sent must only survive a crash of this
                # process (it is written again, fsync'ed, with the outcome): no fsync, ~1 ms.
                ahead = i + 1 < len(commands) and isinstance(commands[i + 1], io.SendGait)
                self.store.save(persistence.state_document(len(self.archive), c.snapshot),
                                sync=not ahead)

    @guard(what='announcement')
    def _release_saved(self):
        for items, error in self.store.released():
            if error:
                self._report(io.Level.ERROR, f'{error}: what was learned since the last '
                             'good save is only in memory')
            for c in items:
                if isinstance(c, io.SendGait):
                    self._send_gait(c)
                elif isinstance(c, io.PublishReward):
                    self.pubs['reward'].publish(Float64(data=c.value))
                else:
                    self._status(c.level, c.message, dict(
                        c.values, saved='False' if error else 'True'))
                    if 'end_pose' in c.values and 'step' in c.values:
                        self._outcome_markers(c.values['end_pose'])

    def _send_gait(self, c):
        self.pubs['behavior'].publish(conv.behavior_to_msg(self.archive.params[c.index],
                                                           c.behavior_id))
        if not c.resend:
            self.pubs['prediction'].publish(conv.prediction_to_msg(
                c.behavior_id, c.predicted_gr, c.sigma))
            self._decision_markers(c)

    def _decision_markers(self, gait):
        # What SELA thinks, for RViz/Foxglove: the waypoint, the best candidates by UCB
        # (discs of 2 sigma where each is predicted to land), the chosen one.
        if gait.candidates is None or not len(gait.candidates):
            return
        chosen = gait.candidates[0]
        self.pubs['markers'].publish(markers.decision_markers(
            self.frame_id, self.get_clock().now().to_msg(), gait.pose, gait.waypoint,
            gait.candidates, chosen[:2], chosen[2]))

    def _outcome_markers(self, end_pose_text):
        try:
            end = [float(v) for v in end_pose_text.split()[:2]]
        except ValueError:
            return
        self._trail.append(end)
        self.pubs['markers'].publish(markers.outcome_markers(
            self.frame_id, self.get_clock().now().to_msg(), end, list(self._trail)))

    def _request_plan(self, command):
        if not self.plan_client.service_is_ready():
            self._deferred_plan = command  # sent by the timer once the planner is up
            return
        request = GetPlan.Request(
            start=conv.pose_stamped(command.start[:2], command.start[2], frame_id=self.frame_id),
            goal=conv.pose_stamped(command.goal, 0.0, frame_id=self.frame_id))

        def event(answer):
            poses = answer.plan.poses if answer is not None else []
            waypoint = (poses[-1].pose.position.x, poses[-1].pose.position.y) if poses else None
            return io.PlanReceived(command.step, tuple(command.start), waypoint,
                                   'the planner says why on /diagnostics')
        self._call(self.plan_client, request, event)

    def _call(self, client, request, event):
        """Call ``client``; its answer (None: not available) becomes ``event(answer)``."""
        if not client.service_is_ready():
            self.get_logger().error(f'{client.srv_name} is not available')
            self._feed(event(None))
            return
        client.call_async(request).add_done_callback(lambda f: self._feed(event(f.result())))

    def _report(self, level, message):
        # One call site per severity: rclpy refuses to log one site at two severities.
        if level is io.Level.ERROR:
            self.get_logger().error(message)
            self._status(level, message, {})
        elif level is io.Level.WARN:
            self.get_logger().warn(message)
        else:
            self.get_logger().info(message)

    def _status(self, level, message, values):
        self.pubs['diagnostics'].publish(conv.diagnostic_array(conv.diagnostic_status(
            conv.diagnostic_level(level), ifc.MISSION_STATUS, message, values),
            self.get_clock().now().to_msg()))

    def destroy_node(self):
        self.store.close()  # the last snapshot reaches the disk
        super().destroy_node()


def _same_file(a, b):
    try:
        return os.path.samefile(a, b)
    except (OSError, ValueError, TypeError):
        return False


def main(args=None):
    run_node(SelaAdapter, args)


if __name__ == '__main__':
    main()
