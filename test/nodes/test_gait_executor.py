"""The gait executor's bookkeeping of a running gait, without ROS."""
from sela_ros.nodes import conversions as conv
from sela_ros.nodes.gait_executor_node import RunningGait


def _gait(use_imu):
    return RunningGait(7, start=(0.0, 0.0, 0.0), start_stamp=0.0, end=3.0, sent=0.0,
                       standing_start=False, use_imu=use_imu)


def test_a_gait_whose_end_is_not_seen_says_which_topic_did_not_show_it():
    odom = conv.odometry_msg((0.3, 0.0, 0.0), stamp=3.2)
    gait = _gait(use_imu=True)
    assert gait.unseen('odom', 'imu').endswith('(3.00 s) came on odom nor imu')
    gait.odometry(3.2, odom)  # odometry past the end, no IMU sample after it
    assert not gait.ended
    assert gait.unseen('odom', 'imu').endswith('came on imu')
    gait.attitude(3.25, odom.pose.pose.orientation)
    assert gait.ended
    without_imu = _gait(use_imu=False)
    assert without_imu.unseen('odom', '').endswith('came on odom')
