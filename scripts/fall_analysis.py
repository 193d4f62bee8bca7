#!/usr/bin/env python3
"""What makes a damaged hexapod fall: a random sample of a map's gaits, each run once from a
standing start on the damaged robot, their fall rate by decile of the map's stability feature
(the 8-D map's support: the sum of the six duty factors), and how well each descriptor
dimension and the intact displacement rank the gaits that fall (AUC).

    .venv/bin/python scripts/fall_analysis.py MAP.npz --damage remove:front_left --gaits 1500

Behind the fall model's prior (sela_ros/core/learning/fall_risk.py; docs/archive.md, "What tips a
damaged hexapod over"). About 0.1 s of one core per gait.
"""
import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from sela_ros.core.storage import load_archive  # noqa: E402
from sim_bridge.evaluation import evaluate_gait  # noqa: E402


def auc(score, positive):
    """Probability that a random positive scores above a random negative (ties: half)."""
    pos, neg = score[positive], score[~positive]
    if not pos.size or not neg.size:
        return float('nan')
    return float((pos[:, None] > neg[None, :]).mean()
                 + 0.5 * (pos[:, None] == neg[None, :]).mean())


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('archive')
    parser.add_argument('--damage', default='remove:front_left')
    parser.add_argument('--gaits', type=int, default=1500)
    parser.add_argument('--seed', type=int, default=0)
    args = parser.parse_args(argv)
    archive = load_archive(args.archive)
    stability = archive.stability
    if stability is None:
        parser.error(f'{args.archive} has no stability feature (not an 8-D duty-factor map)')
    settings = archive.simulator_settings
    rng = np.random.default_rng(args.seed)
    idx = rng.choice(len(archive), min(args.gaits, len(archive)), replace=False)
    fallen = np.zeros(idx.size, dtype=bool)
    for k, i in enumerate(idx):
        fallen[k] = evaluate_gait(archive.params[i], args.damage, settings['dt'],
                                  settings['gait_duration'],
                                  settings['solver_iterations']).fallen
        if (k + 1) % 250 == 0:
            print(f'{k + 1}/{idx.size} gaits run', file=sys.stderr, flush=True)
    support = stability[idx]
    print(f'{args.archive}: {len(archive)} gaits; {idx.size} sampled; damage {args.damage}; '
          f'{fallen.sum()} fall from a standing start ({fallen.mean():.1%})')
    edges = np.quantile(support, np.linspace(0, 1, 11))
    decile = np.clip(np.searchsorted(edges, support, side='right') - 1, 0, 9)
    print('| support decile | support | gaits | fall rate |')
    print('| --- | --- | --- | --- |')
    for d in range(10):
        m = decile == d
        print(f'| {d + 1} | {edges[d]:.2f}-{edges[d + 1]:.2f} | {m.sum()} | '
              f'{fallen[m].mean():.0%} |')
    names = ['x', 'y'] + [f'duty {leg}' for leg in ('front_left', 'middle_left', 'rear_left',
                                                   'front_right', 'middle_right', 'rear_right')]
    desc = archive.normalised_descriptors()[idx]
    speed = np.hypot(*archive.generic_reward[idx, :2].T)
    print('AUC of falling (0.5: says nothing):', ', '.join(
        [f'less support {auc(-support, fallen):.2f}', f'intact speed {auc(speed, fallen):.2f}']
        + [f'less {n} {auc(-desc[:, j], fallen):.2f}' for j, n in enumerate(names)]))
    return 0


if __name__ == '__main__':
    sys.exit(main())
