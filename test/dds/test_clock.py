"""A ``/clock`` no time can be made of (negative seconds) is refused in every node that takes
``/clock``: one log line, no stack trace per message, and sim time goes on with good ones."""
import pytest
from rosgraph_msgs.msg import Clock

from sela_ros.nodes import interface as ifc

from ros_graph import Client, NodeProcesses

pytestmark = [pytest.mark.dds]

TAKERS = ('planner', 'damage_detector', 'sela_adapter')
GOOD = 12345  # s: a sim time no node can have reached on its own


def _log(nodes, name):
    path = nodes.logdir / f'{name}.log'
    return path.read_text() if path.exists() else ''


def test_a_clock_with_negative_seconds_is_refused_with_one_line_in_every_node():
    nodes = NodeProcesses({n: {'use_sim_time': 'true'} for n in TAKERS}, names=TAKERS)
    client = Client('bad_clock')
    heard = {}  # node -> the latest stamp (s) of its heartbeat, in its own (sim) time
    try:
        node = client.node
        ifc.subscription(node, ifc.DIAGNOSTICS, lambda m: heard.update(
            {s.name.removesuffix(ifc.HEARTBEAT_SUFFIX): m.header.stamp.sec
             for s in m.status if s.name.endswith(ifc.HEARTBEAT_SUFFIX)}))
        pub = ifc.publisher(node, ifc.CLOCK)
        client.spin_until(lambda: pub.get_subscription_count() >= len(TAKERS), 60,
                          'every node subscribed to /clock')
        bad = Clock()
        bad.clock.sec = -5

        def refused_everywhere():
            pub.publish(bad)
            return all('/clock refused: negative seconds' in _log(nodes, n) for n in TAKERS)
        client.spin_until(refused_everywhere, 60, 'the bad /clock refused by every node')
        for _ in range(30):
            pub.publish(bad)
            client.executor.spin_once(timeout_sec=0.02)
        good = Clock()
        good.clock.sec = GOOD

        def good_time_taken():
            pub.publish(good)
            return all(heard.get(n, 0) >= GOOD for n in TAKERS)
        client.spin_until(good_time_taken, 60, "every node's heartbeat stamped at the good time")
        for name in TAKERS:
            log = _log(nodes, name)
            assert log.count('/clock refused') == 1, log
            assert 'Traceback' not in log and 'callback failed' not in log, log
        assert all(nodes.alive().values()), nodes.logs()
    finally:
        client.close()
        nodes.stop()
