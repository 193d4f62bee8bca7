"""``MissionClient``: send a goal to a sela_ros stack and follow its mission.

In the spirit of nav2_simple_commander's ``BasicNavigator``: :meth:`MissionClient.go_to_pose`,
:meth:`~MissionClient.follow_goals` (a mission of several goals, as ``followWaypoints``),
:meth:`~MissionClient.is_task_complete`, :meth:`~MissionClient.get_feedback`,
:meth:`~MissionClient.get_result`, and a ``namespace`` argument to drive a stack started
under a namespace. The demo, the tests and the benchmarks use it; it is the one reader of
the adapter's mission status (``diagnostics``, name ``sela_adapter: mission``).

It runs on a node its caller owns (and spins), so that the caller can record or watch other
topics on the same node: pass ``spin_once(timeout_sec)``.
"""
import time
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from sela_ros.nodes import conversions as conv
from sela_ros.nodes import interface as ifc

STATUSES_KEPT = 100_000  # the latest diagnostics statuses, for errors() and heartbeats


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
        self.goal = self.result = self._acked = self._mission = None
        self._goal_pub = node.create_publisher(ifc.GOAL.type, self.name(ifc.GOAL.name),
                                               ifc.GOAL.qos)
        self._goals_pub = node.create_publisher(ifc.GOAL_PATH.type,
                                                self.name(ifc.GOAL_PATH.name), ifc.GOAL_PATH.qos)
        node.create_subscription(ifc.DIAGNOSTICS.type, self.name(ifc.DIAGNOSTICS.name),
                                 self._diagnostics, ifc.DIAGNOSTICS.qos)

    def name(self, relative):
        """``relative`` (an interface name) in the stack's namespace."""
        if relative.startswith('/') or not self.namespace:
            return relative
        return f'{self.namespace}/{relative}'

    def _diagnostics(self, msg):
        for status in msg.status:
            self.statuses.append(status)
            if status.name != ifc.MISSION_STATUS:
                continue
            values = conv.status_values(status)
            if 'step' in values:
                self.steps.append(StepFeedback.from_values(values))
            elif 'adapt' in values:
                self.detections.append(Detection(int(values['behavior_id']),
                                                 float(values['error']), values['threshold'],
                                                 values['adapt']))
            elif 'goal_reached' in values and self._acked:
                self.goals_reached.append(GoalReached(
                    int(values['goal_index']) - 1, np.array(values['goal_reached'].split(),
                                                            float),
                    int(values['goal_reached_steps'])))
            elif ('goal' in values and 'success' not in values and self.goal is not None
                    and np.allclose(np.array(values['goal'].split(), float), self.goal)):
                self._acked = True
                self._mission = values.get('mission')
            # The result of this client's mission (said again while the adapter is idle), not
            # of an earlier one to the same goal.
            if ('success' in values and self._acked
                    and values.get('mission') == self._mission):
                self.result = MissionResult(values['success'] == 'True', int(values['steps']),
                                            int(values['adaptations']), status.message, values)

    def spin_until(self, predicate, timeout, what='condition'):
        deadline = time.monotonic() + timeout
        while not predicate():
            if time.monotonic() > deadline:
                raise TimeoutError(f'timed out after {timeout} s waiting for {what}')
            self.spin_once(0.05)

    def wait_until_ready(self, timeout=60.0, publisher=None, nodes=ifc.NODES):
        """Wait until the adapter hears goals (on ``publisher``'s topic; default goal_pose)
        and this client hears ``nodes`` (their statuses on ``diagnostics``: what one says
        before it is heard would be lost)."""
        publisher = publisher or self._goal_pub
        topic = self.node.resolve_topic_name(self.name(ifc.DIAGNOSTICS.name))

        def ready():
            talkers = {i.node_name for i in self.node.get_publishers_info_by_topic(topic)}
            return set(nodes) <= talkers and publisher.get_subscription_count() > 0
        self.spin_until(ready, timeout, f"{', '.join(nodes)} on {topic}")

    def wait_for_goal_listeners(self, count, timeout=60.0):
        """Wait until ``count`` nodes hear goals (e.g. the planner and the adapter)."""
        self.spin_until(lambda: self._goal_pub.get_subscription_count() >= count, timeout,
                        f'{count} subscriber(s) of {self.name(ifc.GOAL.name)}')

    def go_to_pose(self, x, y, frame_id='odom', timeout=60.0, resend_period=2.0):
        """Send the goal (x, y); returns once the adapter has taken it (resent until then:
        ``goal_pose`` is volatile, as RViz sends it)."""
        self._send(self._goal_pub, conv.pose_stamped((x, y), frame_id=frame_id), (x, y),
                   timeout, resend_period)

    def follow_goals(self, goals, frame_id='odom', timeout=60.0, resend_period=2.0):
        """Send a mission of several goals ``[(x, y), ...]``, visited in order, as a
        nav_msgs/Path on ``goal_path``; returns once the adapter has taken it. Each goal
        reached is appended to :attr:`goals_reached`; the result comes after the last."""
        path = conv.path_to_msg(np.asarray(goals, dtype=float), frame_id=frame_id)
        self._send(self._goals_pub, path, goals[0], timeout, resend_period)

    def _send(self, publisher, msg, first_goal, timeout, resend_period):
        self.wait_until_ready(timeout, publisher)
        self.goal = np.array(first_goal, dtype=float)
        self.result, self._acked, self._mission, self.goals_reached = None, False, None, []
        deadline = time.monotonic() + timeout
        while not self._acked:
            publisher.publish(msg)
            try:
                self.spin_until(lambda: self._acked, resend_period, 'the goal')
            except TimeoutError:
                if time.monotonic() > deadline:
                    raise TimeoutError(f'the adapter did not take the goal {tuple(first_goal)} '
                                       f'within {timeout} s') from None

    def publish_goal(self, x, y, frame_id='odom'):
        """Send a goal once, without waiting for it to be taken (e.g. a bad goal)."""
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
