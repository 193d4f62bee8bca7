"""Decisions do not depend on timing: under CPU load, and with a goal sent while the nodes are
still starting, the same seed takes the same gaits as an unloaded run."""
import subprocess
import sys

import pytest

from sela_ros.tools.mission_client import MissionClient

from ros_graph import Client, NodeProcesses

pytestmark = [pytest.mark.dds, pytest.mark.slow]

SETUP = {'sim_bridge': {'damage': 'remove:middle_right', 'seed': 7}}
GOAL = (1.5, 1.0)


def _mission(early_goal):
    """The gaits (archive indices) of one mission; with ``early_goal`` the goal is sent as
    the nodes start (before any of them can hear it: it is sent again until taken)."""
    client = Client('sela_timing')
    nodes = None
    try:
        mission = MissionClient(client.node, lambda t: client.executor.spin_once(timeout_sec=t))
        if early_goal:
            mission.publish_goal(*GOAL)
        nodes = NodeProcesses(SETUP)
        # The nodes start under the load: their start-up is part of this wait, as of the next.
        mission.go_to_pose(*GOAL, timeout=600)
        client.spin_until(mission.get_result, 600, 'the end of the mission')
        assert mission.get_result().success, nodes.logs()
        return [s.behavior_index for s in mission.steps]
    finally:
        client.close()
        if nodes is not None:
            nodes.stop()


@pytest.mark.timeout(1500)  # two missions, one of them on a machine kept busy on purpose
def test_same_seed_same_gaits_under_cpu_load_and_with_an_early_goal():
    reference = _mission(early_goal=False)
    busy = [subprocess.Popen([sys.executable, '-c', 'while 1: pass']) for _ in range(2)]
    try:
        loaded = _mission(early_goal=True)
    finally:
        for proc in busy:
            proc.kill()
            proc.wait(timeout=10)
    assert loaded == reference
