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

A node also watches for a namesake: another node of its name and namespace in the domain (a
second stack started without ``namespace:=``), whose topics would mix with its own. It is
one only while the graph holds two nodes of the name *and* a writer on the node's
``<node>/alive`` from another process is alive (the liveliness events of a subscription
count the writers of other participants: Fast DDS does not report the process's own): a
killed node's entry stays in the graph for the middleware's lease, but its writer loses its
liveliness within ``interface.LIVELINESS_LEASE``.
"""
import functools
import os
import time
import weakref

from diagnostic_msgs.msg import DiagnosticStatus
from rclpy.clock import Clock, ClockType
from rclpy.event_handler import SubscriptionEventCallbacks

from sela_ros.nodes import interface as ifc
from sela_ros.nodes.conversions import diagnostic_array, diagnostic_status
from sela_ros.nodes.guard import report_exception

SUFFIX = ifc.HEARTBEAT_SUFFIX
#: s: a writer matched this long without asserting its liveliness is taken for dead. A live
#: one asserts every two thirds of its lease (rmw_fastrtps's announcement period); the rest
#: is the events' delivery under load.
UNASSERTED = ifc.LIVELINESS_LEASE + 2.0


# Each node's liveliness writer, held for the node's life.
_WRITERS = weakref.WeakKeyDictionary()

def namesake_problem(full_name, in_graph, alive_writers, domain_id):
    """What a node says while it has a namesake (see the module), or None: ``in_graph``
    nodes of its full name in the graph, ``alive_writers`` of other processes alive on its
    ``<node>/alive``."""
    if in_graph < 2 or alive_writers < 1:
        return None
    return (f'{in_graph - 1} other node(s) named {full_name} in this domain (ROS_DOMAIN_ID '
            f'{domain_id}): their topics mix with this one\'s; start a second stack with '
            'namespace:=/<robot> or another ROS_DOMAIN_ID')


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
    namesake = _NamesakeWatch(node, alive) if alive is not None else None
    if alive is not None:
        # Kept as long as the node lives (DDS asserts it while the writer exists).
        _WRITERS[node] = node.create_publisher(alive.type, alive.own_name, alive.qos)

    def beat():
        message = problem() if problem is not None else None
        message = (namesake.check() if namesake is not None else None) or message
        pub.publish(diagnostic_array(diagnostic_status(
            DiagnosticStatus.ERROR if message else DiagnosticStatus.OK, name,
            message or 'alive', {'uptime_s': f'{time.monotonic() - started:.1f}'}),
            node.get_clock().now().to_msg()))

    beat()
    return node.create_timer(period, beat, clock=Clock(clock_type=ClockType.STEADY_TIME))


class _NamesakeWatch:
    """Whether ``node`` has a namesake (see the module): said once on the log as it appears
    and as it goes; :meth:`check` is the problem its heartbeat carries meanwhile."""

    def __init__(self, node, alive):
        self.node, self.alive_writers, self.said = node, 0, None
        node.create_subscription(
            alive.type, alive.own_name, lambda _msg: None, alive.qos,
            event_callbacks=SubscriptionEventCallbacks(liveliness=self._changed))

    def _changed(self, event):
        self.alive_writers = event.alive_count

    def check(self):
        node = self.node
        full_name = node.get_fully_qualified_name()
        in_graph = sum(1 for n, ns in node.get_node_names_and_namespaces()
                       if (n, ns) == (node.get_name(), node.get_namespace()))
        problem = namesake_problem(full_name, in_graph, self.alive_writers,
                                   os.environ.get('ROS_DOMAIN_ID', '0'))
        if problem != self.said:
            if problem:
                node.get_logger().error(problem)
            elif self.said:
                node.get_logger().info(f'no other node named {full_name} any more')
            self.said = problem
        return problem


class LivenessWatch:
    """Which watched nodes are alive, from liveliness-changed events (ROS-free bookkeeping).

    A node is *lost* from the event that one of its writers lost its liveliness until a
    writer of the node's own, one that was not there when it was lost, is alive (a
    restarted node); a node never seen alive is *silent* once ``grace`` seconds have
    passed since the watch started (start-up is not an alarm).

    A writer is asserted first a little after it is matched (DDS asserts a live writer
    every two thirds of its lease): one killed in between never gets an event, alive or
    lost. So a writer matched (:meth:`matched`) and still unasserted ``unasserted``
    seconds later makes its node lost too; an assertion that comes after all makes it
    alive again.

    Whose a writer is comes from the graph: the caller passes ``writers``, the ids of the
    writers on the node's topic that belong to a node of that name (None: unknown, every
    alive writer counts). A writer of someone else's, or one of the node's that was there
    when it was lost, never makes it alive: only the watched node, started again, can.
    """

    def __init__(self, nodes, grace, now=None, unasserted=UNASSERTED):
        self.started = time.monotonic() if now is None else now
        self.grace = float(grace)
        self.unasserted = float(unasserted)
        self.alive = {n: 0 for n in nodes}  # writers alive, as the latest event said
        self.not_alive = {n: 0 for n in nodes}  # matched writers not alive, as it said
        self.unasserted_since = {}  # node -> since when a matched writer has no liveliness
        self.never_asserted = set()  # nodes lost for a writer that never asserted
        self.seen = set()  # nodes seen alive at least once
        self.lost = {}  # node -> when it was lost
        self.silent = set()
        self.own = {n: set() for n in nodes}  # the node's writers it was last seen alive with
        self.dead = {n: set() for n in nodes}  # its writers that were there when it was lost

    def set_grace(self, seconds) -> None:
        """How long a node may stay unseen after the watch started (``heartbeat.timeout``)."""
        self.grace = float(seconds)

    def changed(self, node, alive_count, alive_change, not_alive_change=0, now=None,
                writers=None, not_alive_count=None):
        """A liveliness-changed event on ``node``'s topic (its alive count, and the changes
        of the alive and not-alive counts since the last event; ``writers``: see the class;
        ``not_alive_count``: its matched writers not alive, for :meth:`matched`); returns
        'lost', 'alive' or None (nothing to report)."""
        now = time.monotonic() if now is None else now
        before, self.alive[node] = self.alive[node], int(alive_count)
        if not_alive_count is not None:
            self.not_alive[node] = int(not_alive_count)
        if alive_change > 0 and node in self.never_asserted:
            # The writer taken for dead asserted after all: it may make the node alive.
            self.never_asserted.discard(node)
            self.lost.pop(node, None)
        # Changes are summed between two reads: a writer lost while another appeared shows
        # in the not-alive count, or in an alive count lower than before.
        if alive_change < 0 or not_alive_change > 0 or alive_count < before:
            # One of its writers died: reported even while another writer (a restarted
            # node not yet gone from the graph, or someone else's) is still alive.
            if node not in self.lost:
                self.dead[node] |= self.own[node]
            self.never_asserted.discard(node)
            self.lost[node] = now
            return 'lost'
        if alive_change > 0:
            return self.confirm(node, writers)
        return None

    def matched(self, node, count, now=None):
        """``node``'s topic has ``count`` writers matched (the middleware's count, polled):
        'lost' once one of them has stayed without an assertion ``unasserted`` seconds (see
        the class), else None."""
        now = time.monotonic() if now is None else now
        if int(count) <= self.alive[node] + self.not_alive[node]:
            self.unasserted_since.pop(node, None)
            return None
        since = self.unasserted_since.setdefault(node, now)
        if now - since < self.unasserted or node in self.lost:
            return None
        self.never_asserted.add(node)
        self.lost[node] = now
        return 'lost'

    def waiting(self):
        """Nodes with a writer alive that is not yet known to be their own (the graph says
        whose a writer is a little after the event): :meth:`confirm` them again later."""
        return sorted(n for n, count in self.alive.items()
                      if count > 0 and (n in self.lost or n not in self.seen))

    def confirm(self, node, writers):
        """``node`` has ``writers`` of its own on its topic (see the class): 'alive' when
        that makes it alive again (or for the first time), else None."""
        if self.alive[node] <= 0 or not (node in self.lost or node not in self.seen):
            return None
        if writers is not None:
            fresh = set(writers) - self.dead[node]
            if not fresh:
                return None  # someone else's writer, or the dead node's: not the node
            self.own[node] = fresh
        self.seen.add(node)
        self.lost.pop(node, None)
        return 'alive'

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
        if node in self.never_asserted:
            return (f'{node} silent for {now - self.lost[node]:.1f} s: a writer on its '
                    f'liveliness topic matched {now - self.unasserted_since.get(node, now):.1f}'
                    ' s ago never asserted its liveliness (killed as it started?)')
        if node in self.lost:
            return (f'{node} silent for {now - self.lost[node]:.1f} s: its liveliness lease '
                    f'({ifc.LIVELINESS_LEASE:g} s) expired or its writer went away')
        return (f'{node} silent: never alive in {now - self.started:.1f} s '
                f'(heartbeat.timeout {self.grace:g} s)')


class LivenessMonitor:
    """``node`` watches the liveliness of the nodes ``names`` (a :class:`LivenessWatch`):
    a subscription with liveliness events on each one's ``<name>/alive``, and whose each
    writer is from the graph (a writer of a node named ``<name>`` in ``node``'s namespace).

    ``on_change(name, 'lost' | 'alive')`` is called as a node is lost or (back) alive;
    :meth:`poll` (from a timer) confirms writers the graph had not placed yet at their event,
    and counts the writers matched, for one that never asserts its liveliness.
    """

    def __init__(self, node, names, grace, on_change):
        self.node, self.on_change = node, on_change
        self.watch = LivenessWatch(names, grace)
        self._subs = {n: ifc.subscription(
            node, ifc.ALIVE[n], lambda _msg: None, event_callbacks=SubscriptionEventCallbacks(
                liveliness=functools.partial(self._event, n))) for n in names}

    def writers(self, name):
        """The ids of the writers on ``name``'s liveliness topic that are ``name``'s own."""
        infos = self.node.get_publishers_info_by_topic(self._subs[name].topic_name)
        namespace = self.node.get_namespace()
        return {tuple(i.endpoint_gid) for i in infos
                if i.node_name == name and i.node_namespace == namespace}

    def lost(self, name):
        """Whether ``name`` was alive and its liveliness was lost since."""
        return name in self.watch.lost

    def _event(self, name, info):
        try:
            change = self.watch.changed(name, info.alive_count, info.alive_count_change,
                                        info.not_alive_count_change,
                                        writers=self.writers(name),
                                        not_alive_count=info.not_alive_count)
            if change is not None:
                self.on_change(name, change)
        except Exception as exc:  # noqa: BLE001 - reported; the node keeps running
            report_exception(self.node, f'{name} liveliness', exc)

    def poll(self):
        for name in self.watch.waiting():
            if self.watch.confirm(name, self.writers(name)) == 'alive':
                self.on_change(name, 'alive')
        for name, sub in self._subs.items():
            if self.watch.matched(name, sub.get_publisher_count()) == 'lost':
                self.on_change(name, 'lost')
