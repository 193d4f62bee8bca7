"""MissionClient's reading of the adapter's statuses, without DDS (a stand-in node)."""
import pytest
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


def test_the_result_taken_is_that_of_the_mission_its_goal_started():
    client = MissionClient(_Node(), lambda t: None)
    client._goal_id = 'a1b2'
    # An earlier mission's result, said again while the adapter is idle, and another
    # client's goal: not this client's mission.
    client._diagnostics(_status(mission=3, goal='1.0 0.5', success=True, steps=4, adaptations=0,
                                goal_id=''))
    client._diagnostics(_status(mission=4, goal='1.0 0.5', steps=0, adaptations=0,
                                goal_id='ffff'))
    assert client._mission is None and client.result is None
    client._diagnostics(_status(mission=5, goal='1.0 0.5', steps=0, adaptations=0,
                                goal_id='a1b2'))
    assert client._mission == '5'
    client._diagnostics(_status(mission=4, success=True, steps=4, adaptations=0))
    assert client.result is None
    # Said again after the adapter restarted: the goal is gone, the mission is the same.
    client._diagnostics(_status(mission=5, success=False, steps=100, adaptations=1,
                                goal_id=''))
    assert client.result is not None and not client.result.success
    assert client.result.steps == 100


def test_statuses_heard_before_the_goal_was_answered_are_read_again():
    client = MissionClient(_Node(), lambda t: None)
    client._diagnostics(_status(mission=7, goal='1.0 0.5', steps=0, adaptations=0,
                                goal_id='c3d4'))
    client._diagnostics(_status(mission=7, goal='1.0 0.5', steps=2, adaptations=0, goals=2,
                                goal_index=2, goal_reached='1.0 0.5', goal_reached_steps=2,
                                goal_id='c3d4'))
    assert client._mission is None and client.goals_reached == []
    client._goal_id = 'c3d4'
    for status in list(client.statuses):
        client._read(status, again=True)
    assert client._mission == '7' and len(client.goals_reached) == 1


class _LossyActionClient:
    """An action client whose first ``lost`` goal requests never get an answer."""

    def __init__(self, lost):
        from rclpy.task import Future

        self._future = Future
        self.lost = lost
        self.sent = []

    def send_goal_async(self, goal):
        future = self._future()
        self.sent.append(future)
        if len(self.sent) > self.lost:
            future.set_result('the answer')
        return future


def test_a_goal_whose_request_is_lost_is_sent_again_until_answered(monkeypatch):
    import sela_ros.tools.mission_client as mc

    clock = [0.0]
    monkeypatch.setattr(mc.time, 'monotonic', lambda: clock[0])

    def spin_once(timeout):
        clock[0] += timeout  # time passes only while the client waits

    client = MissionClient(_Node(), spin_once)
    lossy = _LossyActionClient(lost=2)
    client._actions[ifc.NAVIGATE_TO_POSE.name] = lossy
    assert client._send_goal(ifc.NAVIGATE_TO_POSE, 'goal', timeout=60) == 'the answer'
    assert len(lossy.sent) == 3 and all(f.cancelled() for f in lossy.sent[:2])
    # Never answered: the caller's timeout, once.
    client._actions[ifc.NAVIGATE_TO_POSE.name] = _LossyActionClient(lost=100)
    with pytest.raises(TimeoutError, match='after 25 s waiting for the answer'):
        client._send_goal(ifc.NAVIGATE_TO_POSE, 'goal', timeout=25)


class _Handle:
    def __init__(self, number):
        from types import SimpleNamespace

        from rclpy.task import Future

        self.accepted = True
        self.goal_id = SimpleNamespace(uuid=bytes([number] * 16))
        self.result = Future()

    def get_result_async(self):
        return self.result


class _Server:
    """An action client whose goals are all accepted, each answered when ``answer`` is
    called (at once if ``at_once``)."""

    def __init__(self, at_once=True):
        self.handles, self.answers, self.at_once = [], [], at_once

    def send_goal_async(self, goal):
        from rclpy.task import Future

        self.handles.append(_Handle(len(self.handles) + 1))
        self.answers.append(Future())
        if self.at_once:
            self.answer()
        return self.answers[-1]

    def answer(self):
        self.answers[-1].set_result(self.handles[-1])


def _stand_in(server):
    """A client whose goals go to ``server``; each wait runs the next of its ``events``."""
    events = []
    client = MissionClient(_Node(), lambda t: events.pop(0)() if events else None)
    client.wait_until_ready = lambda timeout: None
    client._actions[ifc.NAVIGATE_TO_POSE.name] = server
    return client, events


def _succeeded():
    """An action result: the goal succeeded."""
    from types import SimpleNamespace

    from action_msgs.msg import GoalStatus

    return SimpleNamespace(status=GoalStatus.STATUS_SUCCEEDED,
                           result=SimpleNamespace(error_msg='', error_code=0))


def test_an_earlier_goals_late_result_is_not_the_next_goals():
    server = _Server()
    client, events = _stand_in(server)
    first, second = bytes([1] * 16).hex(), bytes([2] * 16).hex()
    events.append(lambda: client._diagnostics(_status(mission=1, steps=0, adaptations=0,
                                                      goal_id=first)))
    client.go_to_pose(1.6, 1.0, timeout=5)
    client._diagnostics(_status(mission=1, success=True, steps=3, adaptations=0,
                                goal_id=first))
    assert client.get_result().success
    # The next goal: the first one's action result comes while it is being taken.
    done = _succeeded()
    events += [lambda: server.handles[0].result.set_result(done),
               lambda: client._diagnostics(_status(mission=2, steps=0, adaptations=0,
                                                   goal_id=second))]
    client.go_to_pose(0.6, 1.0, timeout=5)
    assert client._mission == '2' and client.get_result() is None
    assert client.action_result is None
    server.handles[1].result.set_result(done)  # its own result is taken
    assert client.action_result is done


def test_an_earlier_goals_late_result_while_the_next_goal_awaits_its_answer_is_ignored():
    server = _Server(at_once=False)
    client, events = _stand_in(server)
    first, second = bytes([1] * 16).hex(), bytes([2] * 16).hex()
    events += [server.answer,
               lambda: client._diagnostics(_status(mission=1, steps=0, adaptations=0,
                                                   goal_id=first))]
    client.go_to_pose(0.2, 1.2, timeout=5)
    client._diagnostics(_status(mission=1, success=True, steps=3, adaptations=0,
                                goal_id=first))
    done = _succeeded()
    # The first goal's action result comes before the second goal is answered.
    events += [lambda: server.handles[0].result.set_result(done), server.answer,
               lambda: client._diagnostics(_status(mission=2, steps=0, adaptations=0,
                                                   goal_id=second))]
    client.go_to_pose(1.2, 1.4, timeout=5)
    assert client._mission == '2' and client.get_result() is None
    assert client.action_result is None


def test_the_last_goal_of_several_is_reached_with_the_result_and_counted_once():
    client = MissionClient(_Node(), lambda t: None)
    client._goals = [(1.0, 0.5), (2.0, 0.0)]
    client._goal_id = 'e5f6'
    client._diagnostics(_status(mission=9, goal='1.0 0.5', steps=0, adaptations=0,
                                goal_id='e5f6'))
    client._diagnostics(_status(mission=9, steps=3, adaptations=0, goal_index=2,
                                goal_reached='1.0 0.5', goal_reached_steps=3))
    assert [g.index for g in client.goals_reached] == [1]
    for _ in range(2):  # said again while idle
        client._diagnostics(_status(mission=9, success=True, steps=4, adaptations=0))
    assert [(g.index, tuple(g.goal), g.steps) for g in client.goals_reached] == [
        (1, (1.0, 0.5), 3), (2, (2.0, 0.0), 4)]
