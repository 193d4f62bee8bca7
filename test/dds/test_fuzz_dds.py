"""Property-based fuzzing over DDS: every subscribed topic, service and parameter of every node
gets seeded random and boundary values (huge finite numbers, NaN and infinity, long strings,
wrong types, wrong lengths); afterwards every node is alive, nothing learned is lost and a
mission completes.

Seeded (``@seed``) with a bounded example count, so a run is repeatable and takes about a
minute. ``sela_adapter/clear`` is the one input left out: forgetting is what it is for.
"""
import json
import math

import pytest
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped
from hypothesis import HealthCheck, given, seed, settings
from hypothesis import strategies as st
from nav_msgs.msg import Odometry
from nav_msgs.srv import GetPlan
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64MultiArray, MultiArrayDimension
from std_srvs.srv import Trigger

from sela_ros.nodes import conversions as conv
from sela_ros.nodes import interface as ifc
from sela_ros.tools.mission_client import MissionClient

from ros_graph import CONFIG, Client, NodeProcesses

pytestmark = [pytest.mark.dds, pytest.mark.slow]

HUGE = [1e308, -1e308, 1.7976931348623157e308, 5e-324, -0.0, 1e9, -1e9, 2.0**53]
FLOATS = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.sampled_from(
    HUGE + [math.nan, math.inf, -math.inf]), st.floats(-3.0, 3.0), st.floats(0.0, 1.0))
TEXT = st.one_of(st.text(max_size=40), st.sampled_from(
    ['', 'odom', 'map', 'base_link', '\x00', 'x' * 20000, 'behavior_id=7', 'behavior_id=-1',
     'behavior_id=1e400', 'behavior_id=99999999999999999999', conv.OUTCOME_LABEL,
     'sela_adapter: heartbeat', 'planner: heartbeat', 'sim_bridge: heartbeat']))
INT32 = st.integers(-2**31, 2**31 - 1)
UINT32 = st.integers(0, 2**32 - 1)


def _stamp(draw):
    return Time(sec=draw(INT32), nanosec=draw(UINT32))


@st.composite
def float_arrays(draw):
    size = draw(st.one_of(st.sampled_from([0, 1, 2, 5, 18, 35, 36, 37]),
                          st.integers(0, 200)))
    msg = Float64MultiArray(data=draw(st.lists(FLOATS, min_size=size, max_size=size)))
    if draw(st.booleans()):
        msg.layout.dim = [MultiArrayDimension(label=draw(TEXT), size=draw(UINT32),
                                              stride=draw(UINT32))
                          for _ in range(draw(st.integers(1, 3)))]
    return msg


@st.composite
def poses(draw):
    msg = PoseStamped()
    msg.header.stamp = _stamp(draw)
    msg.header.frame_id = draw(TEXT)
    p, q = msg.pose.position, msg.pose.orientation
    p.x, p.y, p.z, q.x, q.y, q.z, q.w = (draw(FLOATS) for _ in range(7))
    return msg


@st.composite
def odometry(draw):
    msg = Odometry()
    msg.header.stamp = _stamp(draw)
    msg.header.frame_id = draw(TEXT)
    msg.child_frame_id = draw(TEXT)
    msg.pose.pose = draw(poses()).pose
    msg.pose.covariance = [draw(FLOATS) for _ in range(36)]
    msg.twist.twist.linear.x = draw(FLOATS)
    return msg


@st.composite
def diagnostics(draw):
    names = st.one_of(TEXT, st.sampled_from([f'{n}{ifc.HEARTBEAT_SUFFIX}' for n in ifc.NODES]
                                            + [ifc.MISSION_STATUS, ifc.DETECTOR_STATUS]))
    msg = DiagnosticArray()
    msg.header.stamp = _stamp(draw)
    msg.status = [DiagnosticStatus(level=draw(st.sampled_from([b'\x00', b'\x02', b'\xff'])),
                                   name=draw(names), message=draw(TEXT),
                                   hardware_id=draw(TEXT),
                                   values=[KeyValue(key=draw(TEXT), value=draw(TEXT))
                                           for _ in range(draw(st.integers(0, 3)))])
                  for _ in range(draw(st.integers(0, 4)))]
    return msg


@st.composite
def clocks(draw):
    return Clock(clock=_stamp(draw))


# Every topic a node subscribes to, with what is sent on it.
TOPICS = {t.name: (t, strategy) for t, strategy in (
    (ifc.BEHAVIOR, float_arrays()), (ifc.OUTCOME, float_arrays()),
    (ifc.PREDICTION, float_arrays()), (ifc.VERDICT, float_arrays()), (ifc.GOAL, poses()),
    (ifc.ODOM, odometry()), (ifc.DIAGNOSTICS, diagnostics()), (ifc.CLOCK, clocks()))}
SERVICES = {s.name: s for s in (ifc.MAKE_PLAN, ifc.ADAPT, ifc.RESET)}


def _parameter_value(draw):
    kind = draw(st.sampled_from(['double', 'integer', 'string', 'bool', 'double_array',
                                 'string_array', 'none']))
    v = ParameterValue()
    if kind == 'double':
        v.type, v.double_value = ParameterType.PARAMETER_DOUBLE, draw(FLOATS)
    elif kind == 'integer':
        v.type, v.integer_value = ParameterType.PARAMETER_INTEGER, draw(
            st.integers(-2**63, 2**63 - 1))
    elif kind == 'string':
        v.type, v.string_value = ParameterType.PARAMETER_STRING, draw(TEXT)
    elif kind == 'bool':
        v.type, v.bool_value = ParameterType.PARAMETER_BOOL, draw(st.booleans())
    elif kind == 'double_array':
        v.type = ParameterType.PARAMETER_DOUBLE_ARRAY
        v.double_array_value = draw(st.lists(FLOATS, max_size=9))
    elif kind == 'string_array':
        v.type = ParameterType.PARAMETER_STRING_ARRAY
        v.string_array_value = draw(st.lists(TEXT, max_size=4))
    return v


def _declared(config):
    """Every running node's parameter names, from the config file (they are all there; the
    gait_executor, which replaces sim_bridge on a robot, is not started here)."""
    return {_node(key): sorted(section['ros__parameters']) for key, section in config.items()
            if _node(key) in ifc.NODES}


def _node(key):
    """The node name of a parameters-file key (``/**/planner`` matches it in any namespace)."""
    return key.rsplit('/', 1)[-1]


@st.composite
def actions(draw, parameters):
    kind = draw(st.sampled_from(['topic'] * 4 + ['service', 'parameter']))
    if kind == 'topic':
        name = draw(st.sampled_from(sorted(TOPICS)))
        return ('topic', name, draw(TOPICS[name][1]))
    if kind == 'service':
        service = draw(st.sampled_from(sorted(SERVICES)))
        if service == ifc.MAKE_PLAN.name:
            request = GetPlan.Request(start=draw(poses()), goal=draw(poses()),
                                      tolerance=draw(st.floats(width=32)))
        else:
            request = Trigger.Request()
        return ('service', service, request)
    node = draw(st.sampled_from(sorted(parameters)))
    name = draw(st.one_of(st.sampled_from(parameters[node]), TEXT))
    return ('parameter', node, Parameter(name=name, value=_parameter_value(draw)))


class Fuzzer:
    def __init__(self, client, parameters):
        self.client = client
        node = client.node
        self.pubs = {name: node.create_publisher(t.type, t.root_name, t.qos)
                     for name, (t, _) in TOPICS.items()}
        self.services = {name: ifc.client(node, s) for name, s in SERVICES.items()}
        self.param_clients = {n: node.create_client(SetParameters, f'/{n}/set_parameters')
                              for n in parameters}
        self.counts = {'topic': 0, 'service': 0, 'parameter': 0}

    def act(self, action):
        kind, target, payload = action
        self.counts[kind] += 1
        if kind == 'topic':
            self.pubs[target].publish(payload)
        elif kind == 'service':
            self.client.call(self.services[target], payload, timeout=30)
        else:
            self.client.call(self.param_clients[target],
                             SetParameters.Request(parameters=[payload]), timeout=30)
        self.client.executor.spin_once(timeout_sec=0.01)


def _set_back(client, config):
    """Every parameter back to its configured value (a fuzzed valid value may stay)."""
    from rclpy.parameter import Parameter as RclpyParameter

    for key, section in config.items():
        node = _node(key)
        if node not in ifc.NODES:
            continue
        values = [RclpyParameter(k, value=v).to_parameter_msg()
                  for k, v in section['ros__parameters'].items() if k != 'use_sim_time']
        cli = client.node.create_client(SetParameters, f'/{node}/set_parameters')
        client.call(cli, SetParameters.Request(parameters=values), timeout=30)


def _observations(path):
    return json.loads(path.read_text())['sela']['indices']


def test_random_and_boundary_inputs_to_every_node_leave_them_alive_and_learning_intact(
        tmp_path):
    import yaml

    config = yaml.safe_load(CONFIG.read_text())
    parameters = _declared(config)
    nodes = NodeProcesses({'sela_adapter': {'adapt_on_start': True}})
    client = Client('sela_fuzzer')
    try:
        mission = MissionClient(client.node, lambda t: client.executor.spin_once(timeout_sec=t))
        # Something learned first: a short mission, adapting from the first step.
        mission.go_to_pose(0.6, 0.0)
        client.spin_until(mission.get_result, 300, 'the first mission')
        learned = _observations(nodes.state_file)
        assert learned
        fuzzer = Fuzzer(client, parameters)

        @seed(20261130)
        @settings(max_examples=40, deadline=None, database=None,
                  suppress_health_check=list(HealthCheck))
        @given(st.lists(actions(parameters), min_size=1, max_size=6))
        def fuzz(batch):
            for action in batch:
                fuzzer.act(action)

        fuzz()
        print(f'fuzzed: {fuzzer.counts}')
        assert all(fuzzer.counts.values()) and sum(fuzzer.counts.values()) >= 40, \
            fuzzer.counts
        _set_back(client, config)
        # Every node alive and serving: each beats again after the last input.
        start = len(mission.statuses)
        client.spin_until(lambda: {s.name.removesuffix(ifc.HEARTBEAT_SUFFIX)
                                   for s in list(mission.statuses)[start:]} >= set(nodes.procs),
                          60, 'a heartbeat from every node')
        assert all(nodes.alive().values()), nodes.logs()
        # A mission completes, and nothing learned before the fuzzing was lost.
        mission.go_to_pose(0.0, 0.6)
        client.spin_until(mission.get_result, 300, 'the mission after the fuzzing')
        assert mission.get_result().success, (mission.get_result(), nodes.logs())
        after = _observations(nodes.state_file)
        assert after[:len(learned)] == learned, (learned, after)
        assert all(nodes.alive().values()), nodes.logs()
    finally:
        client.close()
        nodes.stop()
