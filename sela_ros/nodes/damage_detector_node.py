"""The ``damage_detector`` node: compares each outcome with the prediction that preceded it.

Pairs ``/sela/prediction`` and ``/hexapod/behavior_outcome`` by command id, judges the error
with :class:`sela_ros.core.damage_detection.DamageDetector` and publishes one verdict per outcome
on ``/diagnostics`` (name ``damage_detector: prediction error``; level ERROR when damage is
detected). When it detects damage it first calls ``/sela_adapter/adapt`` and publishes the
verdict once the adapter has answered, so that the adapter's next choice already knows.
"""
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import Trigger

from sela_ros.core.damage_detection import DamageDetector, DetectorConfig
from sela_ros.nodes import conversions as conv
from sela_ros.nodes.heartbeat import SilenceWatch, add_heartbeat
from sela_ros.nodes.node_main import run_node
from sela_ros.nodes.params import Spec, declare
from sela_ros.nodes.qos import COMMAND_QOS, OUTCOME_QOS, STATE_QOS

STATUS_NAME = 'damage_detector: prediction error'
ADAPT_TIMEOUT = 5.0


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
        Spec('heartbeat.timeout', 5.0, 'wall time without a heartbeat before a node is reported '
             'silent', low=0.1, high=3600.0, unit=' s'),
        Spec('heartbeat.nodes', ['sim_bridge', 'planner', 'sela_adapter'],
             'nodes whose heartbeat is watched', read_only=True),
    )


class DamageDetectorNode(Node):
    def __init__(self):
        super().__init__('damage_detector')
        values = declare(self, parameters(DetectorConfig()), on_change=self.parameters_callback)
        self.detector = DamageDetector(self._config_from({}))
        self.predictions = {}
        self.waiting = []  # verdicts waiting for the adapter's answer: (future, deadline, msg)
        self.wall = Clock(clock_type=ClockType.STEADY_TIME)

        self.diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', STATE_QOS)
        self.create_subscription(Float64MultiArray, '/sela/prediction', self.prediction_callback,
                                 COMMAND_QOS)
        self.create_subscription(Float64MultiArray, '/hexapod/behavior_outcome',
                                 self.outcome_callback, OUTCOME_QOS)
        self.adapt_client = self.create_client(Trigger, '/sela_adapter/adapt')
        # Verdicts go out when the adapter answers (a done callback); this timer only
        # catches an adapter that does not answer within ADAPT_TIMEOUT.
        self.create_timer(0.25, self.flush_verdicts, clock=self.wall)
        # Watch the other nodes' heartbeats: a silent node is reported on /diagnostics.
        self.watch = SilenceWatch(values['heartbeat.nodes'], values['heartbeat.timeout'])
        self.create_subscription(DiagnosticArray, '/diagnostics', self.diagnostics_callback,
                                 STATE_QOS)
        self.create_timer(0.5, self.check_heartbeats, clock=self.wall)
        add_heartbeat(self)
        self.get_logger().info(f'threshold {self.detector.config.threshold} m')

    def diagnostics_callback(self, msg):
        for status in msg.status:
            self.watch.heard(status.name)

    def check_heartbeats(self):
        newly_silent, back = self.watch.check()
        statuses = []
        for node in newly_silent:
            message = (f'{node} silent for {self.watch.silence(node):.1f} s '
                       f'(heartbeat.timeout {self.watch.timeout} s)')
            self.get_logger().error(message)
            statuses.append(conv.diagnostic_status(DiagnosticStatus.ERROR,
                                                   f'{node}: liveness', message))
        for node in back:
            self.get_logger().info(f'{node} is back')
            statuses.append(conv.diagnostic_status(DiagnosticStatus.OK, f'{node}: liveness',
                                                   'heartbeat back'))
        if statuses:
            self.diag_pub.publish(conv.diagnostic_array(statuses,
                                                        self.get_clock().now().to_msg()))

    def _config_from(self, overrides):
        values = {name: self.get_parameter(f'detection.{name}').value
                  for name in ('threshold', 'yaw_weight', 'window', 'cooldown', 'max_sigma')}
        values.update(overrides)
        return DetectorConfig(**values)

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
                self.watch.timeout = float(p.value)
        if config is not None:
            self.detector = DamageDetector(config)
        return SetParametersResult(successful=True)

    def prediction_callback(self, msg):
        try:
            behavior_id, gr, sigma = conv.prediction_from_msg(msg)
        except conv.MessageError as exc:
            self.get_logger().error(f'ignored prediction: {exc}')
            return
        self.predictions[behavior_id] = (gr, sigma)
        while len(self.predictions) > 1000:
            self.predictions.pop(next(iter(self.predictions)))

    def outcome_callback(self, msg):
        try:
            outcome = conv.outcome_from_msg(msg)
        except conv.MessageError as exc:
            self.get_logger().error(f'ignored outcome: {exc}')
            return
        prediction = self.predictions.pop(outcome.behavior_id, None)
        if prediction is None:
            return  # no prediction: a command from someone else, nothing to compare with
        verdict = self.detector.observe(prediction[0], outcome.generic_reward, prediction[1])
        level = DiagnosticStatus.ERROR if verdict.fire else DiagnosticStatus.OK
        message = ('damage detected: adaptation requested' if verdict.fire
                   else 'prediction too uncertain to judge' if not verdict.judged
                   else 'outcome as predicted' if verdict.error <= self.detector.config.threshold
                   else 'outcome off prediction')
        out = conv.diagnostic_array(conv.diagnostic_status(
            level, STATUS_NAME, message,
            {'behavior_id': outcome.behavior_id, 'error': f'{verdict.error:.6f}',
             'mean_error': f'{verdict.mean_error:.6f}', 'sigma': f'{prediction[1]:.6f}',
             'threshold': self.detector.config.threshold,
             'detections': self.detector.detections}, hardware_id='hexapod'),
            self.get_clock().now().to_msg())
        if not verdict.fire:
            self.diag_pub.publish(out)
            return
        self.get_logger().warn(f'damage detected on behaviour {outcome.behavior_id}: error '
                               f'{verdict.error:.3f} m > {self.detector.config.threshold} m')
        future = None
        if self.adapt_client.service_is_ready():
            future = self.adapt_client.call_async(Trigger.Request())
            future.add_done_callback(lambda _: self.flush_verdicts())
        else:
            self.get_logger().error('/sela_adapter/adapt is not available')
        deadline = self.wall.now().nanoseconds * 1e-9 + ADAPT_TIMEOUT
        self.waiting.append((future, deadline, out))

    def flush_verdicts(self):
        now = self.wall.now().nanoseconds * 1e-9
        still = []
        for future, deadline, msg in self.waiting:
            if future is not None and not future.done() and now < deadline:
                still.append((future, deadline, msg))
                continue
            answer = future.result() if future is not None and future.done() else None
            msg.status[0].values.append(KeyValue(
                key='adapt', value=answer.message if answer else 'no answer from the adapter'))
            self.diag_pub.publish(msg)
        self.waiting = still


def main(args=None):
    run_node(DamageDetectorNode, args)


if __name__ == '__main__':
    main()
