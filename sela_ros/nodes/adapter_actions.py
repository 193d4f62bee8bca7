"""The ``sela_adapter``'s missions as nav2's actions: ``navigate_to_pose`` (NavigateToPose),
``navigate_through_poses`` (NavigateThroughPoses: the poses visited in order, one mission) and
``follow_waypoints`` (FollowWaypoints), with nav2 Jazzy's types.

A goal becomes the same stepper event as a goal on ``goal_pose`` or ``goal_path``
(:mod:`sela_ros.nodes.adapter_node`); the goal handle is bound to the mission it started, by the
stepper's mission id, so that the mission's statuses become the goal's feedback and its
:class:`~sela_ros.core.mission.stepper_io.MissionEnded` the goal's result. One mission at a
time, as nav2: a new goal (an action's, or one on the topics) ends the running mission and
aborts its goal ("preempted"). A cancel ends the mission after the running gait (no gait after
it); the goal is then CANCELED (a cancel that comes once the mission has ended is rejected).
A goal off the map or in an obstacle is accepted and aborted at once, with ``error_code`` and
``error_msg`` saying why; a mission that ends without reaching its goal is aborted with the
stepper's reason. Every goal request is answered: the services keep a burst of requests, and
a goal is rejected with the reason logged when too many are active or it makes too many
waypoints.

No callback waits: the execute callbacks are coroutines that await the mission's end, which
the node's event loop resolves (:meth:`MissionActions.mission_ended`).
"""
import math
from dataclasses import dataclass, field

from builtin_interfaces.msg import Duration
from nav2_msgs.msg import MissedWaypoint
from nav_msgs.msg import Path
from rclpy.action import CancelResponse, GoalResponse
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.task import Future

from sela_ros.core.mission import stepper_io as io
from sela_ros.core.mission import vector_from_text
from sela_ros.nodes import conversions as conv
from sela_ros.nodes import interface as ifc


@dataclass
class Binding:
    """An action goal and the mission it started."""

    handle: object  # rclpy ServerGoalHandle
    action: ifc.Action
    goals: list  # [(x, y), ...] in the odom frame, in order
    poses: list  # the goal's PoseStamped, for missed waypoints
    first_index: int  # FollowWaypoints: the rank in ``poses`` of goals[0] (else 0)
    started: float  # the node's clock (s): sim time under use_sim_time, as nav2's
    ended: Future = field(default_factory=Future)  # resolved with the MissionEnded
    start_distance: float = None


#: The action servers' goal, cancel and result services keep this many requests (and
#: replies) each: a burst from several clients is answered, none dropped (rclpy's default
#: keeps 10).
SERVICE_DEPTH = 1000
#: Goals accepted and not yet ended, at most: one more is rejected, with the reason logged.
MAX_ACTIVE_GOALS = 200
#: Ends of missions not (yet) bound to a goal that are kept (topic goals' ones age out).
UNBOUND_KEPT = 16
#: At most this far (s) ahead of the node's clock an outcome's stamp is taken as the time of
#: its feedback (the clock's messages late); further, the clocks differ and the node's wins.
CLOCK_LAG = 10.0
_SERVICE_QOS = QoSProfile(depth=SERVICE_DEPTH, history=HistoryPolicy.KEEP_LAST,
                          reliability=ReliabilityPolicy.RELIABLE)


def _seconds(time):
    """A time of the node's clock in seconds (the simulator's under use_sim_time)."""
    return time.nanoseconds * 1e-9


def _duration(seconds):
    seconds = max(0.0, float(seconds)) if math.isfinite(seconds) else 0.0
    sec = int(seconds)
    return Duration(sec=sec, nanosec=min(999_999_999, int(round((seconds - sec) * 1e9))))


def _legs(goals, index):
    """The length of the way from ``goals[index]`` through the goals after it, in order."""
    return sum(math.hypot(b[0] - a[0], b[1] - a[1])
               for a, b in zip(goals[index:], goals[index + 1:]))


def goal_id_text(handle):
    """A goal handle's id as the hex text statuses carry (``goal_id``)."""
    return bytes(handle.goal_id.uuid).hex()


def goal_count(request):
    """How many waypoints a FollowWaypoints ``request`` makes (``goal_index`` on, then
    ``number_of_loops`` more rounds), without expanding them; a NavigateThroughPoses one,
    its poses."""
    poses = len(request.poses)
    if not hasattr(request, 'goal_index'):
        return poses
    return max(0, poses - int(request.goal_index)) + poses * int(request.number_of_loops)


def unused_request(action, request):
    """What a goal asks that this stack does not do (nav2's ``behavior_tree``), in words for
    a warning; None: nothing. The goal goes on all the same."""
    tree = getattr(request, 'behavior_tree', '')
    if not tree:
        return None
    return (f'{action.name}: behavior_tree {tree!r} is not used here (no behaviour trees: '
            'SELA chooses every gait); the goal goes on')


class MissionActions:
    """The action servers of ``node`` (a :class:`~sela_ros.nodes.adapter_node.
    SelaAdapter`), and which goal each mission belongs to."""

    def __init__(self, node):
        self.node = node
        self.bindings = {}  # mission id -> Binding
        # Ends of missions no goal was bound to yet, by mission id: a mission can end within
        # the event that starts it (its goal reached already), before _run binds its goal.
        self._unbound = {}
        # The latest status of each such mission, said before its goal was bound (so without
        # the goal's id): said again, with it, once the goal is bound.
        self._said_unbound = {}
        self._cancels = []  # goal handles whose cancel was accepted, to feed after it
        self._cancel_ready = node.create_guard_condition(self._feed_cancels)
        self.active = 0  # goals accepted and not yet ended
        self.servers = [
            ifc.action_server(node, action, self._execute, goal_callback=self._goal,
                              cancel_callback=self._cancel,
                              goal_service_qos_profile=_SERVICE_QOS,
                              result_service_qos_profile=_SERVICE_QOS,
                              cancel_service_qos_profile=_SERVICE_QOS)
            for action in ifc.ACTIONS]

    def destroy(self):
        for server in self.servers:
            server.destroy()

    # --- goals -----------------------------------------------------------------------------

    def _goal(self, request):
        """Accept a goal, or reject it saying why (a goal response has no reason)."""
        refusal = self._refusal(request)
        if refusal is None:
            self.active += 1
            return GoalResponse.ACCEPT
        self.node.report(io.Level.ERROR, f'goal rejected: {refusal}')
        return GoalResponse.REJECT

    def _refusal(self, request):
        if self.node.stepper is None:  # no archive, no stepper: nothing could walk to it
            return 'no archive loaded: set the archive parameter first'
        if self.active >= MAX_ACTIVE_GOALS:
            return (f'{self.active} accepted goals have not ended yet (at most '
                    f'{MAX_ACTIVE_GOALS}); send it again later')
        if hasattr(request, 'poses'):
            count = goal_count(request)
            limit = self.node.values['max_waypoints']
            if count > limit and not hasattr(request, 'goal_index'):  # NavigateThroughPoses
                return (f'navigate_through_poses: {count} poses, more than max_waypoints '
                        f'{limit}')
            if count > limit:  # FollowWaypoints
                return (f'follow_waypoints: {len(request.poses)} pose(s) from goal_index '
                        f'{request.goal_index} and {request.number_of_loops} more loop(s) '
                        f'make {count} waypoints, more than max_waypoints {limit}')
        return None

    def _cancel(self, handle):
        mission = self._mission_of(handle)
        stepper = self.node.stepper
        if mission is not None and not (stepper is not None and stepper.running()
                                        and stepper.mission_id == mission):
            # Its mission has ended (its result is on its way): it ends as that says.
            return CancelResponse.REJECT
        self._cancels.append(handle)
        self._cancel_ready.trigger()  # fed once the goal is CANCELING (after this returns)
        return CancelResponse.ACCEPT

    def _feed_cancels(self):
        handles, self._cancels = self._cancels, []
        stepper = self.node.stepper
        for handle in handles:
            mission = self._mission_of(handle)
            if mission is not None and stepper is not None and stepper.running() \
                    and stepper.mission_id == mission:
                self.node.feed(io.CancelRequested('canceled by its action client'))

    def _mission_of(self, handle):
        return next((m for m, b in self.bindings.items() if b.handle is handle), None)

    async def _execute(self, handle):
        try:
            return await self._run(handle)
        finally:
            self.active -= 1

    async def _run(self, handle):
        action = self._action_of(handle)
        try:
            goals, poses, first = self._goals_of(action, handle.request)
        except conv.MessageError as exc:
            message = f'{action.name} goal refused: {exc}'
            self.node.report(io.Level.ERROR, message)
            return self._finish(handle, action, False, ifc.UNKNOWN_ERROR, message, [])
        unused = unused_request(action, handle.request)
        if unused is not None:
            self.node.report(io.Level.WARN, unused)
        problem = self._problem(goals)
        if problem is not None:
            index, code, why = problem
            message = (f'goal ({goals[index][0]:.2f}, {goals[index][1]:.2f}) refused: {why}')
            self.node.report(io.Level.ERROR, message)
            return self._finish(handle, action, False, code, message,
                                self._missed(poses, first, 0, goals, ended_at=(index, code)))
        binding = Binding(handle, action, goals, poses, first,
                          _seconds(self.node.get_clock().now()))
        stepper = self.node.stepper
        before = stepper.mission_id
        self.node.sim_check.poll()  # first: a mismatch found now holds this goal's first gait
        self._unbound.clear()  # a mission that ends within the feed below is this goal's
        self._said_unbound.clear()
        event = (io.GoalReceived(goals[0]) if action is ifc.NAVIGATE_TO_POSE
                 else io.GoalsReceived(tuple(goals)))
        self.node.feed(event)
        stepper = self.node.stepper
        if stepper.mission_id == before:
            if not (stepper.running() and tuple(stepper.goal) == tuple(goals[0])):
                return self._finish(handle, action, False, ifc.UNKNOWN_ERROR,
                                    'the adapter did not take the goal (see its log)',
                                    self._missed(poses, first, 0, goals,
                                                 ended_at=(0, ifc.UNKNOWN_ERROR)))
            # The goal the mission is walking to: it goes on, under this goal now.
            old = self.bindings.pop(before, None)
            if old is not None:
                old.ended.set_result(io.MissionEnded(
                    before, False, 'preempted', 'preempted by a new goal (the mission goes '
                    'on under it)', stepper.steps))
        self.bindings[stepper.mission_id] = binding
        said = self._said_unbound.pop(str(stepper.mission_id), None)
        if said is not None:  # its client waits for a status that names its goal
            level, message, values = said
            self.node.say(level, message, dict(values, goal_id=goal_id_text(handle)))
        early = self._unbound.pop(stepper.mission_id, None)
        if early is not None:
            self.mission_ended(early)
        if handle.is_cancel_requested:  # canceled before its mission started
            self.node.feed(io.CancelRequested('canceled by its action client'))
        ended = await binding.ended
        return self._result(binding, ended)

    def _action_of(self, handle):
        return next(a for a in ifc.ACTIONS if isinstance(handle.request, a.type.Goal))

    def _goals_of(self, action, request):
        """The mission's goals in the odom frame, the poses as sent and the rank of the first
        goal among them (FollowWaypoints' ``goal_index``; ``number_of_loops`` more rounds)."""
        frames = self.node.goal_frames
        if action is ifc.NAVIGATE_TO_POSE:
            goal = tuple(conv.goal_from_pose_stamped(request.pose, frames))
            return [goal], [request.pose], 0
        poses = list(request.poses)
        if not poses:
            raise conv.MessageError('the goal has no poses')
        first = int(getattr(request, 'goal_index', 0))
        if first >= len(poses):
            raise conv.MessageError(f'goal_index {first} is past the '
                                    f'{len(poses)} poses')
        path = Path(poses=poses)
        path.header.frame_id = poses[0].header.frame_id
        # Checked once; the loops repeat the goals, bounded by max_waypoints (_refusal).
        once = list(conv.goals_from_path(path, frames))
        loops = int(getattr(request, 'number_of_loops', 0))
        return once[first:] + once * loops, poses, first

    def _problem(self, goals):
        """``(index, error_code, why)`` of the first goal the map rules out, or None."""
        grid = self.node.map
        if grid is None:
            return None
        for i, goal in enumerate(goals):
            why = grid.goal_problem(goal)
            if why is not None:
                return i, self._map_code(goal), why
        return None

    # --- what the mission says -------------------------------------------------------------

    def goal_id(self, mission):
        """The id of the goal that owns ``mission`` (text), '' for a goal sent on a topic."""
        binding = self.bindings.get(int(mission)) if str(mission).isdigit() else None
        return goal_id_text(binding.handle) if binding is not None else ''

    def status_released(self, level, message, values):
        """A mission status went out: a step (or a goal reached) is the goal's feedback. One
        of a mission no goal is bound to yet is kept, unless it tells a step, a detection, a
        goal reached or a result (each read once by a client)."""
        binding = self.bindings.get(int(values.get('mission', -1)))
        if binding is None and values.get('mission') and not (
                {'step', 'adapt', 'goal_reached', 'success'} & values.keys()):
            self._said_unbound[values['mission']] = (level, message, values)
            while len(self._said_unbound) > UNBOUND_KEPT:
                del self._said_unbound[next(iter(self._said_unbound))]
        if binding is None or not binding.handle.is_active:
            return
        pose = values.get('end_pose')
        index = int(values.get('goal_index', 1)) - 1
        if binding.action is ifc.FOLLOW_WAYPOINTS:
            feedback = ifc.FOLLOW_WAYPOINTS.type.Feedback(
                current_waypoint=self._rank(binding, max(0, index)))
            binding.handle.publish_feedback(feedback)
            return
        if pose is None:
            return
        pose = vector_from_text(pose)
        goal_index = min(max(0, index), len(binding.goals) - 1)
        goal = binding.goals[goal_index]
        # The rest of the way: to the goal walked to, then from each goal to the next.
        left = math.hypot(goal[0] - pose[0], goal[1] - pose[1]) + _legs(binding.goals,
                                                                          goal_index)
        if binding.start_distance is None:
            start = vector_from_text(values['pose']) if 'pose' in values else pose
            binding.start_distance = math.hypot(goal[0] - start[0], goal[1] - start[1]) \
                + _legs(binding.goals, goal_index)
        now = self._feedback_time()
        elapsed = now - binding.started
        progress = binding.start_distance - left
        extra = {}
        if binding.action is ifc.NAVIGATE_THROUGH_POSES:
            extra['number_of_poses_remaining'] = min(32767, len(binding.goals) - goal_index)
        feedback = binding.action.type.Feedback(
            current_pose=conv.pose_stamped(pose[:2], pose[2], stamp=now,
                                           frame_id=self.node.frame_id),
            navigation_time=_duration(elapsed),
            estimated_time_remaining=_duration(elapsed * left / progress
                                               if progress > 1e-3 else 0.0),
            # SELA's recoveries: adaptations (re)started, and falls it got up from.
            number_of_recoveries=min(32767, int(values.get('adaptations', 0))
                                     + int(values.get('failed_steps', 0))),
            distance_remaining=float(left), **extra)
        binding.handle.publish_feedback(feedback)

    def _feedback_time(self):
        """The node's clock (s), or the latest outcome's stamp where the clock has not caught
        up with it yet: the simulator's ``clock`` and its outcomes travel apart, and a gait's
        feedback must not say that no time has passed since its goal."""
        seconds = _seconds(self.node.get_clock().now())
        stamp = getattr(self.node.stepper, 'pose_stamp', None)
        if stamp is not None and seconds < stamp <= seconds + CLOCK_LAG:
            return stamp
        return seconds

    def _rank(self, binding, index):
        """The rank in the goal's ``poses`` of the mission's goal ``index`` (from 0)."""
        return (binding.first_index + index) % len(binding.poses)

    def mission_ended(self, ended):
        """The mission ``ended`` (a MissionEnded, released after its save): its goal ends."""
        binding = self.bindings.pop(ended.mission_id, None)
        if binding is None:
            # A topic's goal, or an action goal about to be bound: kept for a while.
            self._unbound[ended.mission_id] = ended
            while len(self._unbound) > UNBOUND_KEPT:
                del self._unbound[next(iter(self._unbound))]
        elif not binding.ended.done():
            binding.ended.set_result(ended)

    def _result(self, binding, ended):
        handle, action = binding.handle, binding.action
        code = ifc.END_ERROR_CODES.get(ended.code, ifc.UNKNOWN_ERROR)
        if handle.is_cancel_requested:
            # A cancel accepted is a goal CANCELED, whatever its mission's last step did
            # (a cancel that comes once the mission has ended is rejected: _cancel).
            missed = self._missed(binding.poses, binding.first_index, ended.goals_reached,
                                  binding.goals, ended_at=(ended.goals_reached, code))
            handle.canceled()
            return self._message(action, code, ended.reason, missed)
        missed = []
        if not ended.success:
            missed = self._missed(binding.poses, binding.first_index, ended.goals_reached,
                                  binding.goals, ended_at=(ended.goals_reached, code))
        return self._finish(handle, action, ended.success, code, ended.reason, missed)

    def _missed(self, poses, first, reached, goals, ended_at):
        """The waypoints of a FollowWaypoints goal not reached: the mission's goals from the
        ``reached``-th on. Each carries its own code: ``ended_at`` is ``(i, code)``, the
        goal the mission ended at and why; a goal after it that the map rules out, that
        reason's code; any other, :data:`~sela_ros.nodes.interface.NOT_ATTEMPTED`."""
        missed = []
        for i in range(reached, len(goals)):
            code = ended_at[1] if i == ended_at[0] else self._map_code(goals[i])
            missed.append(MissedWaypoint(index=(first + i) % len(poses),
                                         goal=poses[(first + i) % len(poses)],
                                         error_code=code))
        return missed

    def _map_code(self, goal):
        """The code of why the map rules ``goal`` out, or NOT_ATTEMPTED."""
        grid = self.node.map
        if grid is None or grid.goal_problem(goal) is None:
            return ifc.NOT_ATTEMPTED
        return ifc.GOAL_OUTSIDE_MAP if not grid.in_map(goal) else ifc.GOAL_OCCUPIED

    def _finish(self, handle, action, success, code, message, missed):
        if success:
            handle.succeed()
        else:
            handle.abort()
        return self._message(action, code, message, missed)

    def _message(self, action, code, message, missed):
        result = action.type.Result(error_code=int(code), error_msg=message)
        if action is ifc.FOLLOW_WAYPOINTS:
            # nav2's waypoint follower has its own codes; each missed waypoint carries why.
            result.missed_waypoints = missed
            if code:
                result.error_code = action.type.Result.UNKNOWN
        return result
