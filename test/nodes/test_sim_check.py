"""The adapter's check of the archive against the simulator's settings: an answer DDS lost
does not hold the gaits for good."""
from types import SimpleNamespace

from rcl_interfaces.msg import ParameterType, ParameterValue
from rcl_interfaces.srv import GetParameters
from rclpy.task import Future

from sela_ros.nodes import sim_check
from sela_ros.nodes.sim_check import ANSWER_TIMEOUT, SimulatorCheck

METADATA = {'dt': 0.01, 'gait_duration': 3.0, 'solver_iterations': 30}


class FakeClient:
    """A parameter client whose requests are answered (or lost) by the test."""

    srv_name = '/sim_bridge/get_parameters'

    def __init__(self):
        self.sent, self.removed = [], []

    def service_is_ready(self):
        return True

    def call_async(self, request):
        future = Future()
        self.sent.append(future)
        return future

    def remove_pending_request(self, future):
        self.removed.append(future)


class FakeNode:
    def __init__(self):
        self.client, self.warnings = FakeClient(), []

    def create_client(self, srv_type, name):
        return self.client

    def get_logger(self):
        return SimpleNamespace(warn=self.warnings.append)


def answer(dt, duration, iterations):
    values = [ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=dt),
              ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=duration),
              ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=iterations)]
    return GetParameters.Response(values=values)


def test_a_lost_answer_is_asked_again_and_a_late_one_is_dropped(monkeypatch):
    now = [100.0]
    monkeypatch.setattr(sim_check.time, 'monotonic', lambda: now[0])
    node, holds = FakeNode(), []
    check = SimulatorCheck(node, 'sim_bridge', holds.append)
    check.use(SimpleNamespace(metadata=METADATA), 'archive.npz')
    check.poll()
    assert len(node.client.sent) == 1 and holds[-1] == ''
    now[0] += ANSWER_TIMEOUT / 2
    check.poll()  # not answered yet, not long enough to call it lost
    assert len(node.client.sent) == 1 and not node.warnings
    now[0] += ANSWER_TIMEOUT
    check.poll()  # lost: asked again, the first question forgotten
    first, second = node.client.sent
    assert node.client.removed == [first] and len(node.warnings) == 1
    assert holds[-1] == ''
    # A late answer to the first question (another simulator's settings) counts for nothing.
    first.set_result(answer(0.02, 3.0, 30))
    assert holds[-1] == ''
    second.set_result(answer(0.01, 3.0, 30))
    assert holds[-1] is None
    now[0] += 10 * ANSWER_TIMEOUT
    check.poll()  # answered: never asked again for this archive
    assert len(node.client.sent) == 2


def test_a_mismatch_answered_holds_the_gaits_with_the_reason(monkeypatch):
    node, holds = FakeNode(), []
    check = SimulatorCheck(node, 'sim_bridge', holds.append)
    check.use(SimpleNamespace(metadata=METADATA), 'archive.npz')
    check.poll()
    node.client.sent[0].set_result(answer(0.02, 3.0, 30))
    assert 'archive.npz was built with other simulator settings' in holds[-1]
    # A new archive gets its own question.
    check.poll()
    check.use(SimpleNamespace(metadata={**METADATA, 'dt': 0.02}), 'other.npz')
    check.poll()
    node.client.sent[1].set_result(answer(0.02, 3.0, 30))
    assert holds[-1] is None


def test_once_answered_an_archive_is_checked_at_once_against_the_simulators_physics():
    node, holds = FakeNode(), []
    check = SimulatorCheck(node, 'sim_bridge', holds.append)
    other = SimpleNamespace(metadata={**METADATA, 'solver_iterations': 50})
    assert check.mismatch(other, 'other.npz') is None  # not answered yet: nothing to say
    check.use(SimpleNamespace(metadata=METADATA), 'archive.npz')
    check.poll()
    node.client.sent[0].set_result(answer(0.01, 3.0, 30))
    assert holds[-1] is None
    assert check.mismatch(SimpleNamespace(metadata=METADATA), 'same.npz') is None
    reason = check.mismatch(other, 'other.npz')
    assert 'other.npz was built with other simulator settings' in reason
    assert 'sim.solver_iterations 30' in reason
