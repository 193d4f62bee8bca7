"""sim_bridge runs another robot from its description (over DDS): the A1's gaits, joints,
duty factors and damage names, and a map of another robot refused."""
import json

import numpy as np
import pytest
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters
from sensor_msgs.msg import JointState

from sela_ros.nodes import conversions as conv
from sela_ros.nodes import interface as ifc
from sim_bridge.robots import get_robot

from ros_graph import Client, NodeProcesses

pytestmark = [pytest.mark.dds, pytest.mark.slow]


def _set_damage(client, value):
    cli = client.node.create_client(SetParameters, '/sim_bridge/set_parameters')
    value_msg = ParameterValue(type=ParameterType.PARAMETER_STRING, string_value=value)
    request = SetParameters.Request(parameters=[Parameter(name='damage', value=value_msg)])
    return client.call(cli, request).results[0]


@pytest.fixture
def a1_bridge(tmp_path):
    # A map of the hexapod given to the A1's simulator: refused, the sim.* values kept.
    hexapod_map = tmp_path / 'hexapod_map.npz'
    np.savez(hexapod_map, metadata=np.array(json.dumps({'dt': 1 / 120, 'gait_duration': 3.0,
                                                        'solver_iterations': 30})))
    nodes = NodeProcesses({'sim_bridge': {'robot': 'a1', 'archive': str(hexapod_map),
                                          'damage': 'block:rear_left.thigh'}},
                          names=('sim_bridge',))
    client = Client()
    yield nodes, client
    client.close()
    nodes.stop()


def test_sim_bridge_walks_the_a1_and_speaks_its_names(a1_bridge):
    nodes, client = a1_bridge
    a1 = get_robot('a1')
    node = client.node
    outcomes, joints, descriptions = [], [], []
    ifc.subscription(node, ifc.OUTCOME, outcomes.append)
    node.create_subscription(JointState, 'hexapod/joint_states', joints.append, 10)
    ifc.subscription(node, ifc.ROBOT_DESCRIPTION, descriptions.append)
    behavior_pub = ifc.publisher(node, ifc.BEHAVIOR)
    client.wait_for_publishers(['/hexapod/behavior_outcome', '/hexapod/joint_states'])
    client.spin_until(lambda: joints and descriptions, 60, 'joint states and the URDF')
    assert list(joints[-1].name) == list(a1.joint_names)
    # The blocked thigh stays a reported joint, at its standing angle.
    assert joints[-1].position[a1.joint_names.index('RL_upper_joint')] == pytest.approx(0.8)
    assert 'a1_description' in descriptions[-1].data and 'RL_upper_joint" type="fixed' in \
        descriptions[-1].data

    client.spin_until(lambda: behavior_pub.get_subscription_count() > 0, 60,
                      'sim_bridge subscribed to behaviours')
    behavior_pub.publish(conv.behavior_to_msg(a1.example_gait(), 31))
    client.spin_until(lambda: any(conv.outcome_from_msg(m).behavior_id == 31
                                  for m in outcomes), 120, 'the outcome of the A1 gait')
    outcome = next(conv.outcome_from_msg(m) for m in outcomes
                   if conv.outcome_from_msg(m).behavior_id == 31)
    assert outcome.duty_factors.shape == (4,) and np.all(outcome.duty_factors > 0)
    assert outcome.generic_reward[0] > 0.1 and not outcome.fallen  # the trot walks forward

    # The hexapod's damages are not the A1's: refused, with the A1's names.
    refused = _set_damage(client, 'remove:middle_right')
    assert not refused.successful and 'valid kinds: intact, shorten, block, weaken' in \
        refused.reason
    refused = _set_damage(client, 'block:middle_right.knee')
    assert not refused.successful and 'front_left, front_right, rear_left, rear_right' in \
        refused.reason
    assert _set_damage(client, 'shorten:front_left:0.7').successful
    client.spin_until(lambda: 'damage: shorten:front_left:0.7 ' in descriptions[-1].data, 60,
                      'the shortened leg published')
    log = nodes.logs()['sim_bridge.log']
    assert 'is a map of the hexapod, not of the a1' in log and 'a1 ready' in log
    assert nodes.alive() == {'sim_bridge': True}
