"""Heartbeats on ``diagnostics``: every node says it is alive; a watcher reports silence."""
import time

from diagnostic_msgs.msg import DiagnosticStatus
from rclpy.clock import Clock, ClockType

from sela_ros.nodes import interface as ifc
from sela_ros.nodes.conversions import diagnostic_array, diagnostic_status

SUFFIX = ifc.HEARTBEAT_SUFFIX


def add_heartbeat(node, period=1.0):
    """Publish ``<node name>: heartbeat`` (level OK) every ``period`` wall-clock seconds."""
    pub = ifc.publisher(node, ifc.DIAGNOSTICS)
    name = node.get_name() + SUFFIX
    started = time.monotonic()

    def beat():
        pub.publish(diagnostic_array(diagnostic_status(
            DiagnosticStatus.OK, name, 'alive', {'uptime_s': f'{time.monotonic() - started:.1f}'}),
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

    def heard(self, status_name, now=None):
        if status_name.endswith(SUFFIX):
            node = status_name[:-len(SUFFIX)]
            if node in self.last:
                self.last[node] = time.monotonic() if now is None else now

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
