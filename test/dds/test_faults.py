"""Reliability over DDS: bad input never crashes a node; killed nodes come back; nothing
learned is lost."""
import contextlib
import json
import math

import numpy as np
import pytest
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import GetParameters, SetParameters
from std_msgs.msg import Float64MultiArray, MultiArrayDimension
from std_srvs.srv import Trigger

from sela_ros.nodes import conversions as conv
from sela_ros.nodes import interface as ifc
from sela_ros.tools.mission_client import MissionClient

from ros_graph import Client, NodeProcesses

pytestmark = [pytest.mark.dds, pytest.mark.slow]


class Diagnostics(MissionClient):
    """The mission client of a test's client node."""

    def __init__(self, client):
        super().__init__(client.node, lambda t: client.executor.spin_once(timeout_sec=t))

    def wait_for_heartbeats(self, client, names, timeout=60):
        """Wait until every node in ``names`` has published a heartbeat after this call."""
        start = len(self.statuses)
        client.spin_until(lambda: {s.name.removesuffix(ifc.HEARTBEAT_SUFFIX)
                                   for s in list(self.statuses)[start:]} >= set(names),
                          timeout, f'a heartbeat from each of {sorted(names)}')


def _set(client, node, name, value, kind):
    cli = client.node.create_client(SetParameters, f'/{node}/set_parameters')
    field = {ParameterType.PARAMETER_STRING: 'string_value',
             ParameterType.PARAMETER_DOUBLE: 'double_value',
             ParameterType.PARAMETER_INTEGER: 'integer_value'}[kind]
    value_msg = ParameterValue(type=kind, **{field: value})
    request = SetParameters.Request(parameters=[Parameter(name=name, value=value_msg)])
    return client.call(cli, request).results[0]


@pytest.fixture
def graph(request):
    nodes = NodeProcesses(getattr(request, 'param', {}))
    client = Client()
    yield nodes, client
    client.close()
    nodes.stop()


def test_bad_input_gets_a_clear_error_and_no_node_crashes(graph, tmp_path):
    nodes, client = graph
    diag = Diagnostics(client)
    node = client.node
    behavior_pub = ifc.publisher(node, ifc.BEHAVIOR)
    outcome_pub = ifc.publisher(node, ifc.OUTCOME)
    outcomes = []
    ifc.subscription(node, ifc.OUTCOME, outcomes.append)
    client.spin_until(lambda: behavior_pub.get_subscription_count() > 0, 30, 'sim_bridge')

    # Behaviour commands: wrong length, NaN, infinity, out of [0, 1], bad id label.
    bad_id = Float64MultiArray(data=[0.5] * 36)
    bad_id.layout.dim = [MultiArrayDimension(label='behavior_id=x', size=36, stride=36)]
    for msg in (Float64MultiArray(data=[0.5] * 35), Float64MultiArray(data=[math.nan] * 36),
                Float64MultiArray(data=[math.inf] + [0.5] * 35),
                Float64MultiArray(data=[1.5] + [0.5] * 35), bad_id):
        behavior_pub.publish(msg)
    client.spin_until(lambda: len(diag.errors('sim_bridge: command')) >= 5, 30,
                      'five rejected commands')
    errors = diag.errors('sim_bridge: command')
    assert any('expected 36 values, got 35' in e for e in errors)
    assert any('expected finite numbers' in e for e in errors)
    assert any('expected every parameter in [0, 1]' in e for e in errors)
    assert any('not an integer' in e for e in errors)
    # ... and a good one still works afterwards, answered by exactly one outcome.
    behavior_pub.publish(conv.behavior_to_msg(np.full(36, 0.5), 424242))
    client.spin_until(lambda: any(conv.outcome_from_msg(m).behavior_id == 424242
                                  for m in outcomes), 60, 'the outcome of a good command')

    # Goals: off the map, in another frame, NaN.
    diag.wait_until_ready()
    diag.wait_for_goal_listeners(2)  # the planner and the adapter
    diag.publish_goal(40.0, 0.0)
    client.spin_until(lambda: any('off the map' in e for e in diag.errors('planner')), 30,
                      'goal off the map reported')
    diag.publish_goal(1.0, 0.0, frame_id='base_link')
    for who in ('planner', 'sela_adapter'):  # both say it where the user looks
        client.spin_until(lambda n=who: any("frame 'base_link'" in e for e in diag.errors(n)),
                          30,
                          f'goal in another frame reported by the {who}')
    diag.publish_goal(math.nan, 0.0)
    for who in ('planner', 'sela_adapter'):
        client.spin_until(lambda n=who: any('finite' in e for e in diag.errors(n)), 30,
                          f'NaN goal reported by the {who}')

    # An outcome that pairs with no command, and a malformed outcome.
    outcome_pub.publish(conv.outcome_to_msg(conv.BehaviorOutcome(
        99_999_999, np.zeros(3), np.zeros(3), np.zeros(3))))
    outcome_pub.publish(Float64MultiArray(data=[1.0, 2.0]))

    # Parameters: invalid values are rejected with a reason, the old value kept.
    r = _set(client, 'sim_bridge', 'damage', 'remove:leg7', ParameterType.PARAMETER_STRING)
    assert not r.successful and 'valid' in r.reason
    for bad, reason in (('friction:-0.5', 'friction coefficient'),
                        ('remove:rear_left,payload:500@0.08,0.05', 'payload mass')):
        r = _set(client, 'sim_bridge', 'damage', bad, ParameterType.PARAMETER_STRING)
        assert not r.successful and reason in r.reason, r.reason
    r = _set(client, 'planner', 'planner.inflation', -1.0, ParameterType.PARAMETER_DOUBLE)
    assert not r.successful and 'inflation' in r.reason
    r = _set(client, 'damage_detector', 'detection.window', 0,
             ParameterType.PARAMETER_INTEGER)
    assert not r.successful and 'detection.window' in r.reason
    r = _set(client, 'sela_adapter', 'max_steps', -3, ParameterType.PARAMETER_INTEGER)
    assert not r.successful and 'max_steps' in r.reason
    # A name the node does not have: said, with the closest names it has.
    r = _set(client, 'sela_adapter', 'gp.kernel.length', 0.4, ParameterType.PARAMETER_DOUBLE)
    assert not r.successful and "no parameter 'gp.kernel.length'" in r.reason, r.reason
    assert "'gp.kernel.sigma'" in r.reason
    r = _set(client, 'sim_bridge', 'damages', 'remove:rear_left', ParameterType.PARAMETER_STRING)
    assert not r.successful and "/sim_bridge has no parameter 'damages'" in r.reason, r.reason
    # A truncated archive file is refused, and the adapter keeps the one it had.
    broken = tmp_path / 'broken.npz'
    broken.write_bytes(b'PK\x03\x04 truncated')
    r = _set(client, 'sela_adapter', 'archive', str(broken), ParameterType.PARAMETER_STRING)
    assert not r.successful and 'broken.npz' in r.reason
    adapt = client.call(ifc.client(node, ifc.ADAPT), Trigger.Request())
    assert adapt.success
    # Alive after all of it: each node beats again after the last bad input (a condition,
    # not a pause: a crashed node never beats again).
    diag.wait_for_heartbeats(client, nodes.procs)
    assert all(nodes.alive().values()), nodes.logs()


def test_adapter_with_corrupt_archive_stays_up_and_says_why(tmp_path):
    corrupt = tmp_path / 'corrupt.npz'
    corrupt.write_bytes(b'not an archive at all')
    nodes = NodeProcesses({'sela_adapter': {'archive': str(corrupt)}}, names=('sela_adapter',))
    client = Client()
    try:
        answer = client.call(ifc.client(client.node, ifc.ADAPT), Trigger.Request(),
                             timeout=30)
        assert not answer.success and 'no archive loaded' in answer.message
        assert nodes.alive() == {'sela_adapter': True}
        assert 'corrupt.npz' in nodes.logs()['sela_adapter.log']
    finally:
        client.close()
        nodes.stop()


def test_adapter_with_unusable_damage_priors_adapts_from_the_intact_map(tmp_path):
    corrupt = tmp_path / 'priors.npz'
    corrupt.write_bytes(b'not a table of anything')
    nodes = NodeProcesses({'sela_adapter': {'priors.tables': str(corrupt)}},
                          names=('sela_adapter',))
    client = Client()
    try:
        answer = client.call(ifc.client(client.node, ifc.ADAPT), Trigger.Request(),
                             timeout=30)
        assert answer.success  # the archive is loaded: the adapter works without them
        client.spin_until(lambda: 'adapting from the intact map alone' in
                          nodes.logs().get('sela_adapter.log', ''), timeout=30,
                          what='the damage priors error in the log')
        log = nodes.logs()['sela_adapter.log']
        assert 'priors.npz is not an .npz file' in log and 'Traceback' not in log
        assert nodes.alive() == {'sela_adapter': True}
    finally:
        client.close()
        nodes.stop()


def _observations(state_file):
    try:
        state = json.loads(state_file.read_text())
    except (OSError, ValueError):
        return [], []
    return state['sela']['indices'], state['sela']['generic_rewards']


@pytest.mark.parametrize('graph', [{'sim_bridge': {'damage': 'remove:middle_right', 'seed': 11},
                                    'sela_adapter': {'outcome_timeout': 3.0},
                                    'damage_detector': {'heartbeat.timeout': 2.0}}],
                         indirect=True)
def test_killed_nodes_come_back_and_the_mission_completes(graph):
    nodes, client = graph
    diag = Diagnostics(client)
    diag.go_to_pose(1.6, 1.2)
    # Mid-mission, once it has learned a few steps and every observation it announced is
    # on disk (the state is written off the step's critical path: wait for the write, never
    # for a time).
    def learned_and_saved():
        saved = len(_observations(nodes.state_file)[0])
        return (len(diag.steps) >= 5 and saved >= 3
                and saved >= int(diag.steps[-1].values['observations']))

    client.spin_until(learned_and_saved, 200, 'three observations announced and saved')

    # SIGKILL the adapter mid-mission: what it learned is on disk and comes back.
    nodes.kill('sela_adapter')
    before = _observations(nodes.state_file)
    assert len(before[0]) >= 3
    nodes.start('sela_adapter')
    steps_at_restart = len(diag.steps)
    # (or the end of the mission: on a loaded machine the kill may come late in it)
    client.spin_until(lambda: len(diag.steps) >= steps_at_restart + 2 or diag.get_result(),
                      200, 'two steps after the adapter restarted')
    after = _observations(nodes.state_file)
    assert after[0][:len(before[0])] == before[0]
    assert after[1][:len(before[1])] == before[1]

    # SIGKILL the planner: reported silent, and the mission ends (no plan can come), unless
    # it ended already; started again, it plans the same goal sent again.
    nodes.kill('planner')
    client.spin_until(lambda: any('planner silent' in e for e in diag.errors('liveness')), 60,
                      'the silent planner reported')
    client.spin_until(diag.get_result, 200, 'the end of the mission')
    assert diag.get_result().success or 'the planner is lost' in diag.get_result().message
    adapter_log = nodes.logdir / 'sela_adapter.log'
    seen = adapter_log.read_text().count('planner alive')
    nodes.start('planner')
    client.spin_until(lambda: adapter_log.read_text().count('planner alive') > seen, 120,
                      'the adapter seeing the restarted planner')
    diag.go_to_pose(1.6, 1.2, timeout=120)

    # SIGKILL the simulator: a new one starts, the adapter resends the lost command.
    steps_now = len(diag.steps)
    client.spin_until(lambda: len(diag.steps) >= steps_now + 1 or diag.get_result(), 200,
                      'one more step')
    nodes.kill('sim_bridge')
    nodes.start('sim_bridge')
    client.spin_until(diag.get_result, 400, 'the end of the mission')
    assert diag.get_result().success, nodes.logs()
    assert all(nodes.alive().values()), nodes.logs()



def test_a_result_not_yet_heard_when_the_adapter_stopped_is_said_again_after_it_restarts(graph):
    """The adapter is killed just after a mission ended: a client that had not heard the
    result yet hears it from the restarted adapter, naming its mission."""
    nodes, client = graph
    diag = Diagnostics(client)
    diag.go_to_pose(0.3, 0.0)
    client.spin_until(diag.get_result, 200, 'the end of the mission')
    ended = diag.get_result().values
    nodes.kill('sela_adapter')
    heard = len(diag.statuses)
    nodes.start('sela_adapter')

    def said_again():
        return any(s.name == ifc.MISSION_STATUS and 'success' in conv.status_values(s)
                   and conv.status_values(s)['mission'] == ended['mission']
                   for s in list(diag.statuses)[heard:])

    client.spin_until(said_again, 120, f"mission {ended['mission']}'s result said again")
    again = next(conv.status_values(s) for s in list(diag.statuses)[heard:]
                 if s.name == ifc.MISSION_STATUS and 'success' in conv.status_values(s))
    assert (again['success'], again['steps'], again['code']) == (
        ended['success'], ended['steps'], ended['code']), (again, ended)


OBSTACLE = (0.6, 0.6, 1.2, 1.2)


@pytest.mark.parametrize('graph', [{'planner': {'map.obstacles': list(OBSTACLE)}}],
                         indirect=True)
def test_goal_inside_an_obstacle_is_refused_and_the_next_goal_goes_around_it(graph):
    nodes, client = graph
    diag = Diagnostics(client)
    paths = []
    ifc.subscription(client.node, ifc.PATH, paths.append)
    client.wait_for_publishers((ifc.DIAGNOSTICS.root_name, ifc.PATH.root_name))
    diag.wait_until_ready()
    diag.publish_goal(0.9, 0.9)
    client.spin_until(lambda: any('inside an obstacle' in e for e in diag.errors('planner')),
                      60, 'the goal inside the obstacle reported by the planner')
    # The adapter refuses it (against the planner's map) or, without the map yet, has no plan.
    client.spin_until(lambda: any('inside an obstacle' in e or 'no plan to the goal' in e
                                  for e in diag.errors('sela_adapter')), 60,
                      'the adapter refusing the goal')
    assert not diag.steps  # no gait was sent toward a goal that cannot be reached
    # A goal behind the obstacle: reached, on paths that never cross it, although goals that
    # cannot be planned arrive on the way: refused, and the running mission goes on.
    diag.go_to_pose(1.5, 1.5)
    client.spin_until(lambda: len(diag.steps) >= 2, 300, 'two steps')
    for bad in ((0.9, 0.9), (40.0, 0.0)):
        diag.publish_goal(*bad)
    client.spin_until(lambda: len([e for e in diag.errors('sela_adapter')
                                   if 'the mission to (1.50, 1.50) goes on' in e]) >= 2, 60,
                      'both bad goals refused mid-mission')
    client.spin_until(diag.get_result, 300, 'the end of the mission')
    assert diag.get_result().success, nodes.logs()
    assert paths
    for path in paths:
        for pose in path.poses:
            x, y = pose.pose.position.x, pose.pose.position.y
            assert not (OBSTACLE[0] < x < OBSTACLE[2] and OBSTACLE[1] < y < OBSTACLE[3]), \
                (x, y)
    assert all(nodes.alive().values()), nodes.logs()


FALLING_GAIT = 21  # of the shipped 2-D archive: tips the robot over without its front left leg


@pytest.mark.parametrize('episodic', [False, True])
def test_a_fallen_robot_gets_up_where_it_lies_or_is_reset_and_the_step_failed(tmp_path,
                                                                             episodic):
    from sela_ros.core.storage import Archive, load_archive, shipped_archive_path

    # An archive whose most attractive gait (straight to the first waypoint, on paper) is
    # one that makes the damaged robot fall.
    shipped = load_archive(shipped_archive_path('2d'))
    keep = [FALLING_GAIT] + [i for i in range(300) if i != FALLING_GAIT]
    rewards = shipped.generic_reward[keep].copy()
    rewards[0] = (0.6, 0.0, 0.0)
    path = Archive(shipped.params[keep], shipped.descriptors[keep], rewards,
                   shipped.fitness[keep], shipped.metadata).save(tmp_path / 'falling.npz')
    # The default: the robot gets up where it lies. Episodic: it is put back at the start.
    bridge = {'damage': 'remove:front_left', 'archive': str(path)}
    adapter = {'archive': str(path), 'max_steps': 4}
    if episodic:
        bridge['right_on_fall'], adapter['reset_on_fall'] = False, True
    nodes = NodeProcesses({'sim_bridge': bridge, 'sela_adapter': adapter})
    client = Client()
    try:
        diag = Diagnostics(client)
        diag.go_to_pose(1.0, 0.0)
        client.spin_until(lambda: len(diag.steps) >= 2, 120, 'two steps')
        first, second = diag.steps[:2]
        assert first.behavior_index == 0 and first.fallen, first
        assert first.failed_steps == 1

        # The reports come on their own messages, which a loaded machine may deliver after
        # the steps': wait for them, then say which is missing.
        def reported():
            return (any('fell' in e for e in diag.errors('sim_bridge: robot'))
                    and any('failed: the robot fell' in e for e in diag.errors('sela_adapter'))
                    and (not episodic or (
                        any('/sim_bridge/reset' in e for e in diag.errors('sela_adapter'))
                        and 'reset: robot back at the start' in nodes.logs()['sela_adapter.log'])))
        with contextlib.suppress(TimeoutError):  # the assertions below say what is missing
            client.spin_until(reported, 60, 'the fall reported')
        assert any('fell' in e for e in diag.errors('sim_bridge: robot'))
        assert any('failed: the robot fell' in e for e in diag.errors('sela_adapter'))
        end, start = first.end_pose, second.pose
        assert np.linalg.norm(end[:2]) > 0.1, first  # it fell away from the start
        if episodic:  # the next step started from the start again
            assert any('/sim_bridge/reset' in e for e in diag.errors('sela_adapter'))
            assert np.linalg.norm(start[:2]) < 0.02 and abs(start[2]) < 0.02, second
            assert 'reset: robot back at the start' in nodes.logs()['sela_adapter.log']
        else:  # it got up where it lay, and the next step started there
            assert np.allclose(start, end), (first, second)
            assert 'reset' not in nodes.logs()['sela_adapter.log']
        assert all(nodes.alive().values()), nodes.logs()
    finally:
        client.close()
        nodes.stop()


@pytest.mark.parametrize('graph', [{'sim_bridge': {'sim.dt': 0.005, 'archive': 'none'}}],
                         indirect=True)
def test_archive_built_for_another_simulator_is_refused_with_the_reason(graph):
    nodes, client = graph
    diag = Diagnostics(client)
    commands = []
    ifc.subscription(client.node, ifc.BEHAVIOR, commands.append)
    # The mismatch is reported when found and again with every goal (the goal is taken once
    # the adapter hears this client, so the report then reaches it too).
    diag.go_to_pose(1.0, 0.0)
    client.spin_until(lambda: any('other simulator settings' in e
                                  for e in diag.errors('sela_adapter')), 60,
                      'the mismatch reported')
    error = next(e for e in diag.errors('sela_adapter') if 'other simulator settings' in e)
    assert 'dt' in error and '0.005' in error and 'archive' in error
    # A second goal: handled (the mismatch is reported again) and still no gait sent. The
    # report proves the adapter processed the goal, whatever the machine's load.
    def reports():
        return len([e for e in diag.errors('sela_adapter') if 'other simulator settings' in e])

    reported = reports()
    diag.publish_goal(0.5, 0.5)
    client.spin_until(lambda: reports() > reported, 60,
                      'the mismatch reported again with the second goal')
    assert not commands and not diag.steps  # nothing sent on a map of another simulator
    assert all(nodes.alive().values()), nodes.logs()


def test_an_archive_of_other_physics_than_the_simulators_is_refused_when_set(graph):
    nodes, client = graph
    diag = Diagnostics(client)
    diag.go_to_pose(0.5, 0.0)
    # A step taken: the simulator has told the adapter its physics.
    client.spin_until(lambda: diag.steps, 120, 'a first step')
    result = _set(client, 'sela_adapter', 'archive', '2d', ParameterType.PARAMETER_STRING)
    assert not result.successful
    assert 'other simulator settings' in result.reason, result.reason
    assert 'archive:=' in result.reason, result.reason
    steps = len(diag.steps)
    diag.go_to_pose(0.0, 0.5)  # the archive in use goes on
    client.spin_until(lambda: len(diag.steps) > steps, 120, 'a step on the archive in use')
    assert all(nodes.alive().values()), nodes.logs()


def test_a_step_is_announced_only_once_saved_and_a_failed_save_is_an_error(tmp_path):
    # Learning from the first step: every step adds an observation to the state file.
    nodes = NodeProcesses({'sela_adapter': {'adapt_on_start': True}})
    client = Client()
    try:
        diag = Diagnostics(client)
        on_disk = []

        def check(msg):  # at the moment a step is announced, it is on disk already
            for status in msg.status:
                values = conv.status_values(status)
                if status.name == ifc.MISSION_STATUS and 'step' in values:
                    on_disk.append((int(values['observations']),
                                    len(_observations(nodes.state_file)[0]), values['saved']))
        ifc.subscription(client.node, ifc.DIAGNOSTICS, check)
        diag.go_to_pose(0.8, 0.0)
        client.spin_until(diag.get_result, 300, 'the end of the mission')
        assert on_disk and all(saved >= announced and flag == 'True'
                               for announced, saved, flag in on_disk), on_disk
        # The archive in use set again keeps what was learned; another one is refused
        # while anything is learned (its observations index the old archive's gaits).
        from sela_ros.core.storage import default_archive_path

        learned = _observations(nodes.state_file)
        r = _set(client, 'sela_adapter', 'archive', '', ParameterType.PARAMETER_STRING)
        assert r.successful, r.reason
        copy = tmp_path / 'another.npz'
        copy.write_bytes(default_archive_path().read_bytes())
        r = _set(client, 'sela_adapter', 'archive', str(copy), ParameterType.PARAMETER_STRING)
        assert not r.successful and 'clear first' in r.reason, r.reason
        assert _observations(nodes.state_file) == learned
        answer = client.call(ifc.client(client.node, ifc.ADAPT), Trigger.Request())
        assert answer.success  # still serving, still the same learning
    finally:
        client.close()
        nodes.stop()
    # A state file that cannot be written (its folder is a file): every step says so.
    blocker = tmp_path / 'not_a_folder'
    blocker.write_text('')
    nodes = NodeProcesses({'sela_adapter': {'adapt_on_start': True,
                                            'state_file': str(blocker / 'state.json')}})
    client = Client()
    try:
        diag = Diagnostics(client)
        diag.go_to_pose(0.5, 0.0)
        client.spin_until(lambda: diag.steps and any(
            'could not save the learned state' in e for e in diag.errors('sela_adapter')),
            300, 'the failed save reported')
        assert diag.steps[0].values['saved'] == 'False'
        assert all(nodes.alive().values()), nodes.logs()
    finally:
        client.close()
        nodes.stop()


def test_a_second_adapter_on_the_same_state_file_neither_resumes_nor_erases_it(tmp_path):
    """Two adapters given one state file (two robots' stacks sharing it by mistake): the
    first keeps it, the second says why it will not use it, and the first's learning is
    left as it is."""
    state = tmp_path / 'state.json'
    first = NodeProcesses({'sela_adapter': {'state_file': str(state)}},
                          names=('sela_adapter',), namespace='/robot1')
    client = Client()
    second = None
    try:
        # Up (its parameters answer): it has claimed the file in its constructor.
        get = client.node.create_client(GetParameters, '/robot1/sela_adapter/get_parameters')
        client.call(get, GetParameters.Request(names=['state_file']), timeout=90)
        kept = b'{"kept": "as it is"}'
        state.write_bytes(kept)  # stands for what the first adapter learned
        second = NodeProcesses({'sela_adapter': {'state_file': str(state)}},
                               names=('sela_adapter',), namespace='/robot2')
        client.spin_until(lambda: 'is in use by another process' in
                          second.logs().get('sela_adapter.log', ''), 120,
                          "the second adapter's reason")
        log = second.logs()['sela_adapter.log']
        assert 'own state_file' in log and 'resumed from' not in log, log
        answer = client.call(client.node.create_client(Trigger, '/robot2/sela_adapter/adapt'),
                             Trigger.Request(), timeout=60)
        assert answer is not None  # still serving
        assert state.read_bytes() == kept
        assert all(first.alive().values()) and all(second.alive().values())
    finally:
        client.close()
        first.stop()
        if second is not None:
            second.stop()
