"""The ``sela_adapter`` node: the archive, the GPs and UCB; chooses gaits and learns.

Each step (a small state machine driven by events, so no callback ever waits):

1. call ``/planner/make_plan`` from the latest observed pose to the goal, and take the
   waypoint the planner publishes on ``/sela/target`` for that request (same stamp: seconds
   the step number, nanoseconds a random nonce); the answer is only awaited when no target
   comes (planning failed);
2. ``SELA.ask`` picks a behaviour; publish the 36 parameters on ``/hexapod/behavior`` (with a
   command id) and the prediction on ``/sela/prediction``;
3. the matching ``/hexapod/behavior_outcome`` arrives: request the next step's plan from the
   new pose at once (the planner works while this node learns), learn from the outcome when
   adapting, publish the specialised reward observed on ``/sela/reward``;
4. wait (at most ``detector_timeout`` s) for the damage detector's verdict on that outcome on
   ``/diagnostics``: if it decided to adapt, it has called ``/sela_adapter/adapt`` first.

An outcome that says the robot fell is a failed step: with ``reset_on_fall`` the robot is put
back at the start through ``/sim_bridge/reset`` before the next step, and the gait is learnt
as going nowhere. Before the first step with an archive, the simulator's ``sim.dt`` and
``sim.gait_duration`` are checked against the archive's (``simulator_node``).

The mission starts trusting the intact map; ``/sela_adapter/adapt`` starts adaptation, or
restarts it from scratch when it was running. Progress is published on ``/diagnostics``
(name ``sela_adapter: mission``) once per step.

What was learned (the GPs' observations) and the mission state are written atomically to
``state_file`` after every step and read back at start-up (``resume``), so a killed adapter
loses at most the step in flight; learning is lifelong across goals until
``/sela_adapter/clear`` is called. A bad archive is reported and the node stays up: set a
good one with ``ros2 param set /sela_adapter archive PATH``.
"""
import math
import os
from collections import deque
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PointStamped, PoseStamped
from nav_msgs.msg import Odometry
from nav_msgs.srv import GetPlan
from rcl_interfaces.msg import ParameterType, SetParametersResult
from rcl_interfaces.srv import GetParameters
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from std_msgs.msg import Float64, Float64MultiArray
from std_srvs.srv import Trigger

from sela_ros.core.archive import ArchiveError, check_settings, default_archive_path, load_archive
from sela_ros.core.mission import MissionLogic, make_sela
from sela_ros.core.persistence import (
    STATE_FORMAT,
    StateError,
    atomic_write_json,
    load_state,
    set_aside,
)
from sela_ros.core.sela import Decision
from sela_ros.nodes import conversions as conv
from sela_ros.nodes.heartbeat import add_heartbeat
from sela_ros.nodes.node_main import run_node
from sela_ros.nodes.params import (
    first_problem,
    positive_int,
    positive_number,
    startup_only,
    string,
)
from sela_ros.nodes.qos import COMMAND_QOS, LATCHED_QOS, OUTCOME_QOS, STATE_QOS

DETECTOR_STATUS = 'damage_detector: prediction error'
MISSION_STATUS = 'sela_adapter: mission'
TICK_PERIOD = 0.25  # s (wall)
SELA_KEYS = ('gp.kernel.sigma', 'gp.noise', 'acquisition.ucb.alpha', 'goal.eps',
             'fall.risk.threshold')


class SelaAdapter(Node):
    def __init__(self):
        super().__init__('sela_adapter')
        self.declare_parameter('archive', '')
        self.declare_parameter('gp.kernel.sigma', 0.1)
        self.declare_parameter('gp.noise', 0.001)
        self.declare_parameter('acquisition.ucb.alpha', 0.05)
        self.declare_parameter('goal.eps', 0.1)
        self.declare_parameter('fall.risk.threshold', 0.3)
        self.declare_parameter('max_steps', 100)
        self.declare_parameter('detector_timeout', 2.0)
        self.declare_parameter('outcome_timeout', 10.0)
        self.declare_parameter('adapt_on_start', False)
        self.declare_parameter('frame_id', 'odom')
        self.declare_parameter('state_file', '')
        self.declare_parameter('resume', True)
        self.declare_parameter('reset_on_fall', True)
        # The node whose sim.dt and sim.gait_duration the archive must have been built with
        # ('' on a real robot: nothing to check).
        self.declare_parameter('simulator_node', 'sim_bridge')

        self.frame_id = self.get_parameter('frame_id').value
        self.max_steps = int(self.get_parameter('max_steps').value)
        self.state_file = self.get_parameter('state_file').value or os.path.join(
            os.environ.get('ROS_HOME', os.path.expanduser('~/.ros')), 'sela_ros',
            'sela_adapter_state.json')
        self.archive = self.sela = self.logic = None
        self._saver = ThreadPoolExecutor(max_workers=1, thread_name_prefix='state_saver')
        self.wall = Clock(clock_type=ClockType.STEADY_TIME)
        self.state = 'idle'
        self.goal = None
        self.odom_pose = None
        self.pose = None  # latest observed pose (from outcomes), None before the first one
        self.next_id = 1
        self.pending = {}
        self.targets = {}
        self.verdicts = deque(maxlen=16)  # behaviour ids the detector judged lately
        self.reset_needed = False  # the robot fell: reset it through the service first
        self.adapt_after_outcome = False
        self._nonce = np.random.default_rng()
        self.steps = 0
        self.next_plan = None
        self.failed_steps = 0
        self.result = None

        self.behavior_pub = self.create_publisher(Float64MultiArray, '/hexapod/behavior',
                                                  COMMAND_QOS)
        self.prediction_pub = self.create_publisher(Float64MultiArray, '/sela/prediction',
                                                    COMMAND_QOS)
        self.reward_pub = self.create_publisher(Float64, '/sela/reward', COMMAND_QOS)
        self.diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', STATE_QOS)
        self.create_subscription(PoseStamped, '/goal_pose', self.goal_callback, LATCHED_QOS)
        self.create_subscription(Odometry, '/hexapod/odom', self.odom_callback, STATE_QOS)
        self.create_subscription(Float64MultiArray, '/hexapod/behavior_outcome',
                                 self.outcome_callback, OUTCOME_QOS)
        self.create_subscription(PointStamped, '/sela/target', self.target_callback,
                                 LATCHED_QOS)
        self.create_subscription(DiagnosticArray, '/diagnostics', self.diagnostics_callback,
                                 STATE_QOS)
        self.plan_client = self.create_client(GetPlan, '/planner/make_plan')
        self.reset_client = self.create_client(Trigger, '/sim_bridge/reset')
        simulator = self.get_parameter('simulator_node').value
        self.sim_params_client = (self.create_client(GetParameters, f'/{simulator}/get_parameters')
                                  if simulator else None)
        self.sim_check = None  # None: not checked yet, 'pending', True: matches, str: why not
        self.create_service(Trigger, '/sela_adapter/adapt', self.adapt_callback)
        self.create_service(Trigger, '/sela_adapter/clear', self.clear_callback)
        self.add_on_set_parameters_callback(self.parameters_callback)
        add_heartbeat(self)
        path = self.get_parameter('archive').value or str(default_archive_path())
        try:
            self._use_archive(path)
        except ArchiveError as exc:
            self._error(f'no archive loaded: {exc}')
        else:
            if self.get_parameter('resume').value:
                self._resume()
        # Steps advance on events (goal, target, outcome, verdict); this timer only catches
        # time-outs and start-up (planner not up yet), so it is slow: every wake-up of this
        # process costs the simulator CPU time on a small machine.
        self.timer = self.create_timer(TICK_PERIOD, self.tick, clock=self.wall)

    # --- archive and persistence ---------------------------------------------------------

    def _use_archive(self, path):
        archive = load_archive(path)
        self.archive = archive
        self.archive_path = path
        self.sim_check = None  # a new archive is checked against the simulator again
        self.sela = make_sela(archive, {k: self.get_parameter(k).value for k in SELA_KEYS})
        if self.goal is not None:
            self.sela.set_goal(self.goal)
        self.logic = MissionLogic(self.sela, self.get_parameter('adapt_on_start').value,
                                  reset_on_fall=self.get_parameter('reset_on_fall').value)
        self.get_logger().info(f'archive {path}: {len(archive)} behaviours')

    def _resume(self):
        try:
            state = load_state(self.state_file, len(self.archive))
        except StateError as exc:
            kept = set_aside(self.state_file)
            self._error(f'{exc}; kept it as {kept} and started afresh')
            return
        if state is None:
            return
        self.sela.load_state_dict(state['sela'])
        m = state['mission']
        self.logic.adapting = bool(m['adapting'])
        self.logic.adaptations = int(m['adaptations'])
        self.logic.last = None if m['last'] is None else (int(m['last'][0]),
                                                          np.array(m['last'][1]))
        self.next_id = int(m['next_id'])
        self.steps = int(m['steps'])
        self.pose = None if m['pose'] is None else np.array(m['pose'])
        self.reset_needed = bool(m.get('reset_needed', False))
        if m['goal'] is not None:
            self.goal = np.array(m['goal'])
            self.sela.set_goal(self.goal)
        pending = m.get('pending')
        if pending is not None and m['state'] in ('executing', 'verdict'):
            decision = Decision(index=int(pending['index']), waypoint=np.array(
                pending['waypoint']), predicted_gr=np.array(pending['predicted_gr']),
                predicted_pose=np.array(pending['predicted_pose']),
                reward=float(pending['reward']), sigma=float(pending['sigma']))
            self.pending = {'id': int(pending['id']), 'pose': np.array(pending['pose']),
                            'waypoint': decision.waypoint, 'decision': decision,
                            'deadline': self.wall.now().nanoseconds * 1e-9
                            + float(self.get_parameter('outcome_timeout').value)}
            # The outcome may already be waiting (outcomes are latched by sim_bridge).
            self.state = 'executing' if m['state'] == 'executing' else 'ready'
            if m['state'] == 'verdict':
                self.pending = {}
        elif self.goal is not None and m['state'] not in ('done', 'idle'):
            # (a reset in flight is asked again: reset_needed was saved before asking)
            self.state = 'ready'
        self.get_logger().warn(
            f'resumed from {self.state_file}: {len(self.sela.observations[0])} observation(s), '
            f"step {self.steps}, {'adapting' if self.logic.adapting else 'trusting the map'}")

    def _save(self):
        if self.logic is None:
            return
        pending = None
        if self.pending.get('decision') is not None and 'id' in self.pending:
            d = self.pending['decision']
            pending = {'id': self.pending['id'], 'index': int(d.index),
                       'pose': np.asarray(self.pending['pose'], float).tolist(),
                       'waypoint': np.asarray(d.waypoint, float).tolist(),
                       'predicted_gr': d.predicted_gr.tolist(),
                       'predicted_pose': d.predicted_pose.tolist(), 'reward': d.reward,
                       'sigma': d.sigma}
        last = self.logic.last
        state = {
            'format': STATE_FORMAT, 'archive_size': len(self.archive),
            'sela': self.sela.state_dict(),
            'mission': {'state': self.state, 'steps': self.steps,
                        'goal': None if self.goal is None else self.goal.tolist(),
                        'pose': None if self.pose is None else np.asarray(self.pose).tolist(),
                        'adapting': self.logic.adapting,
                        'adaptations': self.logic.adaptations,
                        'last': None if last is None else [int(last[0]), last[1].tolist()],
                        'next_id': self.next_id, 'pending': pending,
                        'reset_needed': self.reset_needed}}
        # The snapshot is taken here; the fsync'ed write happens off the step's critical path,
        # one at a time and in order (a later snapshot always lands after an earlier one).
        self._saver.submit(self._write_state, state)

    def _write_state(self, state):
        try:
            atomic_write_json(self.state_file, state)
        except (OSError, ValueError) as exc:
            self.get_logger().error(f'could not save the learned state to {self.state_file}: '
                                    f'{exc}')

    def _error(self, message):
        self.get_logger().error(message)
        self.diag_pub.publish(conv.diagnostic_array(conv.diagnostic_status(
            DiagnosticStatus.ERROR, MISSION_STATUS, message), self.get_clock().now().to_msg()))

    # --- inputs --------------------------------------------------------------------------

    def goal_callback(self, msg):
        try:
            goal = conv.goal_from_pose_stamped(msg, self.frame_id)
        except conv.MessageError as exc:
            self.get_logger().error(f'goal rejected: {exc}')
            return
        if (self.goal is not None and np.array_equal(goal, self.goal)
                and self.state not in ('idle', 'done')):
            return  # the latched goal again (e.g. after a restart): the mission goes on
        self.goal = goal
        self.next_plan = None
        self.targets.clear()
        if self.sela is not None:
            self.sela.set_goal(goal)
        self.steps = 0
        self.result = None
        if self.state in ('idle', 'done'):
            self.state = 'ready'
        self._save()
        self.get_logger().info(f'new goal ({goal[0]:.2f}, {goal[1]:.2f})')
        if isinstance(self.sim_check, str):
            self._error(self.sim_check)
        self.tick()

    def odom_callback(self, msg):
        try:
            self.odom_pose = conv.pose_from_odometry(msg)
        except conv.MessageError as exc:
            self.get_logger().error(f'ignored odometry: {exc}')
            return
        if self.state == 'ready' and self.pose is None:
            self.tick()  # waiting for a pose (start, or after a reset): here it is

    def target_callback(self, msg):
        try:
            self.targets[(msg.header.stamp.sec, msg.header.stamp.nanosec)] = \
                conv.point_from_msg(msg)
        except conv.MessageError as exc:
            self.get_logger().error(f'ignored target: {exc}')
            return
        self.tick()

    def outcome_callback(self, msg):
        try:
            outcome = conv.outcome_from_msg(msg)
        except conv.MessageError as exc:
            self.get_logger().error(f'ignored outcome: {exc}')
            return
        if self.state != 'executing' or outcome.behavior_id != self.pending.get('id'):
            if outcome.behavior_id >= self.next_id:
                self.get_logger().warn(f'ignored outcome {outcome.behavior_id}: it pairs with '
                                       'no command of this adapter')
            return
        self._on_outcome(outcome)

    def diagnostics_callback(self, msg):
        for status in msg.status:
            if status.name != DETECTOR_STATUS:
                continue
            # Kept even when it comes before the outcome it judges: the detector and this
            # node hear the outcome independently, and on a busy machine either may be first.
            self.verdicts.append(conv.status_values(status).get('behavior_id'))
        self._verdict_heard()

    def _verdict_heard(self):
        if self.state == 'verdict' and str(self.pending.get('id')) in self.verdicts:
            self.state = 'ready'
            self.tick()

    def adapt_callback(self, request, response):
        if self.logic is None:
            response.success = False
            response.message = 'no archive loaded: set the archive parameter first'
            return response
        response.success = True
        if self.state == 'executing':
            # The detector judged an outcome this node has not processed yet (or a user
            # asked mid-gait): adapt from that outcome, as soon as it is processed.
            self.adapt_after_outcome = True
            response.message = ('adaptation will ' + ('restart' if self.logic.adapting
                                                       else 'start') +
                                f" from the outcome of command {self.pending['id']}")
            self.get_logger().warn(response.message)
            return response
        response.message = self._adapt()
        return response

    def _adapt(self):
        restarting = self.logic.adapting
        self.logic.adapt()
        message = ('adaptation restarted from scratch' if restarting
                   else 'adaptation started') + \
            f' ({len(self.sela.observations[0])} observation(s))'
        self.get_logger().warn(message)
        self._save()
        return message

    def clear_callback(self, request, response):
        if self.logic is None:
            response.success = False
            response.message = 'no archive loaded: nothing to clear'
            return response
        forgotten = len(self.sela.observations[0])
        self.sela.reset_learning()
        self.logic.adapting = bool(self.get_parameter('adapt_on_start').value)
        self.logic.last = None
        self._save()
        response.success = True
        response.message = f'forgot {forgotten} observation(s): back to the intact map'
        self.get_logger().warn(response.message)
        return response

    def parameters_callback(self, params):
        rules = dict.fromkeys(SELA_KEYS + ('adapt_on_start', 'state_file', 'resume',
                                           'frame_id', 'simulator_node', 'reset_on_fall'),
                              startup_only)
        rules.update({'detector_timeout': positive_number(' (s)'),
                      'outcome_timeout': positive_number(' (s)'), 'max_steps': positive_int,
                      'archive': string})
        problem = first_problem(((p.name, p.value) for p in params), rules)
        if problem:
            return SetParametersResult(successful=False, reason=problem)
        for param in params:
            if param.name == 'archive':
                if self.state not in ('idle', 'done', 'ready'):
                    return SetParametersResult(successful=False,
                                               reason='archive cannot change mid-step')
                try:
                    self._use_archive(param.value or str(default_archive_path()))
                except ArchiveError as exc:
                    return SetParametersResult(successful=False, reason=str(exc))
            elif param.name == 'max_steps':
                self.max_steps = param.value
        return SetParametersResult(successful=True)

    # --- the step state machine ----------------------------------------------------------

    def tick(self):
        """Advance the step state machine: on events, and on a slow timer for time-outs."""
        now = self.wall.now().nanoseconds * 1e-9
        self._check_simulator()
        if self.state == 'ready':
            self._start_step(now)
        elif self.state == 'planning':
            self._finish_planning(now)
        elif self.state == 'executing' and now > self.pending['deadline']:
            self.get_logger().error(f"no outcome for command {self.pending['id']} within "
                                    f"{self.get_parameter('outcome_timeout').value} s; "
                                    'sending it again')
            self._send(now)
        elif self.state == 'verdict' and now > self.pending['deadline']:
            self.state = 'ready'
        elif self.state == 'resetting':
            self._finish_reset(now)

    def _check_simulator(self):
        """Ask the simulator (once per archive) for the settings the archive must match."""
        if (self.sim_check is not None or self.archive is None
                or self.sim_params_client is None
                or not self.sim_params_client.service_is_ready()):
            return
        self.sim_check = 'pending'
        future = self.sim_params_client.call_async(
            GetParameters.Request(names=['sim.dt', 'sim.gait_duration']))
        archive = self.archive
        future.add_done_callback(lambda f: self._on_simulator_settings(f, archive))

    def _on_simulator_settings(self, future, archive):
        if archive is not self.archive:
            return  # the archive changed meanwhile: it gets its own check
        values = future.result().values if future.result() is not None else []
        if len(values) != 2 or any(v.type != ParameterType.PARAMETER_DOUBLE for v in values):
            self.sim_check = None  # not a simulator we know how to ask: try again later
            return
        settings = {'dt': values[0].double_value, 'gait_duration': values[1].double_value}
        try:
            check_settings(archive.metadata, settings, source=self.archive_path)
        except ArchiveError as exc:
            self.sim_check = (f'{exc} The simulator runs sim.dt {settings["dt"]:g} s, '
                              f'sim.gait_duration {settings["gait_duration"]:g} s: no gait is '
                              'sent until the archive parameter names a matching archive.')
            self._error(self.sim_check)
            return
        self.sim_check = True
        self.tick()

    def _start_step(self, now):
        if isinstance(self.sim_check, str) or self.sim_check == 'pending':
            return  # does not match the simulator (reported), or the answer is on its way
        if self.reset_needed:
            return self._request_reset(now)
        pose = self.pose if self.pose is not None else self.odom_pose
        if pose is None or self.goal is None or self.logic is None:
            return
        if self.sela.goal_reached(pose):
            return self._finish(True, pose)
        if self.steps >= self.max_steps:
            return self._finish(False, pose)
        plan = self.next_plan
        self.next_plan = None
        if plan is None or not np.array_equal(plan['pose'], pose) or \
                plan['step'] != self.steps + 1:
            plan = self._request_plan(pose, self.steps + 1, now)
            if plan is None:
                return
        self.steps += 1
        self.pending = plan
        self.state = 'planning'
        if plan['future'].done():
            self._finish_planning(now)
        else:
            # Event-driven: continue as soon as the plan is back (the timer: time-outs only).
            plan['future'].add_done_callback(lambda _: self.tick())

    def _request_plan(self, pose, step, now):
        """Ask the planner for the path of ``step`` from ``pose`` (None: planner not up)."""
        if not self.plan_client.service_is_ready():
            return None
        # The stamp pairs the request with the target the planner publishes for it: seconds
        # are the step number, nanoseconds a fresh random nonce (no stale target can match).
        stamp = conv.time_to_msg(step)
        stamp.nanosec = int(self._nonce.integers(0, 1_000_000_000))
        request = GetPlan.Request()
        request.start = conv.pose_stamped(pose[:2], pose[2], stamp, self.frame_id)
        request.goal = conv.pose_stamped(self.goal, 0.0, stamp, self.frame_id)
        return {'pose': pose, 'step': step, 'stamp': (stamp.sec, stamp.nanosec), 't_start': now,
                'future': self.plan_client.call_async(request), 'deadline': now + 10.0}

    def _finish_planning(self, now):
        # The planner publishes the target (paired by stamp) before it answers the request:
        # go on as soon as the target is here. It publishes none when planning fails, and
        # then the answer (an empty plan) says so.
        waypoint = self.targets.pop(self.pending['stamp'], None)
        if waypoint is None:
            future = self.pending['future']
            if future.done() and not future.result().plan.poses:
                self._error('no plan to the goal (the planner says why on /diagnostics); '
                            'waiting for a new goal')
                self.steps -= 1
                self.state = 'idle'
            elif now > self.pending['deadline']:
                self.get_logger().error('planner did not answer; retrying')
                self.steps -= 1
                self.state = 'ready'
            return
        self.targets.clear()
        decision = self.logic.decide(self.pending['pose'], waypoint)
        self.pending.update(decision=decision, waypoint=waypoint, id=self.next_id)
        self.next_id += 1
        self._send(now)
        self.prediction_pub.publish(conv.prediction_to_msg(
            self.pending['id'], decision.predicted_gr, self.logic.prediction_sigma(decision)))
        self._save()

    def _send(self, now):
        params = self.archive.params[self.pending['decision'].index]
        self.pending['t_sent'] = now
        self.behavior_pub.publish(conv.behavior_to_msg(params, self.pending['id']))
        self.pending['deadline'] = now + float(self.get_parameter('outcome_timeout').value)
        self.state = 'executing'

    def _on_outcome(self, outcome):
        decision = self.pending['decision']
        now = self.pending['t_outcome'] = self.wall.now().nanoseconds * 1e-9
        self.pose = outcome.end_pose
        self.reset_needed = bool(outcome.fallen) and bool(
            self.get_parameter('reset_on_fall').value)
        # First ask for the next step's plan (it depends only on the pose, not on what is
        # learnt or on the detector's verdict): the planner works while this node learns.
        self.next_plan = None
        if self.goal is not None and not self.sela.goal_reached(self.pose) \
                and self.steps < self.max_steps and not self.reset_needed:
            self.next_plan = self._request_plan(self.pose, self.steps + 1, now)
        record = self.logic.outcome(decision, self.pending['pose'], outcome.generic_reward,
                                    fallen=outcome.fallen)
        if outcome.fallen:
            self.failed_steps += 1
            self._error(f'step {self.steps} failed: the robot fell or flipped' +
                        ('; resetting it through /sim_bridge/reset' if self.reset_needed
                         else ''))
        reward = -float(np.linalg.norm(self.pending['waypoint'] - outcome.end_pose[:2]))
        self.reward_pub.publish(Float64(data=reward))
        self._publish_status(DiagnosticStatus.OK, 'step', record, reward)
        self.pending['deadline'] = now + float(self.get_parameter('detector_timeout').value)
        self.state = 'verdict'
        if self.adapt_after_outcome:
            self.adapt_after_outcome = False
            self._adapt()  # saves
        else:
            self._save()
        self._verdict_heard()

    def _request_reset(self, now):
        """The robot fell: put it back at the start through the service, then go on."""
        if not self.reset_client.service_is_ready():
            self.reset_needed = False
            self._error('/sim_bridge/reset is not available: going on from where the robot '
                        'lies')
            return
        self.pending = {'future': self.reset_client.call_async(Trigger.Request()),
                        'deadline': now + float(self.get_parameter('outcome_timeout').value)}
        self.pending['future'].add_done_callback(lambda _: self.tick())
        self.state = 'resetting'
        self.get_logger().warn('robot fell: calling /sim_bridge/reset')

    def _finish_reset(self, now):
        future = self.pending['future']
        if not future.done():
            if now > self.pending['deadline']:
                self.reset_needed = False
                self.state = 'ready'
                self._error('/sim_bridge/reset did not answer: going on from where the robot '
                            'lies')
            return
        answer = future.result()
        self.reset_needed = False
        self.state = 'ready'
        if answer is not None and answer.success:
            # The next step starts from the pose the simulator reports after the reset.
            self.pose = self.odom_pose = None
            self.next_plan = None
            self.get_logger().warn(f'reset: {answer.message}')
        else:
            self._error('reset refused: ' + (answer.message if answer else 'no answer') +
                        '; going on from where the robot lies')
        self._save()
        self.tick()

    def _finish(self, success, pose):
        self.state = 'done'
        self.result = success
        level = DiagnosticStatus.OK if success else DiagnosticStatus.ERROR
        message = 'goal reached' if success else f'goal not reached in {self.max_steps} steps'
        self.get_logger().info(f'{message} after {self.steps} steps, pose '
                               f'({pose[0]:.2f}, {pose[1]:.2f})')
        self._publish_status(level, message, None, None)
        self._save()

    def _publish_status(self, level, message, record, reward):
        values = {'state': self.state, 'steps': self.steps,
                  'adapting': self.logic.adapting, 'adaptations': self.logic.adaptations,
                  'observations': len(self.sela.observations[0]),
                  'failed_steps': self.failed_steps}
        if record is not None:
            values.update(step=record.step, behavior_id=self.pending['id'],
                          behavior_index=record.behavior_index,
                          pose=_fmt(record.pose), waypoint=_fmt(record.waypoint),
                          predicted_gr=_fmt(record.predicted_gr),
                          observed_gr=_fmt(record.observed_gr), reward=f'{reward:.6f}',
                          end_pose=_fmt(self.pose), fallen=record.fallen,
                          # wall time of the step so far: choosing, and the gait's round trip
                          decide_ms=_ms(self.pending, 't_start', 't_sent'),
                          execute_ms=_ms(self.pending, 't_sent', 't_outcome'))
        if self.result is not None:
            values['success'] = self.result
        self.diag_pub.publish(conv.diagnostic_array(
            conv.diagnostic_status(level, MISSION_STATUS, message, values),
            self.get_clock().now().to_msg()))


    def destroy_node(self):
        self._saver.shutdown(wait=True)  # the last snapshot reaches the disk
        super().destroy_node()


def _ms(pending, start, end):
    if start in pending and end in pending:
        return f'{(pending[end] - pending[start]) * 1e3:.1f}'
    return 'nan'


def _fmt(values):
    return ' '.join(f'{float(v):.6f}' if math.isfinite(float(v)) else 'nan' for v in values)


def main(args=None):
    run_node(SelaAdapter, args)


if __name__ == '__main__':
    main()
