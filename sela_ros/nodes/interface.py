"""The sela_ros graph, written once: every topic and service name, its type and its QoS.

Names are relative, so that ``__ns:=/robot1`` (or a launch namespace) moves a whole stack:
a node's own topics and services are ``~/name`` for it and ``<node>/name`` for everyone
else (``planner/make_plan``). In the root namespace every name is the one of the DESIGN.md
table (``/goal_pose``, ``/sela_adapter/adapt``...). Nodes, the demo, the tests and the
benchmarks create their endpoints through :func:`publisher`, :func:`subscription`,
:func:`server` and :func:`client`, never from string literals.

QoS, by what a lost message would cost:

* ``STATE_QOS``: streams where the latest sample is what matters (odometry, diagnostics).
* ``LATCHED_QOS``: the last sample must reach a late joiner (map, path, target).
* ``COMMAND_QOS``: gait commands and rewards, reliable, deep enough that none is dropped.
* ``DECISION_QOS``: what a decision depends on (outcomes, predictions, verdicts): reliable
  and transient_local with a deep history, so a subscriber that joins (or rejoins) late
  still gets them; the receivers pair them by command id, in whatever order they arrive.
* ``GOAL_QOS``: what RViz's 2D Goal Pose tool and ``ros2 topic pub`` send (reliable,
  volatile, as nav2 subscribes): a latched publisher is compatible with it, but an old
  goal is never replayed to a node that (re)starts.
"""
from dataclasses import dataclass

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PointStamped, PoseStamped
from nav_msgs.msg import OccupancyGrid, Odometry, Path
from nav_msgs.srv import GetPlan
from rclpy.qos import QoSDurabilityPolicy, QoSHistoryPolicy, QoSProfile, QoSReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, Float64MultiArray
from std_srvs.srv import Trigger

STATE_QOS = QoSProfile(depth=10, history=QoSHistoryPolicy.KEEP_LAST,
                       reliability=QoSReliabilityPolicy.RELIABLE)
LATCHED_QOS = QoSProfile(depth=1, history=QoSHistoryPolicy.KEEP_LAST,
                         reliability=QoSReliabilityPolicy.RELIABLE,
                         durability=QoSDurabilityPolicy.TRANSIENT_LOCAL)
COMMAND_QOS = QoSProfile(depth=50, history=QoSHistoryPolicy.KEEP_LAST,
                         reliability=QoSReliabilityPolicy.RELIABLE)
DECISION_QOS = QoSProfile(depth=50, history=QoSHistoryPolicy.KEEP_LAST,
                          reliability=QoSReliabilityPolicy.RELIABLE,
                          durability=QoSDurabilityPolicy.TRANSIENT_LOCAL)
GOAL_QOS = QoSProfile(depth=10, history=QoSHistoryPolicy.KEEP_LAST,
                      reliability=QoSReliabilityPolicy.RELIABLE,
                      durability=QoSDurabilityPolicy.VOLATILE)
#: Kept for readers of the outcome stream (an alias: outcomes are decision inputs).
OUTCOME_QOS = DECISION_QOS

# Node names (public: ``ros2 run sela_ros <executable>`` starts a node of that name).
SIM_BRIDGE = 'sim_bridge'
PLANNER = 'planner'
DAMAGE_DETECTOR = 'damage_detector'
SELA_ADAPTER = 'sela_adapter'
NODES = (SIM_BRIDGE, PLANNER, DAMAGE_DETECTOR, SELA_ADAPTER)

# Names of the statuses on ``diagnostics`` (monitoring only: no node decides on them).
MISSION_STATUS = 'sela_adapter: mission'
DETECTOR_STATUS = 'damage_detector: prediction error'
HEARTBEAT_SUFFIX = ': heartbeat'
ERROR_LEVEL = DiagnosticStatus.ERROR


@dataclass(frozen=True)
class Topic:
    """A topic: ``name`` as any node but its owner writes it, its type and its QoS."""

    name: str
    type: type
    qos: QoSProfile
    owner: str = ''  # the node that publishes it under its own name (``~/...``), if any

    @property
    def own_name(self):
        """The name the owner uses (``~/path``), or ``name`` for a shared topic."""
        return '~/' + self.name.split('/', 1)[1] if self.owner else self.name

    @property
    def root_name(self):
        """The name in the root namespace, as DESIGN.md lists it."""
        return self.name if self.name.startswith('/') else '/' + self.name


@dataclass(frozen=True)
class Service:
    """A service of ``owner``: served as ``~/<leaf>``, called as ``<owner>/<leaf>``."""

    name: str
    type: type
    owner: str

    @property
    def own_name(self):
        return '~/' + self.name.split('/', 1)[1]

    @property
    def root_name(self):
        return '/' + self.name


CLOCK = Topic('/clock', Clock, STATE_QOS)  # absolute: use_sim_time listens to /clock
ODOM = Topic('hexapod/odom', Odometry, STATE_QOS)
JOINT_STATES = Topic('hexapod/joint_states', JointState, STATE_QOS)
BEHAVIOR = Topic('hexapod/behavior', Float64MultiArray, COMMAND_QOS)
OUTCOME = Topic('hexapod/behavior_outcome', Float64MultiArray, DECISION_QOS)
GOAL = Topic('goal_pose', PoseStamped, GOAL_QOS)
# A mission of several goals, in order (as waypoint followers take them); QoS as goal_pose.
GOAL_PATH = Topic('goal_path', Path, GOAL_QOS)
PATH = Topic('planner/path', Path, LATCHED_QOS, owner=PLANNER)
MAP = Topic('planner/map', OccupancyGrid, LATCHED_QOS, owner=PLANNER)
# A map for the planner, as map_server publishes it (reliable, transient local).
MAP_IN = Topic('map', OccupancyGrid, LATCHED_QOS)
TARGET = Topic('sela/target', PointStamped, LATCHED_QOS)  # for observers: the plan has it
PREDICTION = Topic('sela/prediction', Float64MultiArray, DECISION_QOS)
REWARD = Topic('sela/reward', Float64, COMMAND_QOS)
VERDICT = Topic('damage_detector/verdict', Float64MultiArray, DECISION_QOS,
                owner=DAMAGE_DETECTOR)
DIAGNOSTICS = Topic('diagnostics', DiagnosticArray, STATE_QOS)

MAKE_PLAN = Service('planner/make_plan', GetPlan, PLANNER)
ADAPT = Service('sela_adapter/adapt', Trigger, SELA_ADAPTER)
CLEAR = Service('sela_adapter/clear', Trigger, SELA_ADAPTER)
RESET = Service('sim_bridge/reset', Trigger, SIM_BRIDGE)

TOPICS = (CLOCK, ODOM, JOINT_STATES, BEHAVIOR, OUTCOME, GOAL, GOAL_PATH, PATH, MAP, MAP_IN,
          TARGET, PREDICTION, REWARD, VERDICT, DIAGNOSTICS)
SERVICES = (MAKE_PLAN, ADAPT, CLEAR, RESET)


def publisher(node, topic):
    """A publisher of ``topic`` (under the owner's own name when ``node`` owns it)."""
    return node.create_publisher(topic.type, _as_seen_by(node, topic), topic.qos)


def subscription(node, topic, callback, qos=None):
    """A subscription to ``topic`` with its QoS (or ``qos``, e.g. to record it latched)."""
    return node.create_subscription(topic.type, _as_seen_by(node, topic), callback,
                                    qos or topic.qos)


def server(node, service, callback):
    """Serve ``service`` as ``~/<leaf>`` (``node`` must be its owner)."""
    return node.create_service(service.type, service.own_name, callback)


def client(node, service):
    """A client of another node's ``service`` (``planner/make_plan``)."""
    return node.create_client(service.type, service.name)


def _as_seen_by(node, topic):
    return topic.own_name if topic.owner and node.get_name() == topic.owner else topic.name
