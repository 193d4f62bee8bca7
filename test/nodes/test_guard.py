"""A guard at every edge: an exception in a callback is an ERROR on /diagnostics, and the
node keeps running (on a stand-in node; real nodes over DDS: dds/test_guard_graph.py)."""
from diagnostic_msgs.msg import DiagnosticStatus
from std_srvs.srv import Trigger

from sela_ros.nodes import conversions as conv
from sela_ros.nodes.guard import guard, guard_parameters, guard_service


class _Logger:
    def __init__(self):
        self.errors = []

    def error(self, text):
        self.errors.append(text)


class _Clock:
    def now(self):
        class _Now:
            def to_msg(self):
                return conv.time_to_msg(0.0)
        return _Now()


class _Publisher:
    def __init__(self):
        self.sent = []

    def publish(self, msg):
        self.sent.append(msg)


class FakeNode:
    """Just what the guard uses of an rclpy Node."""

    def __init__(self):
        self.logger, self.pub, self.calls = _Logger(), _Publisher(), []

    def get_logger(self):
        return self.logger

    def get_name(self):
        return 'fake'

    def get_clock(self):
        return _Clock()

    def create_publisher(self, *args):
        return self.pub

    @guard
    def odom_callback(self, msg):
        self.calls.append(msg)
        return 1 / msg

    @guard(what='heartbeat check')
    def check(self):
        raise RuntimeError('x' * 10_000)

    @guard_service
    def adapt_callback(self, request, response):
        raise KeyError('pending')

    @guard_parameters
    def parameters_callback(self, params):
        raise TypeError('unhashable')


def test_a_callback_that_raises_is_reported_and_the_next_call_works():
    node = FakeNode()
    assert node.odom_callback(0) is None
    assert node.odom_callback(4) == 0.25  # the node goes on with the next message
    [array] = node.pub.sent
    [status] = array.status
    assert status.level == DiagnosticStatus.ERROR and status.name == 'fake: odom'
    assert 'odom failed: ZeroDivisionError' in status.message
    assert 'keeps running' in status.message
    assert 'Traceback' in node.logger.errors[0] and 'odom_callback' in node.logger.errors[0]


def test_huge_exception_messages_are_cut():
    node = FakeNode()
    node.check()
    message = node.pub.sent[0].status[0].message
    assert node.pub.sent[0].status[0].name == 'fake: heartbeat check'
    assert len(message) < 600 and '(10000 chars)' in message


def test_a_service_answers_failure_and_a_parameter_change_is_refused():
    node = FakeNode()
    response = node.adapt_callback(Trigger.Request(), Trigger.Response())
    assert response.success is False and "KeyError: 'pending'" in response.message
    result = node.parameters_callback([])
    assert not result.successful and 'TypeError: unhashable' in result.reason
