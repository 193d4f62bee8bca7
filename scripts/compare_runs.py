#!/usr/bin/env python3
"""Compare SELA settings run on the same cells: total steps over every run, split into the
single-leg removals and the other damages, the ratio to the oracle's total on the same cells,
falls and runs home. Each DIR is a ``sela-experiment campaign --out``; ``--oracle`` one run
with ``--methods oracle`` over the same goals and damages (docs/archive.md, "Damage priors").

    .venv/bin/python scripts/compare_runs.py docs/results/priors_8goals/{paper,defaults} \\
        --oracle docs/results/priors_8goals/oracle
"""
import argparse
import json
import sys
from pathlib import Path


def totals(directory, method):
    """``{'single': [steps, falls, runs], 'other': [...], 'home': [home, runs]}``."""
    out = {'single': [0, 0, 0], 'other': [0, 0, 0], 'home': [0, 0]}
    for path in sorted(Path(directory).glob('*/*/*/results.json')):
        doc = json.loads(path.read_text())
        damage = doc['parameters']['damage']
        runs = doc['methods'].get(method)
        if runs is None:
            continue
        group = 'single' if damage.startswith('remove:') and ',' not in damage else 'other'
        out[group][0] += sum(runs['steps'])
        out[group][1] += sum(runs['falls'])
        out[group][2] += len(runs['steps'])
        out['home'][0] += sum(runs['success'])
        out['home'][1] += len(runs['success'])
    return out


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('dirs', nargs='+', help='campaign output directories (SELA runs)')
    parser.add_argument('--oracle', required=True, help='the oracle on the same cells')
    args = parser.parse_args(argv)
    oracle = totals(args.oracle, 'oracle')
    print('| runs | single legs: total steps (x oracle), falls | other damages: total steps '
          '(x oracle), falls | home |')
    print('| --- | --- | --- | --- |')

    def cell(t, group):
        steps, falls, runs = t[group]
        if not runs:
            return '-'
        ratio = steps / oracle[group][0] if oracle[group][0] else float('nan')
        return f'{steps} ({ratio:.2f}x), {falls}'

    for directory in args.dirs:
        t = totals(directory, 'sela')
        print(f'| {directory} | {cell(t, "single")} | {cell(t, "other")} | '
              f'{t["home"][0]}/{t["home"][1]} |')
    print(f'| oracle | {cell(oracle, "single")} | {cell(oracle, "other")} | '
          f'{oracle["home"][0]}/{oracle["home"][1]} |')
    return 0


if __name__ == '__main__':
    sys.exit(main())
