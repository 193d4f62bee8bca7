"""The package is installed the way ROS finds it: ament index, lib/sela_ros, share/."""
import os
import re
from importlib import metadata
from pathlib import Path
from xml.etree import ElementTree

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope='module')
def prefix():
    from ament_index_python.packages import get_package_prefix

    return Path(get_package_prefix('sela_ros'))


def _declared_console_scripts():
    text = (ROOT / 'setup.py').read_text()
    block = re.search(r'CONSOLE_SCRIPTS = \[(.*?)\]', text, re.S).group(1)
    return sorted(re.findall(r"'([\w\-]+) = [\w\.]+:\w+'", block))


def test_ament_index_knows_sela_ros(prefix):
    from ament_index_python.packages import get_packages_with_prefixes

    assert 'sela_ros' in get_packages_with_prefixes()
    index = prefix / 'share' / 'ament_index' / 'resource_index' / 'packages'
    assert (index / 'sela_ros').is_file()


def test_every_console_script_is_executable_under_lib_sela_ros(prefix):
    declared = _declared_console_scripts()
    installed = sorted(ep.name for ep in metadata.distribution('sela_ros').entry_points
                       if ep.group == 'console_scripts')
    assert declared, 'setup.py declares no console scripts'
    assert installed == declared, 'installed package is stale: run make venv'
    for name in declared:
        exe = prefix / 'lib' / 'sela_ros' / name
        assert exe.exists(), f'{exe} missing: ros2 run sela_ros {name} would fail'
        assert os.access(exe, os.X_OK), f'{exe} is not executable'


def test_nodes_of_the_design_are_declared():
    assert {'sim_bridge', 'damage_detector', 'planner', 'sela_adapter'} <= set(
        _declared_console_scripts())


def test_data_files_are_installed_under_share(prefix):
    from ament_index_python.packages import get_package_share_directory

    share = Path(get_package_share_directory('sela_ros'))
    assert share == prefix / 'share' / 'sela_ros'
    assert (share / 'package.xml').is_file()
    for sub, pattern in (('config', '*.yaml'), ('launch', '*.py'), ('rviz', '*.rviz'),
                         ('config/maps', '*.*')):
        sources = sorted((ROOT / sub).glob(pattern))
        assert sources, f'nothing in {sub}/'
        for src in sources:
            assert (share / sub / src.name).is_file(), f'{sub}/{src.name} not installed'
    assert (share / 'urdf' / 'hexapod.urdf').is_file(), 'the URDF is not under share/urdf'
    assert (share / 'config' / 'maps' / 'maze.pgm').is_file()


def test_package_xml_declares_runtime_dependencies():
    tree = ElementTree.parse(ROOT / 'package.xml')
    assert tree.getroot().get('format') == '3'
    deps = {e.text for e in tree.getroot() if e.tag in ('exec_depend', 'depend')}
    for dep in ('rclpy', 'std_msgs', 'geometry_msgs', 'nav_msgs', 'sensor_msgs', 'std_srvs',
                'diagnostic_msgs', 'rosgraph_msgs', 'tf2_msgs', 'visualization_msgs',
                'robot_state_publisher', 'rviz2', 'python3-numpy', 'python3-scipy'):
        assert dep in deps, dep
    assert any('pybullet' in d for d in deps)
    assert tree.find('export/build_type').text == 'ament_python'


def test_setup_cfg_puts_scripts_in_lib_sela_ros():
    text = (ROOT / 'setup.cfg').read_text()
    assert 'install_scripts=$base/lib/sela_ros' in text
    assert 'script_dir=$base/lib/sela_ros' in text


def test_every_import_of_the_project_in_scripts_and_benchmarks_resolves():
    """Scripts and benchmarks run outside the tests: a module moved in a refactor must not
    leave one of them with an ImportError (benchmarks/bench_physics.py had one)."""
    import ast
    import importlib
    import importlib.util

    root = Path(__file__).resolve().parents[1]
    files = sorted([*root.glob('scripts/*.py'), *root.glob('benchmarks/*.py')])
    assert files
    missing = []
    for path in files:
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module and \
                    node.module.split('.')[0] in ('sela_ros', 'sim_bridge'):
                try:
                    module = importlib.import_module(node.module)
                except ImportError as exc:
                    missing.append(f'{path.name}:{node.lineno}: {exc}')
                    continue
                missing += [f'{path.name}:{node.lineno}: {node.module}.{alias.name}'
                            for alias in node.names if not hasattr(module, alias.name)
                            and importlib.util.find_spec(f'{node.module}.{alias.name}') is None]
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.name.split('.')[0] in ('sela_ros', 'sim_bridge') and \
                            importlib.util.find_spec(alias.name) is None:
                        missing.append(f'{path.name}:{node.lineno}: {alias.name}')
    assert not missing, missing
