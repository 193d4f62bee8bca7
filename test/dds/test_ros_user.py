"""What a ROS user does, over DDS: see the robot (/tf, /robot_description), inspect and set
parameters, start with a bad one, stop the stack with Ctrl-C (issue #12)."""
import os
import signal
import subprocess
import time

import pytest
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import DescribeParameters, GetParameters, SetParameters
from rclpy.parameter import parameter_value_to_python
from std_msgs.msg import String

from sela_ros.nodes.interface import LATCHED_QOS
from sela_ros.tools.ros_env import executable

from ros_graph import CONFIG, Client, NodeProcesses

pytestmark = [pytest.mark.dds]


@pytest.fixture
def client():
    c = Client('ros_user_test')
    yield c
    c.close()


def _set(client, node, name, value_msg):
    cli = client.node.create_client(SetParameters, f'/{node}/set_parameters')
    request = SetParameters.Request(parameters=[Parameter(name=name, value=value_msg)])
    return client.call(cli, request).results[0]


def test_sim_publishes_tf_and_the_damaged_robot_description(client):
    from tf2_msgs.msg import TFMessage  # generated into .venv by make venv

    nodes = NodeProcesses({'sim_bridge': {'damage': 'remove:middle_right'}},
                          names=('sim_bridge',))
    try:
        transforms, descriptions, static = [], [], []
        client.node.create_subscription(TFMessage, '/tf',
                                        lambda m: transforms.extend(m.transforms), 10)
        client.node.create_subscription(TFMessage, '/tf_static',
                                        lambda m: static.extend(m.transforms), LATCHED_QOS)
        client.node.create_subscription(String, '/robot_description',
                                        lambda m: descriptions.append(m.data), LATCHED_QOS)
        client.spin_until(lambda: transforms and descriptions and static, 60,
                          '/tf, /tf_static and /robot_description')
        tf = transforms[-1]
        assert (tf.header.frame_id, tf.child_frame_id) == ('odom', 'base_link')
        # map -> odom, the identity, latched: RViz with the fixed frame map draws the robot.
        (parent,) = static
        assert (parent.header.frame_id, parent.child_frame_id) == ('map', 'odom')
        t, r = parent.transform.translation, parent.transform.rotation
        assert (t.x, t.y, t.z, r.x, r.y, r.z, r.w) == (0, 0, 0, 0, 0, 0, 1)
        assert 0.05 < tf.transform.translation.z < 0.5  # the body stands above the ground
        urdf = descriptions[-1]
        assert '<robot name="sela_hexapod">' in urdf and 'damage: remove:middle_right' in urdf
        assert 'middle_right.coxa' not in urdf and 'middle_left.coxa' in urdf
        # The description follows the damage at run time.
        value = ParameterValue(type=ParameterType.PARAMETER_STRING, string_value='intact')
        assert _set(client, 'sim_bridge', 'damage', value).successful
        client.spin_until(lambda: 'damage: intact' in descriptions[-1], 30,
                          'the intact description')
        assert 'middle_right.coxa' in descriptions[-1]
        assert all(nodes.alive().values()), nodes.logs()
    finally:
        nodes.stop()


def test_parameters_are_described_and_take_an_integer_for_a_double(client):
    nodes = NodeProcesses(names=('planner',))
    try:
        describe = client.node.create_client(DescribeParameters, '/planner/describe_parameters')
        answer = client.call(describe, DescribeParameters.Request(
            names=['planner.inflation', 'map.resolution']))
        inflation, resolution = answer.descriptors
        assert 'clearance' in inflation.description
        (span,) = inflation.floating_point_range
        assert span.from_value == 0.0 and span.to_value >= 5.0
        assert not inflation.read_only and resolution.read_only
        # `ros2 param set /planner planner.inflation 1`: an integer, stored as a double.
        one = ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=1)
        assert _set(client, 'planner', 'planner.inflation', one).successful
        get = client.node.create_client(GetParameters, '/planner/get_parameters')
        (value,) = client.call(get, GetParameters.Request(names=['planner.inflation'])).values
        assert value.type == ParameterType.PARAMETER_DOUBLE and value.double_value == 1.0
        text = ParameterValue(type=ParameterType.PARAMETER_STRING, string_value='abc')
        result = _set(client, 'planner', 'planner.inflation', text)
        assert not result.successful
        assert result.reason == "planner.inflation must be a number in [0, 10] m, got 'abc'"
        result = _set(client, 'planner', 'map.resolution',
                      ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=0.1))
        assert not result.successful and 'read-only' in result.reason
    finally:
        nodes.stop()


def test_a_word_or_a_number_is_taken_at_run_time_and_a_wrong_word_refused(client):
    """``ros2 param set /sim_bridge publish_max_rate none`` (no cap), a number, or the 0 that
    meant none (read as none); a misspelt word is refused and the node runs on."""
    nodes = NodeProcesses(names=('sim_bridge',))
    get = client.node.create_client(GetParameters, '/sim_bridge/get_parameters')

    def rate():
        (value,) = client.call(get, GetParameters.Request(names=['publish_max_rate']),
                               timeout=60).values
        return parameter_value_to_python(value)

    try:
        assert rate() == 5.0
        word = ParameterValue(type=ParameterType.PARAMETER_STRING, string_value='none')
        assert _set(client, 'sim_bridge', 'publish_max_rate', word).successful
        assert rate() == 'none'
        three = ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=3)
        assert _set(client, 'sim_bridge', 'publish_max_rate', three).successful
        assert rate() == 3.0
        zero = ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=0.0)
        assert _set(client, 'sim_bridge', 'publish_max_rate', zero).successful
        assert rate() == 'none'
        wrong = ParameterValue(type=ParameterType.PARAMETER_STRING, string_value='off')
        result = _set(client, 'sim_bridge', 'publish_max_rate', wrong)
        assert not result.successful
        assert result.reason == ("publish_max_rate must be a number in [0, 1000] Hz or none, "
                                 "got 'off'")
        assert rate() == 'none' and all(nodes.alive().values()), nodes.logs()
    finally:
        nodes.stop()
    assert 'publish_max_rate: 0 is spelled none now' in nodes.logs()['sim_bridge.log']


@pytest.mark.parametrize('node, args, message', [
    ('sim_bridge', ['-p', 'seed:=abc'],
     "[ERROR] [sim_bridge]: seed must be an integer in [0, 2147483647], got 'abc' "
     '(not started)'),
    ('planner', ['-p', 'planner.inflation:=abc'],
     "[ERROR] [planner]: planner.inflation must be a number in [0, 10] m, got 'abc' "
     '(not started)'),
    ('damage_detector', ['-p', 'detection.window:=0'],
     '[ERROR] [damage_detector]: Parameter detection.window out of range. Min: 1, Max: 1000, '
     'value: 0 (not started)'),
    ('sela_adapter', ['-p', 'planner.horizon:=automatic'],
     "[ERROR] [sela_adapter]: planner.horizon must be an integer in [1, 2] or auto, got "
     "'automatic' (not started)"),
    ('sim_bridge', ['-p', 'sim.gui:=true'],
     '[ERROR] [sim_bridge]: sim.gui needs a display (DISPLAY and WAYLAND_DISPLAY are not set); '
     'use sim.gui:=false for headless DIRECT mode (not started)'),
])
def test_a_bad_start_up_parameter_ends_the_node_with_one_line(ros_env, node, args, message):
    env = {k: v for k, v in ros_env.items() if k not in ('DISPLAY', 'WAYLAND_DISPLAY')}
    proc = subprocess.run([str(executable(node)), '--ros-args'] + args, env=env,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.strip().splitlines() == [message]
    assert proc.stdout == ''


def test_an_integer_for_a_double_at_start_up_is_taken(ros_env, client):
    nodes = NodeProcesses({'planner': {'planner.inflation': 1}}, names=('planner',))
    try:
        get = client.node.create_client(GetParameters, '/planner/get_parameters')
        (value,) = client.call(get, GetParameters.Request(names=['planner.inflation']),
                               timeout=60).values
        assert value.type == ParameterType.PARAMETER_DOUBLE and value.double_value == 1.0
    finally:
        nodes.stop()


def test_a_list_written_by_launch_ros_as_a_python_tuple_is_taken(ros_env, client, tmp_path):
    """launch_ros writes a list given in a launch file as ``!!python/tuple``; rcl reads it as a
    list, and so must the node's own check of its parameter files."""
    tagged = tmp_path / 'launch_params.yaml'
    tagged.write_text('/**/damage_detector:\n  ros__parameters:\n    heartbeat.nodes: '
                      '!!python/tuple\n    - planner\n    - sela_adapter\n')
    nodes = NodeProcesses(names=('damage_detector',), params_files=(CONFIG, tagged))
    try:
        get = client.node.create_client(GetParameters, '/damage_detector/get_parameters')
        (value,) = client.call(get, GetParameters.Request(names=['heartbeat.nodes']),
                               timeout=60).values
        assert list(value.string_array_value) == ['planner', 'sela_adapter'], nodes.logs()
    finally:
        nodes.stop()


def test_ctrl_c_under_a_launch_like_process_group_exits_cleanly(ros_env, client, tmp_path):
    """A terminal's Ctrl-C reaches the whole process group, then `ros2 launch` sends its own
    SIGINT to each node: every node exits 0, with no traceback and nothing on stdout."""
    names = ('sim_bridge', 'planner', 'damage_detector', 'sela_adapter')
    procs = {}
    state = tmp_path / 'state.json'  # not the user's ~/.ros one
    for name in names:
        extra = ['--ros-args', '-p', f'state_file:={state}'] if name == 'sela_adapter' else []
        procs[name] = subprocess.Popen(
            [str(executable(name)), *extra], env=ros_env, stdout=subprocess.PIPE,
            stderr=subprocess.PIPE, text=True,
            process_group=procs['sim_bridge'].pid if procs else 0)
    try:
        for name in names:  # up: its parameter services answer
            cli = client.node.create_client(GetParameters, f'/{name}/get_parameters')
            client.call(cli, GetParameters.Request(names=['use_sim_time']), timeout=90)
        group = procs['sim_bridge'].pid
        deadline = time.monotonic() + 30
        # Ctrl-C, then launch's SIGINTs, repeated until every node is gone (bounded).
        while any(p.poll() is None for p in procs.values()) and time.monotonic() < deadline:
            os.killpg(group, signal.SIGINT)
            for proc in procs.values():
                if proc.poll() is None:
                    proc.send_signal(signal.SIGINT)
            client.executor.spin_once(timeout_sec=0.05)  # paces the signals
    finally:
        outputs = {}
        for name, proc in procs.items():
            if proc.poll() is None:
                proc.kill()
            out, err = proc.communicate(timeout=30)
            outputs[name] = (proc.returncode, out, err)
    for name, (status, out, err) in outputs.items():
        assert status == 0, (name, status, err[-2000:])
        assert 'Traceback' not in err and 'KeyboardInterrupt' not in err, (name, err)
        assert out == '', (name, out)  # nothing on stdout: no banner (logs go to stderr)


def test_sigterm_ends_a_node_cleanly(ros_env, client):
    """`ros2 launch` escalates to SIGTERM when a node outlives its SIGINT: status 0 too."""
    proc = subprocess.Popen([str(executable('planner'))], env=ros_env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        cli = client.node.create_client(GetParameters, '/planner/get_parameters')
        client.call(cli, GetParameters.Request(names=['use_sim_time']), timeout=90)
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate(timeout=30)
    assert proc.returncode == 0 and 'Traceback' not in err, (proc.returncode, err[-2000:])
