#!/usr/bin/env python3
"""Run the course experiment and write its table and figures into docs/ (one command).

``python scripts/course_results.py --archive 8d --replicates 20 --courses maze,wall_gap,corridor
--out results/courses_8d`` runs ``sela-experiment hexapod --map <course> --archive 8d`` (middle
right leg removed; SELA, the IT&E baselines and the oracle, or ``--methods``) for every course
that has no ``results.json`` under ``--out`` yet (so a stopped run resumes course by course),
copies each course's ``paths.png`` to ``docs/figures/course_<name>_<archive>.png`` and
rewrites the table between the markers ``<!-- course table <archive>: begin -->`` and
``... end -->`` of ``docs/course_results.md``.
"""
import argparse
import json
import shutil
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # this repository's sela_ros, not a copy installed elsewhere
DOC = ROOT / 'docs' / 'course_results.md'


def markers(label):
    return f'<!-- course table {label}: begin -->', f'<!-- course table {label}: end -->'


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
    parser.add_argument('--out', default=None,
                        help='where the runs go (default results/courses_<archive>)')
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--workers', type=int, default=1)
    parser.add_argument('--archive', default='8d',
                        help="the map: '8d' (shipped default), '2d' or a path (default 8d)")
    parser.add_argument('--methods', default='sela,ite_uncertainty,ite_4dir,oracle')
    args = parser.parse_args(argv)
    from sela_ros.experiments.cli import main as experiment

    label = Path(args.archive).stem if args.archive.endswith('.npz') else args.archive
    begin, end = markers(label)
    args.out = args.out or f'results/courses_{label}'
    text = DOC.read_text()
    if begin not in text or end not in text:
        parser.error(f'{DOC} has no {begin} ... {end} markers for this map: add them where '
                     'its table should go')
    docs = {}
    for course in args.courses.split(','):
        out = Path(args.out) / course
        if not (out / 'results.json').exists():
            code = experiment(['hexapod', '--map', course, '--replicates', str(args.replicates),
                               '--seed', str(args.seed), '--workers', str(args.workers),
                               '--damage', 'remove:middle_right', '--archive', args.archive,
                               '--methods', args.methods, '--out', str(out)])
            if code:
                return code
        docs[course] = json.loads((out / 'results.json').read_text())
        shutil.copyfile(out / 'paths.png',
                        ROOT / 'docs' / 'figures' / f'course_{course}_{label}.png')
    text = DOC.read_text()
    head, rest = text.split(begin)
    _, tail = rest.split(end)
    DOC.write_text(f'{head}{begin}\n{table(docs)}\n{end}{tail}')
    print(f'wrote {DOC} and docs/figures/course_*_{label}.png')
    return 0


if __name__ == '__main__':
    sys.exit(main())
