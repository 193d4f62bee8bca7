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

``--known`` runs nothing: each damage is what is known of it (a shipped or cached table,
else the gaits the damage library evaluated, ``build_library.known_outcomes``), and the
error is also given by how far the map says each gait goes: a prediction's error grows with
the step it predicts (docs/damage_library.md)::

    .venv/bin/python scripts/prior_error.py 8d --known --damage block:rear_left.knee=-0.4
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
    parser.add_argument('--known', action='store_true',
                        help='simulate nothing: what is known of each damage, and the error by '
                             'the displacement the map predicts')
    args = parser.parse_args(argv)
    archive = load_archive(resolve_archive_path(args.archive))
    settings = archive.simulator_settings
    prior = archive.generic_reward
    print('| damage | gaits that fall | scale s | (dx, dy) error rms: map | map x s | '
          'the 5 / 100 fastest forward by the map: mean true forward of those that stay up '
          '| the 100 truly fastest forward: mean true forward |')
    print('| --- | --- | --- | --- | --- | --- | --- |')
    bands = []
    for damage in args.damage:
        if args.known:
            gr, fallen, known = known_outcomes(archive, damage)
            bands.append((damage, prior[known & ~fallen], gr[known & ~fallen]))
        else:
            gr, fallen = oracle_table(archive.params, damage, workers=args.workers,
                                      dt=settings['dt'], gait_duration=settings['gait_duration'],
                                      solver_iterations=settings['solver_iterations'])
            known = np.ones(len(fallen), bool)
        up = ~fallen & known
        x, y = prior[up, :2], gr[up, :2]
        scale = float(np.sum(x * y) / np.sum(x * x))
        forward = np.where(fallen, np.nan, gr[:, 0])
        order = [i for i in np.argsort(-prior[:, 0]) if known[i]]
        top = []
        for k in (5, 100):
            falls = int(fallen[order[:k]].sum())
            mean = (f'{np.nanmean(forward[order[:k]]):.2f} m' if falls < k else 'none stays up')
            top.append(f'{mean} ({falls} fall)')
        print(f'| {damage} | {int(fallen[known].sum())} of {int(known.sum())} | {scale:.2f} | '
              f'{rms(y - x):.3f} m | {rms(y - scale * x):.3f} m | {" / ".join(top)} '
              f'| {np.mean(np.sort(forward[up])[-100:]):.2f} m |')
    if bands:
        print()
        print(by_displacement(bands))
    return 0


#: Bands of the map's predicted displacement |(dx, dy)| (m).
BANDS = (0.0, 0.1, 0.2, 0.3, 0.4, 0.5, np.inf)


def by_displacement(bands):
    """Median and 90th percentile of the (dx, dy) error per band of the map's displacement,
    over the gaits that stay up of every damage in ``bands`` ``[(damage, map, true)]``."""
    names = [f'{lo:g}-{hi:g} m' if np.isfinite(hi) else f'>= {lo:g} m'
             for lo, hi in zip(BANDS, BANDS[1:])]
    lines = ['| damage | ' + ' | '.join(names) + ' |', '| --- |' + ' --- |' * len(names)]
    for damage, x, y in bands:
        step = np.hypot(x[:, 0], x[:, 1])
        error = np.hypot(*(y[:, :2] - x[:, :2]).T)
        band = np.digitize(step, BANDS) - 1
        cells = [f'{np.median(error[band == b]):.3f} / {np.percentile(error[band == b], 90):.3f}'
                 f' ({int((band == b).sum())})' if (band == b).any() else '-'
                 for b in range(len(names))]
        lines.append(f'| {damage} | ' + ' | '.join(cells) + ' |')
    return '\n'.join(lines)


def known_outcomes(archive, damage):
    """``(generic_reward, fallen, known)`` of what is known of ``damage``, simulating
    nothing."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import build_library

    from sela_ros.core.learning import resolve_priors
    from sela_ros.core.storage import default_archive_path

    shipped = resolve_priors('auto', default_archive_path(), archive.params)
    known = build_library.known_outcomes(archive, damage, shipped=shipped)
    if known is None:
        raise SystemExit(f'prior_error: nothing is known of {damage}: no shipped or cached '
                         'table, and no gait of it in the damage library')
    gr, fallen, where, _ = known
    return gr, fallen, where


if __name__ == '__main__':
    sys.exit(main())
