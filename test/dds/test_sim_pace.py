"""sim_bridge holds its gaits to ``real_time_factor`` times the wall clock (over DDS)."""
import time

import pytest
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import DescribeParameters, SetParameters

from sela_ros.nodes import conversions as conv
from sela_ros.nodes import interface as ifc
from sim_bridge.robots import get_robot

from ros_graph import Client, NodeProcesses

pytestmark = [pytest.mark.dds, pytest.mark.slow]

FACTOR = 4.0


def _set_factor(client, value):
    cli = client.node.create_client(SetParameters, '/sim_bridge/set_parameters')
    value_msg = ParameterValue(type=ParameterType.PARAMETER_STRING, string_value=value) \
        if isinstance(value, str) else \
        ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=value)
    request = SetParameters.Request(parameters=[Parameter(name='real_time_factor',
                                                          value=value_msg)])
    return client.call(cli, request).results[0]


def test_a_paced_gait_lasts_its_sim_time_over_the_factor():
    nodes = NodeProcesses({'sim_bridge': {'real_time_factor': FACTOR}}, names=('sim_bridge',))
    client = Client()
    try:
        node = client.node
        outcomes = []
        ifc.subscription(node, ifc.OUTCOME,
                         lambda m: outcomes.append((time.monotonic(), conv.outcome_from_msg(m))))
        behavior_pub = ifc.publisher(node, ifc.BEHAVIOR)
        client.wait_for_publishers(['/hexapod/behavior_outcome'])
        client.spin_until(lambda: behavior_pub.get_subscription_count() > 0, 60,
                          'sim_bridge subscribed to behaviours')
        gait = get_robot('hexapod').example_gait()

        def run(behavior_id):
            sent = time.monotonic()
            behavior_pub.publish(conv.behavior_to_msg(gait, behavior_id))
            client.spin_until(lambda: any(o.behavior_id == behavior_id for _, o in outcomes),
                              120, f'the outcome of gait {behavior_id}')
            received, outcome = next((t, o) for t, o in outcomes
                                     if o.behavior_id == behavior_id)
            return received - sent, outcome

        wall, outcome = run(1)
        # The outcome goes out once the gait has run: never before its sim time over the
        # factor has passed on the wall clock (a lower bound, whatever the machine's load).
        assert outcome.sim_time > 0
        gait_duration = 3.0
        assert wall >= gait_duration / FACTOR

        refused = _set_factor(client, 0.05)
        assert not refused.successful and 'must be 0 (no pacing) or at least 0.1' in \
            refused.reason
        # A value of the wrong type is refused, and the parameter keeps its type: `ros2 param
        # describe` says double still.
        refused = _set_factor(client, 'fast')
        assert not refused.successful and "got 'fast'" in refused.reason
        describe = client.node.create_client(DescribeParameters,
                                             '/sim_bridge/describe_parameters')
        (descriptor,) = client.call(describe, DescribeParameters.Request(
            names=['real_time_factor'])).descriptors
        assert descriptor.type == ParameterType.PARAMETER_DOUBLE
        assert _set_factor(client, 0.0).successful
        _, unpaced = run(2)  # no pacing: the same gait, the same physics
        assert unpaced.duty_factors.shape == outcome.duty_factors.shape
        assert nodes.alive() == {'sim_bridge': True}, nodes.logs()
    finally:
        client.close()
        nodes.stop()
