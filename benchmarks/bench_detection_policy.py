"""What to do with what the GPs learned when the damage detector fires again while adapting.

Runs the in-process mission (the same MissionStepper as the sela_adapter node, the PyBullet
hexapod, the damage detector) with each policy of ``adaptation.on_detection`` over a few
damages, one of which changes mid-mission, and prints successes and median steps::

    nice .venv/bin/python benchmarks/bench_detection_policy.py --replicates 3

Policies: ``reset`` (forget everything but the triggering step: the paper's restart),
``keep`` (keep every observation), ``evidence`` (forget only when the triggering gait had
been learnt already and now does something else: the damage changed).
"""
import argparse
import statistics
import time

import numpy as np

from sela_ros.core.detection import DetectorConfig
from sela_ros.core.mission import StepperConfig, make_sela, run_mission
from sela_ros.core.planning import GridPlanner, default_grid
from sela_ros.core.storage import default_archive_path, load_archive
from sim_bridge.experiment_env import HexapodEnvironment

POLICIES = ('reset', 'keep', 'evidence')
# (name, damage at the start, (step, damage from that step) or None, goal)
SCENARIOS = (
    ('middle_right removed', 'remove:middle_right', None, (2.0, 2.0)),
    ('front_left shortened', 'shorten:front_left:0.5', None, (2.0, -1.0)),
    ('intact, then middle_right removed at step 4', 'intact', (4, 'remove:middle_right'),
     (2.5, 2.0)),
    ('middle_right removed, then also front_left at step 6', 'remove:middle_right',
     (6, 'remove:middle_right,remove:front_left'), (2.5, 2.0)),
)


def run(archive, scenario, policy, seed, max_steps, adapt_on_start=False):
    _, damage, change, goal = scenario
    env = HexapodEnvironment(archive.params, damage, 0.01, seed=seed)

    def on_step(record):
        if change is not None and record.step == change[0]:
            env.robot.set_damage(change[1])
    try:
        run = run_mission(env, make_sela(archive, {'planner.lookahead': 0.6}), [goal],
                          GridPlanner(default_grid()), detector_config=DetectorConfig(),
                          stepper_config=StepperConfig(max_steps=max_steps,
                                                       on_detection=policy,
                                                       adapt_on_start=adapt_on_start),
                          on_step=on_step)
    finally:
        env.close()
    detections = sum(r.detected for r in run.logic.records)
    return run.success, run.steps, detections


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--replicates', type=int, default=3)
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--max-steps', type=int, default=60)
    parser.add_argument('--adapt-on-start', action='store_true',
                        help='learn from the first step: every detection comes while adapting')
    parser.add_argument('--scenarios', default=None,
                        help='comma-separated scenario numbers (1-based; default: all)')
    args = parser.parse_args()
    archive = load_archive(default_archive_path())
    print(f'{args.replicates} replicates (seeds {args.seed}..{args.seed + args.replicates - 1}), '
          f'max {args.max_steps} steps' + (', adapting from the first step'
                                           if args.adapt_on_start else ''))
    chosen = SCENARIOS if not args.scenarios else [
        SCENARIOS[int(i) - 1] for i in args.scenarios.split(',')]
    print(f'{"scenario":55s} {"policy":9s} success  median steps  detections  wall')
    for scenario in chosen:
        for policy in POLICIES:
            start = time.perf_counter()
            runs = [run(archive, scenario, policy, args.seed + i, args.max_steps,
                        args.adapt_on_start) for i in range(args.replicates)]
            ok = sum(r[0] for r in runs)
            steps = statistics.median(r[1] for r in runs)
            detections = np.mean([r[2] for r in runs])
            print(f'{scenario[0]:55s} {policy:9s} {ok}/{len(runs)}      {steps:6.1f}       '
                  f'{detections:5.1f}    {time.perf_counter() - start:5.1f} s', flush=True)


if __name__ == '__main__':
    main()
