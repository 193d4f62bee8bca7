#!/usr/bin/env python3
"""Build an archive's damage priors: every gait of the map run once from a standing start on
each foreseen damage (the oracle's tables, cached as the experiments cache them), written
beside the archive as ``<archive>_priors.npz`` (docs/archive.md, "Damage priors").

    .venv/bin/python scripts/build_priors.py 8d --damages single-legs --workers 2
    .venv/bin/python scripts/build_priors.py a1 --out a1_priors.npz \
        --damages 'shorten:front_left:0.5;block:rear_right.calf' --chained-repeats 0

The damages are in the names of the map's robot (the one its metadata names, or ``--robot``
for a robot of your own module, as ``sela-build-archive`` took it); ``single-legs`` and
``two-legs`` are the hexapod's. The adapter takes ``<archive>_priors.npz`` beside its map
(``priors.tables: auto``) or the file ``priors.tables`` names.

A damage whose table is not cached costs about 0.1 s of one core per gait (14-21 minutes of
one core per damage for the 8-D map); the tables already cached cost nothing.

Then the gaits the fall model fears and a robot would want (fast: 0.3 m or more from a
standing start, the table sees them standing, the support model gives them a risk above
0.1) are run right after ``--chained-repeats`` random walking gaits each (0.2 m or more,
standing), to learn which of them tip the robot over when chained (about 0.3 s of one core
per pair: 5-7 minutes per front or rear leg, none for a middle leg, whose gaits the model does
not fear; cached too). ``--chained-repeats 0`` leaves them out.
"""
import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from sela_ros.core.learning import (  # noqa: E402
    DamagePriors,
    FallRisk,  # noqa: E402
    params_checksum,
    priors_path,
)
from sela_ros.core.storage import (
    load_archive,  # noqa: E402
    resolve_archive_path,  # noqa: E402
)
from sela_ros.experiments.campaign import damage_list  # noqa: E402
from sim_bridge.damage import DamageSpecError  # noqa: E402
from sim_bridge.experiment_env import chained_runs, oracle_table  # noqa: E402
from sim_bridge.robots import get_robot, robot_of  # noqa: E402

#: Which gaits are run chained (module docstring).
CHAINED_MIN_DISTANCE = 0.3
CHAINED_MIN_RISK = 0.1
PREDECESSOR_MIN_DISTANCE = 0.2


def chained_choice(archive, gr, fallen, repeats, rng):
    """``(gaits, predecessors (len(gaits), repeats))`` to run chained on one damage."""
    model = FallRisk(archive.normalised_descriptors(), None, stability=archive.stability)
    risk = model.untried_risk(model.table_support(fallen))
    distance = np.hypot(gr[:, 0], gr[:, 1])
    gaits = np.flatnonzero(~fallen & (distance >= CHAINED_MIN_DISTANCE)
                           & (risk > CHAINED_MIN_RISK))
    walking = np.flatnonzero(~fallen & (distance >= PREDECESSOR_MIN_DISTANCE))
    before = np.array([rng.choice(walking, repeats) for _ in gaits], dtype=int)
    return gaits, before.reshape(len(gaits), repeats)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('archive', help="a map: '8d', '2d' or a path")
    parser.add_argument('--damages', type=damage_list, default=None,
                        help="';'-separated damage specs or groups, in the names of the map's "
                        "robot (default: the hexapod's single-legs; another robot's are "
                        'to be given)')
    parser.add_argument('--robot', default=None,
                        help="the map's robot as package.module:DESCRIPTION, for a robot of "
                        "your own (default: the one the map's metadata names)")
    parser.add_argument('--workers', type=int, default=1)
    parser.add_argument('--chained-repeats', type=int, default=4,
                        help='predecessors of each gait run chained (0: none)')
    parser.add_argument('--seed', type=int, default=1,
                        help="of the predecessors (each damage's drawn from it)")
    parser.add_argument('--out', default=None,
                        help='where to write (default: <archive>_priors.npz beside it)')
    args = parser.parse_args(argv)
    path = resolve_archive_path(args.archive)
    archive = load_archive(path)
    settings = archive.simulator_settings
    named = robot_of(archive.metadata)
    robot_arg = args.robot if args.robot is not None else named  # what workers find it by
    try:
        robot = get_robot(robot_arg)
    except ValueError as exc:
        parser.error(f'{path} is a map of the {named}: {exc}' if args.robot is None
                     else f'--robot: {exc}')
    if robot.name != named:
        parser.error(f'{path} is a map of the {named}, not of the {robot.name}')
    if args.damages is None:
        if robot.name != get_robot(None).name:
            parser.error(f'--damages: give the damages of the {robot.name}, in its names '
                         f'(legs {", ".join(robot.vocabulary.legs)}; kinds '
                         f'{", ".join(robot.vocabulary.kinds)})')
        args.damages = damage_list('single-legs')
    try:  # every damage in the robot's names, before the first table is built
        args.damages = [robot.parse_damage(d).canonical() for d in args.damages]
    except DamageSpecError as exc:
        parser.error(f'--damages: {exc}')
    if args.chained_repeats and archive.stability is None:
        parser.error(f'{path} has no support feature (a 2-D map): use --chained-repeats 0')
    grs, falls, runs, chained_falls = [], [], [], []
    for damage in args.damages:
        print(f'{damage}: evaluating {len(archive)} gaits (or reading the cached table)',
              flush=True)
        gr, fallen = oracle_table(archive.params, damage, workers=args.workers,
                                  dt=settings['dt'], gait_duration=settings['gait_duration'],
                                  solver_iterations=settings['solver_iterations'],
                                  robot=robot_arg)
        grs.append(gr)
        falls.append(fallen)
        print(f'{damage}: {int(fallen.sum())} of {len(fallen)} gaits fall', flush=True)
        if not args.chained_repeats:
            continue
        gaits, before = chained_choice(archive, gr, fallen, args.chained_repeats,
                                       np.random.default_rng(args.seed))
        print(f'{damage}: {len(gaits)} fast gaits the fall model fears, each run after '
              f'{args.chained_repeats} others (or reading the cache)', flush=True)
        n, f = chained_runs(archive.params, damage, gaits, before, workers=args.workers,
                            dt=settings['dt'], gait_duration=settings['gait_duration'],
                            solver_iterations=settings['solver_iterations'], robot=robot_arg)
        runs.append(np.zeros(len(archive), int))
        chained_falls.append(np.zeros(len(archive), int))
        runs[-1][gaits], chained_falls[-1][gaits] = n, f
        print(f'{damage}: {int(f.sum())} falls in {int(n.sum())} chained runs; '
              f'{int((f > 0).sum())} of the {len(gaits)} gaits fell at least once', flush=True)
    chained = (np.array(runs), np.array(chained_falls)) if args.chained_repeats else ()
    priors = DamagePriors(tuple(args.damages), np.array(grs), np.array(falls),
                          params_checksum(archive.params), *chained)
    out = Path(args.out) if args.out else priors_path(path)
    priors.save(out)
    print(f'wrote {out}: {len(priors)} damage priors for {len(archive)} gaits')
    return 0


if __name__ == '__main__':
    sys.exit(main())
