"""The ``sim_bridge`` node: the PyBullet hexapod on the ROS graph.

Publishes ``/clock`` (it owns sim time), ``/hexapod/odom`` (odom -> base_link),
``/hexapod/joint_states``; executes each command on ``/hexapod/behavior`` and answers with
exactly one ``/hexapod/behavior_outcome`` carrying the command's id; serves
``/sim_bridge/reset``. ``damage`` can be changed at run time with ``ros2 param set``.

Gaits run on a worker thread that owns the simulator, so the node's single-threaded
executor keeps answering services, parameters and subscriptions while the robot walks.
(A MultiThreadedExecutor here delayed some commands by 10-350 ms, measured.)
"""
import threading
import time
from collections import deque

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import Trigger

from sela_ros.nodes import conversions as conv
from sela_ros.nodes.heartbeat import add_heartbeat
from sela_ros.nodes.node_main import run_node
from sela_ros.nodes.params import first_problem, non_negative_number, positive_number, startup_only
from sela_ros.nodes.qos import COMMAND_QOS, OUTCOME_QOS, STATE_QOS
from sim_bridge.damage import DamageSpecError, parse_damage
from sim_bridge.environment import ObservedHexapod
from sim_bridge.hexapod import Hexapod


def damage_rule(value):
    """A damage spec users can type; the error lists the valid names."""
    if not isinstance(value, str):
        return f'must be a string such as remove:middle_right, got {value!r}'
    try:
        parse_damage(value)
    except DamageSpecError as exc:
        return f'is invalid: {exc}'
    return None


IDLE_PERIOD = 0.1  # s (wall) between state messages while no gait runs

PARAMETER_RULES = {
    'damage': damage_rule,
    'observation.noise_std': non_negative_number(' (m)'),
    'publish_period': positive_number(' (s of sim time)'),
    'publish_max_rate': non_negative_number(' (Hz of wall time, 0: no cap)'),
    'sim.dt': startup_only, 'sim.gait_duration': startup_only, 'sim.gui': startup_only,
    'seed': startup_only, 'right_on_fall': startup_only,
}


class SimBridge(Node):
    def __init__(self):
        super().__init__('sim_bridge')
        self.declare_parameter('damage', 'remove:middle_right')
        self.declare_parameter('sim.dt', 1.0 / 240.0)
        self.declare_parameter('sim.gait_duration', 3.0)
        self.declare_parameter('sim.gui', False)
        self.declare_parameter('publish_period', 0.5)
        self.declare_parameter('publish_max_rate', 5.0)
        self.declare_parameter('observation.noise_std', 0.01)
        self.declare_parameter('seed', 0)
        # False: a fallen robot stays down until /sim_bridge/reset (the adapter calls it);
        # True: rebuilt standing where it lies after the gait (no adapter needed).
        self.declare_parameter('right_on_fall', False)

        damage = self.get_parameter('damage').value
        try:
            parse_damage(damage)
        except DamageSpecError as exc:
            self.get_logger().error(f'parameter damage: {exc}; starting intact')
            damage = 'intact'
        robot = Hexapod(dt=self.get_parameter('sim.dt').value,
                        gait_duration=self.get_parameter('sim.gait_duration').value,
                        damage=damage, gui=self.get_parameter('sim.gui').value)
        self.env = ObservedHexapod(robot, self.get_parameter('observation.noise_std').value,
                                   seed=self.get_parameter('seed').value,
                                   right_on_fall=self.get_parameter('right_on_fall').value)
        self.publish_period = float(self.get_parameter('publish_period').value)
        self.publish_max_rate = float(self.get_parameter('publish_max_rate').value)
        self.right_on_fall = bool(self.get_parameter('right_on_fall').value)

        self._sim_lock = threading.Lock()  # held by whoever touches the simulator
        # The worker's queue (FIFO): commands, resets, damage and noise changes.
        self._cond = threading.Condition()
        self._work = deque()
        self._busy = False  # the worker holds an item from the queue
        self._next_auto_id = 1_000_000_000  # ids for commands sent without one

        self.clock_pub = self.create_publisher(ClockMsg, '/clock', STATE_QOS)
        self.odom_pub = self.create_publisher(conv.Odometry, '/hexapod/odom', STATE_QOS)
        self.joint_pub = self.create_publisher(JointState, '/hexapod/joint_states', STATE_QOS)
        self.outcome_pub = self.create_publisher(Float64MultiArray, '/hexapod/behavior_outcome',
                                                 OUTCOME_QOS)
        self.diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', STATE_QOS)
        self.create_subscription(Float64MultiArray, '/hexapod/behavior', self.behavior_callback,
                                 COMMAND_QOS)
        self.create_service(Trigger, '/sim_bridge/reset', self.reset_callback)
        self.add_on_set_parameters_callback(self.parameters_callback)
        add_heartbeat(self)

        self._stop = threading.Event()
        self._worker = threading.Thread(target=self._work_loop, name='gait_worker', daemon=True)
        self._worker.start()
        self._publish_state(self.env.robot.sim_time)
        self.get_logger().info(f"hexapod ready, damage '{damage}', "
                               f'noise std {self.env.noise_std} m')

    # --- callbacks (short: they only validate and enqueue) -------------------------------

    def behavior_callback(self, msg):
        try:
            params, behavior_id = conv.behavior_from_msg(msg)
        except conv.MessageError as exc:
            message = f'rejected command on /hexapod/behavior: {exc}'
            self.get_logger().error(message)
            self.diag_pub.publish(conv.diagnostic_array(conv.diagnostic_status(
                DiagnosticStatus.ERROR, 'sim_bridge: command', message, hardware_id='hexapod'),
                self.env.robot.sim_time))
            return
        if behavior_id is None:
            behavior_id = self._next_auto_id
            self._next_auto_id += 1
        self._enqueue('gait', behavior_id, params)

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

    def parameters_callback(self, params):
        problem = first_problem(((p.name, p.value) for p in params), PARAMETER_RULES)
        if problem:
            return SetParametersResult(successful=False, reason=problem)
        for param in params:
            if param.name == 'damage':
                self._enqueue('damage', parse_damage(param.value).canonical(), None)
            elif param.name == 'observation.noise_std':
                self._enqueue('noise', float(param.value), None)
            elif param.name == 'publish_period':
                self.publish_period = float(param.value)
            elif param.name == 'publish_max_rate':
                self.publish_max_rate = float(param.value)
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
                    elif kind == 'reset':
                        self.env.reset()
                        self._publish_state(self.env.robot.sim_time)
                    elif kind == 'damage':
                        self.env.robot.set_damage(a)
                        self._publish_state(self.env.robot.sim_time)
                        self.get_logger().warn(f"damage is now '{a}'")
                    elif kind == 'noise':
                        self.env.noise_std = a
            except Exception as exc:  # keep the bridge alive whatever one command does
                self.get_logger().error(f'{kind} failed: {type(exc).__name__}: {exc}')
            finally:
                with self._cond:
                    self._busy = False

    def _run_gait(self, behavior_id, params):
        # Mid-gait state every publish_period of sim time, but at most publish_max_rate times
        # per wall second: every message wakes each subscriber's executor, and on a small
        # machine that CPU time is taken from the gait (+15 % per step measured at 0.5 s sim
        # uncapped, 20x real time). The state at the end of the gait always goes out.
        min_gap = 1.0 / self.publish_max_rate if self.publish_max_rate > 0 else 0.0
        last = [time.monotonic()]

        def on_step(sim_time, pose, positions, velocities):
            now = time.monotonic()
            if now - last[0] >= min_gap:
                last[0] = now
                self._publish_state(sim_time, pose, positions, velocities)

        result = self.env.execute(params, callback=on_step, callback_period=self.publish_period)
        outcome = conv.BehaviorOutcome(
            behavior_id=behavior_id, generic_reward=result.observed_generic_reward,
            start_pose=result.observed_start, end_pose=result.observed_end,
            fallen=result.fallen, sim_time=result.sim_time, duty_factors=result.duty_factors)
        # The outcome first: the adapter's next step waits for it, not for the state.
        self.outcome_pub.publish(conv.outcome_to_msg(outcome))
        if result.fallen:
            self._report_fall(behavior_id)
        self._publish_state(self.env.robot.sim_time)

    def _report_fall(self, behavior_id):
        values = {'behavior_id': behavior_id,
                  'action': 'righted in place' if self.right_on_fall
                  else 'down until /sim_bridge/reset'}
        self.diag_pub.publish(conv.diagnostic_array(conv.diagnostic_status(
            DiagnosticStatus.ERROR, 'sim_bridge: robot', 'robot fell or flipped', values,
            hardware_id='hexapod'), self.env.robot.sim_time))
        self.get_logger().error(f'robot fell during behavior {behavior_id}')

    def _publish_state(self, sim_time, pose=None, positions=None, velocities=None):
        stamp = conv.time_to_msg(sim_time)
        self.clock_pub.publish(ClockMsg(clock=stamp))
        pose = self.env.true_pose() if pose is None else pose
        odom = conv.odometry_msg(pose, stamp=sim_time)
        self.odom_pub.publish(odom)
        if positions is None:
            positions, velocities = self.env.robot.joint_states()
        js = JointState()
        js.header.stamp = stamp
        js.name = list(self.env.robot.joint_names)
        js.position = [float(v) for v in positions]
        js.velocity = [float(v) for v in velocities]
        self.joint_pub.publish(js)

    def destroy_node(self):
        self._stop.set()
        self._worker.join(timeout=5.0)
        super().destroy_node()


def main(args=None):
    run_node(SimBridge, args)


if __name__ == '__main__':
    main()
