"""How SELA learns a damage no table foresaw: the whole evaluation in one command.

Runs one method of ``compare_priors.py`` (default ``caution``: the ``sela_adapter`` node's
defaults) through the loop the nodes run, on every part of the evaluation, then sets each
figure against its target:

* ``library``: the damage library's 102 damages, each measured as if no table held it or
  anything near it (its own condition and near duplicates left out), at most 60 steps;
* ``pairs``: the 15 pairs of removed legs (also in ``library``) with at most 150 steps;
* ``deviations``: the ground's friction and a payload, alone and with a leg removed or
  shortened: no table or map was built on them (their oracles: ``build_library.py
  --oracle-only``, kept in ``mapbuild/oracles``);
* ``foreseen``: the three single legs whose table ships beside the map, and the paper's case
  (middle right leg removed, goal (2, 2), seed 0);
* ``toy``: the paper's toy task, 50 replicates (``sela-experiment toy``).

Every run is appended to ``<dir>/<part>.jsonl`` as it finishes and a rerun skips those done,
so an interrupted evaluation resumes. The oracle's median steps come from the runs kept in
docs/results (``--oracle-runs``); an oracle that none of those holds is run here (seeds 0-1).
Falls are set against today's default's on the same damages, goals and seeds
(``--baseline``). Writes ``<dir>/summary.md`` (the targets, then each part's tables) and
``<dir>/library.png`` (every damage's ratios to the oracle)::

    nice -n 10 .venv/bin/python scripts/evaluate_learning.py --method caution --seeds 20
    .venv/bin/python scripts/evaluate_learning.py --method caution --seeds 1 --pair-seeds 1 \\
        --check-seeds 1 --parts library,foreseen     # a screen: seed 0 only
"""
from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import statistics
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / 'scripts'))
sys.path.insert(0, str(ROOT))  # this repository's sela_ros, not a copy installed elsewhere

from sela_ros import single_blas_thread  # noqa: E402

single_blas_thread()  # before numpy

import compare_priors  # noqa: E402

PARTS = ('library', 'pairs', 'deviations', 'foreseen', 'toy')
GOALS = '2,2 -2,1.5 1.5,-2'
LIBRARY = 'sela_ros/data/hexapod_archive_library.npz'
ORACLE_RUNS = ('docs/results/library_loo_all/runs.jsonl',
               'docs/results/learning/pairs150_all.jsonl',
               'docs/results/learning/deviations_3seeds.jsonl',
               'docs/results/learning/foreseen_3seeds.jsonl')
BASELINE = 'docs/results/library_loo_all/runs.jsonl'
BASELINE_METHOD = 'caution'
#: Two legs side by side on one side, both front or both rear.
NEIGHBOURS = tuple(frozenset(p) for p in (
    ('front_left', 'middle_left'), ('middle_left', 'rear_left'),
    ('front_right', 'middle_right'), ('middle_right', 'rear_right'),
    ('front_left', 'front_right'), ('rear_left', 'rear_right')))
PAPER_CASE = ('remove:middle_right', (2.0, 2.0), 0)
#: The toy's figures with the paper's rules, noise 0.01 m (docs/toy_results.md): SELA home in
#: every one of 50 replicates, a median of 29 task steps.
TOY_HOME, TOY_MEDIAN_STEPS = 50, 29
#: The targets a design of learning is judged by (docs/learning_the_damage.md).
RATIO, HOME, TWO_LEGS_HOME, NEIGHBOURS_HOME, PAIR_RATIO, FALLS_SHARE = \
    1.40, 0.98, 0.90, 0.80, 2.5, 0.60
DEVIATIONS_HOME, DEVIATIONS_RATIO = 0.95, 1.5


def removed_legs(damage):
    """The legs ``damage`` removes (a frozenset of names)."""
    return frozenset(p.split(':')[1] for p in damage.split(',') if p.startswith('remove:'))


def pair_labels(library):
    """The cases of the 15 pairs of removed legs, as :func:`compare_priors.library_cases`
    names them."""
    return [c[0] for c in compare_priors.library_cases(library)
            if len(removed_legs(c[1])) == 2 and c[1].count(',') == 1]


def read_runs(paths):
    runs = []
    for path in paths:
        if path and os.path.exists(path):
            with open(path) as handle:
                runs += [json.loads(line) for line in handle if line.strip()]
    return runs


def oracle_of(runs):
    """``{(canonical damage, goal): the oracle's median steps}``, a whole table's before
    one told only some gaits, then the campaigns' in docs/results (as compare_priors)."""
    return {**compare_priors.measured_oracle(runs, whole=False),
            **compare_priors.oracle_medians(),
            **compare_priors.measured_oracle(runs, whole=True)}


def case_ratios(runs, oracle, method):
    """``{case: the median over its goals of (median steps / the oracle's)}`` of
    ``method``'s runs (compare_priors' cells: the median of these is "the median of the
    cells' ratios")."""
    return {row['case']: row['median_ratio']
            for row in compare_priors.summarise(runs, oracle, [method])
            if row['median_ratio'] is not None}


def share(runs):
    return sum(r['success'] for r in runs) / len(runs) if runs else None


def paired_falls(runs, baseline, method):
    """Falls of ``method`` and of :data:`BASELINE_METHOD` on the runs both made (same
    case, goal and seed): ``(falls, baseline's falls, runs paired)``."""
    base = {(r['case'], tuple(r['goal']), r['seed']): r['falls'] for r in baseline
            if r['method'] == BASELINE_METHOD}
    mine = [r for r in runs if r['method'] == method
            and (r['case'], tuple(r['goal']), r['seed']) in base]
    return (sum(r['falls'] for r in mine),
            sum(base[(r['case'], tuple(r['goal']), r['seed'])] for r in mine), len(mine))


class Target:
    """One line of the targets' table."""

    def __init__(self, what, goal, measured, met):
        self.what, self.goal, self.measured, self.met = what, goal, measured, met

    def row(self):
        met = '-' if self.met is None else ('met' if self.met else 'not met')
        return f'| {self.what} | {self.goal} | {self.measured} | {met} |'


def _pct(x):
    return '-' if x is None else f'{100 * x:.1f} %'


def targets(parts, oracle, baseline, method, toy=None, library_labels=None):
    """The targets against ``parts`` (``{part: its runs}``; of the library part, only
    the cases ``library_labels`` where given): a list of :class:`Target`."""
    out = []
    lib = [r for r in parts.get('library', []) if r['method'] == method
           and (library_labels is None or r['case'] in library_labels)]
    if lib:
        ratios = list(case_ratios(lib, oracle, method).values())
        median = statistics.median(ratios) if ratios else None
        out.append(Target(f'{len({r["case"] for r in lib})} damages foreseen by no table: '
                          "median of the cells' ratios to the oracle", f'<= {RATIO:.2f}x',
                          f'{median:.2f}x' if median else '-',
                          None if median is None else median <= RATIO))
        home = share(lib)
        out.append(Target('the same: runs home', f'>= {_pct(HOME)}',
                          f"{sum(r['success'] for r in lib)}/{len(lib)} ({_pct(home)})",
                          home >= HOME))
        two = [r for r in lib if len(removed_legs(r['damage'])) == 2
               and r['damage'].count(',') == 1]
        if two:
            out.append(Target('two legs removed (the 15 pairs), 60 steps: home',
                              f'>= {_pct(TWO_LEGS_HOME)}',
                              f"{sum(r['success'] for r in two)}/{len(two)} "
                              f'({_pct(share(two))})', share(two) >= TWO_LEGS_HOME))
            near = [r for r in two if removed_legs(r['damage']) in NEIGHBOURS]
            out.append(Target('the six neighbouring pairs, 60 steps: home',
                              f'>= {_pct(NEIGHBOURS_HOME)}',
                              f"{sum(r['success'] for r in near)}/{len(near)} "
                              f'({_pct(share(near))})', share(near) >= NEIGHBOURS_HOME))
        falls, base, paired = paired_falls(lib, baseline, method)
        if paired:
            out.append(Target("falls, against today's default's on the same runs",
                              f'<= {_pct(FALLS_SHARE)}',
                              f'{falls} against {base} on {paired} runs '
                              f'({_pct(falls / base if base else None)})',
                              falls <= FALLS_SHARE * base))
    pairs = [r for r in parts.get('pairs', []) if r['method'] == method]
    if pairs:
        per = case_ratios(pairs, oracle, method)
        within = sum(v <= PAIR_RATIO for v in per.values())
        worst = max(per, key=per.get) if per else None
        out.append(Target('each of the 15 pairs, 150 steps: median ratio to the oracle',
                          f'<= {PAIR_RATIO}x each',
                          f'{within} of {len(per)} within; median '
                          f'{statistics.median(per.values()):.2f}x, worst {per[worst]:.2f}x '
                          f'({worst.split("/")[0]}); {sum(r["success"] for r in pairs)}/'
                          f'{len(pairs)} home' if per else '-',
                          bool(per) and within == len(per)))
    dev = [r for r in parts.get('deviations', []) if r['method'] == method]
    if dev:
        ratios = list(case_ratios(dev, oracle, method).values())
        out.append(Target('deviations nothing foresaw (friction, payload): home',
                          f'>= {_pct(DEVIATIONS_HOME)}',
                          f"{sum(r['success'] for r in dev)}/{len(dev)} "
                          f'({_pct(share(dev))})', share(dev) >= DEVIATIONS_HOME))
        if ratios:
            median = statistics.median(ratios)
            out.append(Target("the same: median of the cells' ratios (oracles told 600 "
                              'gaits)', f'<= {DEVIATIONS_RATIO}x', f'{median:.2f}x',
                              median <= DEVIATIONS_RATIO))
    seen = [r for r in parts.get('foreseen', []) if r['method'] == method]
    if seen:
        ratios = list(case_ratios(seen, oracle, method).values())
        if ratios:
            median = statistics.median(ratios)
            out.append(Target("foreseen damages: median of the cells' ratios", '1.00x',
                              f'{median:.2f}x', median <= 1.0 + 1e-9))
        paper = [r for r in seen if (r['damage'], tuple(r['goal']), r['seed']) == PAPER_CASE]
        if paper:
            out.append(Target("the paper's case (middle right leg, goal (2, 2), seed 0)",
                              '6 steps', f"{paper[0]['steps']} steps",
                              paper[0]['success'] and paper[0]['steps'] <= 6))
    if toy:
        sela = toy.get('methods', {}).get('sela')
        if sela:
            home = sum(sela['success'])
            steps = statistics.median(sela['steps'])
            out.append(Target('the toy (50 replicates, noise 0.01 m)',
                              f'{TOY_HOME}/50 home, median {TOY_MEDIAN_STEPS} steps',
                              f'{home}/{len(sela["success"])} home, median {steps:g} steps',
                              home >= TOY_HOME and steps <= TOY_MEDIAN_STEPS))
    return out


class _Progress(io.TextIOBase):
    """Passes compare_priors' progress lines on and keeps its tables back."""

    def __init__(self, stream):
        self.stream, self.buffer = stream, ''

    def write(self, text):
        self.buffer += text
        *lines, self.buffer = self.buffer.split('\n')
        for line in lines:
            if line.startswith('[') or 'runs to do' in line or 'left out' in line:
                self.stream.write(line + '\n')
                self.stream.flush()
        return len(text)


def run_part(argv, markdown):
    """compare_priors.main(argv), its progress shown, its tables written to ``markdown``."""
    with contextlib.redirect_stdout(_Progress(sys.stdout)):
        compare_priors.main(argv + ['--markdown', str(markdown)])


def part_cases(part, library):
    if part == 'pairs':
        return ';'.join(pair_labels(library))
    return part


def missing_oracles(part, args, oracle):
    """The case labels of ``part`` with a goal whose oracle no kept run holds."""
    from sim_bridge.damage import parse_damage

    if part == 'library':
        cases = compare_priors.library_cases(args.library)
    elif part == 'pairs':
        wanted = set(pair_labels(args.library))
        cases = [c for c in compare_priors.library_cases(args.library) if c[0] in wanted]
    elif part == 'deviations':
        cases = compare_priors.DEVIATIONS
    else:
        cases = compare_priors.FORESEEN
    goals = [tuple(float(v) for v in g.split(',')) for g in args.goals.split()]
    return [c[0] for c in cases
            if any((parse_damage(c[1]).canonical(), g) not in oracle for g in goals)]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--method', default='caution',
                        help="a method of compare_priors.py (default %(default)s: the node's "
                             'defaults)')
    parser.add_argument('--parts', default=','.join(PARTS),
                        help=f"comma-separated, of {', '.join(PARTS)} (default all)")
    parser.add_argument('--seeds', type=int, default=20,
                        help='seeds of the 102 damages (default %(default)s)')
    parser.add_argument('--pair-seeds', type=int, default=2,
                        help='seeds of the pairs with 150 steps (default %(default)s)')
    parser.add_argument('--check-seeds', type=int, default=3,
                        help='seeds of the deviations and the foreseen damages (default '
                             '%(default)s)')
    parser.add_argument('--goals', default=GOALS, help='goals X,Y separated by spaces')
    parser.add_argument('--library', default=LIBRARY,
                        help='the damage library whose conditions are the 102 damages')
    parser.add_argument('--dir', default=None,
                        help='where the runs and the summary go (default '
                             'results/learning_eval/<method>)')
    parser.add_argument('--oracle-runs', default=','.join(ORACLE_RUNS),
                        help="kept runs the oracle's medians come from (comma-separated)")
    parser.add_argument('--baseline', default=BASELINE,
                        help=f"runs of today's default ({BASELINE_METHOD}) the falls are set "
                             'against')
    parser.add_argument('--workers', type=int, default=1, help='runs at once')
    parser.add_argument('--report-only', action='store_true', help='run nothing')
    args = parser.parse_args(argv)
    parts = [p for p in args.parts.split(',') if p]
    unknown = set(parts) - set(PARTS)
    if unknown:
        parser.error(f'unknown parts {sorted(unknown)}; expected some of {PARTS}')
    if args.method not in compare_priors.METHODS or args.method in compare_priors.ORACLE_METHODS:
        parser.error(f'unknown method {args.method!r}; expected one of '
                     f'{sorted(set(compare_priors.METHODS) - set(compare_priors.ORACLE_METHODS))}')
    out = Path(args.dir or ROOT / 'results' / 'learning_eval' / args.method)
    out.mkdir(parents=True, exist_ok=True)
    kept = read_runs([p for p in args.oracle_runs.split(',') if p])
    seeds = {'library': args.seeds, 'pairs': args.pair_seeds,
             'deviations': args.check_seeds, 'foreseen': args.check_seeds}
    steps = {'pairs': 150}
    for part in parts:
        if part == 'toy':
            if not args.report_only:
                print('toy: 50 replicates', flush=True)
                from sela_ros.experiments.cli import main as experiment
                with contextlib.redirect_stdout(_Progress(sys.stdout)):
                    experiment(['toy', '--replicates', '50', '--seed', '0', '--noise-std',
                                '0.01', '--methods', 'sela', '--out', str(out / 'toy'),
                                '--workers', str(args.workers)])
            continue
        common = ['--goals', args.goals, '--library', args.library,
                  '--max-steps', str(steps.get(part, 60)), '--workers', str(args.workers)]
        oracle = oracle_of(kept + read_runs([out / f'{part}.jsonl']))
        missing = missing_oracles(part, args, oracle)
        if missing and not args.report_only:
            print(f'{part}: the oracle on {len(missing)} cases no kept run holds', flush=True)
            run_part(['--cases', ';'.join(missing), '--methods', 'oracle', '--seeds', '2',
                      '--out', str(out / f'{part}.jsonl')] + common, out / f'{part}_oracle.md')
        print(f'{part}: {args.method}, {seeds[part]} seed(s)', flush=True)
        run_part(['--cases', part_cases(part, args.library), '--methods', args.method,
                  '--seeds', str(seeds[part]), '--out', str(out / f'{part}.jsonl')]
                 + common + (['--report-only'] if args.report_only else []),
                 out / f'{part}.md')
    # The summary holds every part run in ``out`` so far, whichever were asked this time.
    runs = {p: read_runs([out / f'{p}.jsonl']) for p in PARTS if p != 'toy'}
    labels = {c[0] for c in compare_priors.library_cases(args.library)}
    runs['library'] = [r for r in runs['library'] if r['case'] in labels]
    oracle = oracle_of(kept + [r for rs in runs.values() for r in rs])
    toy = None
    if (out / 'toy' / 'results.json').exists():
        toy = json.loads((out / 'toy' / 'results.json').read_text())
    baseline = [r for r in read_runs([args.baseline]) if r['seed'] < args.seeds]
    lines = [f'# {args.method}: the evaluation of learning a damage no table foresaw', '',
             '| target | goal | measured | |', '|---|---|---|---|']
    table = [t.row() for t in targets(runs, oracle, baseline, args.method, toy, labels)]
    lines += table
    for part in PARTS:
        if part != 'toy' and (out / f'{part}.md').exists():
            lines += ['', f'## {part}', '', (out / f'{part}.md').read_text()]
    if runs.get('library'):
        shown = [args.method] + ([BASELINE_METHOD] if baseline and
                                 args.method != BASELINE_METHOD else [])
        cases = {r['case'] for r in runs['library']}
        library_runs = runs['library'] + [r for r in baseline if r['method'] in shown[1:]
                                          and r['case'] in cases]
        compare_priors.figure(library_runs, oracle, shown, out / 'library.png')
        lines += ['', '![every damage\'s ratios to the oracle](library.png)']
    (out / 'summary.md').write_text('\n'.join(lines) + '\n')
    print('\n'.join(lines[:4 + len(table)]))
    print(f'\nthe runs, tables and figure: {out}')


if __name__ == '__main__':
    main()
