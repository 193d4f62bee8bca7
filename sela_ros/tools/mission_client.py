"""``MissionClient``: send a goal to a sela_ros stack and follow its mission.

A thin client of the adapter's nav2 actions, in the spirit of nav2_simple_commander's
``BasicNavigator``: :meth:`MissionClient.go_to_pose` sends a ``navigate_to_pose`` goal,
:meth:`~MissionClient.follow_goals` a ``follow_waypoints`` goal (several goals in order),
:meth:`~MissionClient.cancel_task` cancels it; :meth:`~MissionClient.is_task_complete`,
:meth:`~MissionClient.get_feedback`, :meth:`~MissionClient.get_result`, and a ``namespace``
argument to drive a stack started under a namespace. The goal's handle pairs the mission with
this client: the adapter's statuses on ``diagnostics`` (name ``sela_adapter: mission``) name
the goal that owns their mission (``goal_id``), and the client reads SELA's own detail from
them (every step's gait, prediction and reward, detections, goals reached), and the result,
which the adapter says again while idle, so that it is heard even when the adapter restarted
mid-mission and the action's own result is lost with it. The demo, the tests and the
benchmarks use it.

It runs on a node its caller owns (and spins), so that the caller can record or watch other
topics on the same node: pass ``spin_once(timeout_sec)``.
"""
import time
from collections import deque
from dataclasses import dataclass, field

import numpy as np
from action_msgs.msg import GoalStatus

from sela_ros.nodes import conversions as conv
from sela_ros.nodes import interface as ifc

STATUSES_KEPT = 100_000  # the latest diagnostics statuses, for errors() and heartbeats
#: Seconds a goal waits for the adapter's answer before it is sent again (the adapter
#: answers at once; only a request lost in discovery goes unanswered).
ANSWER_WAIT = 10.0


def send_goal_answered(client, name, goal, spin_until, timeout, feedback_callback=None):
    """Send ``goal`` with ``client``, the client of the action ``name``, and return its
    answer (the goal handle), spinning with ``spin_until(predicate, seconds, what)``.

    The goal is asked again when it is not answered within :data:`ANSWER_WAIT`: a server
    that is ready to this client may not hear it yet (a relaunched adapter, or one whose last
    run DDS has not forgotten), or the writer of its answers may not have matched this client
    yet, and the request or the answer is then lost. An answer lost on its way back is asked
    again too: the second goal preempts the first."""
    deadline = time.monotonic() + timeout
    extra = {} if feedback_callback is None else {'feedback_callback': feedback_callback}
    while True:
        sent = client.send_goal_async(goal, **extra)
        wait = min(ANSWER_WAIT, max(0.0, deadline - time.monotonic()))
        try:
            spin_until(sent.done, wait, f'the answer to the {name} goal')
            return sent.result()
        except TimeoutError:
            if time.monotonic() >= deadline:
                raise TimeoutError(f'timed out after {timeout} s waiting for the answer to '
                                   f'the {name} goal') from None
            sent.cancel()


@dataclass
class StepFeedback:
    """One step of the mission, as the adapter reported it."""

    step: int
    behavior_id: int
    behavior_index: int
    pose: np.ndarray  # where the step started (x, y, yaw)
    waypoint: np.ndarray
    predicted_gr: np.ndarray
    observed_gr: np.ndarray
    reward: float
    end_pose: np.ndarray
    adapting: bool
    adaptations: int
    fallen: bool
    failed_steps: int
    decide_ms: float
    execute_ms: float
    values: dict = field(repr=False)  # the status as sent (text)

    @classmethod
    def from_values(cls, v):
        vector = lambda key: np.array(v[key].split(), dtype=float)  # noqa: E731
        return cls(step=int(v['step']), behavior_id=int(v['behavior_id']),
                   behavior_index=int(v['behavior_index']), pose=vector('pose'),
                   waypoint=vector('waypoint'), predicted_gr=vector('predicted_gr'),
                   observed_gr=vector('observed_gr'), reward=float(v['reward']),
                   end_pose=vector('end_pose'), adapting=v['adapting'] == 'True',
                   adaptations=int(v['adaptations']), fallen=v['fallen'] == 'True',
                   failed_steps=int(v['failed_steps']), decide_ms=float(v['decide_ms']),
                   execute_ms=float(v['execute_ms']), values=dict(v))


@dataclass
class Detection:
    """The damage detector fired and the adapter (re)started adaptation."""

    behavior_id: int
    error: float
    threshold: str
    adapt: str  # the adapter's words


@dataclass
class GoalReached:
    """A goal of a mission of several was reached; the mission goes on to the next."""

    index: int  # its rank in the mission, from 1
    goal: np.ndarray
    steps: int  # steps it took from the previous goal


@dataclass
class MissionResult:
    success: bool
    steps: int
    adaptations: int
    message: str
    values: dict = field(repr=False)


class MissionClient:
    """Args:
        node: an rclpy node (the caller spins it through ``spin_once``).
        spin_once: ``spin_once(timeout_sec)`` of the node's executor.
        namespace: the stack's namespace ('' : the node's own).
    """

    def __init__(self, node, spin_once, namespace=''):
        self.node = node
        self.spin_once = spin_once
        self.namespace = namespace.rstrip('/')
        self.statuses = deque(maxlen=STATUSES_KEPT)  # heard on diagnostics (any node)
        self.steps, self.detections, self.goals_reached = [], [], []
        self._goals = []  # the goals of the mission of several sent (follow_goals)
        self.result = self.action_result = self._mission = None
        self.goal_handle = None  # of the goal sent last
        self._goal_id = None  # its id as statuses say it
        self._actions = {}  # created at the first goal (a stand-in node has none)
        self._goal_pub = node.create_publisher(ifc.GOAL.type, self.name(ifc.GOAL.name),
                                               ifc.GOAL.qos)
        node.create_subscription(ifc.DIAGNOSTICS.type, self.name(ifc.DIAGNOSTICS.name),
                                 self._diagnostics, ifc.DIAGNOSTICS.qos)

    def name(self, relative):
        """``relative`` (an interface name) in the stack's namespace."""
        if relative.startswith('/') or not self.namespace:
            return relative
        return f'{self.namespace}/{relative}'

    def _action(self, action):
        if action.name not in self._actions:
            self._actions[action.name] = ifc.action_client(self.node, action, self.namespace)
        return self._actions[action.name]

    def _diagnostics(self, msg):
        for status in msg.status:
            self.statuses.append(status)
            if status.name == ifc.MISSION_STATUS:
                self._read(status)

    def _read(self, status, again=False):
        """Take what a mission status says (``again``: one heard before, for this client's
        mission only: its steps and detections are already in)."""
        values = conv.status_values(status)
        if (self._mission is None and self._goal_id is not None
                and values.get('goal_id') == self._goal_id):
            self._mission = values.get('mission')  # this client's mission
        mine = self._mission is not None and values.get('mission') == self._mission
        if again and not mine:
            return
        if 'step' in values and not again:
            self.steps.append(StepFeedback.from_values(values))
        elif 'adapt' in values and not again:
            self.detections.append(Detection(int(values['behavior_id']),
                                             float(values['error']), values['threshold'],
                                             values['adapt']))
        elif 'goal_reached' in values and mine:
            self.goals_reached.append(GoalReached(
                int(values['goal_index']) - 1, np.array(values['goal_reached'].split(),
                                                        float),
                int(values['goal_reached_steps'])))
        # The result of this client's mission (said again while the adapter is idle), not
        # of an earlier one.
        if 'success' in values and mine:
            self.result = MissionResult(values['success'] == 'True', int(values['steps']),
                                        int(values['adaptations']), status.message, values)
            if self.result.success and len(self.goals_reached) == len(self._goals) - 1 > 0:
                # The last goal of several is reached with the mission: its result says so.
                self.goals_reached.append(GoalReached(
                    len(self._goals), np.array(self._goals[-1], float), self.result.steps))

    def spin_until(self, predicate, timeout, what='condition'):
        deadline = time.monotonic() + timeout
        while not predicate():
            if time.monotonic() > deadline:
                raise TimeoutError(f'timed out after {timeout} s waiting for {what}')
            self.spin_once(0.05)

    def wait_until_ready(self, timeout=60.0, nodes=ifc.NODES):
        """Wait until the adapter's actions are served, ``goal_pose`` is heard (for
        :meth:`publish_goal`) and this client hears ``nodes`` (their statuses on
        ``diagnostics``: what one says before it is heard would be lost)."""
        topic = self.node.resolve_topic_name(self.name(ifc.DIAGNOSTICS.name))
        clients = [self._action(a) for a in ifc.ACTIONS]

        def ready():
            talkers = {i.node_name for i in self.node.get_publishers_info_by_topic(topic)}
            return (set(nodes) <= talkers and all(c.server_is_ready() for c in clients)
                    and self._goal_pub.get_subscription_count() > 0)
        self.spin_until(ready, timeout, f"{', '.join(nodes)} on {topic} and the actions")

    def wait_for_goal_listeners(self, count, timeout=60.0):
        """Wait until ``count`` nodes hear goals on ``goal_pose`` (the planner, the adapter)."""
        self.spin_until(lambda: self._goal_pub.get_subscription_count() >= count, timeout,
                        f'{count} subscriber(s) of {self.name(ifc.GOAL.name)}')

    def go_to_pose(self, x, y, frame_id='odom', timeout=60.0):
        """Send the goal (x, y) (``navigate_to_pose``); returns once the adapter has taken it
        (or ended it at once: :attr:`result` then says why)."""
        goal = ifc.NAVIGATE_TO_POSE.type.Goal(pose=conv.pose_stamped((x, y), frame_id=frame_id))
        self._goals = []
        self._send(ifc.NAVIGATE_TO_POSE, goal, timeout)

    def follow_goals(self, goals, frame_id='odom', timeout=60.0):
        """Send a mission of several goals ``[(x, y), ...]``, visited in order
        (``follow_waypoints``); returns once the adapter has taken it. Each goal reached is
        appended to :attr:`goals_reached` (the last one with the result, which says it)."""
        poses = [conv.pose_stamped(g, frame_id=frame_id) for g in np.asarray(goals, float)]
        self._goals = [tuple(map(float, g)) for g in np.asarray(goals, float)]
        self._send(ifc.FOLLOW_WAYPOINTS, ifc.FOLLOW_WAYPOINTS.type.Goal(poses=poses), timeout)

    def _send_goal(self, action, goal, timeout):
        return send_goal_answered(self._action(action), action.name, goal, self.spin_until,
                                  timeout)

    def _send(self, action, goal, timeout):
        self.wait_until_ready(timeout)
        self.result = self.action_result = self._mission = self._goal_id = None
        self.goal_handle = None  # an earlier goal's result, late, is nobody's now
        self.goals_reached = []
        handle = self._send_goal(action, goal, timeout)
        if not handle.accepted:
            raise RuntimeError(f'the adapter rejected the {action.name} goal (no archive '
                               'loaded?)')
        self.goal_handle, self._goal_id = handle, bytes(handle.goal_id.uuid).hex()
        handle.get_result_async().add_done_callback(
            lambda future, handle=handle: self._action_done(handle, future))
        # Its first statuses may have been heard before the goal's answer: read them again.
        for status in [s for s in self.statuses if s.name == ifc.MISSION_STATUS]:
            self._read(status, again=True)
        self.spin_until(lambda: self._mission is not None or self.action_result is not None,
                        timeout, f'the adapter to take the {action.name} goal')
        if self._mission is None:  # ended before its statuses came: refused, or done at once
            r = self.action_result.result
            done = self.action_result.status == GoalStatus.STATUS_SUCCEEDED
            self.result = MissionResult(done, 0, 0, r.error_msg, {'error_code': r.error_code})

    def _action_done(self, handle, future):
        # Only the goal sent last: an earlier goal's result can come after its mission's
        # statuses, once the next goal is on its way, and is not that goal's.
        if handle is self.goal_handle:
            self.action_result = future.result()

    def cancel_task(self, timeout=30.0):
        """Cancel the goal sent last: the mission ends after the running gait."""
        if self.goal_handle is None:
            return False
        future = self.goal_handle.cancel_goal_async()
        self.spin_until(future.done, timeout, 'the answer to the cancel')
        return bool(future.result().goals_canceling)

    def publish_goal(self, x, y, frame_id='odom'):
        """Send a goal once on ``goal_pose``, as RViz does, without waiting for it to be
        taken (e.g. a bad goal)."""
        self._goal_pub.publish(conv.pose_stamped((x, y), frame_id=frame_id))

    def is_task_complete(self):
        self.spin_once(0.05)
        return self.result is not None

    def get_feedback(self):
        """The latest step (None before the first)."""
        return self.steps[-1] if self.steps else None

    def get_result(self):
        """The mission's end (None while it runs)."""
        return self.result

    def errors(self, name_part):
        """Messages of the ERROR statuses of nodes whose status name contains ``name_part``."""
        return [s.message for s in self.statuses
                if name_part in s.name and s.level == ifc.ERROR_LEVEL]
