#!/usr/bin/env python3
"""A campaign's SELA runs against the oracle, as a markdown table per damage and goal.

``sela-experiment campaign --methods sela`` runs SELA through the product's decision loop
(``run_mission``); the oracle's own loop does not change with SELA's defaults, so its median
steps are taken from the campaigns that ran it (``docs/results``, as
``scripts/compare_priors.py`` does) instead of being run again::

    .venv/bin/python scripts/campaign_table.py results/campaign_loop \\
        --markdown docs/results/campaign_loop/table.md
"""
from __future__ import annotations

import argparse
import glob
import json
import statistics
import sys
from pathlib import Path

from compare_priors import oracle_medians


def rows(campaign):
    """One row per (damage, goal) of the SELA runs under ``campaign``."""
    from sim_bridge.damage import parse_damage

    oracle = oracle_medians()
    out = []
    for path in sorted(glob.glob(str(Path(campaign) / '*' / '*' / '*' / 'results.json'))):
        doc = json.loads(Path(path).read_text())
        sela = doc['methods'].get('sela')
        if not sela:
            continue
        damage = doc['parameters']['damage']
        goal = tuple(float(v) for v in doc['parameters']['goal'])
        steps = [int(s) + int(i) for s, i in zip(sela['steps'], sela['learning_iterations'])]
        median = statistics.median(steps)
        o = oracle.get((parse_damage(damage).canonical(), goal))
        out.append({'damage': damage, 'goal': goal, 'runs': len(steps),
                    'success': int(sum(sela['success'])), 'median': median,
                    'range': (min(steps), max(steps)), 'oracle': o,
                    'ratio': median / o if o else None, 'falls': sela['falls']})
    return out


def markdown(table):
    lines = ['| damage | goal | success | median steps (range) | oracle | ratio | median '
             'falls/run | falls |', '|' + '---|' * 8]
    for r in table:
        lines.append(
            f"| {r['damage']} | ({r['goal'][0]:g}, {r['goal'][1]:g}) | {r['success']}/"
            f"{r['runs']} | {r['median']:g} ({r['range'][0]}-{r['range'][1]}) | "
            f"{'-' if r['oracle'] is None else format(r['oracle'], 'g')} | "
            f"{'-' if r['ratio'] is None else format(r['ratio'], '.2f') + 'x'} | "
            f"{statistics.median(r['falls']):g} | {sum(r['falls'])} |")
    return '\n'.join(lines)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('campaign', help="a campaign's --out folder")
    parser.add_argument('--markdown', default=None, help='write the table here too')
    args = parser.parse_args(argv)
    table = rows(args.campaign)
    if not table:
        parser.error(f'no SELA cell under {args.campaign}')
    text = markdown(table)
    print(text)
    if args.markdown:
        Path(args.markdown).parent.mkdir(parents=True, exist_ok=True)
        Path(args.markdown).write_text(text + '\n')
    return 0


if __name__ == '__main__':
    sys.exit(main())
