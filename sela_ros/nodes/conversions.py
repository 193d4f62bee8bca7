"""Every conversion between ROS messages and numpy arrays, with validation at the edge.

Nodes call these and nothing else touches message fields, so the wire formats below are
defined in one place (and documented in the README):

* ``/hexapod/behavior`` (``std_msgs/Float64MultiArray``): the 36 controller parameters in
  ``data``; the command id travels in ``layout.dim[0].label`` as ``behavior_id=<n>``. A bare
  36-value array (e.g. from ``ros2 topic pub``) is accepted and gets an id from the bridge.
* ``/hexapod/behavior_outcome`` (``std_msgs/Float64MultiArray``): a flat record whose field
  names are listed, in order, in ``layout.dim[0].label``; ``data[0]`` is the id of the command
  it answers, so each command pairs with exactly one outcome.
* ``/sela/prediction`` (``std_msgs/Float64MultiArray``): ``[behavior_id, dx, dy, dyaw,
  sigma]``, what the adapter expected the command to do and how unsure it was (sigma 0 while
  it trusts the intact map), for the damage detector.
* ``/damage_detector/verdict`` (``std_msgs/Float64MultiArray``): ``[behavior_id, fire,
  judged, error, mean_error, threshold]``, the detector's judgement of that command's
  outcome (fire 1: damage detected, adapt; mean_error -1 before anything was judged).

* the hardware face (``trajectory_msgs/JointTrajectory`` to a
  ``joint_trajectory_controller``; ``sensor_msgs/Imu`` and full 3-D ``nav_msgs/Odometry``
  from the robot): :func:`trajectory_to_msg`, :func:`trajectory_from_msg`, :func:`imu_msg`,
  :func:`odometry_3d_msg`, :func:`tilt`.

Occupancy grids (``nav_msgs/OccupancyGrid``) are in :mod:`sela_ros.nodes.grid_conversions`.
"""
import math
from dataclasses import dataclass, field

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PointStamped, PoseStamped, Quaternion
from nav_msgs.msg import Odometry, Path
from sensor_msgs.msg import Imu
from std_msgs.msg import Float64MultiArray, MultiArrayDimension
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from sela_ros.core import geometry
from sela_ros.core.mission.stepper_io import (
    GoalReceived,
    GoalsReceived,
    OutcomeReceived,
    PoseObserved,
    VerdictReceived,
)
from sela_ros.core.validation import finite_array

BEHAVIOR_ID_PREFIX = 'behavior_id='
OUTCOME_PREFIX = 'behavior_outcome:'
#: Most legs an outcome's duty factors may name.
MAX_LEGS = 64


def outcome_fields(legs=6, standing=True):
    """Fields of an outcome of a robot with ``legs`` feet (one duty factor each)."""
    return ('behavior_id', 'dx', 'dy', 'dyaw', 'start_x', 'start_y', 'start_yaw',
            'end_x', 'end_y', 'end_yaw', 'fallen', 'sim_time',
            *(f'duty_{i}' for i in range(legs))) + (('standing_start',) if standing else ())


#: The hexapod's outcome (six duty factors); another robot's names its own number of them.
OUTCOME_FIELDS = outcome_fields()
OUTCOME_LABEL = OUTCOME_PREFIX + ','.join(OUTCOME_FIELDS)
#: The outcome without ``standing_start`` (a driver that cannot tell) is read too.
OUTCOME_LABEL_WITHOUT_STANDING = OUTCOME_PREFIX + ','.join(OUTCOME_FIELDS[:-1])
PREDICTION_LABEL = 'prediction:behavior_id,dx,dy,dyaw,sigma'
VERDICT_LABEL = 'verdict:behavior_id,fire,judged,error,mean_error,threshold'


class MessageError(ValueError):
    """A message that cannot be used: says what was wrong and what was expected."""


@dataclass
class BehaviorOutcome:
    """What one executed behaviour did (the sim_bridge's answer to one command)."""

    behavior_id: int
    generic_reward: np.ndarray  # (dx, dy, dyaw) in the robot frame at the start
    start_pose: np.ndarray  # observed (x, y, yaw) in odom before the gait
    end_pose: np.ndarray  # observed (x, y, yaw) in odom after the gait
    fallen: bool = False
    sim_time: float = 0.0
    duty_factors: np.ndarray = field(default_factory=lambda: np.zeros(6))
    # The gait started from the robot standing still, settled (spawned, reset or righted):
    # how the archive's gaits were evaluated. None: the sender did not say.
    standing_start: bool | None = None


# --- small helpers -------------------------------------------------------------------------


def yaw_to_quaternion(yaw):
    x, y, z, w = geometry.yaw_to_quaternion(yaw)
    return Quaternion(x=x, y=y, z=z, w=w)


def quaternion_to_yaw(q):
    return geometry.quaternion_to_yaw(q.x, q.y, q.z, q.w)


def _unit_quaternion(q, name):
    """``(x, y, z, w)`` of a quaternion message, of norm 1 (one that is not is scaled to
    it); raises MessageError for a non-finite or zero one."""
    x, y, z, w = _finite_array([q.x, q.y, q.z, q.w], name, 4, labels=('x', 'y', 'z', 'w'))
    norm2 = x * x + y * y + z * z + w * w
    if norm2 < 1e-12:
        raise MessageError(f'{name}: the quaternion is zero (no orientation given)')
    if abs(norm2 - 1.0) > 1e-9:
        x, y, z, w = (v / math.sqrt(norm2) for v in (x, y, z, w))
    return x, y, z, w


def time_to_msg(seconds):
    seconds = float(seconds)
    sec = int(math.floor(seconds))
    nanosec = int(round((seconds - sec) * 1e9))
    if nanosec >= 1_000_000_000:
        sec, nanosec = sec + 1, nanosec - 1_000_000_000
    return Time(sec=sec, nanosec=nanosec)


def time_from_msg(stamp):
    return stamp.sec + stamp.nanosec * 1e-9


def _finite_array(values, name, length=None, labels=None):
    return finite_array(values, name, length, error=MessageError, labels=labels)


#: The names of a pose's x and y in a message that carries a geometry_msgs/Pose.
POSITION_XY = ('position.x', 'position.y')


# --- behaviour commands --------------------------------------------------------------------


def validate_behavior_params(params, n_params=None):
    """Return the parameters as a float array, or raise MessageError saying why not.

    ``n_params``: the robot's number of gait parameters (None: any non-empty length)."""
    array = _finite_array(params, 'behavior', n_params)
    if not array.size:
        raise MessageError('behavior: no parameters; expected the gait\'s parameters, each '
                           'in [0, 1]')
    out = (array < 0.0) | (array > 1.0)
    if out.any():
        i = int(np.flatnonzero(out)[0])
        raise MessageError(f'behavior: parameter {i} is {array[i]}; '
                           'expected every parameter in [0, 1]')
    return array


#: The largest command id: outcomes carry it in a Float64MultiArray, exact up to 2^53.
MAX_BEHAVIOR_ID = 2 ** 53
MAX_ID_DIGITS = len(str(MAX_BEHAVIOR_ID))


def behavior_to_msg(params, behavior_id):
    params = validate_behavior_params(params)
    msg = Float64MultiArray()
    msg.layout.dim = [MultiArrayDimension(label=f'{BEHAVIOR_ID_PREFIX}{int(behavior_id)}',
                                          size=params.size, stride=params.size)]
    msg.data = params.tolist()
    return msg


def behavior_from_msg(msg, n_params=None):
    """Return ``(params, behavior_id)``; ``behavior_id`` is None when the sender gave none.

    ``n_params``: the robot's number of gait parameters (None: any non-empty length)."""
    params = validate_behavior_params(msg.data, n_params)
    behavior_id = None
    if msg.layout.dim:
        label = msg.layout.dim[0].label
        if label.startswith(BEHAVIOR_ID_PREFIX):
            text = label[len(BEHAVIOR_ID_PREFIX):]
            try:
                # Checked before the gait runs: its outcome must be able to carry the id.
                behavior_id = int(text) if len(text) <= MAX_ID_DIGITS else None
            except ValueError as exc:
                raise MessageError(f'behavior: id {text[:40]!r} in layout label is not an '
                                   f"integer; expected '{BEHAVIOR_ID_PREFIX}<n>'") from exc
            if behavior_id is None or behavior_id > MAX_BEHAVIOR_ID:
                raise MessageError(f'behavior: id {text[:40]}{"..." if len(text) > 40 else ""} '
                                   f'is larger than {MAX_BEHAVIOR_ID} (2^53), the largest an '
                                   'outcome carries exactly (as a float64)')
            if behavior_id < 0:
                raise MessageError(f'behavior: id {behavior_id} is negative')
    return params, behavior_id


# --- outcomes ------------------------------------------------------------------------------


def outcome_to_msg(outcome):
    values = [float(outcome.behavior_id), *np.asarray(outcome.generic_reward, float),
              *np.asarray(outcome.start_pose, float), *np.asarray(outcome.end_pose, float),
              1.0 if outcome.fallen else 0.0, float(outcome.sim_time),
              *np.asarray(outcome.duty_factors, float)]
    legs = np.asarray(outcome.duty_factors).size
    label = OUTCOME_PREFIX + ','.join(outcome_fields(legs, standing=False))
    if outcome.standing_start is not None:
        values.append(1.0 if outcome.standing_start else 0.0)
        label = OUTCOME_PREFIX + ','.join(outcome_fields(legs))
    msg = Float64MultiArray()
    msg.layout.dim = [MultiArrayDimension(label=label, size=len(values),
                                          stride=len(values))]
    msg.data = values
    return msg


def outcome_from_msg(msg):
    label = msg.layout.dim[0].label if msg.layout.dim else '(no layout)'
    fields = label.removeprefix(OUTCOME_PREFIX).split(',')
    standing = fields[-1] == 'standing_start'
    legs = sum(f.startswith('duty_') for f in fields[:MAX_LEGS + 20])
    if not 0 < legs <= MAX_LEGS or label != OUTCOME_PREFIX + ','.join(
            outcome_fields(legs, standing)):
        raise MessageError(f'behavior_outcome: layout label {label!r} is not {OUTCOME_LABEL!r} '
                           '(or the same with another number of duty factors)')
    values = _finite_array(msg.data, 'behavior_outcome', len(outcome_fields(legs, standing)))
    behavior_id = values[0]
    if behavior_id < 0 or behavior_id != int(behavior_id):
        raise MessageError(f'behavior_outcome: id {behavior_id} is not a non-negative integer')
    return BehaviorOutcome(behavior_id=int(behavior_id), generic_reward=values[1:4].copy(),
                           start_pose=values[4:7].copy(), end_pose=values[7:10].copy(),
                           fallen=bool(values[10] >= 0.5), sim_time=float(values[11]),
                           duty_factors=values[12:12 + legs].copy(),
                           standing_start=bool(values[-1] >= 0.5) if standing else None)


def _labelled(label, values):
    msg = Float64MultiArray()
    msg.layout.dim = [MultiArrayDimension(label=label, size=len(values), stride=len(values))]
    msg.data = [float(v) for v in values]
    return msg


def _unlabelled(msg, label, name):
    """The values of a record labelled ``label``; the first one is a command id."""
    if not msg.layout.dim or msg.layout.dim[0].label != label:
        raise MessageError(f'{name}: layout label is not {label!r}')
    values = _finite_array(msg.data, name, label.count(',') + 1)
    if values[0] < 0 or values[0] != int(values[0]):
        raise MessageError(f'{name}: id {values[0]} is not a non-negative integer')
    return values


def outcome_event(msg):
    """The mission stepper's event for an outcome message."""
    o = outcome_from_msg(msg)
    return OutcomeReceived(o.behavior_id, tuple(o.generic_reward), tuple(o.end_pose),
                           o.fallen, o.sim_time, standing_start=o.standing_start,
                           start_pose=tuple(o.start_pose),
                           duty_factors=tuple(map(float, o.duty_factors)))


def verdict_event(msg):
    return VerdictReceived(*verdict_from_msg(msg))


def odometry_event(msg):
    return PoseObserved(tuple(pose_from_odometry(msg)), time_from_msg(msg.header.stamp))


def goal_event(msg, frames='odom'):
    return GoalReceived(tuple(goal_from_pose_stamped(msg, frames)))


def goals_event(msg, frames='odom'):
    return GoalsReceived(tuple(goals_from_path(msg, frames)))


def prediction_to_msg(behavior_id, generic_reward, sigma=0.0):
    gr = _finite_array(generic_reward, 'prediction', 3)
    sigma = _finite_array([sigma], 'prediction sigma', 1)[0]
    return _labelled(PREDICTION_LABEL, [behavior_id, *gr.tolist(), sigma])


def prediction_from_msg(msg):
    values = _unlabelled(msg, PREDICTION_LABEL, 'prediction')
    if values[4] < 0:
        raise MessageError(f'prediction: sigma {values[4]} is negative')
    return int(values[0]), values[1:4].copy(), float(values[4])


def verdict_to_msg(behavior_id, verdict, threshold):
    """The damage detector's judgement (a core ``Verdict``) of the outcome of a command."""
    return _labelled(VERDICT_LABEL, [behavior_id, verdict.fire, verdict.judged,
                                     verdict.error, _nan_as(verdict.mean_error, -1.0),
                                     threshold])


def verdict_from_msg(msg):
    """Return ``(behavior_id, fire, error, threshold)``."""
    values = _unlabelled(msg, VERDICT_LABEL, 'verdict')
    return int(values[0]), bool(values[1] >= 0.5), float(values[3]), float(values[5])


def _nan_as(value, default):
    return default if math.isnan(value) else value


# --- poses, goals, paths -------------------------------------------------------------------


def odometry_msg(pose, twist=(0.0, 0.0, 0.0), stamp=0.0, frame_id='odom',
                 child_frame_id='base_link', z=0.0):
    msg = Odometry()
    msg.header.stamp = time_to_msg(stamp)
    msg.header.frame_id = frame_id
    msg.child_frame_id = child_frame_id
    msg.pose.pose.position.x = float(pose[0])
    msg.pose.pose.position.y = float(pose[1])
    msg.pose.pose.position.z = float(z)
    msg.pose.pose.orientation = yaw_to_quaternion(float(pose[2]))
    msg.twist.twist.linear.x = float(twist[0])
    msg.twist.twist.linear.y = float(twist[1])
    msg.twist.twist.angular.z = float(twist[2])
    return msg


#: m from the odom origin beyond which an odometry pose is refused: ten times as far as any
#: map may reach (its corner within 100 km, a side of 1 km at most: core.planning.maps).
ODOMETRY_LIMIT = 1e6


def pose_from_odometry(msg):
    p = msg.pose.pose
    yaw = geometry.quaternion_to_yaw(*_unit_quaternion(p.orientation,
                                                        'odometry pose.pose.orientation'))
    pose = np.array([p.position.x, p.position.y, yaw])
    pose = _finite_array(pose, 'odometry pose', 3,
                         labels=('pose.pose.position.x', 'pose.pose.position.y',
                                 'the yaw of pose.pose.orientation'))
    for i in np.flatnonzero(np.abs(pose[:2]) > ODOMETRY_LIMIT)[:1]:
        raise MessageError(f"odometry pose: {'xy'[i]} {pose[i]:g} m is beyond "
                           f'{ODOMETRY_LIMIT:g} m of the odom origin')
    return pose


def goal_frames(frame_id, map_frame=''):
    """The frames a goal may be given in: ``frame_id`` (the odometry's), then ``map_frame``
    taken as the same frame (no localisation here: the odometry is the map), unless ''."""
    return (frame_id,) + ((map_frame,) if map_frame and map_frame != frame_id else ())


def _frames(frames):
    return (frames,) if isinstance(frames, str) else tuple(frames)


def frame_accepted(frame, frames):
    """Whether a header's ``frame`` ('' = the planning frame) is one of ``frames``."""
    return frame == '' or frame in _frames(frames)


def send_in(frames):
    """How a refusal says where to send a pose: ``'odom' (or 'map', taken as 'odom')``."""
    first, *others = _frames(frames)
    taken = ''.join(f" (or '{f}', taken as '{first}')" for f in others)
    return f"'{first}'{taken}"


def goal_from_pose_stamped(msg, frames='odom', name='goal_pose'):
    """Return the goal (x, y) of a PoseStamped; its frame must be one of ``frames`` (a name
    or :func:`goal_frames`). ``name``: what a refusal calls it (a topic, a request's field)."""
    frame = msg.header.frame_id
    if not frame_accepted(frame, frames):
        raise MessageError(f"{name}: frame '{frame}' is not supported; "
                           f"send it in {send_in(frames)}")
    return _finite_array([msg.pose.position.x, msg.pose.position.y], name, 2,
                         labels=POSITION_XY)


def goals_from_path(msg, frames='odom'):
    """The goals ``[(x, y), ...]`` of a mission sent as a nav_msgs/Path, in order.

    Each pose's frame (or, when empty, the path's) must be one of ``frames``.
    """
    if not msg.poses:
        raise MessageError('goal_path: the path has no poses (expected the goals in order)')
    goals = []
    for i, pose in enumerate(msg.poses):
        frame = pose.header.frame_id or msg.header.frame_id
        if not frame_accepted(frame, frames):
            raise MessageError(f"goal_path: pose {i} is in frame '{frame}'; send the goals "
                               f"in {send_in(frames)}")
        goals.append(tuple(_finite_array([pose.pose.position.x, pose.pose.position.y],
                                         f'goal_path pose {i}', 2, labels=POSITION_XY)))
    return goals


def pose_stamped(xy, yaw=0.0, stamp=0.0, frame_id='odom'):
    msg = PoseStamped()
    msg.header.stamp = time_to_msg(stamp) if not isinstance(stamp, Time) else stamp
    msg.header.frame_id = frame_id
    msg.pose.position.x = float(xy[0])
    msg.pose.position.y = float(xy[1])
    msg.pose.orientation = yaw_to_quaternion(float(yaw))
    return msg


def point_stamped(xy, stamp=0.0, frame_id='odom'):
    msg = PointStamped()
    msg.header.stamp = time_to_msg(stamp) if not isinstance(stamp, Time) else stamp
    msg.header.frame_id = frame_id
    msg.point.x = float(xy[0])
    msg.point.y = float(xy[1])
    return msg


def path_to_msg(path_xy, stamp=0.0, frame_id='odom'):
    msg = Path()
    msg.header.stamp = time_to_msg(stamp) if not isinstance(stamp, Time) else stamp
    msg.header.frame_id = frame_id
    path_xy = np.asarray(path_xy, dtype=float).reshape(-1, 2)
    for i, xy in enumerate(path_xy):
        nxt = path_xy[min(i + 1, len(path_xy) - 1)]
        prev = path_xy[max(i - 1, 0)]
        heading = math.atan2(nxt[1] - prev[1], nxt[0] - prev[0]) if len(path_xy) > 1 else 0.0
        msg.poses.append(pose_stamped(xy, heading, msg.header.stamp, frame_id))
    return msg


def path_from_msg(msg):
    xy = [[p.pose.position.x, p.pose.position.y] for p in msg.poses]
    return _finite_array(xy, 'path').reshape(-1, 2)


# --- the hardware face ---------------------------------------------------------------------


def duration_to_msg(seconds):
    from builtin_interfaces.msg import Duration

    stamp = time_to_msg(seconds)
    return Duration(sec=stamp.sec, nanosec=stamp.nanosec)


def trajectory_to_msg(names, times, positions):
    """A JointTrajectory that starts on receipt (stamp 0, as a joint_trajectory_controller
    reads it): one point per row of ``positions`` at ``times`` s from the start."""
    msg = JointTrajectory()
    msg.joint_names = [str(n) for n in names]
    for t, row in zip(np.asarray(times, float), np.asarray(positions, float)):
        msg.points.append(JointTrajectoryPoint(positions=row.tolist(),
                                               time_from_start=duration_to_msg(t)))
    return msg


def trajectory_from_msg(msg):
    """``(names, times, positions)`` of a JointTrajectory; each point needs one position per
    joint (velocities, accelerations and efforts are not used). Raises MessageError."""
    names = list(msg.joint_names)
    if not names:
        raise MessageError('joint_trajectory: no joint names')
    if not msg.points:
        raise MessageError('joint_trajectory: no points')
    rows = []
    for i, point in enumerate(msg.points):
        if len(point.positions) != len(names):
            raise MessageError(f'joint_trajectory: point {i} has {len(point.positions)} '
                               f'positions for {len(names)} joints')
        rows.append(point.positions)
    times = [time_from_msg(point.time_from_start) for point in msg.points]
    return (names, _finite_array(times, 'joint_trajectory times'),
            _finite_array(rows, 'joint_trajectory positions').reshape(len(times), len(names)))


def _quaternion(q):
    return Quaternion(x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3]))


def odometry_3d_msg(xyz, quaternion, stamp, frame_id='odom', child_frame_id='base_link'):
    """Odometry with the body's full pose (height, roll and pitch too): a motion capture's."""
    msg = Odometry()
    msg.header.stamp = time_to_msg(stamp)
    msg.header.frame_id = frame_id
    msg.child_frame_id = child_frame_id
    position = msg.pose.pose.position
    position.x, position.y, position.z = (float(v) for v in xyz)
    msg.pose.pose.orientation = _quaternion(quaternion)
    return msg


def imu_msg(quaternion, stamp, frame_id='base_link'):
    """An Imu with the body's orientation only (no rates or accelerations: covariance -1
    in their first element, as REP-145 says of a field that is not given)."""
    msg = Imu()
    msg.header.stamp = time_to_msg(stamp)
    msg.header.frame_id = frame_id
    msg.orientation = _quaternion(quaternion)
    msg.angular_velocity_covariance[0] = -1.0
    msg.linear_acceleration_covariance[0] = -1.0
    return msg


def tilt(q):
    """The angle (rad) between the body's z axis and the world's, from an orientation
    quaternion message; raises MessageError for a non-finite or zero quaternion."""
    x, y, z, w = _finite_array([q.x, q.y, q.z, q.w], 'orientation', 4)
    norm2 = x * x + y * y + z * z + w * w
    if norm2 < 1e-12:
        raise MessageError('orientation: the quaternion is zero (no orientation given)')
    up_z = 1.0 - 2.0 * (x * x + y * y) / norm2
    return math.acos(max(-1.0, min(1.0, up_z)))


# --- diagnostics ---------------------------------------------------------------------------


def diagnostic_status(level, name, message, values=None, hardware_id='sela_ros'):
    """A DiagnosticStatus; ``values`` is a mapping whose values are shown with ``str``."""
    status = DiagnosticStatus(level=level, name=name, message=message, hardware_id=hardware_id)
    status.values = [KeyValue(key=str(k), value=str(v)) for k, v in (values or {}).items()]
    return status


def diagnostic_level(level):
    """DiagnosticStatus's level for a core ``Level`` (OK 0, WARN 1, ERROR 2: the same)."""
    return bytes([int(level)])


def diagnostic_array(statuses, stamp):
    """A DiagnosticArray of one status or a list of them; ``stamp`` in seconds or a Time."""
    msg = DiagnosticArray()
    msg.header.stamp = stamp if isinstance(stamp, Time) else time_to_msg(stamp)
    msg.status = list(statuses) if isinstance(statuses, (list, tuple)) else [statuses]
    return msg


def status_values(status):
    """The key/value pairs of a DiagnosticStatus as a dict."""
    return {kv.key: kv.value for kv in status.values}
