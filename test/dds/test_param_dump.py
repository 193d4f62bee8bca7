"""``ros2 param dump`` works on every node: the YAML a dump writes loads back with
``--params-file`` to the same values (that no name nests inside another:
nodes/test_param_names.py).

The dump is built the way ros2param builds it: ``list_parameters`` then ``get_parameters``
over the node's parameter services, each dotted name split into nested mappings under
``<node>: ros__parameters:``.
"""
import pytest
import yaml
from rcl_interfaces.srv import GetParameters, ListParameters
from rclpy.parameter import parameter_value_to_python

from sela_ros.tools.parameter_docs import node_parameters
from sim_bridge.trajectory import joint_names

from ros_graph import Client, NodeProcesses

SPECS = node_parameters()  # every node's specs, as docs/parameters.md lists them


# Start-up values other than config/sela.yaml's, so that a dump that did not load back shows.
# Some of the adapter's are given under their earlier names: read as the new ones. A 0 given
# for a parameter that spells it with a word is read as the word; a number given for one whose
# default is a word is a number.
CHANGED = {
    'sim_bridge': {'seed': 7, 'observation.noise_std': 0.02, 'right_on_fall': True,
                   'publish_max_rate': 0},
    'planner': {'planner.inflation': 0.2},  # map.obstacles left not set: dumped as null
    'damage_detector': {'detection.threshold': 0.2, 'heartbeat.nodes': '[planner]'},
    'sela_adapter': {'priors': 'none', 'priors.max.misfit': 0.5, 'goal.eps': 0.15,
                     'gp.kernel.sigma': 0.25, 'planner.horizon': 0,
                     'priors.weights.sd': 'none'},
    # Every array set: ROS cannot write an empty typed array in YAML.
    'gait_executor': {'odometry_topic': 'mocap/odom', 'settle_time': 0.1,
                      'fall.min_height': 0.03,
                      'joint_names': '[' + ', '.join(f'robot_{n}' for n in joint_names()) + ']',
                      'joint_limits': '[' + ', '.join(['-0.5, 0.5'] * len(joint_names())) + ']'},
}


EXPECTED = {
    'sim_bridge': {'seed': 7, 'observation.noise_std': 0.02, 'right_on_fall': True,
                   'publish_max_rate': 'none'},
    'planner': {'planner.inflation': 0.2, 'map.obstacles': None},
    'damage_detector': {'detection.threshold': 0.2, 'heartbeat.nodes': ['planner']},
    'sela_adapter': {'priors.tables': 'none', 'priors.max_misfit': 0.5, 'goal.eps': 0.15,
                     'gp.kernel.sigma': 0.25, 'planner.horizon': 'auto',
                     'fall.kernel.sigma': 'auto', 'priors.weights.sd': 'none'},
    'gait_executor': {'odometry_topic': 'mocap/odom', 'settle_time': 0.1,
                      'fall.min_height': 0.03,
                      'joint_names': [f'robot_{n}' for n in joint_names()],
                      'joint_limits': [-0.5, 0.5] * len(joint_names())},
}


def nest(tree, name, value):
    """Put ``value`` at the dotted ``name`` in ``tree``, as the dump does."""
    head, _, rest = name.partition('.')
    if not rest:
        assert head not in tree, f'{name}: already a mapping in the dump'
        tree[head] = value
        return
    branch = tree.setdefault(head, {})
    assert isinstance(branch, dict), f'{name}: {head} is a value, cannot nest in it'
    nest(branch, rest, value)


def parameters_of(client, node):
    listed = client.call(client.node.create_client(ListParameters, f'/{node}/list_parameters'),
                         ListParameters.Request())
    names = sorted(listed.result.names)
    got = client.call(client.node.create_client(GetParameters, f'/{node}/get_parameters'),
                      GetParameters.Request(names=names))
    return {n: parameter_value_to_python(v) for n, v in zip(names, got.values, strict=True)}


def dump_yaml(node, values):
    tree = {}
    for name, value in values.items():
        nest(tree, name, value)
    return yaml.dump({f'/{node}': {'ros__parameters': tree}}, default_flow_style=False)


@pytest.mark.dds
@pytest.mark.parametrize('changed', [True, False], ids=['changed', 'defaults'])
@pytest.mark.parametrize('node', sorted(SPECS))
def test_a_dump_loads_back_to_the_same_values(node, changed, tmp_path):
    """With values changed at start-up, and with config/sela.yaml's as they are."""
    client = Client(f'sela_dump_{node}')
    try:
        first = NodeProcesses({node: CHANGED[node]} if changed else None, names=(node,))
        try:
            values = parameters_of(client, node)
            assert all(first.alive().values()), first.logs()
        finally:
            first.stop()
        if changed:
            for name, value in EXPECTED[node].items():
                assert values[name] == value, name
        warned = any('0 is spelled' in log for log in first.logs().values())
        assert warned == (changed and node in ('sim_bridge', 'sela_adapter')), first.logs()
        for spec in SPECS[node]:
            assert spec.name in values and (spec.renamed_from or '') not in values
        path = tmp_path / f'{node}.yaml'
        path.write_text(dump_yaml(node, values))
        # The dump alone: nothing else says what the values are.
        again = NodeProcesses({node: {'state_file': values['state_file']}}
                              if 'state_file' in values else None,
                              names=(node,), params_files=(path,))
        try:
            reloaded = parameters_of(client, node)
            assert all(again.alive().values()), again.logs()
        finally:
            again.stop()
        assert reloaded == values
        assert not any('0 is spelled' in log for log in again.logs().values()), again.logs()
    finally:
        client.close()
