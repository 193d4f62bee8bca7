"""Health that cannot be faked: a heartbeat counts only while the graph shows its node."""
import signal

import pytest
from diagnostic_msgs.msg import DiagnosticStatus

from sela_ros.nodes import conversions as conv
from sela_ros.nodes import interface as ifc
from sela_ros.nodes.heartbeat import SilenceWatch

from ros_graph import Client, NodeProcesses


def test_a_heartbeat_from_a_node_the_graph_does_not_show_is_not_counted():
    watch = SilenceWatch(['planner'], timeout=2.0, now=0.0)
    assert watch.heard('planner: heartbeat', now=1.0, publishers={'planner'}) is None
    assert watch.heard('planner: heartbeat', now=3.5, publishers={'spoofer'}) == 'planner'
    assert watch.check(now=3.5) == (['planner'], [])  # the fake did not keep it alive
    assert watch.heard('planner: heartbeat', now=4.0, publishers={'planner'}) is None
    assert watch.check(now=4.0) == ([], ['planner'])


@pytest.mark.dds
def test_faked_heartbeats_do_not_hide_a_missing_or_killed_node():
    nodes = NodeProcesses({'damage_detector': {'heartbeat.timeout': 2.0}},
                          names=('planner', 'damage_detector'))
    client = Client('heartbeat_spoofer')
    statuses = []
    try:
        node = client.node
        ifc.subscription(node, ifc.DIAGNOSTICS, lambda m: statuses.extend(m.status))
        pub = ifc.publisher(node, ifc.DIAGNOSTICS)

        def fake(*names):
            pub.publish(conv.diagnostic_array([conv.diagnostic_status(
                DiagnosticStatus.OK, f'{n}{ifc.HEARTBEAT_SUFFIX}', 'alive') for n in names],
                0.0))

        def errors(part):
            return [s.message for s in statuses
                    if s.level == ifc.ERROR_LEVEL and part in s.message]

        def spoof_until(predicate, timeout, what, *names):
            ticks = [0]

            def check():
                ticks[0] += 1
                if ticks[0] % 2 == 0:  # a fake every ~0.1 s
                    fake(*names)
                return predicate()
            client.spin_until(check, timeout, what)

        # The adapter never started: faking its heartbeat does not make it alive.
        spoof_until(lambda: errors('sela_adapter silent'), 120, 'sela_adapter reported silent',
                    'sela_adapter', 'sim_bridge')
        # ... and the fake is called out (again at every check while the fakes go on).
        spoof_until(lambda: errors('heartbeat of sela_adapter sent by another process'), 60,
                    'the faked heartbeat called out', 'sela_adapter', 'sim_bridge')
        # The planner is killed while its heartbeat is faked: reported silent once the graph
        # no longer shows it (the DDS lease), whatever the fakes say.
        spoof_until(lambda: {'planner', 'damage_detector'} <= {
            i.node_name for i in node.get_publishers_info_by_topic(ifc.DIAGNOSTICS.root_name)},
            120, 'the planner and the detector in the graph', 'sela_adapter', 'sim_bridge')
        nodes.kill('planner', signal.SIGKILL)
        spoof_until(lambda: errors('planner silent'), 150, 'the killed planner reported silent',
                    'planner', 'sela_adapter', 'sim_bridge')
        assert nodes.alive() == {'damage_detector': True}, nodes.logs()
    finally:
        client.close()
        nodes.stop()
