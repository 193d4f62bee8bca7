"""``sela-demo`` (``make demo``): the whole mission over DDS, on this machine, no ROS install.

Starts the four nodes as separate processes with the package's executables (found as
``ros2 run sela_ros <node>`` finds them) and ``config/sela.yaml``, sends the goal on
``/goal_pose``, prints one line per step, records the mission's topics to MCAP, and ends
with a summary (JSON), a trajectory plot (PNG) and exit code 0 when the goal is reached.
"""
import argparse
import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from sela_ros.experiments import arguments

NODES = ('sim_bridge', 'planner', 'damage_detector', 'sela_adapter')
#: With --interface trajectory: the gait executor on the simulator's hardware face, its
#: observed odometry and IMU (with the robot's own fall test: :func:`simulated_hardware`).
#: The simulator's state comes every publish_period (0.5 s) of sim time during a gait, which
#: a loaded machine may stretch past a second of wall time: a longer odometry.timeout.
SIMULATED_HARDWARE = {'odometry_topic': 'hexapod/odom_observed', 'imu_topic': 'hexapod/imu',
                      'odometry.timeout': 5.0}


def simulated_hardware(description, robot=None):
    """The gait executor's parameters on the simulator's hardware face for ``description``:
    :data:`SIMULATED_HARDWARE`, the robot (``robot``, as the user named it: a name or
    ``package.module:DESCRIPTION``; None: the description's name) and the simulator's fall
    test for it."""
    return {**SIMULATED_HARDWARE, 'robot': robot or description.name,
            'fall.tilt': float(description.fall_tilt),
            'fall.min_height': float(description.fall_height)}


def _stack_nodes_running(wait=4.0):
    """The stack's nodes already in the root namespace of this domain, as discovery shows them
    within ``wait`` seconds: at once mostly, at the latest with their participants' next
    announcement (every 3 s with Fast DDS's defaults)."""
    import rclpy
    from rclpy.node import Node

    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        node = Node('sela_demo_lookout', context=context)
        names = set(NODES) | {'gait_executor'}
        deadline = time.monotonic() + wait
        found = []
        while not found and time.monotonic() < deadline:
            found = sorted({n for n, ns in node.get_node_names_and_namespaces()
                            if ns == '/' and n in names})
            time.sleep(0.05)
        node.destroy_node()
        return found
    finally:
        rclpy.try_shutdown(context=context)


def _interrupt(signum, frame):
    raise KeyboardInterrupt


def _course(text):
    from sela_ros.experiments.courses import find_course

    try:
        return find_course(text)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def build_parser():
    from sim_bridge.robots import ROBOTS

    parser = argparse.ArgumentParser(
        prog='sela-demo', description='The damaged hexapod (or another robot) learns to walk '
        'to its goal while walking there: four ROS 2 nodes over DDS (loopback only).')
    parser.add_argument('--robot', default='hexapod',
                        help=f'the simulated robot: {", ".join(ROBOTS)} (default: %(default)s; '
                        'docs/robots.md)')
    parser.add_argument('--damage', default=None,
                        help="damage spec in the robot's names, e.g. 'remove:middle_right' "
                        "(the hexapod's default), 'shorten:front_left:0.5', "
                        "'block:rear_right.knee', 'intact' (default: the robot's)")
    parser.add_argument('--goal', type=arguments.goal, default=None, metavar='X,Y',
                        help="goal in the odom frame, metres (default: 2,2; with --course: "
                        "the course's goals, a mission)")
    parser.add_argument('--course', type=_course, default=None, metavar='NAME',
                        help='an obstacle course shipped in config/maps (wall_gap, corridor, '
                        "maze) or a map YAML: the planner's map; without --goal the mission "
                        "visits the course's goals in order")
    parser.add_argument('--seed', type=arguments.node_seed, default=0,
                        help=f'observation-noise seed, 0 to {arguments.NODE_SEED_MAX} '
                        '(default: %(default)s)')
    parser.add_argument('--gui', action='store_true', help="show PyBullet's window")
    parser.add_argument('--real-time-factor', type=_real_time_factor, default=None,
                        metavar='F', help="1: each gait at the robot's own pace, to watch "
                        'it; 0: as fast as the machine allows (default: 1 with --gui, else '
                        '0)')
    parser.add_argument('--interface', choices=('behavior', 'trajectory'), default='behavior',
                        help='behavior: the simulator plays the gaits; trajectory: the '
                        "hardware path, gait_executor on the simulator's ros2_control face "
                        '(docs/hardware.md)')
    parser.add_argument('--params-file', default=None,
                        help='parameter YAML (default: the installed config/sela.yaml)')
    parser.add_argument('--archive', default='',
                        help="archive file (default: the robot's shipped one)")
    parser.add_argument('--out', default='out/demo', help='output folder (default: %(default)s)')
    parser.add_argument('--timeout', type=float, default=600.0,
                        help='wall-clock seconds before giving up (default: %(default)s)')
    parser.add_argument('--domain-id', type=int, default=None,
                        help='ROS_DOMAIN_ID (default: inherited, else 0)')
    parser.add_argument('--keep-learning', action='store_true',
                        help="resume from what the previous demo in --out learned (the "
                        "adapter's state file) instead of starting from the intact map")
    parser.add_argument('--node-logs', action='store_true',
                        help="show the nodes' own logs here too (default: only in "
                        "--out/<node>.log)")
    arguments.take_negative_points(parser)  # --goal -1.4,1.2
    return parser


def _real_time_factor(text):
    """``--real-time-factor``: 0, or a factor the simulator takes."""
    from sim_bridge.pacing import MIN_REAL_TIME_FACTOR

    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'expected a number, got {text!r}') from None
    if not (value == 0 or MIN_REAL_TIME_FACTOR <= value <= 1000):
        raise argparse.ArgumentTypeError(f'must be 0 (as fast as the machine allows) or in '
                                         f'[{MIN_REAL_TIME_FACTOR}, 1000], got {text}')
    return value


def _pace(args):
    """The simulator's real_time_factor: the one given, else real time with a window."""
    if args.real_time_factor is not None:
        return args.real_time_factor
    return 1.0 if args.gui else 0.0


def _robot_and_damage(parser, args):
    """The robot's description and the damage in its names (canonical); errors through the
    parser."""
    from sim_bridge.damage import DamageSpecError
    from sim_bridge.robots import get_robot

    try:
        description = get_robot(args.robot)
    except ValueError as err:
        parser.error(f'--robot: {err}')
    try:
        damage = description.parse_damage(
            description.default_damage if args.damage is None else args.damage).canonical()
    except DamageSpecError as err:
        parser.error(f'--damage: {err}')
    if not args.archive and not description.archive:
        parser.error(f'--archive: the {description.name} has no shipped map; give one')
    if args.archive:  # a map of another robot: its gaits would never be played
        from sela_ros.core.storage import resolve_archive_path
        from sim_bridge.robots import robot_of
        from sim_bridge.settings import read_archive_metadata

        try:
            mapped = robot_of(read_archive_metadata(resolve_archive_path(args.archive)))
        except (OSError, ValueError) as err:
            parser.error(f'--archive: {err}')
        if mapped != description.name:
            parser.error(f'--archive: {args.archive} is a map of the {mapped}, not of the '
                         f'{description.name}')
    return description, damage


def main(argv=None):
    parser = build_parser()
    args = parser.parse_args(argv)
    description, damage = _robot_and_damage(parser, args)
    # Both the simulator (its physics) and the adapter (its gaits) take the robot's map.
    archive = args.archive or description.archive
    map_path, course = args.course or (None, None)
    # A course without --goal: its mission (goals in order); else the one goal.
    args.goals = [list(g) for g in course.goals] if course and args.goal is None else \
        [list(args.goal or (2.0, 2.0))]
    args.goal = args.goals[-1]
    from sela_ros.tools.ros_env import (
        ensure_ros_environment,
        executable,
        package_prefix,
        ros_environment,
    )

    if args.domain_id is not None:
        os.environ['ROS_DOMAIN_ID'] = str(args.domain_id)
    ensure_ros_environment()
    running = _stack_nodes_running()
    if running:  # the demo's goal would be walked by that stack, its learning changed
        parser.error(f"ROS_DOMAIN_ID={os.environ.get('ROS_DOMAIN_ID', '0')} already runs "
                     f"{', '.join(running)} in the root namespace (another stack or demo): "
                     'stop it, or give --domain-id')
    # SIGTERM (`timeout`, a supervisor) ends the demo as Ctrl-C does: the nodes stopped.
    signal.signal(signal.SIGTERM, _interrupt)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    params_file = args.params_file or str(package_prefix() / 'share' / 'sela_ros' / 'config'
                                          / 'sela.yaml')
    env = ros_environment()
    procs = {}
    logs = {}
    try:
        hardware = args.interface == 'trajectory'
        for name in NODES + (('gait_executor',) if hardware else ()):
            cmd = [str(executable(name)), '--ros-args', '--params-file', params_file]
            if name == 'gait_executor':  # the robot and the gait's length of the map
                from sela_ros.core.storage import resolve_archive_path
                from sim_bridge.settings import read_archive_settings

                duration = read_archive_settings(resolve_archive_path(archive))['gait_duration']
                cmd += ['-p', f'gait_duration:={duration}']
                cmd += [a for key, value in simulated_hardware(description,
                                                               args.robot).items()
                        for a in ('-p', f'{key}:={value}')]
            if name == 'sim_bridge':
                # The robot as the user named it: a description of their own is found by
                # its import path, not its name.
                cmd += ['-p', f'robot:={args.robot}', '-p', f'damage:={damage}',
                        '-p', f'seed:={args.seed}', '-p', f'sim.gui:={str(args.gui).lower()}',
                        '-p', f'real_time_factor:={_pace(args)!r}',
                        '-p', f'archive:={archive}',  # the simulator runs the map's physics
                        '-p', f'interface:={args.interface}']
            if name == 'planner' and map_path:
                cmd += ['-p', f'map.file:={Path(map_path).resolve()}']
            if name == 'sela_adapter':
                state_file = out / 'sela_adapter_state.json'
                if not args.keep_learning and state_file.exists():
                    state_file.unlink()
                cmd += ['-p', f'state_file:={state_file.resolve()}',
                        '-p', f'archive:={archive}']
            logs[name] = open(out / f'{name}.log', 'w')  # noqa: SIM115
            to_file = not args.node_logs
            procs[name] = subprocess.Popen(
                cmd, env=env, stdout=logs[name] if to_file else None,
                stderr=subprocess.STDOUT if to_file else None)
        goals = ', '.join(f'({g[0]}, {g[1]})' for g in args.goals)
        print(f"sela-demo: {description.name}, damage '{damage}', goal(s) {goals}, seed "
              f"{args.seed}, ROS_DOMAIN_ID={env.get('ROS_DOMAIN_ID', '0')}, nodes: "
              + ', '.join(f'{n}[{p.pid}]' for n, p in procs.items()), flush=True)
        summary = run_client(args, damage, out, procs)
    except KeyboardInterrupt:  # Ctrl-C (or SIGTERM) while the nodes were starting
        print('sela-demo: interrupted', file=sys.stderr, flush=True)
        summary = {'problem': 'interrupted'}
    finally:
        for proc in procs.values():
            if proc.poll() is None:
                proc.send_signal(signal.SIGINT)
        deadline = time.monotonic() + 10
        for proc in procs.values():
            try:
                proc.wait(timeout=max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        for handle in logs.values():
            handle.close()
    if summary.get('problem') == 'interrupted':
        return 128 + signal.SIGINT
    return 0 if summary.get('success') else 1


class NodeExited(RuntimeError):
    """A node of the stack exited while the client waited on it."""

    def __init__(self, names):
        super().__init__(f"node(s) {', '.join(names)} exited")
        self.names = names


def run_client(args, damage, out, procs):
    """The user's side of the mission: send the goal, follow the steps, record, summarise."""
    import rclpy
    from rclpy.executors import ExternalShutdownException
    from rclpy.node import Node

    from sela_ros.nodes import conversions as conv
    from sela_ros.nodes import interface as ifc
    from sela_ros.tools.mission_client import MissionClient
    from sela_ros.tools.recording import McapRecorder

    recorded = (ifc.CLOCK, ifc.ODOM, ifc.JOINT_STATES, ifc.BEHAVIOR, ifc.OUTCOME,
                ifc.PREDICTION, ifc.REWARD, ifc.TARGET, ifc.GOAL, ifc.PATH, ifc.MAP,
                ifc.DIAGNOSTICS, ifc.VERDICT, ifc.ROBOT_DESCRIPTION, ifc.MARKERS)
    if ifc.TF.type is not None:  # Foxglove draws the robot moving from /tf
        recorded += (ifc.TF,)
    rclpy.init()
    node = Node('sela_demo')
    trajectory = []

    def spin_once(timeout):
        rclpy.spin_once(node, timeout_sec=timeout)
        dead = [n for n, p in procs.items() if p.poll() is not None]
        if dead:  # whatever the client waits for, it will not come
            raise NodeExited(dead)

    mission = MissionClient(node, spin_once)
    printed = {'steps': 0, 'detections': 0, 'goals': 0}

    def print_progress():
        for s in mission.steps[printed['steps']:]:
            pose, wp, pred, obs = s.pose, s.waypoint, s.predicted_gr, s.observed_gr
            print(f"step {s.step:3d}  pose ({pose[0]:+.2f}, {pose[1]:+.2f}, "
                  f"{math.degrees(pose[2]):+6.1f} deg)  waypoint ({wp[0]:+.2f}, {wp[1]:+.2f})"
                  f"  predicted ({pred[0]:+.3f}, {pred[1]:+.3f}, {pred[2]:+.2f})"
                  f"  observed ({obs[0]:+.3f}, {obs[1]:+.3f}, {obs[2]:+.2f})"
                  f"  reward {s.reward:+.3f}  "
                  f"{'ADAPTING' if s.adapting else 'trusting map'}", flush=True)
        for d in mission.detections[printed['detections']:]:
            print(f"        damage detector fired: error {d.error:.3f} m (threshold "
                  f"{d.threshold} m) -> {d.adapt}", flush=True)
        for g in mission.goals_reached[printed['goals']:]:
            print(f'        goal {g.index}/{len(args.goals)} ({g.goal[0]:.2f}, {g.goal[1]:.2f}) '
                  f'reached in {g.steps} steps', flush=True)
        printed.update(steps=len(mission.steps), detections=len(mission.detections),
                       goals=len(mission.goals_reached))

    def on_odom(msg):
        pose = conv.pose_from_odometry(msg)
        trajectory.append([conv.time_from_msg(msg.header.stamp), *pose.tolist()])

    ifc.subscription(node, ifc.ODOM, on_odom)
    recorder = McapRecorder(node, str(out / 'mission.mcap'),
                            {t.root_name: t.type for t in recorded},
                            qos_for={t.root_name: t.qos for t in recorded}.get)
    start = time.monotonic()
    problem = None  # why there is no result, if there is none
    try:
        if len(args.goals) > 1:
            mission.follow_goals(args.goals, timeout=args.timeout)
        else:
            mission.go_to_pose(*args.goal, timeout=args.timeout)
        while not mission.is_task_complete() and time.monotonic() - start < args.timeout:
            print_progress()
        if mission.get_result() is None:
            problem = f'no result within --timeout {args.timeout:g} s'
        settle = time.monotonic() + 0.5  # the state after the last gait
        while time.monotonic() < settle:
            rclpy.spin_once(node, timeout_sec=0.05)
        print_progress()
    except NodeExited as exc:
        problem = (f"node(s) {', '.join(exc.names)} exited; see "
                   + ', '.join(str(out / f'{n}.log') for n in exc.names))
        for name in exc.names:
            tail = (out / f'{name}.log').read_text(errors='replace').strip().splitlines()[-3:]
            problem += ''.join(f'\n  {name}: {line}' for line in tail)
    except TimeoutError as exc:  # the stack never became ready, or never took the goal
        problem = str(exc)
    except (KeyboardInterrupt, ExternalShutdownException):
        problem = 'interrupted'
    finally:
        recorder.close()
        node.destroy_node()
        rclpy.try_shutdown()
    result = mission.get_result()
    steps = [s.values for s in mission.steps]
    detections = mission.detections
    wall = time.monotonic() - start
    final_true = trajectory[-1][1:3] if trajectory else None
    summary = {
        'success': bool(result and result.success), 'damage': damage,
        'goal': list(args.goal), 'goals': args.goals,
        'goals_reached': [{'goal': g.goal.tolist(), 'steps': g.steps}
                          for g in mission.goals_reached],
        'seed': args.seed, 'steps': len(steps),
        'adaptations': result.adaptations if result else None,
        'learning_started_at_step': next((int(s['step']) for s in steps
                                          if s['adapting'] == 'True'), None),
        'detections': len(detections),
        'final_true_position': final_true,
        'final_distance_to_goal': (math.dist(final_true, args.goal) if final_true else None),
        'wall_time_s': round(wall, 2),
        'behaviors': [int(s['behavior_index']) for s in steps],
        'steps_detail': steps, 'recording': str(out / 'mission.mcap'),
        'recorded_messages': recorder.counts,
        'problem': problem,
    }
    with open(out / 'summary.json', 'w') as handle:
        json.dump(summary, handle, indent=1)
    grid = None
    if args.course:
        from sela_ros.core.planning import load_map_file

        grid = load_map_file(args.course[0])
    plot_trajectory(out / 'trajectory.png', trajectory, steps, args.goals, damage, grid)
    verdict = 'goal reached' if summary['success'] else 'goal NOT reached'
    if result is not None and not result.success:
        # Where the adapter could not say why there was no plan, the planner said it.
        why = [m for m in mission.errors(ifc.PLANNER) if m not in result.message][-1:]
        print(f'sela-demo: mission failed: {result.message}'
              + ''.join(f' (planner: {m})' for m in why), file=sys.stderr, flush=True)
    elif result is None:
        print(f"sela-demo: {problem or 'no result from the adapter'}", file=sys.stderr,
              flush=True)
    started = summary['learning_started_at_step']
    print(f"sela-demo: {verdict} in {summary['steps']} steps "
          f"({'no adaptation' if started is None else f'adaptation from step {started}'}, "
          f"{summary['detections']} detection(s)), final distance "
          f"{_metres(summary['final_distance_to_goal'])}, {wall:.1f} s wall; "
          f"wrote {out}/summary.json, trajectory.png, mission.mcap", flush=True)
    return summary


def _metres(value):
    return 'unknown' if value is None else f'{value:.3f} m'


def plot_trajectory(path, trajectory, steps, goals, damage, grid=None):
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 6))
    if grid is not None:
        xmin, xmax, ymin, ymax = grid.bounds
        ax.imshow(grid.occupied, origin='lower', extent=(xmin, xmax, ymin, ymax), cmap='Greys',
                  vmin=0, vmax=1.4, interpolation='nearest')
    if trajectory:
        xy = [(t[1], t[2]) for t in trajectory]
        ax.plot(*zip(*xy), color='tab:blue', lw=1.2, label='robot (odom)')
    for s in steps:
        p = [float(v) for v in s['pose'].split()]
        w = [float(v) for v in s['waypoint'].split()]
        ax.plot([p[0], w[0]], [p[1], w[1]], color='tab:orange', lw=0.6, alpha=0.6)
        ax.plot(*p[:2], 'o', ms=3, color='tab:red' if s['adapting'] == 'True' else 'tab:gray')
    for i, goal in enumerate(goals):
        ax.add_patch(plt.Circle(goal, 0.1, color='tab:green', alpha=0.4,
                                label='goal (0.1 m)' if i == 0 else None))
    ax.plot(0, 0, 'ks', label='start')
    ax.set_aspect('equal')
    ax.set_xlabel('x (m)')
    ax.set_ylabel('y (m)')
    ax.set_title(f'SELA mission, damage {damage}: {len(steps)} steps\n'
                 'dots: pose at each step (grey: trusting the map, red: adapting);\n'
                 'orange: pose -> waypoint of the reward', fontsize=9)
    ax.legend(loc='lower right', fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


if __name__ == '__main__':
    sys.exit(main())
