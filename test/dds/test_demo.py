"""`sela-demo` (what `make demo` runs): the mission over DDS, its summary, plot and MCAP."""
import json
import os
import subprocess

import pytest

from sela_ros.tools.ros_env import executable

pytestmark = [pytest.mark.dds, pytest.mark.slow]


def test_demo_reaches_goal_and_writes_summary_plot_and_mcap(tmp_path, ros_env):
    out = tmp_path / 'demo'
    proc = subprocess.run(
        [str(executable('sela-demo')), '--goal', '1.0,0.6', '--seed', '2', '--out', str(out),
         '--timeout', '400'],
        env=ros_env, capture_output=True, text=True, timeout=480)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert 'goal reached' in proc.stdout
    step_lines = [line for line in proc.stdout.splitlines() if line.startswith('step ')]
    summary = json.loads((out / 'summary.json').read_text())
    assert summary['success'] is True and summary['steps'] == len(step_lines) > 0
    assert summary['final_distance_to_goal'] < 0.2  # true pose; observed one is within 0.1
    png = (out / 'trajectory.png').read_bytes()
    assert png[:8] == b'\x89PNG\r\n\x1a\n' and len(png) > 10_000

    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    counts = {}
    with open(out / 'mission.mcap', 'rb') as handle:
        reader = make_reader(handle, decoder_factories=[DecoderFactory()])
        for _, channel, _, decoded in reader.iter_decoded_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            if channel.topic == '/hexapod/odom':
                assert decoded.header.frame_id == 'odom'
                assert decoded.child_frame_id == 'base_link'
            elif channel.topic == '/tf':
                (tf,) = decoded.transforms
                assert (tf.header.frame_id, tf.child_frame_id) == ('odom', 'base_link')
            elif channel.topic == '/robot_description':
                assert '<robot name="sela_hexapod">' in decoded.data
                assert 'middle_right.coxa' not in decoded.data  # the demo's damage
    for topic in ('/hexapod/behavior', '/hexapod/behavior_outcome', '/sela/reward'):
        assert counts.get(topic) == summary['steps'], (topic, counts)
    # (The goal goes out as a navigate_to_pose action goal: no /goal_pose message.)
    for topic in ('/clock', '/hexapod/odom', '/planner/path', '/sela/target',
                  '/diagnostics', '/planner/map', '/hexapod/joint_states', '/tf',
                  '/robot_description'):
        assert counts.get(topic, 0) > 0, (topic, counts)
    # SELA's markers: one decision and one outcome per step, drawn back from the recording.
    from sela_ros.tools.mcap_figure import draw, read_recording

    recording = read_recording(str(out / 'mission.mcap'))
    assert counts.get('/sela/markers') == 2 * summary['steps'], counts
    assert len(recording['steps']) == summary['steps']
    for step, detail in zip(recording['steps'], summary['steps_detail']):
        waypoint = [float(v) for v in detail['waypoint'].split()][:2]
        assert step['waypoint'] == pytest.approx(waypoint, abs=1e-3)
        assert len(step['candidates']) == 5 and step['observed'] is not None
    assert draw(recording, tmp_path / 'markers.png').stat().st_size > 10_000


def test_demo_runs_the_hardware_path_with_interface_trajectory(tmp_path, ros_env):
    out = tmp_path / 'demo'
    proc = subprocess.run(
        [str(executable('sela-demo')), '--goal', '1.0,0.6', '--seed', '2', '--out', str(out),
         '--timeout', '400', '--interface', 'trajectory'],
        env=ros_env, capture_output=True, text=True, timeout=480)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    summary = json.loads((out / 'summary.json').read_text())
    assert summary['success'] is True and summary['steps'] > 0
    assert 'interface trajectory' in (out / 'sim_bridge.log').read_text()
    assert 'gait executor ready' in (out / 'gait_executor.log').read_text()


def test_keep_learning_resumes_what_the_previous_demo_learned(tmp_path, ros_env):
    import re

    out = tmp_path / 'demo'
    runs = []
    for goal, extra in (('0.8,0.4', []), ('-0.6,0.6', ['--keep-learning'])):
        proc = subprocess.run(
            [str(executable('sela-demo')), '--goal', goal, '--out', str(out),
             '--timeout', '400', *extra],
            env=ros_env, capture_output=True, text=True, timeout=480)
        assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
        runs.append(json.loads((out / 'summary.json').read_text()))
        state = json.loads((out / 'sela_adapter_state.json').read_text())
        assert state['learned_on'] == 'simulator sim_bridge'
    assert runs[0]['steps'] > 0
    log = (out / 'sela_adapter.log').read_text()
    resumed = re.search(r'resumed from \S+: (\d+) observation', log)
    assert resumed and int(resumed.group(1)) > 0, log[-2000:]


def test_demo_rejects_bad_arguments_with_usage(ros_env):
    for args, reason in ((['--damage', 'remove:middle_centre'], 'middle_centre'),
                         (['--goal', '2;2'], '--goal'),
                         (['--robot', 'toy', '--archive', '8d'],
                          'is a map of the hexapod, not of the toy'),
                         (['--archive', '/nowhere/map.npz'], '--archive: cannot read'),
                         (['--seed', str(2**40)], 'expected a seed <= 2147483647'),
                         (['--seed', '-1'], 'expected a seed >= 0')):
        proc = subprocess.run([str(executable('sela-demo')), *args], env=ros_env,
                              capture_output=True, text=True, timeout=60)
        assert proc.returncode == 2, proc.stderr
        assert 'usage:' in proc.stderr and 'Traceback' not in proc.stderr
        assert reason in proc.stderr, proc.stderr


def test_a_node_that_dies_at_start_up_ends_the_demo_with_its_name_and_log(tmp_path, ros_env):
    """The nodes refuse a broken parameter file and exit: the demo says so at once, with
    their logs' last lines, not after --timeout (the subprocess's own limit is shorter)."""
    broken = tmp_path / 'broken.yaml'
    broken.write_text('/**/planner:\n  ros__parameters:\n    map.file: [oops\n')
    proc = subprocess.run([str(executable('sela-demo')), '--params-file', str(broken),
                           '--out', str(tmp_path / 'out'), '--timeout', '900'], env=ros_env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 1, proc.stderr
    assert 'exited; see' in proc.stderr and 'not valid YAML' in proc.stderr, proc.stderr
    assert 'Traceback' not in proc.stderr, proc.stderr
    assert 'goal NOT reached in 0 steps (no adaptation, ' in proc.stdout, proc.stdout
    summary = json.loads((tmp_path / 'out' / 'summary.json').read_text())
    assert summary['success'] is False and 'exited' in summary['problem']


def test_a_demo_on_a_domain_where_a_stack_runs_is_refused_with_the_reason(tmp_path, ros_env):
    """Its goal would be walked by that stack, and that stack's learning changed."""
    from rcl_interfaces.srv import GetParameters

    from ros_graph import Client, NodeProcesses

    nodes = NodeProcesses(names=('planner',))
    client = Client('demo_lookout_test')
    try:
        get = client.node.create_client(GetParameters, '/planner/get_parameters')
        client.call(get, GetParameters.Request(names=['frame_id']), timeout=90)  # it is up
        proc = subprocess.run([str(executable('sela-demo')), '--out', str(tmp_path)],
                              env=ros_env, capture_output=True, text=True, timeout=120)
        assert proc.returncode == 2, proc.stdout + proc.stderr
        assert 'already runs planner' in proc.stderr and '--domain-id' in proc.stderr
        assert all(nodes.alive().values())
    finally:
        client.close()
        nodes.stop()


def test_demo_takes_goals_with_negative_coordinates_as_written():
    from sela_ros.tools.demo import build_parser

    assert build_parser().parse_args(['--goal', '-1.4,1.2']).goal == [-1.4, 1.2]
    assert build_parser().parse_args(['--goal', '1.6,-1']).goal == [1.6, -1.0]


@pytest.mark.dds
def test_demo_with_a_goal_off_the_map_fails_with_the_reason(tmp_path, ros_env):
    proc = subprocess.run([str(executable('sela-demo')), '--goal', '40,0', '--out',
                           str(tmp_path), '--timeout', '120'], env=ros_env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 1, proc.stderr
    assert 'off the map' in proc.stderr and 'Traceback' not in proc.stderr
    assert json.loads((tmp_path / 'summary.json').read_text())['steps'] == 0


def test_the_a1_demo_reaches_its_goal_over_dds(tmp_path, ros_env):
    out = tmp_path / 'demo_a1'
    proc = subprocess.run(
        [str(executable('sela-demo')), '--robot', 'a1', '--damage', 'block:rear_right.calf',
         '--goal', '1.0,1.0', '--out', str(out), '--timeout', '400'],
        env=ros_env, capture_output=True, text=True, timeout=480)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert proc.stdout.startswith("sela-demo: a1, damage 'block:rear_right.calf=-1.6'")
    summary = json.loads((out / 'summary.json').read_text())
    assert summary['success'] is True and summary['final_distance_to_goal'] < 0.2
    # The A1's map served by the adapter: behaviour indices within its 429 gaits.
    from sela_ros.core.storage import load_archive, resolve_archive_path

    assert max(summary['behaviors']) < len(load_archive(resolve_archive_path('a1')))


_VARIANT = '''
from sim_bridge.robots.a1 import A1Description


class Marked(A1Description):
    """The A1 (its map, its name), its model marked: found only by its import path."""

    def urdf(self, damage='intact'):
        return super().urdf(damage).replace('<robot ', '<!-- the marked a1 -->\\n<robot ', 1)


VARIANT = Marked()
'''


def test_a_robot_of_ones_own_named_by_its_import_path_is_the_one_simulated(tmp_path,
                                                                           ros_env):
    (tmp_path / 'my_robots.py').write_text(_VARIANT)
    env = dict(ros_env, PYTHONPATH=os.pathsep.join(
        p for p in (str(tmp_path), ros_env.get('PYTHONPATH')) if p))
    out = tmp_path / 'demo_variant'
    proc = subprocess.run(
        [str(executable('sela-demo')), '--robot', 'my_robots:VARIANT', '--goal', '0.5,0.3',
         '--out', str(out), '--timeout', '400'],
        env=env, capture_output=True, text=True, timeout=480)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    with open(out / 'mission.mcap', 'rb') as handle:
        reader = make_reader(handle, decoder_factories=[DecoderFactory()])
        models = [decoded.data for _, channel, _, decoded in reader.iter_decoded_messages()
                  if channel.topic == '/robot_description']
    assert models and all('<!-- the marked a1 -->' in m for m in models), models[:1]
