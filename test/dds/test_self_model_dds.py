"""The self-model over DDS: the adapter reads the feet in sim_bridge's outcomes, simulates the
damage they show in its worker processes while the mission goes on, and uses the table."""
import pytest
from test_ros_mission import Watcher

from ros_graph import Client, NodeProcesses

pytestmark = [pytest.mark.dds, pytest.mark.slow]

# Three legs lost, a tripod: no table of the shipped priors holds it.
TRIPOD = 'remove:front_left,remove:middle_right,remove:rear_left'
# As the self-model names it (the legs in the robot's order).
SAID = 'remove:front_left,remove:rear_left,remove:middle_right'


@pytest.fixture
def graph():
    # Gaits at four times the robot's pace: the mission lasts long enough for the worker
    # process to start and simulate, as a robot's real gaits leave it time to.
    nodes = NodeProcesses({'sim_bridge': {'damage': TRIPOD, 'seed': 3, 'real_time_factor': 4.0},
                           'sela_adapter': {'self_model.gaits': 40}})
    client = Client()
    yield nodes, client
    client.close()
    nodes.stop()


def test_the_feet_name_the_legs_lost_and_their_simulation_becomes_a_prior(graph):
    nodes, client = graph
    watcher = Watcher(client)
    said = lambda: [s.values.get('self_model') for s in watcher.steps]  # noqa: E731
    # '<damage> simulated', then, while more of its gaits are simulated, with that said.
    installed = lambda: [s for s in said() if str(s).startswith(f'{SAID} simulated')]  # noqa
    # Missions back and forth until the answer has come: however loaded the machine, the
    # worker's simulation ends while the robot walks (learning carries from one mission to
    # the next).
    for goal in [(2.0, -1.5), (0.0, 0.0)] * 4:
        watcher.send_goal(*goal)
        client.spin_until(lambda: watcher.get_result() or installed(), 400,
                          'the end of the mission or the self-model\'s table')
        if installed():
            break
    steps = said()
    assert steps[0] == 'no leg lost', (steps, nodes.logs())
    assert f'simulating {SAID}' in steps, (steps, nodes.logs())
    first = steps.index(f'simulating {SAID}')
    assert installed() and steps.index(installed()[0]) > first, (steps, nodes.logs())
    # Every step says the prior mean it was chosen on: the intact map, a table, the mixture,
    # or (once it explains the steps best) the self-model's table.
    priors = [s.values.get('prior') for s in watcher.steps]
    assert all(n.startswith(('intact', 'remove', 'shorten', 'block', 'weaken', 'mixture',
                             'self-model')) for n in priors), priors
