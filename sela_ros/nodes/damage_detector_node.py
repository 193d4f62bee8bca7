"""The ``damage_detector`` node: compares each outcome with the prediction that preceded it.

Pairs ``sela/prediction`` and ``hexapod/behavior_outcome`` by command id, in whichever
order they arrive (both are reliable and kept for late joiners), judges the error with
:class:`sela_ros.core.detection.DamageDetector` and publishes one verdict per outcome
on ``~/verdict`` (``/damage_detector/verdict``): the adapter waits for it, and adapts when it
says damage was detected. The same verdict goes to ``diagnostics`` (name ``damage_detector:
prediction error``; level ERROR when damage is detected) for whoever monitors the robot.
"""
from diagnostic_msgs.msg import DiagnosticStatus
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.node import Node

from sela_ros.core.detection import DamageDetector, DetectorConfig
from sela_ros.core.validation import ImplausibleOutcome, OutcomeLimits, check_outcome
from sela_ros.nodes import conversions as conv
from sela_ros.nodes import interface as ifc
from sela_ros.nodes.guard import guard, guard_parameters
from sela_ros.nodes.heartbeat import LivenessMonitor, add_heartbeat
from sela_ros.nodes.node_main import run_node
from sela_ros.nodes.params import Spec, declare

STATUS_NAME = ifc.DETECTOR_STATUS
UNPAIRED_KEPT = 1000  # predictions or outcomes waiting for their other half


def parameters(defaults):
    """The detector's parameters; ``defaults`` is a :class:`DetectorConfig`."""
    return (
        Spec('detection.threshold', defaults.threshold, 'error between predicted and observed '
             'displacement above which damage is detected', low=0.0, high=10.0, unit=' m'),
        Spec('detection.yaw_weight', defaults.yaw_weight, 'heading error counted in the error',
             low=0.0, high=10.0, unit=' m/rad'),
        Spec('detection.window', defaults.window, 'outcomes averaged before deciding', low=1,
             high=1000),
        Spec('detection.cooldown', defaults.cooldown, 'outcomes after a detection before the '
             'next one', low=0, high=1000),
        Spec('detection.max_sigma', defaults.max_sigma, 'only predictions at most this unsure '
             '(std) are judged', low=0.0, high=10.0, unit=' m'),
        Spec('outcome.max_displacement', OutcomeLimits().max_displacement, 'an outcome that '
             'moves the robot further than this in one gait is refused, not judged', low=1e-3,
             high=1e6, unit=' m'),
        Spec('heartbeat.timeout', 10.0, 'wall time from start-up before a watched node never '
             'seen alive is reported silent (a killed node is reported when its liveliness '
             'lease expires)', low=0.1, high=3600.0, unit=' s'),
        Spec('heartbeat.nodes', [ifc.SIM_BRIDGE, ifc.PLANNER, ifc.SELA_ADAPTER],
             'nodes whose liveliness is watched', read_only=True),
    )


class DamageDetectorNode(Node):
    def __init__(self):
        super().__init__(ifc.DAMAGE_DETECTOR)
        values = declare(self, parameters(DetectorConfig()), on_change=self.parameters_callback)
        self.detector = DamageDetector(self._config_from({}))
        self.predictions = {}  # behaviour id -> (gr, sigma), waiting for the outcome
        self.outcomes = {}  # behaviour id -> outcome, waiting for the prediction
        self.limits = OutcomeLimits(float(values['outcome.max_displacement']))
        self.wall = Clock(clock_type=ClockType.STEADY_TIME)

        self.diag_pub = ifc.publisher(self, ifc.DIAGNOSTICS)
        self.verdict_pub = ifc.publisher(self, ifc.VERDICT)
        ifc.subscription(self, ifc.PREDICTION, self.prediction_callback)
        ifc.subscription(self, ifc.OUTCOME, self.outcome_callback)
        # Watch the other nodes' liveliness (the middleware's): a lost node is reported.
        watched = [n for n in values['heartbeat.nodes'] if n in ifc.ALIVE]
        self.liveness = LivenessMonitor(self, watched, values['heartbeat.timeout'],
                                        self.liveliness_callback)
        self.watch = self.liveness.watch
        self.create_timer(0.5, self.check_heartbeats, clock=self.wall)
        add_heartbeat(self)
        self.get_logger().info(f'threshold {self.detector.config.threshold} m')

    def liveliness_callback(self, node, change):
        if change == 'lost':
            self.get_logger().error(self.watch.why(node))
            self._publish_liveness(node, DiagnosticStatus.ERROR, self.watch.why(node))
        elif change == 'alive':
            self.get_logger().info(f'{node} alive')
            self._publish_liveness(node, DiagnosticStatus.OK, f'{node} alive (liveliness)')

    def _publish_liveness(self, node, level, message):
        self.diag_pub.publish(conv.diagnostic_array(
            [conv.diagnostic_status(level, f'{node}: liveness', message)],
            self.get_clock().now().to_msg()))

    @guard
    def check_heartbeats(self):
        self.liveness.poll()
        newly_silent, back = self.watch.check()
        # Every watched node's state at every check, as diagnostics are meant to be read (a
        # monitor that starts late still sees it); a node still starting up is not said.
        statuses = []
        for node in sorted(self.watch.alive):
            if node in self.watch.silent:
                message = self.watch.why(node)
                if node in newly_silent and node not in self.watch.lost:
                    self.get_logger().error(message)  # a lost one was logged by its event
                statuses.append(conv.diagnostic_status(DiagnosticStatus.ERROR,
                                                       f'{node}: liveness', message))
            elif node in self.watch.seen:
                if node in back:
                    self.get_logger().info(f'{node} is back')
                statuses.append(conv.diagnostic_status(DiagnosticStatus.OK, f'{node}: liveness',
                                                       f'{node} alive (liveliness)'))
        if statuses:
            self.diag_pub.publish(conv.diagnostic_array(statuses,
                                                        self.get_clock().now().to_msg()))

    def _config_from(self, overrides):
        values = {name: self.get_parameter(f'detection.{name}').value
                  for name in ('threshold', 'yaw_weight', 'window', 'cooldown', 'max_sigma')}
        values.update(overrides)
        return DetectorConfig(**values)

    @guard_parameters
    def parameters_callback(self, params):
        # Called by params.declare with values its check accepted; the detector's own
        # configuration check still applies to the combination.
        overrides = {p.name.split('.', 1)[1]: p.value for p in params
                     if p.name.startswith('detection.')}
        config = None
        if overrides:
            try:
                config = self._config_from(overrides)
            except (TypeError, ValueError) as exc:
                return SetParametersResult(successful=False, reason=str(exc))
        # Everything checked: apply.
        for p in params:
            if p.name == 'heartbeat.timeout':
                self.watch.set_grace(p.value)
            elif p.name == 'outcome.max_displacement':
                self.limits = OutcomeLimits(float(p.value))
        if config is not None:
            self.detector = DamageDetector(config)
        return SetParametersResult(successful=True)

    @guard
    def prediction_callback(self, msg):
        try:
            behavior_id, gr, sigma = conv.prediction_from_msg(msg)
        except conv.MessageError as exc:
            self.get_logger().error(f'ignored prediction: {exc}')
            return
        outcome = self.outcomes.pop(behavior_id, None)
        if outcome is not None:
            self._judge(outcome, gr, sigma)
        else:
            _keep(self.predictions, behavior_id, (gr, sigma))

    @guard
    def outcome_callback(self, msg):
        try:
            outcome = conv.outcome_from_msg(msg)
        except conv.MessageError as exc:
            self.get_logger().error(f'ignored outcome: {exc}')
            return
        try:
            check_outcome(outcome.generic_reward, outcome.start_pose, outcome.end_pose,
                          self.limits)
        except ImplausibleOutcome as exc:
            # Not judged, not kept (the adapter refuses it too, with the same limit): an
            # outcome no gait can produce says nothing about damage. The prediction stays
            # for the outcome of the command sent again.
            message = f'outcome of command {outcome.behavior_id} refused: {exc}'
            self.get_logger().error(message)
            self.diag_pub.publish(conv.diagnostic_array(conv.diagnostic_status(
                DiagnosticStatus.ERROR, STATUS_NAME, message,
                {'behavior_id': outcome.behavior_id}, hardware_id='hexapod'),
                self.get_clock().now().to_msg()))
            return
        prediction = self.predictions.pop(outcome.behavior_id, None)
        if prediction is not None:
            self._judge(outcome, *prediction)
        else:  # its prediction is on its way (or it was a command from someone else)
            _keep(self.outcomes, outcome.behavior_id, outcome)

    def _judge(self, outcome, predicted_gr, sigma):
        verdict = self.detector.observe(predicted_gr, outcome.generic_reward, sigma)
        threshold = self.detector.config.threshold
        # The decision first, on its own channel: the adapter waits for it.
        self.verdict_pub.publish(conv.verdict_to_msg(outcome.behavior_id, verdict, threshold))
        level = DiagnosticStatus.ERROR if verdict.fire else DiagnosticStatus.OK
        message = ('damage detected: adaptation requested' if verdict.fire
                   else 'prediction too uncertain to judge' if not verdict.judged
                   else 'outcome as predicted' if verdict.error <= threshold
                   else 'outcome off prediction')
        if verdict.fire:
            # What was decided on: the mean over the window, not this step's error alone.
            window = self.detector.config.window
            self.get_logger().warn(
                f'damage detected on behaviour {outcome.behavior_id}: mean error '
                f'{verdict.mean_error:.3f} m over the latest {window} judged outcome(s) > '
                f'{threshold} m (this one: {verdict.error:.3f} m)')
        self.diag_pub.publish(conv.diagnostic_array(conv.diagnostic_status(
            level, STATUS_NAME, message,
            {'behavior_id': outcome.behavior_id, 'error': f'{verdict.error:.6f}',
             'mean_error': f'{verdict.mean_error:.6f}', 'sigma': f'{sigma:.6f}',
             'threshold': threshold, 'detections': self.detector.detections},
            hardware_id='hexapod'), self.get_clock().now().to_msg()))


def _keep(unpaired, behavior_id, value):
    unpaired[behavior_id] = value
    while len(unpaired) > UNPAIRED_KEPT:
        unpaired.pop(next(iter(unpaired)))


def main(args=None):
    run_node(DamageDetectorNode, args)


if __name__ == '__main__':
    main()
