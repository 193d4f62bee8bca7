#!/usr/bin/env python3
"""Run the course experiment and write its table and figures into docs/ (one command).

``python scripts/course_results.py --replicates 20 --courses maze,wall_gap,corridor
--out results/courses`` runs ``sela-experiment hexapod --map <course>`` (middle right leg
removed, SELA, the IT&E baselines and the oracle) for every course that has no
``results.json`` under ``--out`` yet (so a stopped run resumes course by course), copies each
course's ``paths.png`` to ``docs/figures/course_<name>.png`` and rewrites the table between
the markers of ``docs/course_results.md``.
"""
import argparse
import json
import shutil
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / 'docs' / 'course_results.md'
BEGIN, END = '<!-- course table: begin -->', '<!-- course table: end -->'
LABELS = {'sela': '`sela`', 'ite_uncertainty': '`ite_uncertainty` (IT&E #1)',
          'ite_4dir': '`ite_4dir` (IT&E #2)', 'oracle': '`oracle`'}


def table(docs) -> str:
    lines = ['| course | method | successes | median task steps (q25-q75) | median learning '
             'iterations | collisions (runs with any) | falls | wall (min) |',
             '|---|---|---|---|---|---|---|---|']
    for course, doc in docs.items():
        for name, m in doc['methods'].items():
            s = doc['summary'][name]
            q25, q75 = np.percentile(m['steps'], [25, 75])
            wall = doc['timing']['methods'][name]['wall_seconds'] / 60.0
            lines.append(
                f"| {course} | {LABELS.get(name, name)} | {s['successes']}/{doc['replicates']} "
                f"| {s['median_steps']:g} ({q25:g}-{q75:g}) | "
                f"{s['median_learning_iterations']:g} | {s['collisions']} "
                f"({s['runs_with_collisions']}) | {s['falls']} | {wall:.1f} |")
    return '\n'.join(lines)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--replicates', type=int, default=20)
    parser.add_argument('--courses', default='maze,wall_gap,corridor')
    parser.add_argument('--out', default='results/courses')
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--workers', type=int, default=1)
    args = parser.parse_args(argv)
    from sela_ros.experiments.cli import main as experiment

    docs = {}
    for course in args.courses.split(','):
        out = Path(args.out) / course
        if not (out / 'results.json').exists():
            code = experiment(['hexapod', '--map', course, '--replicates', str(args.replicates),
                               '--seed', str(args.seed), '--workers', str(args.workers),
                               '--damage', 'remove:middle_right', '--out', str(out)])
            if code:
                return code
        docs[course] = json.loads((out / 'results.json').read_text())
        shutil.copyfile(out / 'paths.png', ROOT / 'docs' / 'figures' / f'course_{course}.png')
    text = DOC.read_text()
    head, rest = text.split(BEGIN)
    _, tail = rest.split(END)
    DOC.write_text(f'{head}{BEGIN}\n{table(docs)}\n{END}{tail}')
    print(f'wrote {DOC} and docs/figures/course_*.png')
    return 0


if __name__ == '__main__':
    sys.exit(main())
