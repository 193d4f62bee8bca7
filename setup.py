"""ament_python build script for sela_ros (colcon build, or pip install into .venv)."""
from glob import glob

from setuptools import find_packages, setup

package_name = 'sela_ros'

# Every executable of the package. Nodes are reached with `ros2 run sela_ros <name>`; the
# command-line tools keep their dashed names. scripts/link_executables.py mirrors these into
# <prefix>/lib/sela_ros/ when the package is pip-installed into the project's .venv.
CONSOLE_SCRIPTS = [
    'sim_bridge = sim_bridge.node:main',
    'damage_detector = sela_ros.nodes.damage_detector_node:main',
    'planner = sela_ros.nodes.planner_node:main',
    'sela_adapter = sela_ros.nodes.adapter_node:main',
    'gait_executor = sela_ros.nodes.gait_executor_node:main',
    'sela-demo = sela_ros.tools.demo:main',
    'sela-experiment = sela_ros.experiments.cli:main',
    'sela-build-archive = sela_ros.tools.build_archive:main',
]

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    package_data={'sim_bridge': ['urdf/*.urdf'], 'sela_ros': ['data/*']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config',
         sorted(glob('config/*.yaml') + glob('config/*.xml'))),
        ('share/' + package_name + '/config/maps', sorted(glob('config/maps/*.yaml')
                                                          + glob('config/maps/*.pgm'))),
        ('share/' + package_name + '/launch', sorted(glob('launch/*.py'))),
        ('share/' + package_name + '/rviz', sorted(glob('rviz/*.rviz'))),
        # The intact model (robot_state_publisher's); the simulator publishes the damaged one.
        ('share/' + package_name + '/urdf', sorted(glob('sim_bridge/urdf/*.urdf'))),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='sela_ros developers',
    maintainer_email='sela_ros@example.org',
    description='Semi-Episodic Learning Algorithm (SELA) for hexapod damage recovery, on ROS 2',
    license='BSD-3-Clause',
    # 'qd': the offline map builder's extras (sela-build-archive --descriptor 8d, Dask).
    extras_require={'test': ['pytest'], 'qd': ['ribs==0.12.0', 'dask', 'distributed']},
    entry_points={'console_scripts': CONSOLE_SCRIPTS},
)
