"""Liveness that cannot be faked: the middleware's liveliness, not heartbeat messages."""
import signal

import pytest
from diagnostic_msgs.msg import DiagnosticStatus

from sela_ros.nodes import conversions as conv
from sela_ros.nodes import interface as ifc

from ros_graph import Client, NodeProcesses


def _errors(statuses, part):
    return [s.message for s in statuses if s.level == ifc.ERROR_LEVEL and part in s.message]


@pytest.mark.dds
def test_forged_heartbeats_and_a_forged_writer_do_not_hide_a_missing_or_killed_node():
    nodes = NodeProcesses({'damage_detector': {'heartbeat.timeout': 15.0}},
                          names=('planner', 'damage_detector'))
    client = Client('heartbeat_spoofer')
    statuses = []
    try:
        node = client.node
        ifc.subscription(node, ifc.DIAGNOSTICS, lambda m: statuses.extend(m.status))
        pub = ifc.publisher(node, ifc.DIAGNOSTICS)
        forged = []

        def fake(*names):
            pub.publish(conv.diagnostic_array([conv.diagnostic_status(
                DiagnosticStatus.OK, f'{n}{ifc.HEARTBEAT_SUFFIX}', 'alive') for n in names],
                0.0))
            for writer in forged:
                writer.publish(ifc.ALIVE['planner'].type())

        def spoof_until(predicate, timeout, what, *names):
            ticks = [0]

            def check():
                ticks[0] += 1
                if ticks[0] % 2 == 0:  # a fake every ~0.1 s
                    fake(*names)
                return predicate()
            client.spin_until(check, timeout, what)

        fakes = ('planner', 'sela_adapter', 'sim_bridge')
        # The adapter never started: faking its heartbeat does not make it alive.
        spoof_until(lambda: _errors(statuses, 'sela_adapter silent'), 120,
                    'sela_adapter reported silent', *fakes)
        spoof_until(lambda: any(s.message == 'planner alive (liveliness)' for s in statuses),
                    120, "the planner's liveliness seen by the detector", *fakes)
        assert not _errors(statuses, 'planner silent')
        # Once the detector has the planner's own writer: a writer of the forger's on the
        # planner's liveliness topic, with the same QoS, matched by the detector.
        topic = ifc.ALIVE['planner']
        forged.append(node.create_publisher(topic.type, topic.name, topic.qos))
        spoof_until(lambda: forged[0].get_subscription_count() >= 1, 60,
                    'the forged writer matched by the detector', *fakes)
        nodes.kill('planner', signal.SIGKILL)
        try:
            spoof_until(lambda: _errors(statuses, 'planner silent'), 60,
                        'the killed planner reported silent', *fakes)
        except TimeoutError as exc:
            raise AssertionError(nodes.logs().get('damage_detector.log')) from exc
        assert 'liveliness lease' in _errors(statuses, 'planner silent')[0]
        assert nodes.alive() == {'damage_detector': True}, nodes.logs()
    finally:
        client.close()
        nodes.stop()


@pytest.mark.dds
def test_no_liveness_alarm_at_start_up():
    nodes = NodeProcesses({'damage_detector': {'heartbeat.timeout': 60.0}})
    client = Client('liveness_watcher')
    statuses = []
    try:
        ifc.subscription(client.node, ifc.DIAGNOSTICS, lambda m: statuses.extend(m.status))
        watched = ('sim_bridge', 'planner', 'sela_adapter')
        client.spin_until(lambda: all(any(s.message == f'{n} alive (liveliness)'
                                          for s in statuses) for n in watched), 120,
                          'every watched node alive, as the detector sees it')
        alarms = [(s.name, s.message) for s in statuses if s.level == ifc.ERROR_LEVEL
                  and ('liveness' in s.name or 'heartbeat' in s.message)]
        assert not alarms, alarms
        assert all(nodes.alive().values()), nodes.logs()
    finally:
        client.close()
        nodes.stop()
