"""What SELA is thinking, as RViz/Foxglove markers (visualization_msgs/MarkerArray).

One array per step, in the odometry frame, with these namespaces (ids are reused so each
step replaces the last):

- ``waypoint``: the point the specialised reward is built on (a magenta sphere);
- ``candidates``: where each of the top-K gaits by UCB is predicted to land, a flat disc of
  diameter 2 sigma (the GP's posterior standard deviation) and a short label;
- ``chosen``: an arrow from the robot to where the chosen gait is predicted to land;
- ``observed``: where the robot actually went with it (green sphere), sent once the
  outcome is known, and the trail of every observed end so far (a line strip).
"""
from collections import deque

from builtin_interfaces.msg import Duration
from geometry_msgs.msg import Point
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from sela_ros.nodes import conversions as conv

#: Height (m) at which markers are drawn: just above the ground, below the body.
Z = 0.02

WAYPOINT_COLOR = ColorRGBA(r=0.8, g=0.16, b=0.8, a=0.9)
CANDIDATE_COLOR = ColorRGBA(r=0.2, g=0.5, b=1.0, a=0.35)
CHOSEN_COLOR = ColorRGBA(r=1.0, g=0.55, b=0.0, a=0.95)
OBSERVED_COLOR = ColorRGBA(r=0.1, g=0.8, b=0.2, a=0.95)


def _marker(ns, marker_id, kind, frame_id, stamp, color):
    m = Marker()
    m.header.frame_id = frame_id
    m.header.stamp = conv.time_to_msg(stamp) if isinstance(stamp, (int, float)) else stamp
    m.ns, m.id, m.type, m.action = ns, marker_id, kind, Marker.ADD
    m.color = color
    m.pose.orientation.w = 1.0
    m.lifetime = Duration()  # forever: replaced by the next step's marker of the same id
    return m


def _point(xy, z=Z):
    return Point(x=float(xy[0]), y=float(xy[1]), z=float(z))


def decision_markers(frame_id, stamp, pose, waypoint, candidates, chosen_xy, chosen_sigma):
    """Markers of one decision.

    Args:
        frame_id, stamp: header (stamp in seconds or a ``builtin_interfaces/Time``).
        pose: the robot's pose ``(x, y, yaw)`` the decision was made from.
        waypoint: ``(x, y)``.
        candidates: rows ``(x, y, sigma, ucb)`` of the top-K gaits, best first.
        chosen_xy, chosen_sigma: where the chosen gait is predicted to land, and its sigma.
    """
    out = MarkerArray()
    m = _marker('waypoint', 0, Marker.SPHERE, frame_id, stamp, WAYPOINT_COLOR)
    m.pose.position = _point(waypoint)
    m.scale.x = m.scale.y = m.scale.z = 0.08
    out.markers.append(m)
    for i, (x, y, sigma, score) in enumerate(candidates):
        m = _marker('candidates', i, Marker.CYLINDER, frame_id, stamp, CANDIDATE_COLOR)
        m.pose.position = _point((x, y), Z / 2)
        m.scale.x = m.scale.y = max(2.0 * float(sigma), 0.01)
        m.scale.z = 0.005
        out.markers.append(m)
        label = _marker('candidate_labels', i, Marker.TEXT_VIEW_FACING, frame_id, stamp,
                        ColorRGBA(r=0.8, g=0.9, b=1.0, a=0.9))
        label.pose.position = _point((x, y), 0.06)
        label.scale.z = 0.04
        label.text = f'#{i + 1} ucb {score:.2f}'
        out.markers.append(label)
    m = _marker('chosen', 0, Marker.ARROW, frame_id, stamp, CHOSEN_COLOR)
    m.points = [_point(pose[:2]), _point(chosen_xy)]
    m.scale.x, m.scale.y, m.scale.z = 0.02, 0.05, 0.06  # shaft, head diameter, head length
    out.markers.append(m)
    m = _marker('chosen', 1, Marker.CYLINDER, frame_id, stamp,
                ColorRGBA(r=1.0, g=0.55, b=0.0, a=0.35))
    m.pose.position = _point(chosen_xy, Z / 2)
    m.scale.x = m.scale.y = max(2.0 * float(chosen_sigma), 0.01)
    m.scale.z = 0.006
    out.markers.append(m)
    return out


def outcome_markers(frame_id, stamp, observed_xy, trail):
    """Markers of what was observed: the end of the last gait and the trail so far."""
    out = MarkerArray()
    m = _marker('observed', 0, Marker.SPHERE, frame_id, stamp, OBSERVED_COLOR)
    m.pose.position = _point(observed_xy)
    m.scale.x = m.scale.y = m.scale.z = 0.06
    out.markers.append(m)
    if len(trail) >= 2:
        m = _marker('observed', 1, Marker.LINE_STRIP, frame_id, stamp, OBSERVED_COLOR)
        m.points = [_point(p) for p in trail]
        m.scale.x = 0.015
        out.markers.append(m)
    return out


class MarkerPublisher:
    """What SELA thinks, for RViz and Foxglove, published on ``sela/markers``: at each gait
    sent, the waypoint, the best candidates by UCB (discs of 2 sigma where each is predicted
    to land) and the chosen one; at each outcome, where the robot ended and its trail."""

    def __init__(self, node, publisher, frame_id):
        self.node, self.pub, self.frame_id = node, publisher, frame_id
        self.trail = deque(maxlen=500)

    def decision(self, gait):
        if gait.candidates is None or not len(gait.candidates):
            return
        chosen = gait.candidates[0]
        self.pub.publish(decision_markers(
            self.frame_id, self.node.get_clock().now().to_msg(), gait.pose, gait.waypoint,
            gait.candidates, chosen[:2], chosen[2]))

    def outcome(self, end_pose_text):
        try:
            end = [float(v) for v in end_pose_text.split()[:2]]
        except ValueError:
            return
        self.trail.append(end)
        self.pub.publish(outcome_markers(
            self.frame_id, self.node.get_clock().now().to_msg(), end, list(self.trail)))
