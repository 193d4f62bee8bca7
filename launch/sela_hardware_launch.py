"""SELA on a real robot under ros2_control: the planner, the damage detector, the adapter and
the gait executor, with config/sela.yaml. No simulator: the robot's own stack runs its
``joint_trajectory_controller``, its odometry (motion capture, visual or leg odometry) and
its IMU. See docs/hardware.md.

Usage: ``ros2 launch sela_ros sela_hardware_launch.py odometry_topic:=/mocap/odom
[imu_topic:=/imu/data] [trajectory_topic:=...] [namespace:=/robot1] [archive:=...]
[map:=...] [map_frame:=map]``.

Arguments: params_file (the installed config/sela.yaml), odometry_topic (odom),
imu_topic ('' = falls told from the odometry's orientation), trajectory_topic (the
controller's command topic, joint_trajectory_controller/joint_trajectory), archive ('' = the
shipped one), map (the planner's map YAML; '' = the map.* parameters), namespace ('' = the
root), map_frame ('' = goals only in the odometry's frame; map when the odometry is the
map's, as motion capture's). Every node runs on the wall clock (no simulator publishes
/clock); the planner and the adapter take the robot's pose from the same odometry
(``hexapod/odom`` remapped to it); the adapter checks no simulator's settings against the
archive, and the damage detector watches the planner, the adapter and the gait executor. A
node that refuses its configuration (a bad parameter: its error says which) ends the launch.
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, GroupAction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node, PushRosNamespace

from sela_ros.tools.launch_actions import end_on_refused_configuration

#: On a robot, time is the wall clock's: no node waits for a /clock.
WALL_CLOCK = {'use_sim_time': False}


def generate_launch_description():
    share = get_package_share_directory('sela_ros')
    params = LaunchConfiguration('params_file')
    arguments = [
        DeclareLaunchArgument('params_file',
                              default_value=os.path.join(share, 'config', 'sela.yaml'),
                              description='parameter YAML keyed by node name'),
        DeclareLaunchArgument('odometry_topic', default_value='odom',
                              description='nav_msgs/Odometry of the body (motion capture, '
                              'visual or leg odometry)'),
        DeclareLaunchArgument('imu_topic', default_value='',
                              description="sensor_msgs/Imu that tells a fall ('' = the "
                              "odometry's orientation)"),
        DeclareLaunchArgument('trajectory_topic',
                              default_value='joint_trajectory_controller/joint_trajectory',
                              description="the joint_trajectory_controller's command topic"),
        DeclareLaunchArgument('robot', default_value='hexapod',
                              description='the robot description the gait executor plays the '
                              'gaits of: hexapod, a1, toy or package.module:DESCRIPTION '
                              '(docs/robots.md)'),
        DeclareLaunchArgument('archive', default_value='',
                              description="archive file ('' = the shipped one)"),
        DeclareLaunchArgument('map', default_value='',
                              description="planner map YAML ('' = the map.* parameters)"),
        DeclareLaunchArgument('namespace', default_value='',
                              description="namespace of the whole stack ('' = the root)"),
        DeclareLaunchArgument('map_frame', default_value='',
                              description="a frame whose goals are taken as given in the "
                              "odometry's ('' = none: with a localisation stack, map -> odom "
                              'is not the identity; map when the odometry is in the map frame, '
                              'e.g. motion capture)'),
    ]
    # The robot's pose for the planner and the adapter: the executor's odometry.
    odometry = [('hexapod/odom', LaunchConfiguration('odometry_topic'))]
    nodes = [
        Node(package='sela_ros', executable='gait_executor', name='gait_executor',
             output='screen',
             parameters=[params, WALL_CLOCK, {
                 'robot': LaunchConfiguration('robot'),
                 'odometry_topic': LaunchConfiguration('odometry_topic'),
                 'imu_topic': LaunchConfiguration('imu_topic'),
                 'trajectory_topic': LaunchConfiguration('trajectory_topic')}]),
        Node(package='sela_ros', executable='planner', name='planner', output='screen',
             parameters=[params, WALL_CLOCK, {'map.file': LaunchConfiguration('map'),
                                               'map_frame': LaunchConfiguration('map_frame')}],
             remappings=odometry),
        Node(package='sela_ros', executable='damage_detector', name='damage_detector',
             output='screen', parameters=[params, WALL_CLOCK, {
                 'heartbeat.nodes': ['planner', 'sela_adapter', 'gait_executor']}]),
        Node(package='sela_ros', executable='sela_adapter', name='sela_adapter',
             output='screen', parameters=[params, WALL_CLOCK, {
                 'archive': LaunchConfiguration('archive'), 'simulator_node': '',
                 'map_frame': LaunchConfiguration('map_frame')}],
             remappings=odometry),
    ]
    stack = GroupAction([PushRosNamespace(LaunchConfiguration('namespace'))] + nodes)
    return LaunchDescription(arguments + [end_on_refused_configuration(), stack])
