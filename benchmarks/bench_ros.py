#!/usr/bin/env python3
"""ROS overhead per step, and a long run of consecutive gaits over DDS.

``overhead``: the same mission (same seed, same decisions) run in process, over DDS with
the four node processes, and in process again, in interleaved rounds; prints each round's
ratio and, step by step, the best of the rounds over DDS against the best in process
(target: DDS at most 10% slower). ``long``: N consecutive gaits over DDS (a goal that
cannot be reached), printing each node's memory (RSS) and the step time at the start and
at the end.

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

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'test' / 'dds'))
os.environ.setdefault('ROS_DOMAIN_ID', str(random.Random().randint(100, 101)))

from sela_ros import single_blas_thread  # noqa: E402

single_blas_thread()  # before numpy

from sela_ros.tools.ros_env import ensure_ros_environment  # noqa: E402

ensure_ros_environment()

from sela_ros.nodes import interface as ifc  # noqa: E402
from sela_ros.tools.mission_client import MissionClient  # noqa: E402

from ros_graph import CONFIG, Client, NodeProcesses  # noqa: E402


def rss_mb(pid):
    with open(f'/proc/{pid}/status') as handle:
        for line in handle:
            if line.startswith('VmRSS:'):
                return int(line.split()[1]) / 1024.0
    return float('nan')


HEARTBEATS = {n + ifc.HEARTBEAT_SUFFIX for n in ifc.NODES}


def dds_mission(goal, seed, damage, overrides=None, steps_wanted=None, timeout=1800,
                settle=3.0, before_goal=None):
    """Start the four nodes, wait until all beat and have settled, then run one mission."""
    overrides = overrides or {}
    overrides.setdefault('sim_bridge', {}).update({'damage': damage, 'seed': seed})
    nodes = NodeProcesses(overrides)
    client = Client('sela_bench')
    mission = MissionClient(client.node, lambda t: client.executor.spin_once(timeout_sec=t))
    times, memory = [], []
    seen = {'steps': 0}

    def progress():
        for step in mission.steps[seen['steps']:]:
            times.append((time.monotonic(), step.values))
            n = len(times)
            if n == 10 or n % 100 == 0 or n == steps_wanted:
                memory.append((n, {name: rss_mb(p.pid) for name, (p, _) in nodes.procs.items()}))
        seen['steps'] = len(mission.steps)
        return mission.get_result() is not None or (steps_wanted and len(times) >= steps_wanted)

    try:
        # Start-up (imports, archive, discovery) is not part of a step: wait for every node's
        # heartbeat, then let the processes settle before the goal goes out.
        client.spin_until(lambda: HEARTBEATS <= {s.name for s in mission.statuses}, 120,
                          'the four heartbeats')
        end = time.monotonic() + settle
        client.spin_until(lambda: time.monotonic() > end, settle + 1)
        if before_goal is not None:
            before_goal()
        mission.go_to_pose(*goal)
        client.spin_until(progress, timeout, 'the mission')
    finally:
        client.close()
        nodes.stop()
    result = mission.get_result()
    return times, memory, None if result is None else result.values


def in_process_mission(damage, seed, goal, on_step=None):
    """The mission the four nodes run, in one process (no DDS): config/sela.yaml's settings
    through the node's stepper (:func:`sela_ros.core.mission.run_mission`), the simulator
    with sim_bridge's noise and seed, the planner's map; returns ``(success, logic)``."""
    from sela_ros.core.detection import DetectorConfig
    from sela_ros.core.learning import resolve_priors
    from sela_ros.core.mission import make_sela, run_mission
    from sela_ros.core.planning import GridPlanner, grid_from_description
    from sela_ros.core.storage import load_archive, resolve_archive_path
    from sela_ros.nodes import adapter_params
    from sim_bridge.experiment_env import HexapodEnvironment

    cfg = {k.removeprefix('/**/'): v['ros__parameters']
           for k, v in yaml.safe_load(Path(CONFIG).read_text()).items()}
    bridge, plan, detector = cfg['sim_bridge'], cfg['planner'], cfg['damage_detector']
    adapter = {spec.name: spec.default for spec in adapter_params.PARAMETERS}
    adapter.update(cfg['sela_adapter'])
    path = resolve_archive_path(adapter['archive'])
    archive = load_archive(path)
    priors = resolve_priors(adapter['priors.tables'], path, archive.params)
    grid = grid_from_description(plan['map.resolution'], plan['map.origin'], plan['map.width'],
                                 plan['map.height'], plan.get('map.obstacles') or [])
    physics = archive.simulator_settings
    with HexapodEnvironment(archive.params, damage, bridge['observation.noise_std'], seed=seed,
                            dt=physics['dt'], gait_duration=physics['gait_duration'],
                            solver_iterations=physics['solver_iterations']) as env:
        run = run_mission(
            env, make_sela(archive, adapter_params.sela_config(adapter), priors=priors), [goal],
            GridPlanner(grid, inflation=plan['planner.inflation']),
            detector_config=DetectorConfig(**{k.split('.', 1)[1]: v for k, v in detector.items()
                                              if k.startswith('detection.')}),
            stepper_config=adapter_params.stepper_config(adapter, archive), on_step=on_step)
    return run.success, run.logic


def in_process(goal, seed, damage):
    """The same mission in process; returns the step times as the DDS run measures them."""
    stamps = []
    success, logic = in_process_mission(damage, seed, goal,
                                        on_step=lambda record: stamps.append(time.monotonic()))
    return stamps, success, logic


def per_step(stamps):
    """Wall time per step: from the first step's end to the last one's, over n-1 steps."""
    return (stamps[-1] - stamps[0]) / max(1, len(stamps) - 1)


def intervals(stamps):
    return [b - a for a, b in zip(stamps, stamps[1:])]


def overhead(args):
    """Interleaved rounds: in process, over DDS, in process again.

    The machine's speed drifts by tens of percent over seconds on shared cores, and
    interference only ever adds time. So the headline figure compares, step by step, the best
    of the rounds: the same seed gives the same gaits in the same order in every run, and
    step k's shortest wall time over DDS is set against step k's shortest in process. The
    per-round ratios (each DDS run against the in-process runs that bracket it) are printed
    too.
    """
    goal = tuple(args.goal)
    overrides = {}
    if args.publish_period is not None:
        overrides['sim_bridge'] = {'publish_period': args.publish_period}
    ratios, dds_all, dds_steps, proc_steps = [], [], [], []
    all_same = True
    for r in range(args.rounds):
        before = {}

        def run_before(before=before):
            before['stamps'], before['success'], before['logic'] = in_process(
                goal, args.seed, args.damage)

        # The in-process run before goes while the idle graph waits for its goal, so that
        # both runs share the machine's state of the moment.
        times, _, final = dds_mission(goal, args.seed, args.damage,
                                      {k: dict(v) for k, v in overrides.items()},
                                      before_goal=run_before)
        after, _, logic = in_process(goal, args.seed, args.damage)
        chosen = [int(v['behavior_index']) for _, v in times]
        same = chosen == [rec.behavior_index for rec in logic.records]
        all_same &= same
        proc = (per_step(before['stamps']) + per_step(after)) / 2
        dds = per_step([t for t, _ in times])
        ratios.append(dds / proc if proc else float('nan'))
        dds_all.extend(v for _, v in times)
        dds_steps.append(intervals([t for t, _ in times]))
        proc_steps += [intervals(before['stamps']), intervals(after)]
        print(f'round {r + 1}: {len(logic.records)} steps in process, {len(times)} over DDS, '
              f'same decisions: {same}; in process {per_step(before["stamps"]) * 1e3:.1f} / '
              f'{per_step(after) * 1e3:.1f} ms per step (before / after), over DDS '
              f'{dds * 1e3:.1f} ms: {(ratios[-1] - 1) * 100:+.1f}%', flush=True)
        if args.verbose:
            print('  per step over DDS (ms), outcome -> command / command -> outcome: ' +
                  ' '.join(f"{v['decide_ms']}/{v['execute_ms']}" for _, v in times))
    decide = sorted(float(v['decide_ms']) for v in dds_all)
    execute = sorted(float(v['execute_ms']) for v in dds_all)
    print(f'mission: damage {args.damage}, goal {goal}, seed {args.seed}, '
          f'{args.rounds} rounds, same decisions in every round: {all_same}')
    print(f'over DDS, median per step: outcome -> next command (plan + learn + '
          f'ask) {decide[len(decide) // 2]:.1f} ms, command -> outcome '
          f'{execute[len(execute) // 2]:.1f} ms')
    ratios.sort()
    print('per round (mean step over DDS / mean step in process): ' +
          ' '.join(f'{(q - 1) * 100:+.1f}%' for q in ratios) +
          f'; median {(ratios[len(ratios) // 2] - 1) * 100:+.1f}%')
    n = min(len(x) for x in dds_steps + proc_steps)
    if all_same and n:
        best_dds = sum(min(x[k] for x in dds_steps) for k in range(n)) / n
        best_proc = sum(min(x[k] for x in proc_steps) for k in range(n)) / n
        print(f'best of {args.rounds} rounds, step by step: in process {best_proc * 1e3:.1f} ms '
              f'per step, over DDS {best_dds * 1e3:.1f} ms per step')
        print(f'ROS overhead per step: {(best_dds / best_proc - 1) * 100:+.1f}% '
              '(target: at most +10%)')
    else:
        print('ROS overhead per step: not computed, ' + (
            'the runs did not take the same gaits' if not all_same
            else 'fewer than two steps per run'))


def long_run(args):
    config = yaml.safe_load(Path(CONFIG).read_text())['/**/planner']['ros__parameters']
    # A goal 1 m from the middle of the map (where the robot starts: a goal there would be
    # reached at once) that can never be reached (goal.eps 1 mm): the robot walks to it and
    # keeps stepping around it without leaving the map.
    centre = [o + size / 2 for o, size in zip(config['map.origin'],
                                               (config['map.width'], config['map.height']))]
    centre[0] += 1.0
    overrides = {'sela_adapter': {'max_steps': args.steps + 5, 'goal.eps': 0.001}}
    times, memory, final = dds_mission(centre, args.seed, args.damage, overrides,
                                       steps_wanted=args.steps, timeout=600)
    if len(times) < 2:
        raise SystemExit(f'{len(times)} step(s) over DDS: the mission ended ({final})')
    k = max(1, min(10, len(times) // 4))
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
    o.add_argument('--rounds', type=int, default=5,
                   help='interleaved rounds (in process, DDS, in process)')
    o.add_argument('--verbose', action='store_true', help='per-step times of each round')
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
