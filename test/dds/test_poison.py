"""Poison refused over DDS: an outcome whose generic reward its own poses contradict is
refused by the adapter and the detector, never learnt or saved."""
import json

import numpy as np
import pytest

from sela_ros.nodes import conversions as conv
from sela_ros.nodes import interface as ifc
from sela_ros.tools.mission_client import MissionClient

from ros_graph import Client, NodeProcesses

pytestmark = [pytest.mark.dds, pytest.mark.slow]


def _learnt(state_file):
    try:
        return json.loads(state_file.read_text())['sela']['generic_rewards']
    except (OSError, ValueError, KeyError):
        return []


def test_an_outcome_whose_reward_its_poses_contradict_is_refused_over_dds():
    nodes = NodeProcesses({'sela_adapter': {'adapt_on_start': True},
                           'sim_bridge': {'seed': 1}})
    client = Client('outcome_forger')
    try:
        node = client.node
        mission = MissionClient(node, lambda t: client.executor.spin_once(timeout_sec=t))
        forger = ifc.publisher(node, ifc.OUTCOME)
        forged = []

        def on_command(msg):
            # Answer the adapter's first command before the simulator does: 1.0 m forward
            # (a distance one gait could cover on this map), from a pose that did not move.
            _, behavior_id = conv.behavior_from_msg(msg)
            if not forged and behavior_id is not None:
                forger.publish(conv.outcome_to_msg(conv.BehaviorOutcome(
                    behavior_id, np.array([1.0, 0.0, 0.0]), np.zeros(3), np.zeros(3))))
                forged.append(behavior_id)
        ifc.subscription(node, ifc.BEHAVIOR, on_command)
        mission.wait_until_ready(timeout=120)
        mission.wait_for_goal_listeners(2)
        mission.go_to_pose(0.8, 0.0, timeout=120)
        client.spin_until(lambda: forged and any(
            f'outcome of command {forged[0]} refused, not learnt' in e
            and 'does not match its own poses' in e for e in mission.errors('sela_adapter')),
            120, "the adapter's refusal of the forged outcome")
        client.spin_until(lambda: any(f'outcome of command {forged[0]} refused' in e
                                      for e in mission.errors('damage_detector')),
                          60, "the detector's refusal")
        # The simulator's own outcome of that command is learnt, the forged one never.
        client.spin_until(lambda: len(_learnt(nodes.state_file)) >= 1, 120,
                          'the real outcome learnt and saved')
        learnt = np.array(_learnt(nodes.state_file))
        assert np.all(np.abs(learnt[:, 0]) < 0.9), learnt
        assert all(nodes.alive().values()), nodes.logs()
    finally:
        client.close()
        nodes.stop()
