"""SELA's markers: the decision (waypoint, candidates by sigma, the choice) and the outcome
(trail)."""

import pytest
from visualization_msgs.msg import Marker

from sela_ros.nodes.markers import decision_markers, outcome_markers


def _decision(step=0):
    candidates = [(0.3 + 0.01 * i, 0.2, 0.05 * (i + 1), -0.1 * i) for i in range(4)]
    return decision_markers('odom', 3.0 * step, (0.1 * step, 0.0, 0.0), (0.5, 0.5),
                            candidates, (0.3, 0.2), 0.05)


def test_decision_markers_show_waypoint_candidates_by_sigma_and_the_choice():
    markers = _decision().markers
    by_ns = {}
    for m in markers:
        by_ns.setdefault(m.ns, []).append(m)
        assert m.header.frame_id == 'odom' and m.action == Marker.ADD
    (waypoint,) = by_ns['waypoint']
    assert (waypoint.pose.position.x, waypoint.pose.position.y) == (0.5, 0.5)
    discs = by_ns['candidates']
    assert [d.id for d in discs] == [0, 1, 2, 3]
    assert [d.scale.x for d in discs] == pytest.approx([0.1, 0.2, 0.3, 0.4])  # 2 sigma
    arrow = next(m for m in by_ns['chosen'] if m.type == Marker.ARROW)
    assert (arrow.points[1].x, arrow.points[1].y) == (0.3, 0.2)
    assert len(by_ns['candidate_labels']) == 4


def test_outcome_markers_and_trail():
    markers = outcome_markers('odom', 1.0, (0.2, 0.1), [(0, 0), (0.2, 0.1)]).markers
    assert markers[0].type == Marker.SPHERE and markers[0].pose.position.x == 0.2
    assert markers[1].type == Marker.LINE_STRIP and len(markers[1].points) == 2
