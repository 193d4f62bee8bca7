"""False restarts of learning over long missions, and the delay to detect a real new damage.

Drives the product's step cycle (:class:`~sela_ros.core.mission.MissionStepper`, as
:func:`sela_ros.core.mission.run_mission` and the ``sela_adapter`` node do) with the node's
defaults from config/sela.yaml (detector, priors, ``adaptation.on_detection``, reset on fall)
through many successive goals, learning carried from one goal to the next::

    nice -n 15 .venv/bin/python benchmarks/bench_restarts.py --goals 30 --seeds 0,1,2
    nice -n 15 .venv/bin/python benchmarks/bench_restarts.py --delay --seeds 0,1,2

Without ``--delay``: the damage never changes, so every restart of learning is a false one;
prints restarts per 100 goals and the observations each one set aside. With ``--delay``: the
robot walks ``--before`` goals with one damage, then a second leg is lost; prints the steps
from the change to the first restart of learning (the new damage acted on).
"""
import argparse
import os
import statistics
import time
from collections import deque
from dataclasses import replace

import numpy as np
import yaml

from sela_ros.core.detection import DamageDetector, DetectorConfig
from sela_ros.core.learning import resolve_priors
from sela_ros.core.mission import MissionStepper, as_seen_in_odometry, make_sela
from sela_ros.core.mission.stepper_io import (
    GoalReceived,
    OutcomeReceived,
    PlanReceived,
    PoseObserved,
    RequestPlan,
    RequestReset,
    ResetDone,
    SendGait,
    VerdictReceived,
)
from sela_ros.core.planning import GridPlanner, PlanningError
from sela_ros.core.storage import default_archive_path, load_archive
from sela_ros.nodes import adapter_params
from sela_ros.nodes.planner_node import grid_from_description
from sim_bridge.environment import ObservedHexapod
from sim_bridge.hexapod import Hexapod

CONFIG = os.path.join(os.path.dirname(__file__), '..', 'config', 'sela.yaml')


def node_parameters():
    with open(CONFIG) as handle:
        config = yaml.safe_load(handle)
    return {k.removeprefix('/**/'): v['ros__parameters'] for k, v in config.items()}


class Mission:
    """The node's configuration, in process, over successive goals."""

    def __init__(self, damage, seed, max_steps=40, verbose=False, **stepper):
        cfg = node_parameters()
        bridge, plan = cfg['sim_bridge'], cfg['planner']
        adapter, detector = cfg['sela_adapter'], cfg['damage_detector']
        self.archive = load_archive(default_archive_path())
        physics = self.archive.simulator_settings
        self.robot = Hexapod(dt=physics['dt'], gait_duration=physics['gait_duration'],
                             solver_iterations=physics['solver_iterations'], damage=damage)
        self.env = ObservedHexapod(self.robot, bridge['observation.noise_std'], seed=seed,
                                   right_on_fall=bridge['right_on_fall'])
        self.grid = grid_from_description(plan['map.resolution'], plan['map.origin'],
                                          plan['map.width'], plan['map.height'], [])
        self.planner = GridPlanner(self.grid, inflation=plan['planner.inflation'])
        priors = resolve_priors(adapter['priors.tables'], default_archive_path(),
                                self.archive.params)
        self.stepper = MissionStepper(
            make_sela(self.archive, adapter_params.sela_config(adapter), priors=priors),
            replace(adapter_params.stepper_config(adapter, self.archive), max_steps=max_steps,
                    **stepper))
        self.detector = DamageDetector(DetectorConfig(**{
            k.split('.', 1)[1]: v for k, v in detector.items() if k.startswith('detection.')}))
        self.steps = 0
        self.restarts = []  # (step, observations set aside)
        self.fires = []  # steps at which the detector fired
        logic = self.stepper.logic
        adapt = logic.adapt

        def counted_adapt():
            before = len(logic.sela.observations[0])
            was_adapting = logic.adapting
            kept = adapt()
            if was_adapting and not kept:
                self.restarts.append((self.steps, before))
            evidence = getattr(logic, 'evidence', None)
            if verbose and was_adapting and evidence is not None:
                print(f'    step {self.steps}: {"kept" if kept else "RESTART"}, '
                      f'{evidence.describe()}: ' + ', '.join(
                          f'{i} {e:.2f}/{a:.2f}' for i, e, a in evidence.errors), flush=True)
            return kept
        logic.adapt = counted_adapt

    def close(self):
        self.robot.close()

    def _odometry(self):
        return PoseObserved(as_seen_in_odometry(self.env.true_pose()))

    def go(self, goal, on_step=None):
        """One goal to the end; returns whether it was reached."""
        now = time.monotonic
        commands = deque(self.stepper.handle(self._odometry(), now()))
        commands += self.stepper.handle(GoalReceived(tuple(goal)), now())
        while commands:
            command = commands.popleft()
            events = []
            if isinstance(command, RequestPlan):
                try:
                    path = self.planner(np.asarray(command.start, float)[:2], command.goal)
                    events.append(PlanReceived(command.step, command.start,
                                               path=tuple(map(tuple, path))))
                except PlanningError as exc:
                    events.append(PlanReceived(command.step, command.start, None, str(exc)))
            elif isinstance(command, SendGait):
                self.steps += 1
                execution = self.env.execute(self.archive.params[command.index])
                observed = execution.observed_generic_reward
                events.append(OutcomeReceived(
                    command.behavior_id, observed, execution.observed_end, execution.fallen,
                    true_pose=execution.true_end,
                    standing_start=getattr(execution, 'standing_start', None)))
                verdict = self.detector.observe(command.predicted_gr, observed, command.sigma)
                if verdict.fire:
                    self.fires.append(self.steps)
                events.append(VerdictReceived(command.behavior_id, verdict.fire, verdict.error,
                                              self.detector.config.threshold))
                if on_step is not None:
                    on_step(self.steps)
            elif isinstance(command, RequestReset):
                self.env.reset()
                events += [ResetDone(True, 'robot back at the start'), self._odometry()]
            for event in events:
                commands += self.stepper.handle(event, now())
        return bool(self.stepper.result)


def goals(rng, count):
    # Inside the default 4 m x 4 m map (origin (-1, -1)), clear of its edges.
    return [tuple(rng.uniform(-0.4, 2.4, size=2)) for _ in range(count)]


def false_restarts(damage, seed, count, verbose=False, **stepper):
    mission = Mission(damage, seed, verbose=verbose, **stepper)
    reached = 0
    try:
        for goal in goals(np.random.default_rng(seed), count):
            reached += mission.go(goal)
    finally:
        mission.close()
    return reached, mission


def delay(first, second, seed, before, verbose=False, after=6):
    """``before`` goals with ``first``, then ``second`` from the next step while adapting,
    then ``after`` goals more. Returns the step of the change, the steps from it to the
    first restart and to the first detection (None: none), and the goals reached after the
    change with the steps they took."""
    mission = Mission(first, seed, verbose=verbose)
    change = {}
    goal_number = [0]

    def on_step(step):
        if 'step' not in change and mission.stepper.logic.adapting and \
                goal_number[0] >= before:
            mission.robot.set_damage(second)
            change['step'] = step
    reached, steps_after = 0, 0
    try:
        for goal in goals(np.random.default_rng(seed), before + after + 3):
            changed = 'step' in change
            steps = mission.steps
            ok = mission.go(goal, on_step)
            goal_number[0] += 1
            if changed:
                reached += ok
                steps_after += mission.steps - steps
                if goal_number[0] - before > after:
                    break
    finally:
        mission.close()
    at = change.get('step')
    restart = next((s for s, _ in mission.restarts if at is not None and s > at), None)
    fire = next((s for s in mission.fires if at is not None and s > at), None)
    return (at, None if restart is None else restart - at, None if fire is None else fire - at,
            reached, steps_after)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--goals', type=int, default=30)
    parser.add_argument('--seeds', default='0,1,2')
    parser.add_argument('--damages', default='remove:middle_right,shorten:front_left:0.5',
                        help='comma-separated; damages joined with "+"')
    parser.add_argument('--delay', action='store_true')
    parser.add_argument('--before', type=int, default=3,
                        help='--delay: goals walked before the second damage')
    parser.add_argument('--after', type=int, default=6,
                        help='--delay: goals walked after the second damage')
    parser.add_argument('--verbose', action='store_true',
                        help='print the evidence weighed at each detection while adapting')
    args = parser.parse_args()
    seeds = [int(s) for s in args.seeds.split(',')]
    if args.delay:
        first, second = 'remove:middle_right', 'remove:middle_right,remove:front_left'
        print(f'{first} -> {second} after {args.before} goals, once adapting')
        delays, fires, goals_after, steps_after = [], [], 0, 0
        for seed in seeds:
            start = time.perf_counter()
            at, steps, fired, reached, walked = delay(first, second, seed, args.before,
                                                      args.verbose, args.after)
            delays.append(steps)
            fires.append(fired)
            goals_after += reached
            steps_after += walked
            print(f'seed {seed}: changed at step {at}, restart after {steps} step(s), '
                  f'detector fired after {fired}; then {reached}/{args.after} goals in '
                  f'{walked} steps, {time.perf_counter() - start:.0f} s', flush=True)
        known = [d for d in delays if d is not None]
        heard = [f for f in fires if f is not None]
        print(f'detection delay: median {statistics.median(heard) if heard else None} steps; '
              f'restart delay: median {statistics.median(known) if known else None} steps, '
              f'{len(delays) - len(known)} never restarted; after the change '
              f'{goals_after}/{args.after * len(seeds)} goals, '
              f'{steps_after / max(1, goals_after):.1f} steps per goal reached')
        return
    total_goals = total_restarts = 0
    for damage in args.damages.split(','):
        damage = damage.replace('+', ',')
        for seed in seeds:
            start = time.perf_counter()
            reached, mission = false_restarts(damage, seed, args.goals, args.verbose)
            total_goals += args.goals
            total_restarts += len(mission.restarts)
            print(f'{damage:28s} seed {seed}: {reached}/{args.goals} goals, '
                  f'{mission.steps} steps, {len(mission.fires)} detections, '
                  f'{len(mission.restarts)} restarts (observations set aside: '
                  f'{[n for _, n in mission.restarts]}), '
                  f'{time.perf_counter() - start:.0f} s', flush=True)
    print(f'false restarts: {100.0 * total_restarts / total_goals:.1f} per 100 goals '
          f'({total_restarts} in {total_goals} goals)')


if __name__ == '__main__':
    main()
