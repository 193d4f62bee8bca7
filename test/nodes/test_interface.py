"""The graph's names, written once: relative in code, DESIGN.md's in the root namespace."""
from sela_ros.nodes import interface as ifc

DESIGN = {  # DESIGN.md's table (plus what the package adds), as seen in the root namespace
    '/clock', '/hexapod/odom', '/hexapod/behavior', '/hexapod/behavior_outcome', '/goal_pose',
    '/planner/path', '/planner/make_plan', '/sela/target', '/sela/reward', '/diagnostics',
    '/sela_adapter/adapt', '/sim_bridge/reset', '/tf', '/robot_description',
    '/navigate_to_pose', '/follow_waypoints',
}
ADDED = {'/hexapod/joint_states', '/planner/map', '/sela/prediction',
         '/damage_detector/verdict', '/sela_adapter/clear', '/sela/markers',
         '/map', '/goal_path',  # map_server's map for the planner; a mission of many goals
         '/sim_bridge/alive', '/planner/alive', '/damage_detector/alive',
         '/sela_adapter/alive',  # liveness from the middleware (QoS liveliness)
         '/navigate_through_poses', '/compute_path_to_pose',  # nav2's, as nav2 names them
         '/compute_path_through_poses'}


def test_root_names_are_the_design_ones():
    names = ({t.root_name for t in ifc.TOPICS} | {s.root_name for s in ifc.SERVICES}
             | {a.root_name for a in ifc.ACTIONS + ifc.PLANNER_ACTIONS})
    assert names == DESIGN | ADDED


def test_names_are_relative_so_a_namespace_moves_the_stack():
    for topic in ifc.TOPICS:
        assert topic is ifc.CLOCK or not topic.name.startswith('/'), topic
    for service in ifc.SERVICES:
        assert not service.name.startswith('/') and service.own_name.startswith('~/')
        assert service.name == f'{service.owner}/{service.own_name[2:]}'
    assert ifc.PATH.own_name == '~/path' and ifc.VERDICT.own_name == '~/verdict'
    assert ifc.GOAL.own_name == 'goal_pose'  # a shared topic: the same name for everyone
    for action in ifc.ACTIONS:  # nav2's names, in the adapter's namespace (not ~/)
        assert action.name in ('navigate_to_pose', 'navigate_through_poses',
                               'follow_waypoints')
        assert action.owner == ifc.SELA_ADAPTER
    assert [(a.name, a.owner) for a in ifc.PLANNER_ACTIONS] == [
        ('compute_path_to_pose', ifc.PLANNER), ('compute_path_through_poses', ifc.PLANNER)]


def test_the_actions_are_nav2s_types():
    from nav2_msgs.action import FollowWaypoints, NavigateToPose

    assert ifc.NAVIGATE_TO_POSE.type is NavigateToPose
    assert ifc.FOLLOW_WAYPOINTS.type is FollowWaypoints
    fields = NavigateToPose.Feedback.get_fields_and_field_types()
    assert fields == {'current_pose': 'geometry_msgs/PoseStamped',
                      'navigation_time': 'builtin_interfaces/Duration',
                      'estimated_time_remaining': 'builtin_interfaces/Duration',
                      'number_of_recoveries': 'int16', 'distance_remaining': 'float'}
    assert FollowWaypoints.Goal.get_fields_and_field_types() == {
        'number_of_loops': 'uint32', 'goal_index': 'uint32',
        'poses': 'sequence<geometry_msgs/PoseStamped>'}
    assert set(FollowWaypoints.Result.get_fields_and_field_types()) == {
        'missed_waypoints', 'error_code', 'error_msg'}


def test_the_added_actions_are_nav2_jazzys_types_field_for_field():
    """The type hash a ROS install checks is over the fields' names and types, in order."""
    from nav2_msgs.action import ComputePathThroughPoses, ComputePathToPose, NavigateThroughPoses

    assert ifc.NAVIGATE_THROUGH_POSES.type is NavigateThroughPoses
    assert ifc.COMPUTE_PATH_TO_POSE.type is ComputePathToPose
    assert list(NavigateThroughPoses.Goal.get_fields_and_field_types().items()) == [
        ('poses', 'sequence<geometry_msgs/PoseStamped>'), ('behavior_tree', 'string')]
    assert list(NavigateThroughPoses.Result.get_fields_and_field_types().items()) == [
        ('error_code', 'uint16'), ('error_msg', 'string')]
    assert list(NavigateThroughPoses.Feedback.get_fields_and_field_types().items()) == [
        ('current_pose', 'geometry_msgs/PoseStamped'),
        ('navigation_time', 'builtin_interfaces/Duration'),
        ('estimated_time_remaining', 'builtin_interfaces/Duration'),
        ('number_of_recoveries', 'int16'), ('distance_remaining', 'float'),
        ('number_of_poses_remaining', 'int16')]
    assert list(ComputePathToPose.Goal.get_fields_and_field_types().items()) == [
        ('goal', 'geometry_msgs/PoseStamped'), ('start', 'geometry_msgs/PoseStamped'),
        ('planner_id', 'string'), ('use_start', 'boolean')]
    assert list(ComputePathToPose.Result.get_fields_and_field_types().items()) == [
        ('path', 'nav_msgs/Path'), ('planning_time', 'builtin_interfaces/Duration'),
        ('error_code', 'uint16'), ('error_msg', 'string')]
    assert list(ComputePathThroughPoses.Goal.get_fields_and_field_types().items()) == [
        ('goals', 'sequence<geometry_msgs/PoseStamped>'),
        ('start', 'geometry_msgs/PoseStamped'), ('planner_id', 'string'),
        ('use_start', 'boolean')]
    assert ComputePathThroughPoses.Result.get_fields_and_field_types() \
        == ComputePathToPose.Result.get_fields_and_field_types()
    assert ComputePathThroughPoses.Result.NO_VIAPOINTS_GIVEN == 309
    assert (ComputePathToPose.Result.START_OUTSIDE_MAP, ComputePathToPose.Result.GOAL_OUTSIDE_MAP,
            ComputePathToPose.Result.GOAL_OCCUPIED, ComputePathToPose.Result.NO_VALID_PATH) \
        == (203, ifc.GOAL_OUTSIDE_MAP, ifc.GOAL_OCCUPIED, ifc.NO_VALID_PATH)


def test_what_a_decision_depends_on_is_reliable_and_kept_for_late_joiners():
    from rclpy.qos import QoSDurabilityPolicy, QoSReliabilityPolicy

    for topic in (ifc.OUTCOME, ifc.PREDICTION, ifc.VERDICT):
        assert topic.qos.reliability == QoSReliabilityPolicy.RELIABLE
        assert topic.qos.durability == QoSDurabilityPolicy.TRANSIENT_LOCAL
        assert topic.qos.depth >= 50
    # /goal_pose as RViz's 2D Goal Pose tool and nav2: reliable, volatile.
    assert ifc.GOAL.qos.reliability == QoSReliabilityPolicy.RELIABLE
    assert ifc.GOAL.qos.durability == QoSDurabilityPolicy.VOLATILE


def test_the_hardware_faces_names_are_relative_and_apart_from_the_stacks():
    names = {t.root_name for t in ifc.HARDWARE_TOPICS}
    assert names == {'/joint_trajectory_controller/joint_trajectory', '/hexapod/imu',
                     '/hexapod/odom_observed', '/gait_executor/alive'}
    assert not names & {t.root_name for t in ifc.TOPICS}  # there only on the hardware path
    assert all(not t.name.startswith('/') for t in ifc.HARDWARE_TOPICS)
    assert ifc.GAIT_EXECUTOR not in ifc.NODES and ifc.GAIT_EXECUTOR in ifc.ALIVE
    from rclpy.qos import QoSReliabilityPolicy

    # What a robot's sensors publish best effort is still heard.
    assert ifc.SENSOR_QOS.reliability == QoSReliabilityPolicy.BEST_EFFORT
