"""Liveness that cannot be faked: the middleware's liveliness, not heartbeat messages."""
import signal
import time

import pytest
from diagnostic_msgs.msg import DiagnosticStatus
from std_srvs.srv import Trigger

from sela_ros.nodes import conversions as conv
from sela_ros.nodes import interface as ifc
from sela_ros.tools.mission_client import MissionClient

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
        killed = len(statuses)
        # The forger's writer destroyed and made again while the planner is dead: a new
        # writer alive on planner/alive, not the planner's.
        node.destroy_publisher(forged.pop())
        forged.append(node.create_publisher(topic.type, topic.name, topic.qos))
        spoof_until(lambda: forged[0].get_subscription_count() >= 1, 60,
                    'the new forged writer matched by the detector', *fakes)
        rematched = len(statuses)
        spoof_until(lambda: len(_errors(statuses[rematched:], 'planner silent')) >= 8, 60,
                    'the detector saying four times more that the planner is silent', *fakes)
        back = [s.message for s in statuses[killed:] if s.name == 'planner: liveness'
                and s.level != ifc.ERROR_LEVEL]
        assert not back, back
        assert 'planner is back' not in nodes.logs()['damage_detector.log']
        assert nodes.alive() == {'damage_detector': True}, nodes.logs()
        # The planner itself, started again, is back.
        nodes.start('planner')
        restarted = len(statuses)
        spoof_until(lambda: any(s.message == 'planner alive (liveliness)'
                                for s in statuses[restarted:]), 120,
                    'the restarted planner alive again', *fakes)
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


@pytest.mark.dds
def test_a_killed_detector_is_reported_by_the_adapter_which_then_adapts_from_every_outcome():
    nodes = NodeProcesses({'sela_adapter': {'adapt_on_start': 'false'}},
                          names=('planner', 'damage_detector', 'sela_adapter'))
    client = Client('detector_watcher')
    statuses = []
    try:
        ifc.subscription(client.node, ifc.DIAGNOSTICS, lambda m: statuses.extend(m.status))
        client.spin_until(lambda: any(s.name == 'damage_detector: liveness'
                                      and s.message == 'damage_detector alive (liveliness)'
                                      for s in statuses), 120,
                          'the adapter seeing the detector alive')
        nodes.kill('damage_detector', signal.SIGKILL)
        try:
            client.spin_until(lambda: _errors(statuses, 'damage_detector silent'), 60,
                              'the killed detector reported by the adapter')
        except TimeoutError as exc:
            raise AssertionError(nodes.logs().get('sela_adapter.log')) from exc
        report = _errors(statuses, 'damage_detector silent')[0]
        assert 'liveliness lease' in report and 'no verdicts' in report, report

        def adapting():
            log = (nodes.logdir / 'sela_adapter.log').read_text()
            return 'adapting from every outcome' in log and 'adaptation started' in log
        client.spin_until(adapting, 30, 'the adapter adapting without verdicts')
        # Learning forgotten (~/clear) while the detector is still lost: adapting again.
        cleared = client.call(ifc.client(client.node, ifc.CLEAR), Trigger.Request())
        assert cleared.success, cleared.message
        client.spin_until(lambda: (nodes.logdir / 'sela_adapter.log').read_text().count(
            'adapting from every outcome') >= 2, 30, 'adapting again after the clear')
        # Said again while it lasts, as diagnostics are read.
        heard = len(statuses)
        client.spin_until(lambda: _errors(statuses[heard:], 'damage_detector silent'), 30,
                          'the report repeated')
        assert nodes.alive() == {'planner': True, 'sela_adapter': True}, nodes.logs()
    finally:
        client.close()
        nodes.stop()


@pytest.mark.dds
@pytest.mark.slow
def test_a_killed_planner_ends_the_mission_within_ten_seconds_of_being_reported():
    nodes = NodeProcesses()
    client = Client('planner_killer')
    try:
        mission = MissionClient(client.node,
                                lambda t: client.executor.spin_once(timeout_sec=t))
        mission.go_to_pose(3.0, 2.5, timeout=120)
        client.spin_until(lambda: mission.steps or mission.get_result(), 200, 'a first step')
        assert mission.get_result() is None, mission.get_result()
        nodes.kill('planner', signal.SIGKILL)
        client.spin_until(lambda: any('planner silent' in e
                                      for e in mission.errors('liveness')), 60,
                          'the killed planner reported')
        reported = time.monotonic()
        # Within PLANNER_RETURN (5 s) of the adapter's own report, killed before or after
        # the planner's first liveliness assertion reached it.
        client.spin_until(mission.get_result, 60, 'the end of the mission')
        ended = time.monotonic() - reported
        result = mission.get_result()
        assert not result.success and result.values['code'] == 'no_plan', result.values
        assert ended < 10.0, (ended, nodes.logs().get('sela_adapter.log', ''))
        assert 'the planner is lost' in result.message, result
        # A new goal while the planner is dead is ended at once, saying why.
        first = result.values['mission']

        def second_ended():
            return [conv.status_values(s) for s in mission.statuses
                    if s.name == ifc.MISSION_STATUS and 'the planner is lost' in s.message
                    and conv.status_values(s).get('mission') not in (None, first)
                    and 'success' in conv.status_values(s)]
        mission.publish_goal(-1.0, 1.0)
        client.spin_until(second_ended, 30, 'the end of the second mission')
        assert second_ended()[0]['steps'] == '0', second_ended()
    finally:
        client.close()
        nodes.stop()


@pytest.mark.dds
def test_a_second_node_of_the_same_name_in_the_domain_is_said_by_both_until_it_goes():
    """A second stack started without a namespace: each planner's heartbeat says that
    another node of its name is in the domain, and says nothing once it is gone."""
    first = NodeProcesses(names=('planner',))
    client = Client('namesake_watcher')
    statuses, second = [], None
    try:
        ifc.subscription(client.node, ifc.DIAGNOSTICS, lambda m: statuses.extend(m.status))
        client.spin_until(lambda: any(s.name == f'planner{ifc.HEARTBEAT_SUFFIX}'
                                      and s.message == 'alive' for s in statuses), 120,
                          "the first planner's heartbeat")
        second = NodeProcesses(names=('planner',))
        client.spin_until(lambda: len(_errors(statuses, 'other node(s) named /planner'))
                          >= 4, 120, 'the namesakes said by the planners')
        said = _errors(statuses, 'other node(s) named /planner')[0]
        assert 'ROS_DOMAIN_ID' in said and 'namespace:=' in said, said
        second.stop()
        gone = len(statuses)
        client.spin_until(lambda: sum(s.name == f'planner{ifc.HEARTBEAT_SUFFIX}'
                                      and s.message == 'alive' for s in statuses[gone:]) >= 3,
                          120, "the first planner's heartbeat alive again")
        assert 'no other node named /planner any more' in first.logs()['planner.log']
        assert all(first.alive().values()), first.logs()
    finally:
        client.close()
        first.stop()
        if second is not None:
            second.stop()
