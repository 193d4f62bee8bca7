"""The ``sim_bridge`` node: a simulated robot (the PyBullet hexapod by default) on the ROS graph.

``robot`` names its description (:mod:`sim_bridge.robots`: ``hexapod``, ``a1``); the topic
and service names are the same whatever the robot (another robot's stack runs in a namespace
of its own, docs/ros.md).

Publishes ``/clock`` (it owns sim time), ``/hexapod/odom`` (odom -> base_link),
``/hexapod/joint_states``; executes each command on ``/hexapod/behavior`` and answers with
exactly one ``/hexapod/behavior_outcome`` carrying the command's id; serves
``/sim_bridge/reset``. With ``interface: trajectory`` it shows the hardware face of a robot
under ros2_control instead (see :class:`HardwareFace`): joint trajectories in, IMU and an
external odometry out, and no gait commands or outcomes (the gait executor's).
``damage`` can be changed at run time with ``ros2 param set``.
The physics (``sim.dt``, ``sim.gait_duration``, ``sim.solver_iterations``) are those stamped
in the ``archive`` parameter's file ('' = the robot's shipped archive, for the hexapod the one
the adapter serves by default; ``none`` = the ``sim.*`` values as given): a map's gaits only do in
simulation what the map says with the settings it was built with.

Gaits run on a worker thread that owns the simulator, so the node's single-threaded
executor keeps answering services, parameters and subscriptions while the robot walks.
(A MultiThreadedExecutor here delayed some commands by 10-350 ms, measured.)
"""
import os
import threading
from collections import deque

from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import TransformStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import JointState
from std_msgs.msg import String

from sela_ros.nodes import conversions as conv
from sela_ros.nodes import interface as ifc
from sela_ros.nodes.guard import guard, guard_parameters, guard_service
from sela_ros.nodes.heartbeat import add_heartbeat
from sela_ros.nodes.node_main import run_node
from sela_ros.nodes.params import Spec, declare
from sim_bridge.damage import DamageSpecError
from sim_bridge.environment import RIGHTING_TIME, ObservedHexapod
from sim_bridge.pacing import MIN_REAL_TIME_FACTOR, GaitPace
from sim_bridge.robots import DEFAULT_ROBOT, ROBOTS, get_robot, robot_of
from sim_bridge.settings import SIM_DEFAULTS, physics_settings, read_archive_metadata
from sim_bridge.simulator import Simulator
from sim_bridge.trajectory import TrajectoryError, check_trajectory, hold_targets


def damage_rule(value, robot=None):
    """A damage spec users can type for ``robot`` (a description; None: the hexapod); the
    error lists the valid names."""
    description = get_robot(robot)
    if not isinstance(value, str):
        return f'must be a string such as {description.default_damage}, got {value!r}'
    try:
        description.parse_damage(value)
    except DamageSpecError as exc:
        return f'is invalid: {exc}'
    return None


def robot_rule(value):
    """A robot the stack has a description of."""
    try:
        get_robot(value)
    except ValueError as exc:
        return f'is invalid: {exc}'
    return None


def _damage_spec(description):
    return Spec('damage', description.default_damage,
                "what is broken; can change at run time: intact (or ''), "
                'remove:<leg>, shorten:<leg>[:f], block:<leg>.<joint>[=rad], '
                'weaken:<leg>.<joint>[=torque share], friction:<ground coefficient>, '
                'payload:<kg>[@<x>,<y> m from the body centre], comma-joined (the kinds and the '
                'leg and joint names the robot takes; the default is the robot\'s)',
                rule=lambda value: damage_rule(value, description))


INTERFACES = ('behavior', 'trajectory')
IDLE_PERIOD = 0.1  # s (wall) between state messages while no gait runs

PARAMETERS = (
    Spec('robot', DEFAULT_ROBOT, f'the simulated robot: {", ".join(ROBOTS)} or '
         'package.module:DESCRIPTION (docs/robots.md)', read_only=True, rule=robot_rule),
    _damage_spec(get_robot(DEFAULT_ROBOT)),
    Spec('sim.dt', 1.0 / 240.0, 'physics step; must match the archive', low=1e-4, high=0.05,
         unit=' s', read_only=True),
    Spec('sim.gait_duration', 3.0, 'duration of one behaviour', low=0.1, high=60.0, unit=' s',
         read_only=True),
    Spec('sim.solver_iterations', SIM_DEFAULTS['solver_iterations'], 'PyBullet constraint-'
         'solver iterations per step; must match the archive', low=1, high=1000,
         read_only=True),
    Spec('archive', '', 'an archive file whose stamped physics (dt, gait duration, solver '
         'iterations) replace the sim.* values; "" = the robot\'s shipped archive (the '
         'hexapod\'s as the adapter), "8d"/"2d"/"a1" = the shipped ones by name, "none" = use '
         'the sim.* values', read_only=True),
    Spec('sim.gui', False, "PyBullet's window (needs a display)", read_only=True,
         rule=lambda v: None if not v or _has_display() else 'needs a display (DISPLAY and '
         'WAYLAND_DISPLAY are not set); use sim.gui:=false for headless DIRECT mode'),
    Spec('publish_period', 0.5, 'sim time between state messages (/clock, odom, joint states, '
         '/tf) during a gait', low=0.001, high=60.0, unit=' s'),
    Spec('publish_max_rate', 5.0, 'at most this many state messages per wall second during a '
         'gait (none: no cap)', low=0.0, high=1000.0, unit=' Hz', word='none'),
    Spec('real_time_factor', 0.0, 'each gait (or trajectory) lasts at least its sim time '
         'divided by this in wall time, from the next gait on: 1 = the robot\'s own pace, '
         'to watch it or to drive it as a robot; 0 = as fast as the machine allows. A gait '
         'then takes sim.gait_duration / real_time_factor: keep the adapter\'s '
         'outcome_timeout above it', low=0.0, high=1000.0,
         rule=lambda v: None if v == 0 or v >= MIN_REAL_TIME_FACTOR else
         f'must be 0 (no pacing) or at least {MIN_REAL_TIME_FACTOR}, got {v}'),
    Spec('observation.noise_std', 0.01, 'std of the Gaussian noise on observed positions',
         low=0.0, high=1.0, unit=' m'),
    Spec('seed', 0, 'seed of the observation noise', low=0, high=2**31 - 1, read_only=True),
    # A real robot that falls gets up where it lies; staying down until /sim_bridge/reset
    # (the adapter's reset_on_fall) is for episodic set-ups.
    Spec('right_on_fall', True, 'true: a fallen robot gets up where it lies (taking '
         'righting_time); false: it stays down until /sim_bridge/reset', read_only=True),
    Spec('righting_time', RIGHTING_TIME, 'sim time a fallen robot takes to get up',
         low=0.0, high=600.0, unit=' s', read_only=True),
    Spec('interface', 'behavior', 'behavior: gaits from the adapter\'s commands, answered with '
         'outcomes; trajectory: the hardware face of a robot under ros2_control (joint '
         'trajectories in, IMU and the observed odometry out), for the gait executor',
         read_only=True, rule=lambda v: None if v in INTERFACES
         else f'must be one of {", ".join(INTERFACES)}, got {v!r}'),
    Spec('map_frame', 'map', "the odometry frame's parent, the identity (the simulator's "
         "odometry does not drift), on /tf_static: RViz with this fixed frame draws the robot "
         "('' = none)", read_only=True,
         rule=lambda v: f'must be another frame than odom and base_link (its children), got {v!r}'
         if v in ('odom', 'base_link') else None),
)


def _max_rate(value):
    """``publish_max_rate`` as Hz, or None for none (no cap)."""
    return None if value == 'none' else float(value)


def _has_display():
    return bool(os.environ.get('DISPLAY') or os.environ.get('WAYLAND_DISPLAY'))


def parameters_for(description):
    """The node's parameters with ``damage`` over ``description``'s names and default."""
    return tuple(_damage_spec(description) if spec.name == 'damage' else spec
                 for spec in PARAMETERS)


# --- the hardware face (interface: trajectory) -------------------------------------------


class HardwareFace:
    """What a robot under ros2_control shows, played by the simulator: a
    ``joint_trajectory_controller``'s command topic in; ``hexapod/imu`` (the body's
    orientation) and ``hexapod/odom_observed`` (an external odometry: the observation
    model's pose, with the body's height and attitude) out, beside the joint states.

    Each trajectory is played as one gait: its points held until the next one's time, with
    the direct path's servo (:func:`sim_bridge.trajectory.hold_targets`), so a trajectory
    that samples the gait controller at its own rate does what the command would. The
    observed pose is drawn, as on the direct path, once at the end of each trajectory: the
    odometry and IMU stamped with the trajectory's end time show the body as it ended
    (fallen or not) and the new observed pose, before a fallen robot is righted.
    A trajectory with unknown joints or targets beyond the joints' limits is refused with
    an ERROR on diagnostics and moves nothing.
    """

    def _start_hardware_face(self):
        self.imu_pub = ifc.publisher(self, ifc.IMU)
        self.observed_pub = ifc.publisher(self, ifc.ODOM_OBSERVED)
        ifc.subscription(self, ifc.JOINT_TRAJECTORY, self.trajectory_callback)

    @guard
    def trajectory_callback(self, msg):
        try:
            names, times, positions = conv.trajectory_from_msg(msg)
            check_trajectory(names, times, positions, robot=self.description)
            if round(times[-1] / self.env.robot.dt) < 1:
                raise TrajectoryError(f'it lasts {times[-1]} s, less than one physics step')
        except (conv.MessageError, TrajectoryError) as exc:
            message = f'rejected trajectory on {ifc.JOINT_TRAJECTORY.name}: {exc}'
            self.get_logger().error(message)
            self.diag_pub.publish(conv.diagnostic_array(conv.diagnostic_status(
                DiagnosticStatus.ERROR, 'sim_bridge: trajectory', message,
                hardware_id=self.description.name), self.env.robot.sim_time))
            return
        self._enqueue('trajectory', names, (times, positions))

    def _run_trajectory(self, names, points):
        times, positions = points
        targets = hold_targets(names, times, positions, self.env.robot.dt,
                               robot=self.description)
        gait_end = self.env.robot.sim_time + len(targets) * self.env.robot.dt
        end = []

        def on_state(sim_time, pose, positions, velocities):
            if sim_time >= gait_end - 1e-9:  # the end: published once observed
                end[:] = [sim_time, self.env.robot.base_pose_3d(), positions, velocities]
            else:
                self._publish_state(sim_time, pose, positions, velocities)

        pace = self._pace(on_state, end=gait_end)
        result = self.env.execute_targets(targets, callback=pace, callback_period=pace.period)
        pace.hold_until(self.env.robot.sim_time)  # a fallen robot's getting up included
        sim_time, (xyz, quaternion), positions, velocities = end
        if result.fallen:
            self._report_fall(None)
        self._publish_joint_states(conv.time_to_msg(sim_time), positions, velocities)
        self._publish_hardware_state(sim_time, xyz, quaternion)
        self._publish_state(self.env.robot.sim_time)

    def _publish_hardware_state(self, sim_time, xyz=None, quaternion=None):
        if xyz is None:
            xyz, quaternion = self.env.robot.base_pose_3d()
        self.imu_pub.publish(conv.imu_msg(quaternion, sim_time))
        # The pose as last observed (held during a gait, as the direct path's observations).
        x, y, _ = self.env.observed_pose()
        self.observed_pub.publish(conv.odometry_3d_msg((x, y, xyz[2]), quaternion, sim_time))


# --- the simulator's node ------------------------------------------------------------------


class SimBridge(HardwareFace, Node):
    def __init__(self):
        super().__init__(ifc.SIM_BRIDGE)
        self.description = self._take_robot()
        physics = self._take_archive_physics()
        values = declare(self, parameters_for(self.description),
                         on_change=self.parameters_callback)
        if physics:  # said once the parameters are known good (a bad one: one line only)
            self.get_logger().info(physics)
        damage = values['damage']
        robot = Simulator(dt=values['sim.dt'], gait_duration=values['sim.gait_duration'],
                          solver_iterations=values['sim.solver_iterations'],
                          damage=damage, gui=values['sim.gui'], robot=self.description)
        self.env = ObservedHexapod(robot, values['observation.noise_std'], seed=values['seed'],
                                   right_on_fall=values['right_on_fall'],
                                   righting_time=values['righting_time'])
        self.publish_period = values['publish_period']
        self.publish_max_rate = _max_rate(values['publish_max_rate'])
        self.real_time_factor = float(values['real_time_factor'])
        self.right_on_fall = values['right_on_fall']

        self._sim_lock = threading.Lock()  # held by whoever touches the simulator
        # The worker's queue (FIFO): commands, resets, damage and noise changes.
        self._cond = threading.Condition()
        self._work = deque()
        self._busy = False  # the worker holds an item from the queue
        self._next_auto_id = 1_000_000_000  # ids for commands sent without one

        self.clock_pub = ifc.publisher(self, ifc.CLOCK)
        self.odom_pub = ifc.publisher(self, ifc.ODOM)
        self.joint_pub = ifc.publisher(self, ifc.JOINT_STATES)
        self.diag_pub = ifc.publisher(self, ifc.DIAGNOSTICS)
        self.interface = values['interface']
        if self.interface == 'trajectory':
            self._start_hardware_face()
        else:
            self.outcome_pub = ifc.publisher(self, ifc.OUTCOME)
            ifc.subscription(self, ifc.BEHAVIOR, self.behavior_callback)
        ifc.server(self, ifc.RESET, self.reset_callback)
        # For RViz and Foxglove (REP-105): odom -> base_link with every state message, and
        # the robot as it is now (legs removed by the damage are absent), latched. Relative
        # names, so that a namespaced robot has its own (remap /tf:=tf in its RViz).
        self.tf_pub = None
        if ifc.TF.type is not None:
            self.tf_pub = ifc.publisher(self, ifc.TF)
            if values['map_frame']:
                self.tf_static_pub = ifc.publisher(self, ifc.TF_STATIC)
                self.tf_static_pub.publish(ifc.TF_STATIC.type(
                    transforms=[self._map_transform(values['map_frame'])]))
        else:
            self.get_logger().warn('tf2_msgs is not installed: no /tf (odometry only)')
        self.description_pub = ifc.publisher(self, ifc.ROBOT_DESCRIPTION)
        self._publish_description(damage)
        add_heartbeat(self)

        self._stop = threading.Event()
        self._worker = threading.Thread(target=self._work_loop, name='gait_worker', daemon=True)
        self._worker.start()
        self._publish_state(self.env.robot.sim_time)
        self.get_logger().info(f"{self.description.name} ready, damage '{damage}', "
                               f'noise std {self.env.noise_std} m, interface {self.interface}')

    def _take_robot(self):
        """The description the start-up value of ``robot`` names (the hexapod when none is
        given; a bad one is reported when ``robot`` is declared)."""
        overrides = getattr(self, '_parameter_overrides', None)
        given = overrides.get('robot') if isinstance(overrides, dict) else None
        try:
            return get_robot(given.value if given is not None else None)
        except ValueError:
            return get_robot(None)

    def _take_archive_physics(self):
        """Start-up values of sim.* from the stamp of the archive given at start-up ('' = the
        shipped one); returns what to log once the parameters are declared, or None.

        They are read-only parameters, so they are set before they are declared, as start-up
        overrides (the way ``params.declare`` coerces them), and report what really runs.
        """
        from rclpy.parameter import Parameter

        from sela_ros.core.storage import resolve_archive_path

        overrides = getattr(self, '_parameter_overrides', None)
        if not isinstance(overrides, dict):
            return None
        archive = overrides.get('archive')
        value = archive.value if archive is not None else ''
        if not isinstance(value, str) or value.strip().lower() == 'none':
            return None  # a wrongly typed archive is reported when it is declared
        value = value or self.description.archive
        if not value:
            return None  # a robot without a shipped map: the sim.* values
        path = resolve_archive_path(value)
        try:
            metadata = read_archive_metadata(path)
        except ValueError as exc:
            self.get_logger().error(f'parameter archive: {exc}; using the sim.* parameters')
            return None
        if robot_of(metadata) != self.description.name:
            self.get_logger().error(f'parameter archive: {path} is a map of the '
                                    f'{robot_of(metadata)}, not of the '
                                    f'{self.description.name}; using the sim.* parameters')
            return None
        settings = physics_settings(metadata)
        for name, key in (('sim.dt', 'dt'), ('sim.gait_duration', 'gait_duration'),
                          ('sim.solver_iterations', 'solver_iterations')):
            overrides[name] = Parameter(name, value=settings[key])
        return f'physics of archive {path}: {settings}'

    # --- callbacks (short: they only validate and enqueue) -------------------------------

    @guard
    def behavior_callback(self, msg):
        try:
            params, behavior_id = conv.behavior_from_msg(msg, self.description.n_params)
        except conv.MessageError as exc:
            message = f'rejected command on /hexapod/behavior: {exc}'
            self.get_logger().error(message)
            self.diag_pub.publish(conv.diagnostic_array(conv.diagnostic_status(
                DiagnosticStatus.ERROR, 'sim_bridge: command', message,
                hardware_id=self.description.name), self.env.robot.sim_time))
            return
        if behavior_id is None:
            behavior_id = self._next_auto_id
            self._next_auto_id += 1
        self._enqueue('gait', behavior_id, params)

    @guard_service
    def reset_callback(self, request, response):
        # Callbacks run one at a time on the executor's thread, and only they fill the queue:
        # an idle worker stays idle while the robot is reset here.
        with self._cond:
            idle = not self._work and not self._busy
        response.success = True
        if idle:
            with self._sim_lock:
                self.env.reset()
                self._publish_state(self.env.robot.sim_time)
            response.message = (f'robot back at the start, sim time '
                                f'{self.env.robot.sim_time:.3f} s')
        else:  # never wait for a gait in a callback: after the commands already received
            self._enqueue('reset', None, None)
            response.message = ('reset queued: the robot goes back to the start after the '
                                f'{len(self._work) - 1 + self._busy} command(s) before it')
        return response

    def _enqueue(self, kind, a, b):
        with self._cond:
            self._work.append((kind, a, b))
            self._cond.notify()

    @guard_parameters
    def parameters_callback(self, params):
        # Called by params.declare with values its check accepted.
        for param in params:
            if param.name == 'damage':
                self._enqueue('damage', self.description.parse_damage(param.value).canonical(),
                              None)
            elif param.name == 'observation.noise_std':
                self._enqueue('noise', float(param.value), None)
            elif param.name == 'publish_period':
                self.publish_period = float(param.value)
            elif param.name == 'publish_max_rate':
                self.publish_max_rate = _max_rate(param.value)
            elif param.name == 'real_time_factor':
                self.real_time_factor = float(param.value)
        return SetParametersResult(successful=True)

    # --- worker thread -------------------------------------------------------------------

    def _work_loop(self):
        while not self._stop.is_set():
            with self._cond:
                if not self._work:
                    self._cond.wait(timeout=IDLE_PERIOD)
                item = self._work.popleft() if self._work else None
                self._busy = item is not None
            if item is None:
                # No gait running: keep /clock and odom alive (sim time stands still) so that
                # nodes started later get a pose. Done here, not by an executor timer, so
                # nothing wakes the executor while a gait runs.
                try:
                    with self._sim_lock:
                        self._publish_state(self.env.robot.sim_time)
                except Exception as exc:  # noqa: BLE001 - the worker must outlive a publish
                    if not self.context.ok():
                        return  # shutting down: nothing to publish on any more
                    self.get_logger().error(f'idle state not published: {exc}')
                continue
            kind, a, b = item
            try:
                with self._sim_lock:
                    if kind == 'gait':
                        self._run_gait(a, b)
                    elif kind == 'trajectory':
                        self._run_trajectory(a, b)
                    elif kind == 'reset':
                        self.env.reset()
                        self._publish_state(self.env.robot.sim_time)
                    elif kind == 'damage':
                        self.env.robot.set_damage(a)
                        self._publish_description(a)
                        self._publish_state(self.env.robot.sim_time)
                        self.get_logger().warn(f"damage is now '{a}'")
                    elif kind == 'noise':
                        self.env.set_noise_std(a)
            except Exception as exc:  # keep the bridge alive whatever one command does
                self.get_logger().error(f'{kind} failed: {type(exc).__name__}: {exc}')
            finally:
                with self._cond:
                    self._busy = False

    def _run_gait(self, behavior_id, params):
        pace = self._pace(self._publish_state)
        result = self.env.execute(params, callback=pace, callback_period=pace.period)
        pace.hold_until(self.env.robot.sim_time)  # a fallen robot's getting up included
        outcome = conv.BehaviorOutcome(
            behavior_id=behavior_id, generic_reward=result.observed_generic_reward,
            start_pose=result.observed_start, end_pose=result.observed_end,
            fallen=result.fallen, sim_time=result.sim_time, duty_factors=result.duty_factors,
            standing_start=result.standing_start)
        # The outcome first: the adapter's next step waits for it, not for the state.
        self.outcome_pub.publish(conv.outcome_to_msg(outcome))
        if result.fallen:
            self._report_fall(behavior_id)
        self._publish_state(self.env.robot.sim_time)

    def _pace(self, on_state, end=None):
        # Mid-gait state every publish_period of sim time, but at most publish_max_rate times
        # per wall second: every message wakes each subscriber's executor, and on a small
        # machine that CPU time is taken from the gait (+15 % per step measured at 0.5 s sim
        # uncapped, 20x real time). The state at the end of the gait always goes out, after
        # it. Shutting down ends the pacing (the gait finishes at once).
        return GaitPace(on_state, self.env.robot.sim_time, self.publish_period,
                        self.env.robot.dt, max_rate=self.publish_max_rate,
                        real_time_factor=self.real_time_factor, end=end,
                        sleep=self._stop.wait)

    def _report_fall(self, behavior_id):
        values = {'behavior_id': 'none (a trajectory)' if behavior_id is None else behavior_id,
                  'action': 'righted in place' if self.right_on_fall
                  else 'down until /sim_bridge/reset'}
        self.diag_pub.publish(conv.diagnostic_array(conv.diagnostic_status(
            DiagnosticStatus.ERROR, 'sim_bridge: robot', 'robot fell or flipped', values,
            hardware_id=self.description.name), self.env.robot.sim_time))
        self.get_logger().error(f'robot fell during behavior {behavior_id}')

    def _publish_state(self, sim_time, pose=None, positions=None, velocities=None):
        stamp = conv.time_to_msg(sim_time)
        self.clock_pub.publish(ClockMsg(clock=stamp))
        pose = self.env.true_pose() if pose is None else pose
        odom = conv.odometry_msg(pose, stamp=sim_time)
        self.odom_pub.publish(odom)
        if self.tf_pub is not None:
            self.tf_pub.publish(ifc.TF.type(transforms=[self._base_transform(odom)]))
        if positions is None:
            positions, velocities = self.env.robot.joint_states()
        self._publish_joint_states(stamp, positions, velocities)
        if self.interface == 'trajectory':
            self._publish_hardware_state(sim_time)

    def _publish_joint_states(self, stamp, positions, velocities):
        js = JointState()
        js.header.stamp = stamp
        js.name = list(self.env.robot.joint_names)
        js.position = [float(v) for v in positions]
        js.velocity = [float(v) for v in velocities]
        self.joint_pub.publish(js)

    def _map_transform(self, map_frame):
        """``map_frame`` -> odom, the identity, stamped at the simulation's start (a static
        transform holds at every time)."""
        tf = TransformStamped()
        tf.header.frame_id = map_frame
        tf.child_frame_id = 'odom'  # the odometry's frame (conv.odometry_msg)
        tf.transform.rotation.w = 1.0
        return tf

    def _base_transform(self, odom):
        """odom -> base_link: the body's full pose in the simulator (height, roll, pitch
        included, so RViz draws it standing on the ground), stamped as the odometry."""
        (x, y, z), (qx, qy, qz, qw) = self.env.robot.base_pose_3d()
        tf = TransformStamped()
        tf.header = odom.header
        tf.child_frame_id = odom.child_frame_id
        t, r = tf.transform.translation, tf.transform.rotation
        t.x, t.y, t.z = float(x), float(y), float(z)
        r.x, r.y, r.z, r.w = float(qx), float(qy), float(qz), float(qw)
        return tf

    def _publish_description(self, damage):
        self.description_pub.publish(String(data=self.description.urdf(damage)))

    def destroy_node(self):
        self._stop.set()
        self._worker.join(timeout=5.0)
        super().destroy_node()


def main(args=None):
    run_node(SimBridge, args)


if __name__ == '__main__':
    main()
