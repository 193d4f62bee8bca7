"""The gait executor's bookkeeping of a running gait, without ROS."""
from sela_ros.nodes import conversions as conv
from sela_ros.nodes.gait_executor_node import CLOCK_WINDOW, ClockCheck, RunningGait


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


def test_stamps_that_go_back_once_are_a_reset_and_again_two_clocks():
    clocks = ClockCheck('odom')
    for wall, stamp in enumerate((100.0, 100.1, 100.2)):
        assert clocks.seen('odom', float(wall), stamp) is None
    assert clocks.problem(3.0, 3.0) is None
    assert abs(clocks.seen('odom', 3.0, 0.5) - 99.7) < 1e-9  # a simulator restarted
    assert clocks.problem(3.5, 3.0) is None  # once: the next gait starts on the new clock
    assert clocks.seen('odom', 4.0, 0.6) is None
    assert clocks.seen('odom', 4.5, 1.7e9) is None  # another publisher, on the wall clock
    assert clocks.seen('odom', 4.6, 0.7) is not None
    assert 'went back twice' in clocks.problem(5.0, 3.0)
    assert clocks.problem(3.0 + CLOCK_WINDOW + 0.1, 3.0) is None  # the second clock gone


def test_odometry_and_imu_more_than_a_gait_apart_are_two_clocks():
    clocks = ClockCheck('odom', 'imu')
    clocks.seen('odom', 0.0, 100.0)
    assert clocks.problem(0.0, 3.0) is None  # no IMU yet: the staleness check says it
    clocks.seen('imu', 0.0, 102.0)  # a sensor's latency: within a gait
    assert clocks.problem(0.1, 3.0) is None
    assert clocks.seen('imu', 0.2, 1.7e9) is None  # forward: not a jump back, yet apart
    assert 'apart, more than a gait' in clocks.problem(0.3, 3.0)
