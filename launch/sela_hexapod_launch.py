"""Start the four sela_ros nodes with config/sela.yaml.

Usage: ``ros2 launch sela_ros sela_hexapod_launch.py [damage:=...] [seed:=...]``.

Arguments: damage (default remove:middle_right), seed (0), gui (false), params_file (the
installed config/sela.yaml), archive ('' = the shipped archive). Send the goal with e.g.
``ros2 topic pub --once -w 1 --qos-durability transient_local /goal_pose
geometry_msgs/msg/PoseStamped "{header: {frame_id: odom}, pose: {position: {x: 2.0, y: 2.0}}}"``.
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def generate_launch_description():
    default_params = os.path.join(get_package_share_directory('sela_ros'), 'config',
                                  'sela.yaml')
    params = LaunchConfiguration('params_file')
    arguments = [
        DeclareLaunchArgument('params_file', default_value=default_params,
                              description='parameter YAML keyed by node name'),
        DeclareLaunchArgument('damage', default_value='remove:middle_right',
                              description="damage spec, e.g. remove:middle_right or intact"),
        DeclareLaunchArgument('seed', default_value='0', description='observation-noise seed'),
        DeclareLaunchArgument('gui', default_value='false', description="PyBullet's window"),
        DeclareLaunchArgument('archive', default_value='',
                              description="archive file ('' = the shipped one)"),
    ]
    nodes = [
        Node(package='sela_ros', executable='sim_bridge', name='sim_bridge', output='screen',
             parameters=[params, {'damage': LaunchConfiguration('damage'),
                                  'seed': LaunchConfiguration('seed'),
                                  'sim.gui': LaunchConfiguration('gui')}]),
        Node(package='sela_ros', executable='planner', name='planner', output='screen',
             parameters=[params]),
        Node(package='sela_ros', executable='damage_detector', name='damage_detector',
             output='screen', parameters=[params]),
        Node(package='sela_ros', executable='sela_adapter', name='sela_adapter',
             output='screen',
             parameters=[params, {'archive': LaunchConfiguration('archive')}]),
    ]
    return LaunchDescription(arguments + nodes)
