"""The launch file and config/sela.yaml, checked without a ROS install.

``launch``/``launch_ros`` are not on PyPI, so the launch file runs here against recording
stand-ins of the few classes it uses; on a ROS install `ros2 launch` uses the real ones.
"""
import importlib.util
import sys
import types
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
NODES = ('sim_bridge', 'planner', 'damage_detector', 'sela_adapter')
#: Nodes of config/sela.yaml beside the four: the hardware path's.
CONFIGURED = NODES + ('gait_executor',)


class _Recorder:
    def __init__(self, *args, **kwargs):
        self.args, self.kwargs = args, kwargs


class _Context:
    """The launch context a robot_nodes function is given: the arguments' values."""

    def __init__(self, values):
        self.launch_configurations = values


def _load_launch(monkeypatch, filename, installed=('robot_state_publisher', 'rviz2'),
                 **values):
    """The launch file's description, its OpaqueFunctions expanded as ``ros2 launch`` would
    with the declared defaults and ``values`` (launch arguments), on a ROS install where of
    the packages beside sela_ros only those ``installed`` are."""
    import ament_index_python.packages as index
    real = index.get_package_prefix

    def prefix(package):
        if package not in ('robot_state_publisher', 'rviz2'):
            return real(package)  # sela_ros: this venv, the ament prefix
        if package not in installed:
            raise index.PackageNotFoundError(package)
        return '/opt/ros/jazzy'

    monkeypatch.setattr(index, 'get_package_prefix', prefix)
    fakes = {'launch': ['LaunchDescription'],
             'launch.actions': ['DeclareLaunchArgument', 'EmitEvent', 'GroupAction', 'LogInfo',
                                'OpaqueFunction', 'RegisterEventHandler'],
             'launch.event_handlers': ['OnProcessExit'], 'launch.events': ['Shutdown'],
             'launch.conditions': ['IfCondition'],
             'launch.substitutions': ['EqualsSubstitution', 'LaunchConfiguration'],
             'launch_ros': [], 'launch_ros.actions': ['Node', 'PushRosNamespace']}
    methods = {'LaunchConfiguration': {'perform': lambda self, context:
                                       context.launch_configurations[self.args[0]]}}
    for name, classes in fakes.items():
        module = types.ModuleType(name)
        for cls in classes:
            setattr(module, cls, type(cls, (_Recorder,), methods.get(cls, {})))
        monkeypatch.setitem(sys.modules, name, module)
    spec = importlib.util.spec_from_file_location('sela_launch', ROOT / 'launch' / filename)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    description = module.generate_launch_description()
    context = _Context({**{a.args[0]: a.kwargs['default_value'] for a in description.args[0]
                           if type(a).__name__ == 'DeclareLaunchArgument'}, **values})

    def expand(actions):
        out = []
        for action in actions:
            if type(action).__name__ == 'OpaqueFunction':
                out += expand(action.kwargs['function'](context,
                                                        *action.kwargs.get('args', ())))
            elif type(action).__name__ == 'GroupAction':
                out.append(type(action)(expand(action.args[0]), **action.kwargs))
            else:
                out.append(action)
        return out
    return type(description)(expand(description.args[0]), **description.kwargs)


@pytest.fixture
def launch_description(monkeypatch):
    return _load_launch(monkeypatch, 'sela_hexapod_launch.py')


def _nodes(launch_description):
    """The Node actions, wherever the launch file groups them."""
    found, todo = [], list(launch_description.args[0])
    while todo:
        action = todo.pop(0)
        if type(action).__name__ == 'Node':
            found.append(action)
        elif type(action).__name__ == 'GroupAction':
            todo.extend(action.args[0])
    return found


def test_launch_starts_the_four_nodes_with_the_config(launch_description):
    actions = launch_description.args[0]
    nodes = [n for n in _nodes(launch_description) if n.kwargs['package'] == 'sela_ros'
             and 'condition' not in n.kwargs]
    assert sorted(n.kwargs['executable'] for n in nodes) == sorted(NODES)
    assert all(n.kwargs['name'] == n.kwargs['executable'] for n in nodes)
    declared = {a.args[0]: a.kwargs['default_value'] for a in actions
                if type(a).__name__ == 'DeclareLaunchArgument'}
    assert declared['params_file'].endswith('share/sela_ros/config/sela.yaml')
    assert Path(declared['params_file']).is_file()
    assert declared['damage'] == '' and declared['robot'] == 'hexapod'
    sim = [n for n in nodes if n.kwargs['executable'] == 'sim_bridge'][0]
    assert sim.kwargs['parameters'][1]['damage'] == 'remove:middle_right'  # the hexapod's
    assert declared['namespace'] == '' and declared['rviz'] == 'false'


def test_namespace_is_pushed_on_every_node(launch_description):
    (group,) = [a for a in launch_description.args[0] if type(a).__name__ == 'GroupAction']
    push, *inside = group.args[0]
    assert type(push).__name__ == 'PushRosNamespace'
    assert push.args[0].args[0] == 'namespace'
    assert {id(n) for n in inside} == {id(n) for n in _nodes(launch_description)}
    for node in inside:  # each robot its own simulator, so its own clock
        assert ('/clock', 'clock') in node.kwargs['remappings'], node.kwargs['executable']


def test_robot_state_publisher_and_optional_rviz_use_installed_files(launch_description):
    by_package = {n.kwargs['package']: n for n in _nodes(launch_description)}
    rsp = by_package['robot_state_publisher']
    urdf = rsp.kwargs['parameters'][0]['robot_description']
    assert '<robot name="sela_hexapod">' in urdf and 'middle_right' in urdf  # intact model
    remaps = dict(rsp.kwargs['remappings'])
    assert remaps['/tf'] == 'tf' and remaps['joint_states'] == 'hexapod/joint_states'
    assert remaps['robot_description'] != 'robot_description'  # the simulator's is the one
    rviz = by_package['rviz2']
    assert rviz.kwargs['condition'].args[0].args[0] == 'rviz'
    config = Path(rviz.kwargs['arguments'][1])
    assert config.parent.name == 'rviz' and config.is_file(), config
    assert dict(rviz.kwargs['remappings'])['/tf'] == 'tf'


def test_without_robot_state_publisher_or_rviz_the_stack_starts_and_says_what_is_missing(
        monkeypatch):
    description = _load_launch(monkeypatch, 'sela_hexapod_launch.py', installed=())
    nodes = _nodes(description)
    assert {n.kwargs['package'] for n in nodes} == {'sela_ros'}
    assert sorted(n.kwargs['executable'] for n in nodes
                  if 'condition' not in n.kwargs) == sorted(NODES)
    (group,) = [a for a in description.args[0] if type(a).__name__ == 'GroupAction']
    said = {a.kwargs['msg']: a.kwargs.get('condition') for a in group.args[0]
            if type(a).__name__ == 'LogInfo'}
    assert len(said) == 2, said
    rsp, rviz = sorted(said)
    assert rsp.startswith('robot_state_publisher is not installed') and said[rsp] is None
    assert 'ros-$ROS_DISTRO-robot-state-publisher' in rsp
    assert rviz.startswith('rviz2 is not installed')
    assert said[rviz].args[0].args[0] == 'rviz'  # said only when RViz is asked for


def _arguments(launch_description):
    return {a.args[0]: a.kwargs['default_value'] for a in launch_description.args[0]
            if type(a).__name__ == 'DeclareLaunchArgument'}


def test_interface_trajectory_runs_the_hardware_path_in_simulation(launch_description):
    assert _arguments(launch_description)['interface'] == 'behavior'
    by_name = {n.kwargs['executable']: n for n in _nodes(launch_description)}
    sim = by_name['sim_bridge'].kwargs['parameters'][1]
    assert sim['interface'].args[0] == 'interface'
    executor = by_name['gait_executor']
    condition = executor.kwargs['condition'].args[0]  # only with interface:=trajectory
    assert type(condition).__name__ == 'EqualsSubstitution'
    assert condition.args[0].args[0] == 'interface' and condition.args[1] == 'trajectory'
    # On the simulator's hardware face: its observed odometry and IMU, its fall test.
    from sela_ros.tools.demo import simulated_hardware
    from sim_bridge.robots import get_robot

    params = executor.kwargs['parameters'][1]
    assert params == simulated_hardware(get_robot('hexapod'))  # as sela-demo's
    assert params['odometry_topic'] == 'hexapod/odom_observed'
    assert params['fall.min_height'] == 0.03
    from sela_ros.nodes import interface as ifc

    assert (ifc.ODOM_OBSERVED.name, ifc.IMU.name) == ('hexapod/odom_observed', 'hexapod/imu')


def test_robot_a1_runs_the_stack_on_the_a1_its_map_model_and_fall_test(monkeypatch):
    launch = _load_launch(monkeypatch, 'sela_hexapod_launch.py', robot='a1')
    from sela_ros.tools.demo import simulated_hardware
    from sim_bridge.robots import get_robot

    a1 = get_robot('a1')
    nodes = {n.kwargs['executable']: n for n in _nodes(launch)}
    sim = nodes['sim_bridge'].kwargs['parameters'][1]
    assert (sim['robot'], sim['archive'], sim['damage']) == ('a1', 'a1', a1.default_damage)
    assert nodes['sela_adapter'].kwargs['parameters'][1]['archive'] == 'a1'
    assert nodes['gait_executor'].kwargs['parameters'][1] == simulated_hardware(a1)
    urdf = nodes['robot_state_publisher'].kwargs['parameters'][0]['robot_description']
    assert urdf == a1.urdf() and 'a1_description' in urdf
    # An archive and a damage given are used as given.
    launch = _load_launch(monkeypatch, 'sela_hexapod_launch.py', robot='a1',
                          archive='/maps/mine.npz', damage='shorten:front_left:0.5')
    nodes = {n.kwargs['executable']: n for n in _nodes(launch)}
    sim = nodes['sim_bridge'].kwargs['parameters'][1]
    assert (sim['archive'], sim['damage']) == ('/maps/mine.npz', 'shorten:front_left:0.5')
    with pytest.raises(ValueError, match='unknown robot'):
        _load_launch(monkeypatch, 'sela_hexapod_launch.py', robot='walrus')


def test_the_simulators_seed_window_and_pace_are_the_params_files_unless_given(monkeypatch):
    def sim_parameters(**values):
        launch = _load_launch(monkeypatch, 'sela_hexapod_launch.py', **values)
        (sim,) = [n for n in _nodes(launch) if n.kwargs['executable'] == 'sim_bridge']
        return sim.kwargs['parameters'][1]

    # the params file's (0, false, 0 shipped) unless given
    assert not {'seed', 'sim.gui', 'real_time_factor'} & set(sim_parameters())
    given = sim_parameters(real_time_factor='1', seed='7', gui='true')
    for name, argument in (('real_time_factor', 'real_time_factor'), ('seed', 'seed'),
                           ('sim.gui', 'gui')):
        # a substitution, which launch_ros types (a plain '1' would stay a string)
        assert type(given[name]).__name__ == 'LaunchConfiguration'
        assert given[name].args[0] == argument


def test_a_robot_named_by_its_import_path_reaches_the_nodes_as_named(monkeypatch):
    launch = _load_launch(monkeypatch, 'sela_hexapod_launch.py',
                          robot='sim_bridge.robots.a1:A1')
    nodes = {n.kwargs['executable']: n for n in _nodes(launch)}
    for name in ('sim_bridge', 'gait_executor'):  # each finds the description by it
        assert nodes[name].kwargs['parameters'][1]['robot'] == 'sim_bridge.robots.a1:A1'
    assert nodes['sela_adapter'].kwargs['parameters'][1]['archive'] == 'a1'
    # A robot without a shipped map needs its own: said before any node starts.
    with pytest.raises(ValueError, match='the toy has no shipped map.*archive:=PATH'):
        _load_launch(monkeypatch, 'sela_hexapod_launch.py', robot='sim_bridge.robots.toy:TOY')
    launch = _load_launch(monkeypatch, 'sela_hexapod_launch.py',
                          robot='sim_bridge.robots.toy:TOY', archive='/maps/toy.npz')
    nodes = {n.kwargs['executable']: n for n in _nodes(launch)}
    assert nodes['sela_adapter'].kwargs['parameters'][1]['archive'] == '/maps/toy.npz'


def test_a_damage_the_robot_cannot_have_is_refused_before_any_node_starts(monkeypatch):
    from sim_bridge.damage import DamageSpecError

    with pytest.raises(DamageSpecError, match="unknown leg 'front_lft'.*valid legs"):
        _load_launch(monkeypatch, 'sela_hexapod_launch.py', damage='remove:front_lft')
    with pytest.raises(DamageSpecError, match='calf'):  # the A1's names, not the hexapod's
        _load_launch(monkeypatch, 'sela_hexapod_launch.py', robot='a1',
                     damage='block:front_left.knee')


@pytest.mark.parametrize('filename', ['sela_hexapod_launch.py', 'sela_hardware_launch.py'])
def test_a_node_refusing_its_configuration_ends_the_launch_and_a_crash_does_not(
        monkeypatch, filename):
    from types import SimpleNamespace

    from sela_ros.nodes.node_main import EXIT_BAD_CONFIGURATION

    launch = _load_launch(monkeypatch, filename)
    (handler,) = [a for a in launch.args[0] if type(a).__name__ == 'RegisterEventHandler']
    (on_exit,) = handler.args
    assert on_exit.kwargs.get('target_action') is None  # every process of the launch
    react = on_exit.kwargs['on_exit']
    said, shutdown = react(SimpleNamespace(process_name='planner-2',
                                           returncode=EXIT_BAD_CONFIGURATION), None)
    assert 'planner-2 refused its configuration' in said.kwargs['msg']
    assert shutdown.kwargs['event'].kwargs['reason'] == said.kwargs['msg']
    for code in (0, 1, -9, -15):  # ended, crashed, killed: the others go on
        assert react(SimpleNamespace(process_name='planner-2', returncode=code), None) is None


def test_the_hardware_launch_runs_the_stack_on_a_robots_own_topics(monkeypatch):
    launch = _load_launch(monkeypatch, 'sela_hardware_launch.py')
    arguments = _arguments(launch)
    assert arguments['odometry_topic'] == 'odom' and arguments['imu_topic'] == ''
    from sela_ros.nodes import interface as ifc

    assert arguments['trajectory_topic'] == ifc.JOINT_TRAJECTORY.name
    nodes = {n.kwargs['executable']: n for n in _nodes(launch)}
    assert set(nodes) == {'planner', 'damage_detector', 'sela_adapter', 'gait_executor'}
    (group,) = [a for a in launch.args[0] if type(a).__name__ == 'GroupAction']
    assert type(group.args[0][0]).__name__ == 'PushRosNamespace'
    for name, node in nodes.items():  # no simulator: no /clock
        assert {'use_sim_time': False} in node.kwargs['parameters'], name
    for name in ('planner', 'sela_adapter'):  # the pose from the robot's odometry
        (remap,) = nodes[name].kwargs['remappings']
        assert remap[0] == ifc.ODOM.name and remap[1].args[0] == 'odometry_topic'
    adapter = nodes['sela_adapter'].kwargs['parameters'][2]
    assert adapter['simulator_node'] == ''
    # On a robot a map frame is a localisation's: goals in it only when the user says so.
    assert arguments['map_frame'] == ''
    for name in ('planner', 'sela_adapter'):
        assert nodes[name].kwargs['parameters'][2]['map_frame'].args[0] == 'map_frame'
    detector = nodes['damage_detector'].kwargs['parameters'][2]
    assert 'sim_bridge' not in detector['heartbeat.nodes']
    assert set(detector['heartbeat.nodes']) <= set(ifc.ALIVE)
    # The robot the executor plays the gaits of is an argument (the hexapod by default).
    assert arguments['robot'] == 'hexapod'
    assert nodes['gait_executor'].kwargs['parameters'][2]['robot'].args[0] == 'robot'


def test_rviz_config_shows_the_robot_and_sets_goals_on_goal_pose():
    config = yaml.safe_load((ROOT / 'rviz' / 'sela.rviz').read_text())
    manager = config['Visualization Manager']
    assert manager['Global Options']['Fixed Frame'] == 'odom'
    displays = {d['Class'].split('/')[-1]: d for d in manager['Displays']}
    assert {'RobotModel', 'TF', 'Path', 'MarkerArray'} <= set(displays)
    assert displays['RobotModel']['Description Topic']['Value'] == 'robot_description'
    (goal_tool,) = [t for t in manager['Tools'] if t['Class'].endswith('/SetGoal')]
    assert goal_tool['Topic']['Value'] == 'goal_pose'  # relative: follows namespace:=
    assert goal_tool['Topic']['Durability Policy'] == 'Volatile'


def _config():
    raw = yaml.safe_load((ROOT / 'config' / 'sela.yaml').read_text())
    # /**/<node>: the node's parameters in any namespace (namespace:=/robot1).
    assert set(raw) == {f'/**/{node}' for node in CONFIGURED}
    return {key.removeprefix('/**/'): value for key, value in raw.items()}


def test_config_is_keyed_by_node_name_with_ros_parameters():
    config = _config()
    from sela_ros.nodes.planner_node import load_map_file

    assert load_map_file(ROOT / 'config' / 'obstacle_map.yaml').occupied.any()
    for node in CONFIGURED:
        assert set(config[node]) == {'ros__parameters'}
    assert config['sim_bridge']['ros__parameters']['use_sim_time'] is False
    for node in ('planner', 'damage_detector', 'sela_adapter'):
        assert config[node]['ros__parameters']['use_sim_time'] is True


def test_config_defaults_are_the_code_defaults():
    """One source of truth: the YAML says what the code would do without it."""
    from sela_ros.core.detection import DetectorConfig
    from sela_ros.core.learning import SELAConfig
    from sela_ros.core.validation import OutcomeLimits

    config = _config()
    adapter = config['sela_adapter']['ros__parameters']
    for key, value in SELAConfig().to_dict().items():
        if key in ('gp.kernel.sigma', 'fall.kernel.sigma', 'planner.horizon'):  # auto: the
            from sela_ros.core.mission import make_sela  # archive's
            from sela_ros.core.storage import default_archive_path, load_archive

            assert adapter[key] == 'auto'
            shipped = load_archive(default_archive_path())
            used = make_sela(shipped, {key: 'auto'}).config
            assert used.gp_kernel_sigma == shipped.kernel_sigma
            assert used.fall_kernel_sigma == shipped.fall_kernel_sigma
            assert used.planner_horizon == shipped.planner_horizon == 2
        elif key in adapter:
            assert adapter[key] == value, key
    detector = config['damage_detector']['ros__parameters']
    for key, value in vars(DetectorConfig()).items():
        assert detector[f'detection.{key}'] == value, key
    assert detector['outcome.max_displacement'] == OutcomeLimits().max_displacement


def test_adaptation_on_detection_has_one_default():
    """The node's parameter, config/sela.yaml, the stepper and the learning logic agree."""
    import inspect

    from sela_ros.core.mission import MissionLogic, StepperConfig
    from sela_ros.nodes import adapter_params

    spec = next(s for s in adapter_params.PARAMETERS if s.name == 'adaptation.on_detection')
    logic = inspect.signature(MissionLogic).parameters['on_detection'].default
    yaml_value = _config()['sela_adapter']['ros__parameters']['adaptation.on_detection']
    assert {spec.default, logic, yaml_value} == {StepperConfig.on_detection}
