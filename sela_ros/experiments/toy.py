"""The toy-simulation experiment: every method on the damaged point robot, N replicates."""
from __future__ import annotations

import argparse

import numpy as np

from sela_ros.experiments import arguments
from sela_ros.experiments.baselines import METHODS
from sela_ros.experiments.toy_world import ToyWorld, toy_problem

DEFAULT_METHODS = ('sela', 'random_babbling', 'ite_4dir', 'oracle')
NUM_BEHAVIOURS = 1000


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``sela-experiment toy`` (the common ones are added by the CLI)."""
    parser.add_argument('--noise-std', type=arguments.noise_std,
                        default=arguments.DEFAULT_NOISE_STD, help=arguments.NOISE_HELP)
    parser.add_argument('--methods', type=arguments.method_list, default=list(DEFAULT_METHODS),
                        help='comma-separated methods (default: %(default)s; also '
                             'ite_uncertainty)')
    parser.add_argument('--max-steps', type=arguments.positive_int, default=100,
                        help='task-step cap; a run that hits it fails (default %(default)s)')


def run_replicate(seed_seq: np.random.SeedSequence, noise_std: float, methods, max_steps):
    """All methods on one replicate; each method gets its own world and generators."""
    out = {}
    for name, child in zip(methods, seed_seq.spawn(len(methods))):
        env_seed, method_seed = child.spawn(2)
        world = ToyWorld(NUM_BEHAVIOURS, noise_std=noise_std,
                         rng=np.random.default_rng(env_seed))
        result = METHODS[name](world, toy_problem(world, max_steps=max_steps),
                               np.random.default_rng(method_seed))
        out[name] = result
    return out


def _run_one(job):
    return run_replicate(*job)


def run(args, progress=None) -> dict:
    """Run the experiment described by ``args``; returns the results.json document."""
    seeds = np.random.SeedSequence(args.seed).spawn(args.replicates)
    jobs = [(s, args.noise_std, args.methods, args.max_steps) for s in seeds]
    results = []
    if args.workers <= 1:
        for job in jobs:
            results.append(_run_one(job))
            if progress:
                progress()
    else:
        from sim_bridge.evaluation import worker_pool

        with worker_pool(args.workers) as pool:
            for r in pool.map(_run_one, jobs):
                results.append(r)
                if progress:
                    progress()
    methods = {}
    for name in args.methods:
        runs = [r[name] for r in results]
        methods[name] = {
            'success': [bool(r.success) for r in runs],
            'steps': [int(r.steps) for r in runs],
            'learning_iterations': [int(r.learning_iterations) for r in runs],
        }
    summary = {name: {'successes': int(sum(m['success'])),
                      'median_steps': float(np.median(m['steps'])),
                      'median_learning_iterations': float(np.median(m['learning_iterations'])),
                      'median_total': float(np.median(np.add(m['steps'],
                                                             m['learning_iterations'])))}
               for name, m in methods.items()}
    return {'scenario': 'toy', 'replicates': args.replicates, 'methods': methods,
            'seed': args.seed,
            'parameters': {'noise_std': args.noise_std, 'max_steps': args.max_steps,
                           'num_behaviours': NUM_BEHAVIOURS, 'goal': [2.0, 2.0],
                           'start': [0.0, 0.0], 'damage_offset': 0.5, 'step': 0.1},
            'summary': summary}
