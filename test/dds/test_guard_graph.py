"""A guard at every edge, in real nodes over DDS: an exception in a callback is an ERROR on
/diagnostics, and the node keeps running."""
import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticStatus
from nav_msgs.srv import GetPlan

from sela_ros.nodes import conversions as conv
from sela_ros.nodes import interface as ifc

from ros_graph import Client, NodeProcesses


@pytest.mark.dds
def test_planner_and_detector_survive_what_used_to_kill_them(tmp_path):
    """A map file with wrongly typed fields, and a prediction and outcome whose yaw
    difference overflows (two finite values). (A negative ``planner.lookahead`` given at
    start-up now stops the planner with exit status 2 and the reason: test_params.py.)"""
    bad_map = tmp_path / 'bad_map.yaml'
    bad_map.write_text('resolution: 0.05\norigin: 5\nwidth: 4\nheight: 4\nobstacles: null\n')
    nodes = NodeProcesses({'planner': {'map.file': str(bad_map)}},
                          names=('planner', 'damage_detector'))
    client = Client()
    statuses = []
    try:
        node = client.node
        ifc.subscription(node, ifc.DIAGNOSTICS, lambda m: statuses.extend(m.status))
        prediction_pub = ifc.publisher(node, ifc.PREDICTION)
        outcome_pub = ifc.publisher(node, ifc.OUTCOME)

        def errors(part):
            return [s.message for s in statuses
                    if s.level == DiagnosticStatus.ERROR and part in s.message]

        client.spin_until(lambda: prediction_pub.get_subscription_count() > 0
                          and outcome_pub.get_subscription_count() > 0, 60, 'the two nodes')
        # (Said once at start-up, on /diagnostics and in the log: the log keeps it.)
        # The map loader names the wrongly typed field (it used to be a bare TypeError).
        client.spin_until(lambda: 'planning on the map.* parameters instead'
                          in nodes.logs().get('planner.log', ''), 60, "the planner's map error")
        assert 'map.origin must be a list [x, y], got 5' in nodes.logs()['planner.log']
        # ... and on /diagnostics at every heartbeat of the planner, for whoever looks later.
        beats = lambda: [s for s in statuses if s.name == 'planner' + ifc.HEARTBEAT_SUFFIX  # noqa: E731
                         and s.level == DiagnosticStatus.ERROR
                         and 'map.origin must be a list [x, y], got 5' in s.message]
        client.spin_until(lambda: len(beats()) >= 2, 30, "the map error in two heartbeats")
        # It plans on the map.* parameters (bounds -1..3 m): a path to (2.5, 2.5).
        request = GetPlan.Request(start=conv.pose_stamped((0.0, 0.0), frame_id='odom'),
                                  goal=conv.pose_stamped((2.5, 2.5), frame_id='odom'))
        plan = client.call(ifc.client(node, ifc.MAKE_PLAN), request, 30)
        assert plan.plan.poses, nodes.logs()

        # The diagnostics subscription made at the start (matched long since): a new one
        # made here could miss the verdict while DDS still matches it (seen under load).
        def verdicts(behavior_id):  # judgements (not refusals) of one command's outcome
            return [s for s in statuses if s.name == ifc.DETECTOR_STATUS
                    and ('behavior_id', str(behavior_id)) in [(v.key, v.value)
                                                              for v in s.values]
                    and 'refused' not in s.message]

        prediction_pub.publish(conv.prediction_to_msg(7, np.array([0.0, 0.0, 1e308])))
        # Its end heading is the one its reward says (else it is refused, not judged).
        outcome_pub.publish(conv.outcome_to_msg(conv.BehaviorOutcome(
            7, np.array([0.0, 0.0, -1e308]), np.zeros(3), np.array([0.0, 0.0, -1e308]))))
        client.spin_until(lambda: verdicts(7) or not all(nodes.alive().values()), 60,
                          'a verdict on the overflowing outcome')
        assert all(nodes.alive().values()), nodes.logs()
        # An outcome no gait can produce is refused with the reason, not judged.
        prediction_pub.publish(conv.prediction_to_msg(8, np.zeros(3)))
        outcome_pub.publish(conv.outcome_to_msg(conv.BehaviorOutcome(
            8, np.array([1e9, 0.0, 0.0]), np.zeros(3), np.array([1e9, 0.0, 0.0]))))
        client.spin_until(lambda: errors('outcome of command 8 refused'), 30,
                          'the implausible outcome refused')
        assert 'outcome.max_displacement 2 m' in errors('outcome of command 8 refused')[0]
        assert not verdicts(8)
        # Both still serve: the planner answers a plan request.
        answer = client.call(ifc.client(node, ifc.MAKE_PLAN), request, 30)
        assert answer.plan.poses
        assert all(nodes.alive().values()), nodes.logs()
    finally:
        client.close()
        nodes.stop()
