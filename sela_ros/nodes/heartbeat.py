"""Liveness: every node holds a liveliness writer; a watcher reports a node whose writer died.

Whether a node is alive is the middleware's to say, not a message's: each node holds a
writer on ``<node>/alive`` (:data:`~sela_ros.nodes.interface.ALIVE_QOS`, AUTOMATIC
liveliness with a lease), and the watcher's subscription gets a liveliness-changed event
when a writer's lease expires (its process was killed or hangs in the kernel) or it goes
away. Anyone can publish ``planner: heartbeat`` on ``diagnostics``, and anyone can add a
writer of their own on ``planner/alive``; neither keeps the planner's writer alive, and the
death of any writer is an event that is reported. The ``<node>: heartbeat`` statuses on
``diagnostics`` stay, for monitors (a node's lasting problem is said in them); nothing
decides on them.
"""
import time
import weakref

from diagnostic_msgs.msg import DiagnosticStatus
from rclpy.clock import Clock, ClockType

from sela_ros.nodes import interface as ifc
from sela_ros.nodes.conversions import diagnostic_array, diagnostic_status

SUFFIX = ifc.HEARTBEAT_SUFFIX


# Each node's liveliness writer, held for the node's life.
_WRITERS = weakref.WeakKeyDictionary()

def add_heartbeat(node, period=1.0, problem=None):
    """Hold the node's liveliness writer (``<node name>/alive``) and publish ``<node name>:
    heartbeat`` on diagnostics every ``period`` wall-clock seconds: level OK ('alive'), or
    ERROR with the message ``problem()`` returns while it returns one (a lasting problem,
    e.g. the planner's map file could not be used: a monitor that starts late still sees
    it; the node is alive all the same)."""
    pub = ifc.publisher(node, ifc.DIAGNOSTICS)
    name = node.get_name() + SUFFIX
    started = time.monotonic()
    alive = ifc.ALIVE.get(node.get_name())
    if alive is not None:
        # Kept as long as the node lives (DDS asserts it while the writer exists).
        _WRITERS[node] = node.create_publisher(alive.type, alive.own_name, alive.qos)

    def beat():
        message = problem() if problem is not None else None
        pub.publish(diagnostic_array(diagnostic_status(
            DiagnosticStatus.ERROR if message else DiagnosticStatus.OK, name,
            message or 'alive', {'uptime_s': f'{time.monotonic() - started:.1f}'}),
            node.get_clock().now().to_msg()))

    beat()
    return node.create_timer(period, beat, clock=Clock(clock_type=ClockType.STEADY_TIME))


class LivenessWatch:
    """Which watched nodes are alive, from liveliness-changed events (ROS-free bookkeeping).

    A node is *lost* from the event that one of its writers lost its liveliness until a
    writer of it becomes alive again (a restarted node); a node never seen alive is *silent*
    once ``grace`` seconds have passed since the watch started (start-up is not an alarm).
    """

    def __init__(self, nodes, grace, now=None):
        self.started = time.monotonic() if now is None else now
        self.grace = float(grace)
        self.alive = {n: 0 for n in nodes}  # writers alive, as the latest event said
        self.seen = set()  # nodes seen alive at least once
        self.lost = {}  # node -> when it was lost
        self.silent = set()

    def set_grace(self, seconds) -> None:
        """How long a node may stay unseen after the watch started (``heartbeat.timeout``)."""
        self.grace = float(seconds)

    def changed(self, node, alive_count, alive_change, not_alive_change=0, now=None):
        """A liveliness-changed event on ``node``'s topic (its alive count, and the changes
        of the alive and not-alive counts since the last event); returns 'lost', 'alive' or
        None (nothing to report)."""
        now = time.monotonic() if now is None else now
        before, self.alive[node] = self.alive[node], int(alive_count)
        # Changes are summed between two reads: a writer lost while another appeared shows
        # in the not-alive count, or in an alive count lower than before.
        if alive_change < 0 or not_alive_change > 0 or alive_count < before:
            # One of its writers died: reported even while another writer (a restarted
            # node not yet gone from the graph, or someone else's) is still alive.
            self.lost[node] = now
            return 'lost'
        if alive_change > 0 and alive_count > 0:
            first = node not in self.seen
            self.seen.add(node)
            if node in self.lost or first:
                self.lost.pop(node, None)
                return 'alive'
        return None

    def check(self, now=None):
        """Return ``(newly_silent, back)``: node lists whose state changed since last check."""
        now = time.monotonic() if now is None else now
        late = now - self.started > self.grace
        silent = set(self.lost) | {n for n in self.alive if late and n not in self.seen}
        newly, back = sorted(silent - self.silent), sorted(self.silent - silent)
        self.silent = silent
        return newly, back

    def why(self, node, now=None):
        """Why ``node`` is silent, in words."""
        now = time.monotonic() if now is None else now
        if node in self.lost:
            return (f'{node} silent for {now - self.lost[node]:.1f} s: its liveliness lease '
                    f'({ifc.LIVELINESS_LEASE:g} s) expired or its writer went away')
        return (f'{node} silent: never alive in {now - self.started:.1f} s '
                f'(heartbeat.timeout {self.grace:g} s)')
