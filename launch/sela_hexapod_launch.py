"""Start the four sela_ros nodes with config/sela.yaml, robot_state_publisher and maybe RViz.

Usage: ``ros2 launch sela_ros sela_hexapod_launch.py [damage:=...] [seed:=...]
[namespace:=/robot1] [rviz:=true] [real_time_factor:=1] [interface:=trajectory] [robot:=a1]``.

Arguments: robot (hexapod; a1, toy or ``package.module:DESCRIPTION``: the simulated robot,
docs/robots.md), damage ('' = the robot's default: remove:middle_right on the hexapod,
block:rear_right.calf on the A1; in the robot's names, e.g. remove:front_left), seed, gui,
real_time_factor ('' = the params file's: 0, false, 0; real_time_factor 1: each gait at the
robot's own pace, to watch it, 0: as fast as the machine allows), params_file (the installed
config/sela.yaml), archive ('' = the robot's shipped archive), map (the planner's map YAML,
map_server's format or the project's, set as its map.file; '' = no file: the map.*
parameters), namespace ('' = the root: every node, topic and service of the stack goes under
it, so two robots can share a domain), rviz (false; true opens RViz with
share/sela_ros/rviz/sela.rviz), interface (behavior; trajectory: the hardware path, the
simulator showing the face of a robot under ros2_control and the gait executor playing the
adapter's gaits on it, measured on the simulator's observed odometry: docs/hardware.md). The
obstacle courses are installed in ``$(ros2 pkg prefix sela_ros)/share/sela_ros/config/maps/``
(wall_gap.yaml, corridor.yaml, maze.yaml); a map published on ``map`` (by map_server)
replaces the planner's. The goal command is in the README ("Send a goal").

/tf and /tf_static are remapped to the namespace's ``tf``/``tf_static`` for
robot_state_publisher and RViz (as nav2 does), so each robot has its own tree, and /clock to
the namespace's ``clock`` for every node (each robot has its own simulator, so its own
time); in the root namespace these are the usual /tf, /tf_static and /clock. The
simulator publishes ``robot_description`` with the current damage (a removed leg is
absent); robot_state_publisher gets the robot's intact model (the hexapod's is
share/sela_ros/urdf/hexapod.urdf) for the legs'
transforms, and its own copy of the description is moved aside so that it does not replace
the simulator's. Where robot_state_publisher or rviz2 is not installed, a line says so and
the rest of the stack starts. A node that refuses its configuration (a bad parameter: its
error says which) ends the launch; a damage the robot cannot have is refused before any node
starts.
"""
import os

from ament_index_python.packages import (
    PackageNotFoundError,
    get_package_prefix,
    get_package_share_directory,
)
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, GroupAction, LogInfo, OpaqueFunction
from launch.conditions import IfCondition
from launch.substitutions import EqualsSubstitution, LaunchConfiguration
from launch_ros.actions import Node, PushRosNamespace

from sela_ros.tools.launch_actions import end_on_refused_configuration

# Each robot has its own simulator, so its own clock: /clock -> <namespace>/clock for every
# node of the stack (the same /clock in the root namespace).
CLOCK_REMAP = [('/clock', 'clock')]
TF_REMAPS = [('/tf', 'tf'), ('/tf_static', 'tf_static')] + CLOCK_REMAP
# The gait executor on the simulator's hardware face: its observed odometry (the pose the
# direct path observes) and IMU, and the simulator's fall test (tilt, and the body's height);
# the simulator's state comes every 0.5 s of sim time during a gait, slower than real time
# on a loaded machine: a longer odometry timeout.
SIMULATED_HARDWARE = {'odometry_topic': 'hexapod/odom_observed', 'imu_topic': 'hexapod/imu',
                      'odometry.timeout': 5.0}


def generate_launch_description():
    share = get_package_share_directory('sela_ros')
    default_params = os.path.join(share, 'config', 'sela.yaml')
    arguments = [
        DeclareLaunchArgument('params_file', default_value=default_params,
                              description='parameter YAML keyed by node name'),
        DeclareLaunchArgument('robot', default_value='hexapod',
                              description='the simulated robot: hexapod, a1, toy or '
                                          'package.module:DESCRIPTION (docs/robots.md)'),
        DeclareLaunchArgument('damage', default_value='',
                              description="damage spec in the robot's names, e.g. "
                                          "remove:middle_right or intact ('' = the robot's "
                                          "default)"),
        DeclareLaunchArgument('seed', default_value='',
                              description="observation-noise seed ('' = the params file's, 0)"),
        DeclareLaunchArgument('gui', default_value='',
                              description="PyBullet's window ('' = the params file's, false)"),
        DeclareLaunchArgument('real_time_factor', default_value='',
                              description="1: the gaits at the robot's own pace (to watch in "
                                          'RViz or PyBullet\'s window); 0: as fast as the '
                                          "machine allows ('' = the params file's, 0)"),
        DeclareLaunchArgument('archive', default_value='',
                              description="archive file ('' = the robot's shipped one)"),
        DeclareLaunchArgument('namespace', default_value='',
                              description="namespace of the whole stack, e.g. /robot1 "
                                          "('' = the root)"),
        DeclareLaunchArgument('rviz', default_value='false',
                              description='true: open RViz on the robot, the path and '
                                          "SELA's markers"),
        DeclareLaunchArgument('map', default_value='',
                              description="planner map YAML, e.g. <share>/config/maps/maze.yaml "
                              "(sets planner map.file; '' = the map.* parameters)"),
        DeclareLaunchArgument('interface', default_value='behavior',
                              description="behavior: the simulator plays the gaits; trajectory: "
                              "the hardware path (gait_executor and the simulator's "
                              "ros2_control face)"),
    ]
    stack = GroupAction([PushRosNamespace(LaunchConfiguration('namespace')),
                         OpaqueFunction(function=robot_nodes, args=[share])])
    return LaunchDescription(arguments + [end_on_refused_configuration(), stack])


def robot_nodes(context, share):
    """The stack's nodes for the robot the ``robot`` argument names: its simulator, its
    map (unless ``archive`` names one), its model for robot_state_publisher and, with
    ``interface:=trajectory``, the simulator's fall test for the gait executor."""
    from sim_bridge.robots import get_robot

    spec = LaunchConfiguration('robot').perform(context)  # the nodes find it by this
    robot = get_robot(spec)
    archive = LaunchConfiguration('archive').perform(context) or robot.archive
    if not archive:
        raise ValueError(f'the {robot.name} has no shipped map: build one (docs/robots.md) '
                         'and give it, archive:=PATH')
    damage = LaunchConfiguration('damage').perform(context) or robot.default_damage
    robot.parse_damage(damage)  # a damage the robot cannot have: said before any node starts
    params = LaunchConfiguration('params_file')
    hardware = IfCondition(EqualsSubstitution(LaunchConfiguration('interface'), 'trajectory'))
    rviz = IfCondition(LaunchConfiguration('rviz'))
    # The simulator's settings given as arguments: substitutions, typed by launch_ros (a
    # performed '1' would stay a string); those not given are the params file's.
    given = {name: LaunchConfiguration(argument) for name, argument in (
        ('seed', 'seed'), ('sim.gui', 'gui'), ('real_time_factor', 'real_time_factor'))
        if LaunchConfiguration(argument).perform(context)}
    return [
        Node(package='sela_ros', executable='sim_bridge', name='sim_bridge', output='screen',
             parameters=[params, {'robot': spec,
                                  'damage': damage,
                                  'archive': archive,
                                  'interface': LaunchConfiguration('interface'),
                                  **given}],
             remappings=CLOCK_REMAP),
        Node(package='sela_ros', executable='gait_executor', name='gait_executor',
             output='screen', parameters=[params, {
                 **SIMULATED_HARDWARE, 'robot': spec,
                 'fall.tilt': float(robot.fall_tilt),
                 'fall.min_height': float(robot.fall_height)}],
             remappings=CLOCK_REMAP, condition=hardware),
        Node(package='sela_ros', executable='planner', name='planner', output='screen',
             parameters=[params, {'map.file': LaunchConfiguration('map')}],
             remappings=CLOCK_REMAP),
        Node(package='sela_ros', executable='damage_detector', name='damage_detector',
             output='screen', parameters=[params], remappings=CLOCK_REMAP),
        Node(package='sela_ros', executable='sela_adapter', name='sela_adapter',
             output='screen', parameters=[params, {'archive': archive}],
             remappings=CLOCK_REMAP),
        Node(package='robot_state_publisher', executable='robot_state_publisher',
             name='robot_state_publisher', output='screen',
             parameters=[{'robot_description': robot.urdf(), 'use_sim_time': True}],
             remappings=TF_REMAPS + [
                 ('joint_states', 'hexapod/joint_states'),
                 ('robot_description', 'robot_state_publisher/robot_description')])
        if _installed('robot_state_publisher') else LogInfo(msg=_missing(
            'robot_state_publisher', "the legs' transforms are not published (the simulator's "
            'odom -> base_link is)')),
        Node(package='rviz2', executable='rviz2', name='rviz2', output='screen',
             arguments=['-d', os.path.join(share, 'rviz', 'sela.rviz')],
             parameters=[{'use_sim_time': True}], remappings=TF_REMAPS, condition=rviz)
        if _installed('rviz2') else LogInfo(msg=_missing('rviz2', 'no RViz'), condition=rviz),
    ]


def _installed(package):
    """Whether ``package`` is in the ament index (a missing one would end the launch after
    the nodes before it had started)."""
    try:
        get_package_prefix(package)
    except PackageNotFoundError:
        return False
    return True


def _missing(package, what):
    return (f"{package} is not installed (apt install ros-$ROS_DISTRO-"
            f"{package.replace('_', '-')}): {what}; the rest of the stack runs")
