#!/usr/bin/env python3
"""ROS overhead per step, and a long run of consecutive gaits over DDS.

``overhead``: the same mission (same seed, same decisions) run in process and over DDS with
the four node processes; prints the wall time per step of each and the ratio (target: DDS at
most 10% slower). ``long``: N consecutive gaits over DDS (a goal that cannot be reached),
printing each node's memory (RSS) and the step time at the start and at the end.

Run with the project's venv: ``.venv/bin/python benchmarks/bench_ros.py overhead`` (or
``long --steps 200``). Uses its own ROS_DOMAIN_ID; DDS stays on loopback.
"""
import argparse
import os
import random
import sys
import time
from pathlib import Path

import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'test'))
os.environ.setdefault('ROS_DOMAIN_ID', str(random.Random().randint(100, 101)))
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('OPENBLAS_NUM_THREADS', '1')

from sela_ros.ros_env import ensure_ros_environment  # noqa: E402

ensure_ros_environment()

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402

from sela_ros import conversions as conv  # noqa: E402
from sela_ros.adapter_node import MISSION_STATUS  # noqa: E402
from sela_ros.qos import LATCHED_QOS, STATE_QOS  # noqa: E402

from ros_graph import CONFIG, Client, NodeProcesses  # noqa: E402


def rss_mb(pid):
    with open(f'/proc/{pid}/status') as handle:
        for line in handle:
            if line.startswith('VmRSS:'):
                return int(line.split()[1]) / 1024.0
    return float('nan')


def dds_mission(goal, seed, damage, overrides=None, steps_wanted=None, timeout=1800):
    overrides = overrides or {}
    overrides.setdefault('sim_bridge', {}).update({'damage': damage, 'seed': seed})
    nodes = NodeProcesses(overrides)
    client = Client('sela_bench')
    times, memory = [], []
    statuses = []
    client.node.create_subscription(DiagnosticArray, '/diagnostics',
                                    lambda m: statuses.extend(m.status), STATE_QOS)
    pub = client.node.create_publisher(conv.PoseStamped, '/goal_pose', LATCHED_QOS)
    done = {'final': None}

    def progress():
        while statuses:
            status = statuses.pop(0)
            if status.name != MISSION_STATUS:
                continue
            values = {kv.key: kv.value for kv in status.values}
            if 'step' in values:
                times.append((time.monotonic(), values))
                n = len(times)
                if n in (10, steps_wanted):
                    memory.append((n, {name: rss_mb(p.pid)
                                       for name, (p, _) in nodes.procs.items()}))
            elif 'success' in values:
                done['final'] = values
        return done['final'] is not None or (steps_wanted and len(times) >= steps_wanted)

    try:
        pub.publish(conv.pose_stamped(goal, frame_id='odom'))
        client.spin_until(progress, timeout, 'the mission')
    finally:
        client.close()
        nodes.stop()
    return times, memory, done['final']


def in_process(goal, seed, damage):
    """The same mission in process; returns the step times as the DDS run measures them."""
    from test_ros_mission import _in_process_mission

    stamps = []
    success, logic = _in_process_mission(damage, seed, goal,
                                         on_step=lambda record: stamps.append(time.monotonic()))
    return stamps, success, logic


def overhead(args):
    goal = tuple(args.goal)
    stamps, success, logic = in_process(goal, args.seed, args.damage)
    n = len(logic.records)
    overrides = {}
    if args.publish_period is not None:
        overrides['sim_bridge'] = {'publish_period': args.publish_period}
    times, _, final = dds_mission(goal, args.seed, args.damage, overrides)
    chosen = [int(v['behavior_index']) for _, v in times]
    same = chosen == [r.behavior_index for r in logic.records]
    # Both: time from the first step's end to the last one's, per step (n-1 intervals), so
    # start-up (loading the archive, building the robot, discovery) is not counted.
    dds_per_step = (times[-1][0] - times[0][0]) / max(1, len(times) - 1)
    proc_per_step = (stamps[-1] - stamps[0]) / max(1, len(stamps) - 1)
    print(f'mission: damage {args.damage}, goal {goal}, seed {args.seed}: '
          f'{n} steps in process, {len(times)} over DDS, same decisions: {same}')
    print(f'in process : {proc_per_step * 1000:7.1f} ms per step')
    print(f'over DDS   : {dds_per_step * 1000:7.1f} ms per step')
    decide = sorted(float(v['decide_ms']) for _, v in times)
    execute = sorted(float(v['execute_ms']) for _, v in times)
    print(f'over DDS, median per step: choosing (plan + target + ask) '
          f'{decide[len(decide) // 2]:.1f} ms, command -> outcome '
          f'{execute[len(execute) // 2]:.1f} ms')
    gaps = [b[0] - a[0] for a, b in zip(times, times[1:])]
    print('over DDS, step intervals (ms): ' + ' '.join(f'{g * 1000:.0f}' for g in gaps))
    print(f'ROS overhead per step: {(dds_per_step / proc_per_step - 1) * 100:+.1f}% '
          '(target: at most +10%)')


def long_run(args):
    config = yaml.safe_load(Path(CONFIG).read_text())['planner']['ros__parameters']
    # A goal in the middle of the map that can never be reached (goal.eps 1 mm): the robot
    # walks to it and keeps stepping around it without leaving the map.
    centre = [o + size / 2 for o, size in zip(config['map.origin'],
                                               (config['map.width'], config['map.height']))]
    overrides = {'sela_adapter': {'max_steps': args.steps + 5, 'goal.eps': 0.001}}
    times, memory, _ = dds_mission(centre, args.seed, args.damage, overrides,
                                   steps_wanted=args.steps, timeout=600)
    k = min(10, len(times) // 4)
    first = (times[k][0] - times[0][0]) / k
    last = (times[-1][0] - times[-1 - k][0]) / k
    print(f'{len(times)} consecutive gaits over DDS, damage {args.damage}')
    print(f'step time: first {k} steps {first * 1000:.0f} ms/step, '
          f'last {k} steps {last * 1000:.0f} ms/step')
    for n, mem in memory:
        print(f'memory (RSS, MB) at step {n:3d}: ' +
              ', '.join(f'{name} {mb:.0f}' for name, mb in sorted(mem.items())))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest='what', required=True)
    o = sub.add_parser('overhead')
    o.add_argument('--goal', type=float, nargs=2, default=(2.0, 2.0))
    o.add_argument('--seed', type=int, default=0)
    o.add_argument('--damage', default='remove:middle_right')
    o.add_argument('--publish-period', type=float, default=None,
                   help="sim_bridge's publish_period (s of sim time) for this run")
    lr = sub.add_parser('long')
    lr.add_argument('--steps', type=int, default=200)
    lr.add_argument('--seed', type=int, default=0)
    lr.add_argument('--damage', default='remove:middle_right')
    args = parser.parse_args()
    overhead(args) if args.what == 'overhead' else long_run(args)


if __name__ == '__main__':
    main()
