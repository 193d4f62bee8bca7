"""The ``gait_executor`` node: the adapter's gaits played on a robot under ros2_control.

It stands where the simulator's gait player stands: it takes each command on
``hexapod/behavior`` (the same message, the same id) and answers with exactly one
``hexapod/behavior_outcome`` carrying that id, so the adapter and the damage detector cannot
tell it from ``sim_bridge``. Between the two, the gait is a ``trajectory_msgs/JointTrajectory``
(the robot description's gait controller sampled at its own rate:
:func:`sim_bridge.trajectory.gait_trajectory`)
on a ``joint_trajectory_controller``'s topic, and the outcome comes from any
``nav_msgs/Odometry`` (motion capture, visual or leg odometry): the pose of the newest
message before the gait, and that of the first message stamped at or after the gait's end.
A fall is told from the body's attitude at the end of the gait (``sensor_msgs/Imu``, or the
odometry's orientation when ``imu_topic`` is ''), and from its height if ``fall.min_height``
is set.

Times: the odometry's stamps say when the gait has ended (the first pose stamped at least
``gait_duration + settle_time`` after the one the gait started from), in whatever clock the
robot stamps them (a simulator's /clock or the wall); the timeouts are wall time.

Refusals (an ERROR on diagnostics and in the log; no trajectory, no outcome): parameters
out of [0, 1], a trajectory beyond the joints' limits (``joint_limits``), no
``joint_trajectory_controller`` subscribed to the topic, and odometry (or IMU) that is stale or
absent when the gait would start (a gait sent within ``odometry.timeout`` of the executor's
start waits that long for the first message). Odometry that stops during a gait, or a gait
whose end is not seen within ``gait_timeout``, ends it without an outcome, reported the same
way. With no outcome, the adapter sends the same command again after its
``outcome_timeout`` (10 s): a robot whose odometry comes back carries on, one whose odometry
stays away does not move.

The stamps must be one clock's (:class:`ClockCheck`): a gait is refused while the stamps on a
topic keep going back (two publishers on different clocks: twice within ``CLOCK_WINDOW``) or
while the odometry's and the IMU's are more than a gait apart, and a running gait ends
without an outcome when its stamps go back (a clock reset): its end could not be told.
"""
import math
import time
from collections import deque

from diagnostic_msgs.msg import DiagnosticStatus
from rclpy.clock import Clock, ClockType
from rclpy.node import Node

from sela_ros.core.geometry import generic_reward
from sela_ros.nodes import conversions as conv
from sela_ros.nodes import interface as ifc
from sela_ros.nodes.guard import guard
from sela_ros.nodes.heartbeat import add_heartbeat
from sela_ros.nodes.node_main import run_node
from sela_ros.nodes.params import Spec, StartupParameterError, declare
from sim_bridge import trajectory as tj
from sim_bridge.robots import DEFAULT_ROBOT, ROBOTS, get_robot

#: s (wall) between two looks at the running gait's timeouts.
TICK = 0.02
#: s: an odometry stamp this close to the gait's end counts as at its end (stamps are ns).
STAMP_EPS = 1e-6
#: The simulator's fall test: tilted more than 60 deg (sim_bridge.model.FALL_TILT).
FALL_TILT = math.radians(60.0)
#: s (wall): stamps that went back twice within this are two clocks, not one reset.
CLOCK_WINDOW = 5.0


def _robot_rule(value):
    try:
        get_robot(value)
    except ValueError as exc:
        return f'is invalid: {exc}'
    return None


def _names_rule(value):
    if len(set(value)) != len(value) or not all(value):
        return 'must be distinct, non-empty names'
    return None


def _limits_rule(value):
    if len(value) % 2 or any(lo > hi for lo, hi in zip(value[0::2], value[1::2])):
        return 'must be pairs (lower, upper) with each lower limit <= its upper limit'
    return None


def _joints(node, description, names, bounds):
    """``(names, {name: (lower, upper)})`` of the controller's joints, in the description's
    order; raises StartupParameterError when the parameters do not fit the description."""
    n = len(description.joint_names)
    if names and len(names) != n:
        raise StartupParameterError(
            f'joint_names must name the {n} joints of the robot description {description.name}'
            f' in its order ({", ".join(description.joint_names)}), got {len(names)} name(s)',
            node.get_name())
    if bounds and len(bounds) != 2 * n:
        raise StartupParameterError(
            f'joint_limits must be {2 * n} numbers (lower, upper for each of the {n} joints '
            f'of {description.name}), got {len(bounds)}', node.get_name())
    names = list(names or description.joint_names)
    if bounds:
        limits = {name: (bounds[2 * i], bounds[2 * i + 1]) for i, name in enumerate(names)}
    else:
        own = tj.joint_limits(description)
        limits = {name: own[joint] for name, joint in zip(names, description.joint_names)
                  if joint in own}
    return names, limits


PARAMETERS = (
    Spec('robot', DEFAULT_ROBOT, f'the robot description (its joints, their limits, its gait '
         f'controller): {", ".join(ROBOTS)} or package.module:DESCRIPTION', read_only=True,
         rule=_robot_rule),
    Spec('trajectory_topic', ifc.JOINT_TRAJECTORY.name, "the joint_trajectory_controller's "
         'command topic', read_only=True, rule=lambda v: None if v else 'must not be empty'),
    Spec('odometry_topic', 'odom', 'nav_msgs/Odometry of the body in a fixed frame (motion '
         'capture, visual or leg odometry): the outcome is measured on it',
         read_only=True, rule=lambda v: None if v else 'must not be empty'),
    Spec('imu_topic', '', "sensor_msgs/Imu whose orientation tells a fall; '' = the "
         "odometry's orientation", read_only=True),
    # Not set by default (the robot description's): ROS cannot hold an empty typed array.
    Spec('joint_names', None, "the controller's names of the robot description's joints, in "
         "the description's order (not set: the description's names)", read_only=True,
         kind='string_array', rule=_names_rule),
    Spec('joint_limits', None, 'lower, upper limit (rad) of each joint, in joint_names order: '
         "a gait that goes beyond one is refused (not set: the description's URDF's)",
         read_only=True, kind='double_array', rule=_limits_rule),
    Spec('gait_duration', 3.0, "duration of one gait; must be the archive's", low=0.1,
         high=60.0, unit=' s', read_only=True),
    Spec('trajectory_rate', 'auto', "points per second of the trajectory; auto = the gait "
         "controller's own sample rate (the hexapod's: 100), which reproduces it exactly",
         low=1.0, high=10000.0, unit=' Hz', read_only=True, word='auto', kind='double'),
    Spec('settle_time', 0.0, "odometry time after the gait's end before its end pose is "
         'taken (latency of a real controller; 0 in simulation, whose time stands still '
         'between gaits)', low=0.0, high=60.0, unit=' s'),
    Spec('odometry.timeout', 1.0, 'wall time without an odometry (or IMU) message after '
         'which it is stale: no gait starts, a running one ends without an outcome',
         low=0.01, high=600.0, unit=' s'),
    Spec('gait_timeout', 60.0, "wall time from sending a trajectory to seeing the gait's end "
         'in the odometry, after which the gait ends without an outcome', low=0.1,
         high=3600.0, unit=' s'),
    Spec('fall.tilt', FALL_TILT, "a body tilted more than this at the gait's end has fallen",
         low=0.0, high=math.pi, unit=' rad'),
    Spec('fall.min_height', 'none', "a body whose odometry height is below this at the gait's "
         'end has fallen (none: height not used)', low=-100.0, high=100.0, unit=' m',
         word='none', kind='double'),
)


class GaitExecutor(Node):
    def __init__(self):
        super().__init__(ifc.GAIT_EXECUTOR)
        values = declare(self, PARAMETERS, on_change=self._on_change)
        self.description = get_robot(values['robot'])
        self.names, self.limits = _joints(self, self.description, values['joint_names'],
                                          values['joint_limits'])
        self.duration = values['gait_duration']
        rate = values['trajectory_rate']
        self.rate = tj.controller_rate(self.description) if rate == 'auto' else float(rate)
        self.settle_time = values['settle_time']
        self.odom_timeout = values['odometry.timeout']
        self.gait_timeout = values['gait_timeout']
        self.fall_tilt = values['fall.tilt']
        self.fall_height = _height(values['fall.min_height'])
        self.odometry_topic = values['odometry_topic']
        self.imu_topic = values['imu_topic']
        self.trajectory_topic = values['trajectory_topic']

        self.queue = deque()  # (behavior_id, times, positions), in the order received
        self.gait = None  # the running gait
        self.standing = True  # the next gait starts standing: the first, or after a fall
        self.odom = None  # newest (wall time received, stamp, message)
        self.finished = None  # wall time the last gait ended
        self.imu = None
        self.clocks = ClockCheck(self.odometry_topic, self.imu_topic)
        self._next_auto_id = 1_000_000_000
        self.started = time.monotonic()

        self.trajectory_pub = ifc.publisher(self, ifc.JOINT_TRAJECTORY,
                                            name=self.trajectory_topic)
        self.outcome_pub = ifc.publisher(self, ifc.OUTCOME)
        self.diag_pub = ifc.publisher(self, ifc.DIAGNOSTICS)
        ifc.subscription(self, ifc.BEHAVIOR, self.behavior_callback)
        ifc.subscription(self, ifc.ODOM_OBSERVED, self.odometry_callback, qos=ifc.SENSOR_QOS,
                         name=self.odometry_topic)
        if self.imu_topic:
            ifc.subscription(self, ifc.IMU, self.imu_callback, qos=ifc.SENSOR_QOS,
                             name=self.imu_topic)
        add_heartbeat(self)
        self.create_timer(TICK, self.tick, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.get_logger().info(
            f'gait executor ready: trajectories on {self.trajectory_pub.topic_name}, odometry '
            f'from {self.odometry_topic}, falls from '
            f'{self.imu_topic or "the odometry"}, {self.description.name}: '
            f'{len(self.names)} joints')

    def _on_change(self, params):
        for param in params:
            if param.name == 'settle_time':
                self.settle_time = float(param.value)
            elif param.name == 'odometry.timeout':
                self.odom_timeout = float(param.value)
            elif param.name == 'gait_timeout':
                self.gait_timeout = float(param.value)
            elif param.name == 'fall.tilt':
                self.fall_tilt = float(param.value)
            elif param.name == 'fall.min_height':
                self.fall_height = _height(param.value)
        return None

    # --- inputs ----------------------------------------------------------------------------

    @guard
    def behavior_callback(self, msg):
        try:
            params, behavior_id = conv.behavior_from_msg(msg, self.description.n_params)
        except conv.MessageError as exc:
            self._error('command', f'rejected command on {ifc.BEHAVIOR.name}: {exc}')
            return
        if behavior_id is None:
            behavior_id = self._next_auto_id
            self._next_auto_id += 1
        elif behavior_id in self._pending():
            # The adapter sends a command again when its outcome is late: the gait is
            # already on its way (its outcome will come), and a robot must not walk it twice.
            self._report(DiagnosticStatus.WARN, 'command', f'gait {behavior_id} is already '
                         'running or queued: the repeated command is not played again')
            return
        try:  # checked now: a gait the robot must not play is refused at once
            times, positions = tj.gait_trajectory(params, self.duration, self.rate,
                                                  robot=self.description)
            tj.check_trajectory(self.names, times, positions, known=self.names,
                                limits=self.limits)
        except ValueError as exc:  # TrajectoryError included
            self._error('trajectory', f'gait {behavior_id} not played: {exc}')
            return
        self.queue.append((behavior_id, times, positions))
        self.tick()

    @guard
    def odometry_callback(self, msg):
        self.odom = (time.monotonic(), conv.time_from_msg(msg.header.stamp), msg)
        if self._clock_went_back(self.odometry_topic, self.odom):
            return
        if self.gait is not None:
            self.gait.odometry(self.odom[1], msg)
            self._finish_if_ended()

    @guard
    def imu_callback(self, msg):
        self.imu = (time.monotonic(), conv.time_from_msg(msg.header.stamp), msg)
        if self._clock_went_back(self.imu_topic, self.imu):
            return
        if self.gait is not None:
            self.gait.attitude(self.imu[1], msg.orientation)
            self._finish_if_ended()

    def _clock_went_back(self, topic, sample):
        """True when ``sample``'s stamp is older than the last on ``topic``; a running gait
        then ends without an outcome (its end can no longer be told)."""
        back = self.clocks.seen(topic, sample[0], sample[1])
        if back is None:
            return False
        if self.gait is not None:
            gait, self.gait = self.gait, None
            self._error('gait', f'gait {gait.behavior_id} ended without an outcome: the '
                        f'stamps on {topic} went back {back:.3f} s during it (a clock reset, '
                        'or two publishers on different clocks); the adapter sends it again')
        return True

    # --- the gait ------------------------------------------------------------------------

    @guard
    def tick(self):
        now = time.monotonic()
        if self.gait is not None:
            problem = self._stale(now)
            if problem is None and now - self.gait.sent > self.gait_timeout:
                problem = (f'{self.gait.unseen(self.odometry_topic, self.imu_topic)} within '
                           f'gait_timeout ({self.gait_timeout:g} s)')
            if problem is not None:
                gait, self.gait = self.gait, None
                self._error('gait', f'gait {gait.behavior_id} ended without an outcome: '
                            f'{problem}; the adapter sends it again')
        while self.gait is None and self.queue:
            try:
                if not self._ready(now):
                    return
            except _Refused as exc:
                behavior_id = self.queue.popleft()[0]
                self._error(exc.what, f'gait {behavior_id} not played: {exc}')
                continue
            self._start(*self.queue.popleft(), now)

    def _stale(self, now):
        """What is wrong with the odometry and IMU now (stale or absent), or None.

        Between gaits, only messages received since the last gait ended count: the next
        gait starts from a pose taken after the robot finished (and, fallen, got up)."""
        for what, topic, sample in (('odometry', self.odometry_topic, self.odom),
                                    ('IMU', self.imu_topic, self.imu)):
            if not topic:
                continue
            if sample is None and self.finished is None:
                if now - self.started <= self.odom_timeout:
                    continue  # just started: its subscription may not have matched yet
                return (f'no {what} received on {topic} since the executor started '
                        f'(odometry.timeout {self.odom_timeout:g} s)')
            last = max(sample[0] if sample is not None else -math.inf,
                       self.finished if self.gait is None and self.finished else -math.inf)
            if now - last > self.odom_timeout:
                return (f'no {what} on {topic} for {now - last:.1f} s: stale or stopped '
                        f'(odometry.timeout {self.odom_timeout:g} s)')
        return None

    def _ready(self, now):
        """True: a gait may start now. False: waiting for a fresh pose. Raises _Refused."""
        problem = self._stale(now) or self.clocks.problem(now, self.duration)
        if problem is not None:
            raise _Refused('odometry', f'{problem}; the adapter sends it again after its '
                           'outcome_timeout')
        return (self.odom is not None and (not self.imu_topic or self.imu is not None)
                and (self.finished is None or self.odom[0] > self.finished))

    def _start(self, behavior_id, times, positions, now):
        refused = f'gait {behavior_id} not played'
        if self.trajectory_pub.get_subscription_count() == 0:
            self._error('controller', f'{refused}: nothing subscribes to '
                        f'{self.trajectory_pub.topic_name}: is the '
                        'joint_trajectory_controller active?')
            return
        _, stamp, msg = self.odom
        start = conv.pose_from_odometry(msg)
        self.gait = RunningGait(behavior_id, start, stamp,
                                stamp + self.duration + self.settle_time, now,
                                self.standing, use_imu=bool(self.imu_topic))
        self.trajectory_pub.publish(conv.trajectory_to_msg(self.names, times, positions))

    def _finish_if_ended(self):
        gait = self.gait
        if not gait.ended:
            return
        self.gait = None
        self.finished = time.monotonic()
        end = conv.pose_from_odometry(gait.end_msg)
        position = gait.end_msg.pose.pose.position
        fallen = gait.tilt() > self.fall_tilt or (
            self.fall_height is not None and position.z < self.fall_height)
        self.standing = fallen  # a fallen robot is got up, standing, before the next gait
        outcome = conv.BehaviorOutcome(
            behavior_id=gait.behavior_id, generic_reward=generic_reward(gait.start, end),
            start_pose=gait.start, end_pose=end, fallen=fallen, sim_time=gait.end_stamp,
            # One per leg, unknown here (no foot contacts): 0.
            duty_factors=[0.0] * len(self.description.legs),
            standing_start=gait.standing_start)
        self.outcome_pub.publish(conv.outcome_to_msg(outcome))
        if fallen:
            self._error('robot', f'robot fell during gait {gait.behavior_id} (tilt '
                        f'{math.degrees(gait.tilt()):.0f} deg, height {position.z:.3f} m)')
        self.tick()

    def _pending(self):
        """Ids of the gait running and those queued."""
        return {b for b, _, _ in self.queue} | (
            {self.gait.behavior_id} if self.gait is not None else set())

    def _error(self, what, message):
        self._report(DiagnosticStatus.ERROR, what, message)

    def _report(self, level, what, message):
        # One logging call per severity: rclpy refuses two severities from one call site.
        if level == DiagnosticStatus.ERROR:
            self.get_logger().error(message)
        else:
            self.get_logger().warning(message)
        self.diag_pub.publish(conv.diagnostic_array(conv.diagnostic_status(
            level, f'{ifc.GAIT_EXECUTOR}: {what}', message,
            hardware_id=self.trajectory_topic), self.get_clock().now().to_msg()))


class _Refused(Exception):
    def __init__(self, what, message):
        super().__init__(message)
        self.what = what


class ClockCheck:
    """Whether the odometry's (and IMU's) stamps can be one clock's.

    A stamp older than the one before it on the same topic went back: once is a clock reset
    (a simulator restarted), again within :data:`CLOCK_WINDOW` is two publishers on different
    clocks. The odometry's and the IMU's newest stamps more than a gait apart are two clocks
    as well: the gait's end, told on one, would never come (or come at once) on the other.
    """

    def __init__(self, odometry_topic, imu_topic=''):
        self.topics = [t for t in (odometry_topic, imu_topic) if t]
        self.last = {}  # topic: newest stamp
        self.back = {t: deque(maxlen=2) for t in self.topics}  # (wall, seconds back)

    def seen(self, topic, wall, stamp):
        """Record a message; the seconds its stamp went back, or None."""
        previous = self.last.get(topic)
        self.last[topic] = stamp
        if previous is None or stamp >= previous - STAMP_EPS:
            return None
        back = previous - stamp
        self.back[topic].append((wall, back))
        return back

    def problem(self, now, gait_duration):
        """Why the stamps cannot be trusted now, or None."""
        for topic in self.topics:
            jumps = self.back[topic]
            if len(jumps) == 2 and now - jumps[0][0] <= CLOCK_WINDOW:
                return (f'the stamps on {topic} went back twice within {CLOCK_WINDOW:g} s '
                        f'(by {max(b for _, b in jumps):.3f} s): two publishers on different '
                        'clocks?')
        if len(self.topics) == 2 and all(t in self.last for t in self.topics):
            odom, imu = (self.last[t] for t in self.topics)
            if abs(odom - imu) > gait_duration:
                return (f'the stamps on {self.topics[0]} ({odom:.3f} s) and {self.topics[1]} '
                        f'({imu:.3f} s) are {abs(odom - imu):.3f} s apart, more than a gait: '
                        'not one clock')
        return None


class RunningGait:
    """One gait sent: where it started, and what the odometry and IMU say of its end.

    The attitude that tells a fall is that of the newest sample (IMU, or odometry without
    one) stamped within the gait, up to its end; after its end a fallen robot may already be
    getting up.
    """

    def __init__(self, behavior_id, start, start_stamp, end, sent, standing_start,
                 use_imu=False):
        self.behavior_id = behavior_id
        self.start = start
        self.start_stamp = start_stamp
        self.end = end
        self.sent = sent
        self.standing_start = standing_start
        self.use_imu = use_imu
        self.end_msg = None
        self.end_stamp = None
        self.attitude_within = None  # (stamp, quaternion) newest within the gait
        self.attitude_after = None  # the first at or after its end

    def odometry(self, stamp, msg):
        if self.end_msg is None and stamp >= self.end - STAMP_EPS:
            self.end_msg, self.end_stamp = msg, stamp
        if not self.use_imu:
            self.attitude(stamp, msg.pose.pose.orientation)

    def attitude(self, stamp, orientation):
        if self.start_stamp < stamp <= self.end + STAMP_EPS:
            self.attitude_within = (stamp, orientation)
        if stamp >= self.end - STAMP_EPS and self.attitude_after is None:
            self.attitude_after = (stamp, orientation)

    @property
    def ended(self):
        return self.end_msg is not None and self.attitude_after is not None

    def unseen(self, odometry_topic, imu_topic):
        """What of the gait's end was not seen: odometry, the attitude, or both."""
        missing = [odometry_topic] if self.end_msg is None else []
        if self.use_imu and self.attitude_after is None:  # else the attitude is odometry's
            missing.append(imu_topic)
        return (f'nothing stamped at or after the end of the gait ({self.end:.2f} s) came on '
                f"{' nor '.join(missing)}")

    def tilt(self):
        sample = self.attitude_within or self.attitude_after
        return conv.tilt(sample[1]) if sample is not None else 0.0


def _height(value):
    return None if value == 'none' else float(value)


def main(args=None):
    run_node(GaitExecutor, args)


if __name__ == '__main__':
    main()
