"""A mission of many goals through the maze course over DDS: the four nodes as processes,
the planner on the shipped maze map, the middle right leg removed, the goals sent as a
nav_msgs/Path on ``goal_path``; every wait is on a condition, with a time-out."""
from pathlib import Path

import numpy as np
import pytest

from sela_ros.core.planning import load_map_file
from sela_ros.experiments.courses import load_courses
from sela_ros.nodes import conversions as conv
from sela_ros.nodes import interface as ifc
from sela_ros.tools.mission_client import MissionClient

from ros_graph import Client, NodeProcesses

pytestmark = [pytest.mark.dds, pytest.mark.slow]

MAPS = Path(__file__).resolve().parents[2] / 'config' / 'maps'
# A gait takes about 0.15 s of CPU; the maze takes about 50 of them, and the machine is
# shared: the limits only catch a mission that is stuck, never a slow one.
MISSION_TIMEOUT = 1500


@pytest.mark.timeout(MISSION_TIMEOUT + 300)
def test_a_mission_through_the_maze_with_a_leg_removed_completes_over_dds():
    maze = load_courses(MAPS)['maze']
    nodes = NodeProcesses({'planner': {'map.file': str(maze.map_path)},
                           'sim_bridge': {'damage': 'remove:middle_right', 'seed': 3}})
    client = Client()
    try:
        mission = MissionClient(client.node, lambda t: client.executor.spin_once(timeout_sec=t))
        odometry = []
        ifc.subscription(client.node, ifc.ODOM,
                         lambda m: odometry.append(conv.pose_from_odometry(m)))
        client.wait_for_publishers([ifc.DIAGNOSTICS.root_name, ifc.ODOM.root_name],
                                   timeout=120)
        mission.follow_goals([list(g) for g in maze.goals], timeout=120)
        mission.spin_until(lambda: mission.result is not None, MISSION_TIMEOUT,
                           'the end of the mission')
        result = mission.get_result()
        assert result.success, (result.message, mission.errors(''), nodes.logs())
        # Progress per goal, in order, the last one with the result.
        reached = [g.goal[:2].tolist() for g in mission.goals_reached]
        assert reached == [list(g) for g in maze.goals]
        assert [g.index for g in mission.goals_reached] == [1, 2, 3, 4]
        assert mission.goals_reached[-1].steps == result.steps
        assert result.values['goal_index'] == result.values['goals'] == '4'
        # Learning carried from goal to goal: the first step toward a new goal starts from
        # all that was learned (fewer observations only after a detection restarted it).
        steps, restarted = mission.steps, {d.behavior_id for d in mission.detections}
        firsts = np.cumsum([g.steps for g in mission.goals_reached[:-1]])  # each leg's first
        assert len(steps) == firsts[-1] + result.steps
        for i in firsts:
            before, after = (int(steps[k].values['observations']) for k in (i - 1, i))
            assert after >= before or steps[i].behavior_id in restarted, (i, before, after)
        assert int(steps[-1].values['observations']) > 0
        final = odometry[-1]
        assert np.hypot(*(final[:2] - maze.goals[-1])) < 0.2  # true pose; observed within 0.1
        grid = load_map_file(maze.map_path)
        walked = [s.end_pose[:2] for s in mission.steps]
        collisions = sum(not grid.is_free(grid.world_to_cell(p)) for p in walked)
        print(f'maze mission over DDS: {len(mission.steps)} steps, goals reached at '
              f'{[g.steps for g in mission.goals_reached]} steps, '
              f'{collisions} step(s) ended in a wall (observed pose)')
        assert all(nodes.alive().values()), nodes.logs()
    finally:
        client.close()
        nodes.stop()
