"""DDS stays on loopback: every socket of every node process is local."""

import psutil
import pytest

from ros_graph import Client, NodeProcesses

LOOPBACK = {'127.0.0.1', '::1'}


def _non_loopback_sockets(pid):
    return [(c.type.name, c.laddr.ip, c.laddr.port)
            for c in psutil.Process(pid).net_connections(kind='inet')
            if c.laddr and c.laddr.ip not in LOOPBACK]


@pytest.mark.dds
def test_every_node_process_binds_loopback_only():
    nodes = NodeProcesses()
    client = Client('sela_loopback_check')
    try:
        # Wait until each node has its DDS participant up and has been discovered: its sockets
        # are all open by then (discovery itself went over them).
        names = set(nodes.procs)
        client.spin_until(lambda: names <= set(client.node.get_node_names()), 60,
                          'the four nodes in the graph')
        pids = {name: proc.pid for name, (proc, _) in nodes.procs.items()}
        pids['test client (this process)'] = psutil.Process().pid
        found = {name: psutil.Process(pid).net_connections(kind='inet')
                 for name, pid in pids.items()}
        assert all(found.values()), found  # each one does use UDP (on loopback)
        outside = {name: _non_loopback_sockets(pid) for name, pid in pids.items()}
        assert not any(outside.values()), outside
        assert all(nodes.alive().values()), nodes.logs()
    finally:
        client.close()
        nodes.stop()
