#!/usr/bin/env python3
"""Build an archive's damage priors: every gait of the map run once from a standing start on
each foreseen damage (the oracle's tables, cached as the experiments cache them), written
beside the archive as ``<archive>_priors.npz`` (docs/archive.md, "Damage priors").

    .venv/bin/python scripts/build_priors.py 8d --damages single-legs --workers 2

A damage whose table is not cached costs about 0.1 s of one core per gait (14-21 minutes of
one core per damage for the 8-D map); the tables already cached cost nothing.
"""
import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from sela_ros.core.archive import load_archive, resolve_archive_path  # noqa: E402
from sela_ros.core.damage_priors import DamagePriors, params_checksum, priors_path  # noqa: E402
from sela_ros.experiments.campaign import damage_list  # noqa: E402
from sim_bridge.experiment_env import oracle_table  # noqa: E402


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('archive', help="a map: '8d', '2d' or a path")
    parser.add_argument('--damages', type=damage_list, default=damage_list('single-legs'),
                        help="';'-separated damage specs or groups (default single-legs)")
    parser.add_argument('--workers', type=int, default=1)
    parser.add_argument('--out', default=None,
                        help='where to write (default: <archive>_priors.npz beside it)')
    args = parser.parse_args(argv)
    path = resolve_archive_path(args.archive)
    archive = load_archive(path)
    settings = archive.simulator_settings
    grs, falls = [], []
    for damage in args.damages:
        print(f'{damage}: evaluating {len(archive)} gaits (or reading the cached table)',
              flush=True)
        gr, fallen = oracle_table(archive.params, damage, workers=args.workers,
                                  dt=settings['dt'], gait_duration=settings['gait_duration'],
                                  solver_iterations=settings['solver_iterations'])
        grs.append(gr)
        falls.append(fallen)
        print(f'{damage}: {int(fallen.sum())} of {len(fallen)} gaits fall', flush=True)
    priors = DamagePriors(tuple(args.damages), np.array(grs), np.array(falls),
                          params_checksum(archive.params))
    out = Path(args.out) if args.out else priors_path(path)
    priors.save(out)
    print(f'wrote {out}: {len(priors)} damage priors for {len(archive)} gaits')
    return 0


if __name__ == '__main__':
    sys.exit(main())
