"""Integration over DDS: the four nodes as processes, asserted on the messages they exchange."""

import numpy as np
import pytest
import yaml
from diagnostic_msgs.msg import DiagnosticStatus
from nav_msgs.srv import GetPlan
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters
from std_srvs.srv import Trigger

from sela_ros.core.storage import default_archive_path, load_archive
from sela_ros.nodes import conversions as conv
from sela_ros.nodes import interface as ifc
from sela_ros.tools.mission_client import MissionClient

from ros_graph import CONFIG, Client, NodeProcesses

pytestmark = [pytest.mark.dds, pytest.mark.slow]


class Watcher(MissionClient):
    """The mission client, plus what else the nodes say: commands, outcomes, rewards and
    the detector's verdicts (on diagnostics, for monitoring)."""

    def __init__(self, client):
        super().__init__(client.node, lambda t: client.executor.spin_once(timeout_sec=t))
        self.commands, self.outcomes, self.rewards = [], [], []
        self.client = client
        node = client.node
        ifc.subscription(node, ifc.BEHAVIOR,
                         lambda m: self.commands.append(conv.behavior_from_msg(m)[1]))
        ifc.subscription(node, ifc.OUTCOME,
                         lambda m: self.outcomes.append(conv.outcome_from_msg(m)))
        ifc.subscription(node, ifc.REWARD, lambda m: self.rewards.append(m.data))

    @property
    def verdicts(self):
        return [(s.level, conv.status_values(s)) for s in self.statuses
                if s.name == ifc.DETECTOR_STATUS]

    def send_goal(self, x, y):
        # Everything published after the goal must reach this watcher.
        self.client.wait_for_publishers([ifc.DIAGNOSTICS.root_name, ifc.BEHAVIOR.root_name,
                                         ifc.OUTCOME.root_name, ifc.REWARD.root_name])
        self.go_to_pose(x, y)


@pytest.fixture
def graph(request):
    overrides = getattr(request, 'param', {})
    nodes = NodeProcesses(overrides)
    client = Client()
    yield nodes, client
    client.close()
    nodes.stop()


def _config():
    """config/sela.yaml keyed by node name (its keys are ``/**/<node>``)."""
    with open(CONFIG) as handle:
        return {k.removeprefix('/**/'): v for k, v in yaml.safe_load(handle).items()}


def _experiment_runner_mission(damage, seed, goal):
    """The same mission through the experiment runner (``sela-experiment hexapod``'s SELA
    replicate, no DDS), with the sim_bridge node's noise seed."""
    from sela_ros.core.detection import DetectorConfig
    from sela_ros.core.learning import SELAConfig
    from sela_ros.core.mission import StepperConfig
    from sela_ros.core.planning import DEFAULT_INFLATION, DEFAULT_MAP
    from sela_ros.experiments import arguments
    from sela_ros.experiments.hexapod import Job, run_method

    # The runner's defaults are the shipped configuration's: the same map, the same
    # settings, so the same decisions.
    cfg = _config()
    bridge = cfg['sim_bridge']['ros__parameters']
    plan = cfg['planner']['ros__parameters']
    adapter = cfg['sela_adapter']['ros__parameters']
    detector = cfg['damage_detector']['ros__parameters']
    assert bridge['right_on_fall'] and not adapter['reset_on_fall']
    assert bridge['observation.noise_std'] == arguments.DEFAULT_NOISE_STD
    assert (plan['map.resolution'], tuple(plan['map.origin']), plan['map.width'],
            plan['map.height']) == tuple(DEFAULT_MAP.values()) and 'map.obstacles' not in plan
    assert plan['planner.inflation'] == DEFAULT_INFLATION
    assert adapter['planner.lookahead'] == SELAConfig.planner_lookahead
    assert adapter['priors.tables'] == 'auto' and adapter['max_steps'] == StepperConfig.max_steps
    assert adapter['adaptation.on_detection'] == StepperConfig.on_detection
    assert {k.split('.', 1)[1]: v for k, v in detector.items()
            if k.startswith('detection.')} == vars(DetectorConfig())
    return run_method(Job('sela', np.random.SeedSequence(seed), str(default_archive_path()),
                          damage, tuple(goal), noise_seed=seed))


@pytest.mark.parametrize('graph', [
    {'sim_bridge': {'damage': 'remove:middle_right', 'seed': 7}},
    {'sim_bridge': {'damage': 'remove:middle_right', 'seed': 7},
     'sela_adapter': {'adapt_on_start': False}}], indirect=True, ids=['defaults', 'detector'])
def test_damaged_mission_reaches_goal_with_the_in_process_decisions(graph):
    nodes, client = graph
    watcher = Watcher(client)
    goal = (1.5, 1.0)
    watcher.send_goal(*goal)
    client.spin_until(lambda: watcher.get_result(), 400, 'the end of the mission')
    assert watcher.get_result().success, (watcher.get_result(), nodes.logs())
    # Each command pairs with exactly one outcome, and each step published one reward.
    ids = [o.behavior_id for o in watcher.outcomes if o.behavior_id in set(watcher.commands)]
    assert sorted(ids) == sorted(watcher.commands)
    assert len(set(watcher.commands)) == len(watcher.commands) == len(watcher.steps)
    assert len(watcher.rewards) == len(watcher.steps)
    # The simulator says which gaits started standing: the first, and any after a fall and
    # the adapter's reset; none other.
    mine = [o for o in watcher.outcomes if o.behavior_id in set(watcher.commands)]
    assert [o.standing_start for o in mine] == [True] + [o.fallen for o in mine[:-1]]
    trusted = nodes.overrides['sela_adapter'].get('adapt_on_start') is False
    if trusted:  # the map trusted until the detector fires
        assert not watcher.steps[0].adapting
        assert any(level == DiagnosticStatus.ERROR for level, _ in watcher.verdicts)
        assert any(s.adapting for s in watcher.steps)
    else:  # the defaults: adaptation from the first step
        assert all(s.adapting for s in watcher.steps)
    # The final observed pose is within goal.eps of the goal.
    end = watcher.steps[-1].end_pose
    assert np.hypot(end[0] - goal[0], end[1] - goal[1]) < 0.1
    if trusted:
        return
    # Same seed, same decisions: the DDS mission took the experiment runner's gaits.
    runner = _experiment_runner_mission('remove:middle_right', 7, goal)
    assert runner['success']
    assert [s.behavior_index for s in watcher.steps] == runner['behaviors']


def _set_param(client, node, name, value):
    cli = client.node.create_client(SetParameters, f'/{node}/set_parameters')
    request = SetParameters.Request()
    request.parameters = [Parameter(name=name, value=ParameterValue(
        type=ParameterType.PARAMETER_STRING, string_value=value))]
    return client.call(cli, request).results[0]


@pytest.mark.parametrize('graph', [{'sela_adapter': {'adapt_on_start': False}}],
                         indirect=True)
def test_every_service_answers(graph):
    nodes, client = graph
    node = client.node
    reset_cli = ifc.client(node, ifc.RESET)
    reset = client.call(reset_cli, Trigger.Request())
    assert reset.success and 'start' in reset.message

    # make_plan answers as GetPlan promises: the whole path to the goal (also published on
    # planner/path); a start off the map is led back onto it.
    paths = []
    ifc.subscription(node, ifc.PATH, paths.append)
    plan_cli = ifc.client(node, ifc.MAKE_PLAN)
    request = GetPlan.Request()
    request.start = conv.pose_stamped((0.0, 0.0), frame_id='odom')
    request.goal = conv.pose_stamped((1.0, 1.5), frame_id='odom')
    plan = conv.path_from_msg(client.call(plan_cli, request).plan)
    assert len(plan) >= 2 and np.allclose(plan[0], 0, atol=0.05)
    assert np.allclose(plan[-1], [1.0, 1.5], atol=1e-6)
    client.spin_until(lambda: paths and len(paths[-1].poses) >= 2, 20, 'the published path')
    assert np.allclose(conv.path_from_msg(paths[-1]), plan)
    request.start = conv.pose_stamped((-9.0, 1.0), frame_id='odom')  # off the map
    plan = conv.path_from_msg(client.call(plan_cli, request).plan)
    assert np.allclose(plan[0], (-9.0, 1.0)) and np.allclose(plan[-1], [1.0, 1.5], atol=1e-6)
    request.start = conv.pose_stamped((0.0, 0.0), frame_id='odom')
    request.goal = conv.pose_stamped((50.0, 0.0), frame_id='odom')  # off the map
    assert client.call(plan_cli, request).plan.poses == []

    adapt = client.call(ifc.client(node, ifc.ADAPT), Trigger.Request())
    assert adapt.success and 'adaptation started' in adapt.message
    adapt = client.call(ifc.client(node, ifc.ADAPT), Trigger.Request())
    assert adapt.success and 'restarted' in adapt.message

    bad = _set_param(client, 'sim_bridge', 'damage', 'remove:middle_centre')
    assert not bad.successful and 'middle_right' in bad.reason  # lists the valid legs
    good = _set_param(client, 'sim_bridge', 'damage',
                      'remove:rear_left,friction:0.5,payload:1.0@0.08,0.05')
    assert good.successful
    good = _set_param(client, 'sim_bridge', 'damage', 'shorten:front_left:0.5')
    assert good.successful

    # While gaits run, the simulator still answers at once: a reset asked during them is
    # queued behind them (the answer says so), and the robot ends up back at the start.
    outcomes, poses = [], []
    ifc.subscription(node, ifc.OUTCOME, lambda m: outcomes.append(conv.outcome_from_msg(m)))
    ifc.subscription(node, ifc.ODOM, lambda m: poses.append(conv.pose_from_odometry(m)))
    behavior_pub = ifc.publisher(node, ifc.BEHAVIOR)
    client.wait_for_publishers((ifc.OUTCOME.root_name, ifc.ODOM.root_name))
    client.spin_until(lambda: behavior_pub.get_subscription_count() > 0, 30, 'sim_bridge')
    archive = load_archive(default_archive_path())
    forward = archive.params[int(np.argmax(archive.generic_reward[:, 0]))]
    mine = lambda: [o for o in outcomes if o.behavior_id >= 777_000]  # noqa: E731
    for k in range(6):
        behavior_pub.publish(conv.behavior_to_msg(forward, 777_000 + k))
    client.spin_until(lambda: mine(), 30, 'the first gait')
    reset = client.call(reset_cli, Trigger.Request())
    # 'queued': answered while gaits were still to run (how many outcomes this client has
    # heard by now depends on scheduling, so it is not asserted).
    assert reset.success and 'queued' in reset.message, reset.message
    client.spin_until(lambda: len(mine()) == 6, 60, 'the six outcomes')
    client.spin_until(lambda: poses and np.linalg.norm(poses[-1][:2]) < 0.01, 10,
                      'the robot back at the start after the queued reset')
    assert all(nodes.alive().values()), nodes.logs()


@pytest.mark.parametrize('graph', [{'sim_bridge': {'damage': 'remove:middle_right', 'seed': 3},
                                    'sela_adapter': {'max_steps': 400}}], indirect=True)
def test_damage_changed_at_run_time_restarts_adaptation(graph):
    nodes, client = graph
    watcher = Watcher(client)
    # Missions back and forth between two corners until each condition holds: the robot
    # may reach a goal (about ten steps) before it. The detector judges only gaits the
    # GPs already know, so it needs some learnt (eight steps) and, after the change, a
    # known gait tried again.
    corners = [(2.5, 2.5), (0.0, 0.0)]
    missions = [0]
    watcher.send_goal(*corners[0])

    def until(condition, what):
        for _ in range(8):
            client.spin_until(lambda: condition() or watcher.get_result() is not None, 300,
                              what)
            if condition():
                return
            missions[0] += 1
            watcher.send_goal(*corners[missions[0] % 2])
        raise AssertionError(f'{what}: not within eight missions; {nodes.logs()}')

    until(lambda: len(watcher.steps) >= 8 and any(s.adapting for s in watcher.steps),
          'eight steps, adapting')
    adaptations_before = watcher.steps[-1].adaptations
    detections_before = sum(level == DiagnosticStatus.ERROR for level, _ in watcher.verdicts)
    change_step = len(watcher.steps)
    result = _set_param(client, 'sim_bridge', 'damage', 'remove:middle_right,remove:front_left')
    assert result.successful, result.reason

    def restarted():
        late = watcher.steps[change_step:]
        return late and late[-1].adaptations > adaptations_before
    until(restarted, 'adaptation to restart after the damage changed')
    detections_after = sum(level == DiagnosticStatus.ERROR for level, _ in watcher.verdicts)
    assert detections_after > detections_before
    assert all(nodes.alive().values()), nodes.logs()


def test_a_namespaced_stack_runs_its_mission_under_its_namespace():
    """Every name is relative: ``__ns:=/robot1`` moves the whole graph, and a client given
    the namespace drives it. (The parameters file's node keys do not match namespaced
    nodes, so they run on the code's defaults here.)"""
    nodes = NodeProcesses(namespace='/robot1')
    client = Client()
    try:
        mission = MissionClient(client.node, lambda t: client.executor.spin_once(timeout_sec=t),
                                namespace='/robot1')
        mission.go_to_pose(0.8, 0.0, timeout=120)
        client.spin_until(mission.get_result, 300, 'the end of the namespaced mission')
        assert mission.get_result().success, nodes.logs()
        topics = {name for name, _ in client.node.get_topic_names_and_types()}
        services = {name for name, _ in client.node.get_service_names_and_types()}
        for topic in ifc.TOPICS:
            if topic is not ifc.CLOCK:
                assert '/robot1' + topic.root_name in topics, topic
                assert topic.root_name not in topics, topic  # nothing left in the root
        for service in ifc.SERVICES:
            assert '/robot1' + service.root_name in services, service
        assert all(nodes.alive().values()), nodes.logs()
    finally:
        client.close()
        nodes.stop()


@pytest.mark.parametrize('graph', [{'sim_bridge': {'damage': 'intact', 'seed': 3},
                                    'planner': {'map.origin': [0.5, -1.0], 'map.width': 3.0,
                                                'map.height': 3.0}}], indirect=True)
def test_a_robot_off_the_planners_map_is_led_onto_it_and_reaches_a_goal_inside(graph):
    nodes, client = graph
    watcher = Watcher(client)
    goal = (1.5, 0.5)  # on the map; the robot starts at (0, 0), off it (x < 0.5)
    watcher.send_goal(*goal)
    client.spin_until(lambda: watcher.get_result(), 300, 'the end of the mission')
    assert watcher.get_result().success, (watcher.get_result(), nodes.logs())
    end = watcher.steps[-1].end_pose
    assert np.hypot(end[0] - goal[0], end[1] - goal[1]) < 0.1
    assert watcher.steps[0].pose[0] < 0.5  # the first step started off the map
