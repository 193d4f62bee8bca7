"""Property-based tests of every message <-> array conversion (sela_ros.nodes.conversions)."""
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from std_msgs.msg import Float64MultiArray, MultiArrayDimension

from sela_ros.core.detection import Verdict
from sela_ros.nodes import conversions as conv
from sela_ros.nodes import grid_conversions as grids

unit = st.floats(0.0, 1.0, allow_nan=False)
finite = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False)
angle = st.floats(-math.pi + 1e-9, math.pi, allow_nan=False)
settings.register_profile('sela', deadline=None, max_examples=60)
settings.load_profile('sela')


@given(st.lists(unit, min_size=36, max_size=36), st.integers(0, 2**40))
def test_behavior_round_trip(params, behavior_id):
    out, got_id = conv.behavior_from_msg(conv.behavior_to_msg(params, behavior_id))
    assert got_id == behavior_id
    assert np.array_equal(out, np.array(params))


@given(st.lists(unit, min_size=0, max_size=60).filter(lambda v: len(v) != 36))
def test_behavior_of_wrong_length_is_rejected(params):
    msg = Float64MultiArray(data=params)
    with pytest.raises(conv.MessageError, match='expected 36 values'):
        conv.behavior_from_msg(msg, 36)


@given(st.lists(unit, min_size=1, max_size=20), st.integers(0, 2**40))
def test_behavior_of_another_robot_round_trips_with_its_own_length(params, behavior_id):
    out, got_id = conv.behavior_from_msg(conv.behavior_to_msg(params, behavior_id),
                                         len(params))
    assert got_id == behavior_id and np.array_equal(out, np.array(params))
    with pytest.raises(conv.MessageError, match=f'expected {len(params) + 1} values'):
        conv.behavior_from_msg(conv.behavior_to_msg(params, behavior_id), len(params) + 1)


def test_behavior_without_parameters_is_rejected():
    with pytest.raises(conv.MessageError, match='no parameters'):
        conv.behavior_from_msg(Float64MultiArray(data=[]))


@given(st.integers(1, 12), st.booleans())
def test_outcome_of_a_robot_with_other_legs_round_trips(legs, standing):
    outcome = conv.BehaviorOutcome(behavior_id=7, generic_reward=np.array([0.1, -0.2, 0.3]),
                                   start_pose=np.zeros(3), end_pose=np.ones(3),
                                   duty_factors=np.linspace(0, 1, legs), standing_start=standing)
    back = conv.outcome_from_msg(conv.outcome_to_msg(outcome))
    assert np.array_equal(back.duty_factors, outcome.duty_factors)
    assert back.standing_start is standing and back.behavior_id == 7


@given(st.integers(0, 35), st.sampled_from([math.nan, math.inf, -math.inf, -0.1, 1.5]))
def test_behavior_with_bad_value_is_rejected(i, bad):
    params = [0.5] * 36
    params[i] = bad
    with pytest.raises(conv.MessageError, match=f'(value|parameter) {i}'):
        conv.behavior_from_msg(Float64MultiArray(data=params))


def test_behavior_without_id_and_with_malformed_id():
    msg = Float64MultiArray(data=[0.5] * 36)
    assert conv.behavior_from_msg(msg)[1] is None
    msg.layout.dim = [MultiArrayDimension(label='behavior_id=abc', size=36, stride=36)]
    with pytest.raises(conv.MessageError, match='not an integer'):
        conv.behavior_from_msg(msg)


@pytest.mark.parametrize('text', ['9' * 400, str(2**53 + 1), '1' * 5000])
def test_a_command_id_no_outcome_can_carry_is_refused_before_the_gait_runs(text):
    msg = Float64MultiArray(data=[0.5] * 36)
    msg.layout.dim = [MultiArrayDimension(label=f'behavior_id={text}', size=36, stride=36)]
    with pytest.raises(conv.MessageError, match=r'larger than 9007199254740992 \(2\^53\)'):
        conv.behavior_from_msg(msg)


def test_the_largest_command_id_comes_back_in_its_outcome():
    params, behavior_id = conv.behavior_from_msg(conv.behavior_to_msg([0.5] * 36, 2**53))
    outcome = conv.BehaviorOutcome(behavior_id=behavior_id, generic_reward=np.zeros(3),
                                   start_pose=np.zeros(3), end_pose=np.zeros(3), fallen=False,
                                   sim_time=3.0, duty_factors=np.zeros(6))
    assert conv.outcome_from_msg(conv.outcome_to_msg(outcome)).behavior_id == 2**53


@given(st.integers(0, 2**40), st.lists(finite, min_size=3, max_size=3),
       st.lists(finite, min_size=6, max_size=6), st.booleans(), st.floats(0, 1e6),
       st.lists(unit, min_size=6, max_size=6), st.sampled_from([None, False, True]))
def test_outcome_round_trip(behavior_id, gr, poses, fallen, sim_time, duty, standing):
    outcome = conv.BehaviorOutcome(behavior_id, np.array(gr), np.array(poses[:3]),
                                   np.array(poses[3:]), fallen, sim_time, np.array(duty),
                                   standing_start=standing)
    msg = conv.outcome_to_msg(outcome)
    back = conv.outcome_from_msg(msg)
    assert back.behavior_id == behavior_id and back.fallen == fallen
    assert back.sim_time == sim_time and back.standing_start is standing
    # A sender that cannot tell a standing start leaves the field out of data and label.
    assert len(msg.data) == 18 + (standing is not None)
    assert msg.layout.dim[0].label.endswith('duty_5,standing_start') == (standing is not None)
    for a, b in ((back.generic_reward, gr), (back.start_pose, poses[:3]),
                 (back.end_pose, poses[3:]), (back.duty_factors, duty)):
        assert np.array_equal(a, np.array(b))


def test_outcome_malformed():
    good = conv.outcome_to_msg(conv.BehaviorOutcome(3, np.zeros(3), np.zeros(3), np.zeros(3)))
    short = Float64MultiArray(layout=good.layout, data=list(good.data)[:-1])
    with pytest.raises(conv.MessageError, match='expected 18 values'):
        conv.outcome_from_msg(short)
    standing = conv.outcome_to_msg(conv.BehaviorOutcome(3, np.zeros(3), np.zeros(3),
                                                        np.zeros(3), standing_start=True))
    with pytest.raises(conv.MessageError, match='expected 19 values'):
        conv.outcome_from_msg(Float64MultiArray(layout=standing.layout, data=list(good.data)))
    with pytest.raises(conv.MessageError, match='layout label'):
        conv.outcome_from_msg(Float64MultiArray(data=list(good.data)))
    nan = Float64MultiArray(layout=good.layout, data=[3.0] + [math.nan] * 17)
    with pytest.raises(conv.MessageError, match='finite'):
        conv.outcome_from_msg(nan)


@given(st.integers(0, 2**40), st.lists(finite, min_size=3, max_size=3), st.floats(0, 10))
def test_prediction_round_trip(behavior_id, gr, sigma):
    got_id, got_gr, got_sigma = conv.prediction_from_msg(
        conv.prediction_to_msg(behavior_id, gr, sigma))
    assert got_id == behavior_id and got_sigma == sigma and np.array_equal(got_gr, gr)


@given(finite, finite, angle)
def test_odometry_round_trip(x, y, yaw):
    msg = conv.odometry_msg([x, y, yaw], stamp=12.5)
    if max(abs(x), abs(y)) > conv.ODOMETRY_LIMIT:
        with pytest.raises(conv.MessageError, match='beyond'):
            conv.pose_from_odometry(msg)
        return
    pose = conv.pose_from_odometry(msg)
    assert pose[0] == x and pose[1] == y
    assert abs(math.remainder(pose[2] - yaw, 2 * math.pi)) < 1e-9


def test_odometry_with_a_zero_or_nan_quaternion_is_refused_and_another_is_normalised():
    msg = conv.odometry_msg([1.0, 2.0, 0.0])
    o = msg.pose.pose.orientation
    o.x = o.y = o.z = o.w = 0.0  # no orientation given
    with pytest.raises(conv.MessageError, match='orientation: the quaternion is zero'):
        conv.pose_from_odometry(msg)
    o.w = math.nan
    with pytest.raises(conv.MessageError, match='orientation.*w is nan'):
        conv.pose_from_odometry(msg)
    # A rotation of 90 deg about z, given at twice its norm: the same heading.
    o.z, o.w = 2.0, 2.0
    assert conv.pose_from_odometry(msg)[2] == pytest.approx(math.pi / 2)
    # A unit quaternion is read as it is, to the bit.
    unit = conv.odometry_msg([1.0, 2.0, 0.7])
    q = unit.pose.pose.orientation
    assert conv.pose_from_odometry(unit)[2] == conv.quaternion_to_yaw(q)


def test_odometry_beyond_any_map_is_refused_with_the_reason():
    with pytest.raises(conv.MessageError, match=r'odometry pose: y 1e\+300 m is beyond'):
        conv.pose_from_odometry(conv.odometry_msg([0.0, 1e300, 0.0]))
    assert conv.pose_from_odometry(conv.odometry_msg([-9.9e5, 9.9e5, 0.0]))[0] == -9.9e5


@given(finite, finite)
def test_goal_round_trip_and_frame(x, y):
    assert np.array_equal(conv.goal_from_pose_stamped(conv.pose_stamped((x, y))), [x, y])
    with pytest.raises(conv.MessageError, match="frame 'map'"):
        conv.goal_from_pose_stamped(conv.pose_stamped((x, y), frame_id='map'))
    # The map frame taken as odom: accepted there, and named in the refusal of others.
    frames = conv.goal_frames('odom', 'map')
    assert np.array_equal(conv.goal_from_pose_stamped(
        conv.pose_stamped((x, y), frame_id='map'), frames), [x, y])
    with pytest.raises(conv.MessageError, match="send it in 'odom' \\(or 'map', taken as"):
        conv.goal_from_pose_stamped(conv.pose_stamped((x, y), frame_id='world'), frames)
    assert conv.goal_frames('odom', '') == conv.goal_frames('odom', 'odom') == ('odom',)


def test_goal_with_nan_is_rejected():
    with pytest.raises(conv.MessageError, match='finite'):
        conv.goal_from_pose_stamped(conv.pose_stamped((math.nan, 0.0)))


@given(st.lists(st.tuples(finite, finite), min_size=1, max_size=20))
def test_path_round_trip(points):
    assert np.array_equal(conv.path_from_msg(conv.path_to_msg(points)), np.array(points))


@given(st.floats(0.0, 1e5, allow_nan=False))
def test_time_round_trip(seconds):
    stamp = conv.time_to_msg(seconds)
    assert 0 <= stamp.nanosec < 1_000_000_000
    assert abs(conv.time_from_msg(stamp) - seconds) < 1e-6


@given(st.integers(1, 12), st.integers(1, 12), st.data())
def test_occupancy_grid_round_trip(h, w, data):
    occ = np.array(data.draw(st.lists(st.booleans(), min_size=h * w, max_size=h * w)))
    occ = occ.reshape(h, w)
    back, res, origin = grids.occupancy_grid_from_msg(
        grids.occupancy_grid_to_msg(occ, 0.05, (-1.0, 2.0)))
    assert np.array_equal(back, occ) and res == 0.05 and np.array_equal(origin, [-1.0, 2.0])


@pytest.mark.parametrize('resolution, origin, reason', [
    (1e-38, (0.0, 0.0), r'resolution 1e-38 m is out of \[0.001, 1\] m'),
    (3e38, (0.0, 0.0), r'resolution 3e\+38 m is out of \[0.001, 1\] m'),
    (0.05, (1e300, 0.0), r'origin x 1e\+300 m is out of'),
    (0.05, (0.0, -2e5), 'origin y -200000 m is out of'),
])
def test_a_grid_out_of_the_map_parameters_ranges_is_refused_with_the_reason(resolution, origin,
                                                                            reason):
    msg = grids.occupancy_grid_to_msg(np.zeros((4, 4), bool), 0.05, (0.0, 0.0))
    msg.info.resolution = resolution
    msg.info.origin.position.x, msg.info.origin.position.y = origin
    with pytest.raises(conv.MessageError, match=reason):
        grids.occupancy_grid_from_msg(msg)


@given(st.integers(0, 2**40), st.booleans(), st.floats(0, 10), st.floats(0, 1))
def test_verdict_round_trip(behavior_id, fire, error, threshold):
    verdict = Verdict(error=error, mean_error=float('nan'), fire=fire, judged=True)
    got = conv.verdict_from_msg(conv.verdict_to_msg(behavior_id, verdict, threshold))
    assert got == (behavior_id, fire, error, threshold)
    with pytest.raises(conv.MessageError, match='layout label'):
        conv.verdict_from_msg(conv.prediction_to_msg(behavior_id, [0, 0, 0]))


def test_goals_from_a_path_in_order_and_bad_paths_refused():
    path = conv.path_to_msg([[1.0, 0.0], [1.0, 1.0], [0.0, 1.0]], frame_id='odom')
    assert conv.goals_from_path(path) == [(1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]
    with pytest.raises(conv.MessageError, match='no poses'):
        conv.goals_from_path(conv.path_to_msg(np.zeros((0, 2))))
    other = conv.path_to_msg([[1.0, 0.0]], frame_id='map')
    with pytest.raises(conv.MessageError, match="pose 0 is in frame 'map'"):
        conv.goals_from_path(other)
    assert conv.goals_from_path(other, conv.goal_frames('odom', 'map')) == [(1.0, 0.0)]
    bad = conv.path_to_msg([[1.0, 0.0], [float('nan'), 1.0]])
    with pytest.raises(conv.MessageError, match='pose 1'):
        conv.goals_from_path(bad)
