"""Heartbeats on ``diagnostics``: every node says it is alive; a watcher reports silence."""
import time

from diagnostic_msgs.msg import DiagnosticStatus
from rclpy.clock import Clock, ClockType

from sela_ros.nodes import interface as ifc
from sela_ros.nodes.conversions import diagnostic_array, diagnostic_status

SUFFIX = ifc.HEARTBEAT_SUFFIX


def add_heartbeat(node, period=1.0, problem=None):
    """Publish ``<node name>: heartbeat`` every ``period`` wall-clock seconds: level OK
    ('alive'), or ERROR with the message ``problem()`` returns while it returns one (a
    lasting problem, e.g. the planner's map file could not be used: a monitor that starts
    late still sees it; the node is alive all the same)."""
    pub = ifc.publisher(node, ifc.DIAGNOSTICS)
    name = node.get_name() + SUFFIX
    started = time.monotonic()

    def beat():
        message = problem() if problem is not None else None
        pub.publish(diagnostic_array(diagnostic_status(
            DiagnosticStatus.ERROR if message else DiagnosticStatus.OK, name,
            message or 'alive', {'uptime_s': f'{time.monotonic() - started:.1f}'}),
            node.get_clock().now().to_msg()))

    beat()
    return node.create_timer(period, beat, clock=Clock(clock_type=ClockType.STEADY_TIME))


class SilenceWatch:
    """Tracks the last heartbeat of each watched node (ROS-free bookkeeping)."""

    def __init__(self, nodes, timeout, now=None):
        start = time.monotonic() if now is None else now
        self.timeout = float(timeout)
        self.last = {n: start for n in nodes}
        self.silent = set()

    def heard(self, status_name, now=None, publishers=None):
        """A status named ``status_name`` was heard. Returns the watched node it claims to
        be the heartbeat of when that claim is refused (else None).

        Anyone can publish ``planner: heartbeat`` on diagnostics. With ``publishers`` (the
        names of the nodes the graph shows publishing diagnostics), a heartbeat counts only
        while its node is among them: a process that fakes the heartbeat of a node that is
        gone does not keep it alive.
        """
        if not status_name.endswith(SUFFIX):
            return None
        node = status_name[:-len(SUFFIX)]
        if node not in self.last:
            return None
        if publishers is not None and node not in publishers:
            return node
        self.last[node] = time.monotonic() if now is None else now
        return None

    def check(self, now=None):
        """Return ``(newly_silent, back)``: node lists whose state changed since last check."""
        now = time.monotonic() if now is None else now
        silent = {n for n, t in self.last.items() if now - t > self.timeout}
        newly, back = sorted(silent - self.silent), sorted(self.silent - silent)
        self.silent = silent
        return newly, back

    def silence(self, node, now=None):
        now = time.monotonic() if now is None else now
        return now - self.last[node]
