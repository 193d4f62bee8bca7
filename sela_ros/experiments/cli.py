"""``sela-experiment``: run the paper's experiments with replicates, write results + figure.

Usage::

    sela-experiment toy --replicates 50 --seed 0 --out results/toy [--noise-std 0.1]

Each scenario is one subcommand, registered in :data:`SCENARIOS`. To add one (e.g.
``hexapod``), write a module with

* ``add_arguments(parser)``: its own options (the common ``--replicates --seed --out
  --workers`` are already there),
* ``run(args, progress) -> dict``: the ``results.json`` document
  ``{"scenario", "replicates", "methods": {name: {"success", "steps",
  "learning_iterations"}}, ...}``; call ``progress()`` once per finished replicate,
* optionally ``finish_arguments(parser, args)``: checks of several options together (errors
  through ``parser.error``),

and add ``'hexapod': Scenario('help text', 'sela_ros.experiments.hexapod')`` to
:data:`SCENARIOS`. The CLI writes ``results.json`` and ``figure.png`` for every scenario.
"""
from __future__ import annotations

import argparse
import importlib
import json
import os
import sys
from dataclasses import dataclass

from sela_ros import single_blas_thread

single_blas_thread()  # before numpy: each worker one BLAS thread

from sela_ros.core.learning import DamagePriorError  # noqa: E402
from sela_ros.core.storage import atomic_write_bytes  # noqa: E402
from sela_ros.experiments import arguments  # noqa: E402


@dataclass(frozen=True)
class Scenario:
    help: str
    module: str  # imported lazily: provides add_arguments(parser) and run(args, progress)


SCENARIOS = {
    'toy': Scenario('the toy simulation: a damaged point robot reaches (2, 2)',
                    'sela_ros.experiments.toy'),
    'hexapod': Scenario('the damaged hexapod (or --robot) reaches (2, 2)',
                        'sela_ros.experiments.hexapod'),
    'robot': Scenario('the damaged robot (--robot, default the hexapod) reaches (2, 2); the '
                      'same as hexapod', 'sela_ros.experiments.hexapod'),
    'campaign': Scenario('the hexapod experiment over many damages, goals and maps '
                         '(resumable; a table per damage)', 'sela_ros.experiments.campaign'),
}


def build_parser() -> argparse.ArgumentParser:
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument('--replicates', type=arguments.positive_int, required=True,
                        help='number of replicates of every method')
    common.add_argument('--seed', type=arguments.seed, default=0, help='master seed (default 0)')
    common.add_argument('--out', required=True,
                        help='output directory (results.json, figure.png)')
    common.add_argument('--workers', type=arguments.positive_int, default=1,
                        help='processes running replicates in parallel (default 1)')
    common.add_argument('--quiet', action='store_true', help='no progress bar')
    parser = argparse.ArgumentParser(
        prog='sela-experiment',
        description='Reproduce the SELA paper experiments with replicates.')
    sub = parser.add_subparsers(dest='scenario', metavar='SCENARIO', required=True)
    parser.scenario_parsers = {}  # for the errors found after parsing
    for name, scenario in SCENARIOS.items():
        p = sub.add_parser(name, parents=[common], help=scenario.help,
                           description=scenario.help)
        parser.scenario_parsers[name] = p
        importlib.import_module(scenario.module).add_arguments(p)
        arguments.take_negative_points(p)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    module = importlib.import_module(SCENARIOS[args.scenario].module)
    # Errors from here on are the scenario's: said with its usage, not the top level's.
    scenario_parser = parser.scenario_parsers[args.scenario]
    if hasattr(module, 'finish_arguments'):  # checks that need several options together
        module.finish_arguments(scenario_parser, args)
    if os.path.exists(args.out) and not os.path.isdir(args.out):
        scenario_parser.error(f'--out {args.out!r} exists and is not a directory')
    try:
        os.makedirs(args.out, exist_ok=True)
    except OSError as err:
        scenario_parser.error(f'cannot create --out directory {args.out!r}: {err.strerror}')

    from tqdm import tqdm

    total = getattr(module, 'progress_total', lambda a: a.replicates)(args)
    with tqdm(total=total, desc=args.scenario, unit='replicate', file=sys.stderr,
              disable=args.quiet) as bar:
        try:
            doc = module.run(args, progress=lambda: bar.update(1))
        except (DamagePriorError, *getattr(module, 'ARGUMENT_ERRORS', ())) as err:
            bar.close()
            scenario_parser.error(str(err))
    results_path = os.path.join(args.out, 'results.json')
    atomic_write_bytes(results_path, json.dumps(doc, indent=1).encode())

    from sela_ros.experiments.figures import plot_methods

    getattr(module, 'plot', plot_methods)(doc, os.path.join(args.out, 'figure.png'))
    if hasattr(module, 'write_figures'):  # a scenario's own figures (e.g. paths on a map)
        for written in module.write_figures(doc, args.out):
            print(f'wrote {written}')
    for name, s in doc.get('summary', {}).items():
        print(f'{name:16s} success {s["successes"]}/{doc["replicates"]}  median learning '
              f'{s["median_learning_iterations"]:g}  median steps {s["median_steps"]:g}')
    print(f'wrote {results_path} and {os.path.join(args.out, "figure.png")}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
