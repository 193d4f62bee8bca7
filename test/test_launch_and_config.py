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


class _Recorder:
    def __init__(self, *args, **kwargs):
        self.args, self.kwargs = args, kwargs


@pytest.fixture
def launch_description(monkeypatch):
    fakes = {'launch': ['LaunchDescription'], 'launch.actions': ['DeclareLaunchArgument'],
             'launch.substitutions': ['LaunchConfiguration'], 'launch_ros': [],
             'launch_ros.actions': ['Node']}
    for name, classes in fakes.items():
        module = types.ModuleType(name)
        for cls in classes:
            setattr(module, cls, type(cls, (_Recorder,), {}))
        monkeypatch.setitem(sys.modules, name, module)
    spec = importlib.util.spec_from_file_location(
        'sela_launch', ROOT / 'launch' / 'sela_hexapod_launch.py')
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.generate_launch_description()


def test_launch_starts_the_four_nodes_with_the_config(launch_description):
    actions = launch_description.args[0]
    nodes = [a for a in actions if type(a).__name__ == 'Node']
    assert sorted(n.kwargs['executable'] for n in nodes) == sorted(NODES)
    assert all(n.kwargs['package'] == 'sela_ros' for n in nodes)
    assert all(n.kwargs['name'] == n.kwargs['executable'] for n in nodes)
    declared = {a.args[0]: a.kwargs['default_value'] for a in actions
                if type(a).__name__ == 'DeclareLaunchArgument'}
    assert declared['params_file'].endswith('share/sela_ros/config/sela.yaml')
    assert Path(declared['params_file']).is_file()
    assert declared['damage'] == 'remove:middle_right'


def test_config_is_keyed_by_node_name_with_ros_parameters():
    config = yaml.safe_load((ROOT / 'config' / 'sela.yaml').read_text())
    assert set(config) == set(NODES)
    from sela_ros.nodes.planner_node import load_map_file

    assert load_map_file(ROOT / 'config' / 'obstacle_map.yaml').occupied.any()
    for node in NODES:
        assert set(config[node]) == {'ros__parameters'}
    assert config['sim_bridge']['ros__parameters']['use_sim_time'] is False
    for node in ('planner', 'damage_detector', 'sela_adapter'):
        assert config[node]['ros__parameters']['use_sim_time'] is True


def test_config_defaults_are_the_code_defaults():
    """One source of truth: the YAML says what the code would do without it."""
    from sela_ros.core.damage_detection import DetectorConfig
    from sela_ros.core.sela import SELAConfig

    config = yaml.safe_load((ROOT / 'config' / 'sela.yaml').read_text())
    adapter = config['sela_adapter']['ros__parameters']
    for key, value in SELAConfig().to_dict().items():
        if key in adapter:
            assert adapter[key] == value, key
    detector = config['damage_detector']['ros__parameters']
    for key, value in vars(DetectorConfig()).items():
        assert detector[f'detection.{key}'] == value, key
