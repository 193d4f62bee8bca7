#!/usr/bin/env python3
"""How far a map's intact displacements (the GPs' prior mean) are from a damaged robot's: every
gait of the map run once from a standing start on the damaged robot (the oracle's table,
cached as the experiments cache it), compared with what the map says.

    .venv/bin/python scripts/prior_error.py 8d --damage remove:front_left --damage remove:rear_left

Per damage: the gaits that fall, the scale ``s`` that best maps the map's (dx, dy) onto the
damaged robot's (least squares over the gaits that stay up), the error of the map as it is and
scaled by ``s``, and how the gaits the map calls fastest forward really do. Behind
docs/archive.md, "Closing the gap to the oracle". A damage whose table is not cached costs
about 0.1 s of one core per gait (20 minutes for the 8-D map).
"""
import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from sela_ros.core.storage import (
    load_archive,  # noqa: E402
    resolve_archive_path,  # noqa: E402
)
from sim_bridge.experiment_env import oracle_table  # noqa: E402


def rms(v):
    return float(np.sqrt(np.mean(np.sum(v * v, axis=1))))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('archive', help="a map: '8d', '2d' or a path")
    parser.add_argument('--damage', action='append', required=True,
                        help='a damage spec (repeat for several)')
    parser.add_argument('--workers', type=int, default=1)
    args = parser.parse_args(argv)
    archive = load_archive(resolve_archive_path(args.archive))
    settings = archive.simulator_settings
    prior = archive.generic_reward
    print('| damage | gaits that fall | scale s | (dx, dy) error rms: map | map x s | '
          'the 5 / 100 fastest forward by the map: mean true forward of those that stay up |')
    print('| --- | --- | --- | --- | --- | --- |')
    for damage in args.damage:
        gr, fallen = oracle_table(archive.params, damage, workers=args.workers,
                                  dt=settings['dt'], gait_duration=settings['gait_duration'],
                                  solver_iterations=settings['solver_iterations'])
        up = ~fallen
        x, y = prior[up, :2], gr[up, :2]
        scale = float(np.sum(x * y) / np.sum(x * x))
        forward = np.where(fallen, np.nan, gr[:, 0])
        order = np.argsort(-prior[:, 0])
        top = []
        for k in (5, 100):
            falls = int(fallen[order[:k]].sum())
            mean = (f'{np.nanmean(forward[order[:k]]):.2f} m' if falls < k else 'none stays up')
            top.append(f'{mean} ({falls} fall)')
        print(f'| {damage} | {int(fallen.sum())} of {len(fallen)} | {scale:.2f} | '
              f'{rms(y - x):.3f} m | {rms(y - scale * x):.3f} m | {" / ".join(top)} |')
    return 0


if __name__ == '__main__':
    sys.exit(main())
