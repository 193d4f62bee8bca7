"""MissionClient's reading of the adapter's statuses, without DDS (a stand-in node)."""
from diagnostic_msgs.msg import DiagnosticStatus

from sela_ros.nodes import conversions as conv
from sela_ros.nodes import interface as ifc
from sela_ros.tools.mission_client import MissionClient


class _Node:
    def create_publisher(self, *args):
        return None

    def create_subscription(self, *args):
        return None


def _status(**values):
    return conv.diagnostic_array(conv.diagnostic_status(
        DiagnosticStatus.OK, ifc.MISSION_STATUS, 'status', {k: str(v) for k, v in values.items()}),
        0.0)


def test_the_result_taken_is_that_of_the_mission_the_adapter_acknowledged():
    client = MissionClient(_Node(), lambda t: None)
    client.goal, client._acked = [1.0, 0.5], False
    # An earlier mission to the same goal, said again while the adapter is idle: not an ack,
    # not this client's result.
    client._diagnostics(_status(mission=3, goal='1.0 0.5', success=True, steps=4, adaptations=0))
    assert not client._acked and client.result is None
    client._diagnostics(_status(mission=4, goal='1.0 0.5', steps=0, adaptations=0))
    assert client._acked
    client._diagnostics(_status(mission=3, success=True, steps=4, adaptations=0))
    assert client.result is None
    client._diagnostics(_status(mission=4, success=False, steps=100, adaptations=1))
    assert client.result is not None and not client.result.success
    assert client.result.steps == 100
