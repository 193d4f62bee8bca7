"""sim_bridge runs with the physics stamped in the archive it serves (over DDS)."""
import json

import numpy as np
import pytest
from rcl_interfaces.srv import GetParameters

from ros_graph import Client, NodeProcesses

pytestmark = [pytest.mark.dds, pytest.mark.slow]

NAMES = ['sim.dt', 'sim.gait_duration', 'sim.solver_iterations']


def _settings(archive_path=None):
    overrides = {'sim_bridge': {'archive': str(archive_path)}} if archive_path is not None \
        else {}
    nodes = NodeProcesses(overrides, names=('sim_bridge',))
    client = Client()
    try:
        answer = client.call(client.node.create_client(GetParameters,
                                                       '/sim_bridge/get_parameters'),
                             GetParameters.Request(names=NAMES), timeout=60)
        values = answer.values
        assert nodes.alive() == {'sim_bridge': True}, nodes.logs()
        return (values[0].double_value, values[1].double_value, values[2].integer_value,
                nodes.logs()['sim_bridge.log'])
    finally:
        client.close()
        nodes.stop()


def test_sim_bridge_takes_the_physics_of_its_archive(tmp_path):
    path = tmp_path / 'map8d.npz'
    # Only the stamp is read: a file with the metadata of an 8-D map is enough.
    np.savez(path, metadata=np.array(json.dumps({'dt': 1 / 120, 'gait_duration': 3.0,
                                                 'solver_iterations': 30})))
    dt, duration, iterations, log = _settings(path)
    assert (dt, duration, iterations) == (1 / 120, 3.0, 30)
    assert 'physics of archive' in log


def test_an_archive_without_solver_iterations_keeps_the_old_default(tmp_path):
    # the shipped 2-D map predates solver_iterations: 1/240 s and 50 iterations
    old = tmp_path / 'old.npz'
    np.savez(old, metadata=np.array(json.dumps({'dt': 1 / 240, 'gait_duration': 3.0})))
    assert _settings(old)[:3] == (1 / 240, 3.0, 50)


def test_without_an_archive_it_takes_the_shipped_one_and_none_keeps_its_own():
    from sela_ros.core.storage import default_archive_path, load_archive

    stamp = load_archive(default_archive_path()).simulator_settings
    dt, duration, iterations, log = _settings()
    assert (dt, duration, iterations) == (stamp['dt'], stamp['gait_duration'],
                                          stamp['solver_iterations'])
    assert 'physics of archive' in log and 'sela_ros/data/hexapod_archive.npz' in log
    assert _settings('none')[:3] == (1 / 240, 3.0, 50)
