"""Where a mission's steps go: each step of SELA's runs put in one class, against the oracle.

Reads the runs of ``scripts/compare_priors.py --trace`` (JSON lines, each SELA run with its
steps' records) and the ``summary.json`` of DDS missions (``sela-demo``: ``steps_detail``),
and classes every step by what it did for the robot, from its record (the pose before it,
the waypoint, the predicted and observed generic rewards, whether it fell):

* ``fell``: the step ended on the ground (the robot got up where it lay);
* ``untried, disappointed``: a gait run for the first time in the mission that landed more
  than ``--miss`` metres from its prediction;
* ``proven, disappointed``: the same for a gait run before in the mission;
* ``turning``: it turned more than ``--turn`` rad and brought the robot less than
  ``--progress`` metres nearer the goal (reorienting);
* ``out of reach``: landed as predicted, but less than ``--progress`` m nearer the goal (no
  gait the model knows moves the robot that way: the waypoint is out of its reach);
* ``progress``: the rest, steps that brought the robot nearer the goal as predicted.

The table gives, per group (kind of damage) and method, the steps taken, the oracle's
(median per damage and goal, as ``compare_priors.py`` reports it) and how many steps of
each class the runs made; ``steps beyond the oracle's`` is their difference::

    .venv/bin/python scripts/step_budget.py docs/results/learning/trace.jsonl \\
        --markdown docs/step_budget.md
    .venv/bin/python scripts/step_budget.py out/demo/summary.json
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CLASSES = ('progress', 'fell', 'untried, disappointed', 'proven, disappointed', 'turning',
           'out of reach')


def _after(pose, gr):
    """The pose a generic reward ``(dx, dy, dyaw)`` leads to from ``pose`` (x, y, yaw)."""
    x, y, yaw = pose[:3]
    c, s = math.cos(yaw), math.sin(yaw)
    return (x + c * gr[0] - s * gr[1], y + s * gr[0] + c * gr[1], yaw + gr[2])


def _vector(value):
    """A record's vector: a list (runs) or the text a DDS status carries ("x y yaw")."""
    return [float(v) for v in (value.split() if isinstance(value, str) else value)]


def classify(steps, goal, miss=0.15, turn=0.35, progress=0.05):
    """The class (:data:`CLASSES`) of each step of a mission whose records are ``steps``
    (dicts of ``StepRecord`` fields) towards ``goal`` (x, y)."""
    seen = set()
    out = []
    for step in steps:
        pose = _vector(step['pose'])
        observed = _vector(step['observed_gr'])
        predicted = _vector(step['predicted_gr'])
        index = int(step['behavior_index'])
        first = index not in seen
        seen.add(index)
        end = _after(pose, observed)
        gain = math.dist(pose[:2], goal) - math.dist(end[:2], goal)
        error = math.hypot(observed[0] - predicted[0], observed[1] - predicted[1])
        if str(step.get('fallen')) == 'True':
            out.append('fell')
        elif error > miss:
            out.append('untried, disappointed' if first else 'proven, disappointed')
        elif gain < progress and len(observed) > 2 and abs(observed[2]) > turn:
            out.append('turning')
        elif gain < progress:
            out.append('out of reach')
        else:
            out.append('progress')
    return out


def load(paths, seeds=None):
    """Every mission of ``paths``: ``(method, case, damage, goal, steps, success, records)``;
    runs kept without their steps' records, or (``seeds``) of other seeds, are skipped."""
    missions = []
    for path in paths:
        text = Path(path).read_text()
        if path.endswith('.json'):
            doc = json.loads(text)
            missions.append(('DDS mission', doc.get('damage', ''), doc.get('damage', ''),
                             tuple(doc['goal']), doc['steps'], doc['success'],
                             doc['steps_detail']))
            continue
        for line in text.splitlines():
            if line.strip():
                r = json.loads(line)
                if 'steps_detail' in r and (seeds is None or r['seed'] in seeds):
                    missions.append((r['method'], r['case'], r['damage'], tuple(r['goal']),
                                     r['steps'], r['success'], r['steps_detail']))
    return missions


def budget_table(missions, oracle, group, **thresholds):
    """Markdown rows per (group, method): runs, home, steps, the oracle's, and steps per
    class."""
    from sim_bridge.damage import parse_damage

    rows = {}
    for method, _case, damage, goal, steps, success, records in missions:
        key = (group(damage), method)
        row = rows.setdefault(key, {'runs': 0, 'home': 0, 'steps': 0, 'oracle': 0.0,
                                    'timed': 0, 'timed_steps': 0,
                                    **{c: 0 for c in CLASSES}})
        row['runs'] += 1
        row['home'] += bool(success)
        row['steps'] += steps
        o = oracle.get((parse_damage(damage).canonical(), tuple(float(v) for v in goal)))
        if o:
            row['timed'] += 1
            row['oracle'] += o
            row['timed_steps'] += steps
        for c in classify(records, goal, **thresholds):
            row[c] += 1
    lines = ['| group | method | runs | home | steps | oracle\'s steps (runs with one) '
             '| steps beyond the oracle\'s | ' + ' | '.join(CLASSES) + ' |',
             '|' + '---|' * (7 + len(CLASSES))]
    for (g, method), r in sorted(rows.items()):
        beyond = f"{r['timed_steps'] - r['oracle']:.0f}" if r['timed'] else '-'
        lines.append(f"| {g} | {method} | {r['runs']} | {r['home']} | {r['steps']} "
                     f"| {r['oracle']:.0f} ({r['timed']}) | {beyond} | "
                     + ' | '.join(str(r[c]) for c in CLASSES) + ' |')
    return '\n'.join(lines)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('paths', nargs='+', help='runs (.jsonl, compare_priors.py --trace) '
                        'or DDS missions (summary.json)')
    parser.add_argument('--miss', type=float, default=0.15,
                        help='m off its prediction that makes a gait disappoint')
    parser.add_argument('--turn', type=float, default=0.35, help='rad of a turning step')
    parser.add_argument('--progress', type=float, default=0.05,
                        help='m nearer the goal that a step must bring the robot')
    parser.add_argument('--seeds', default=None,
                        help='only the runs of these seeds (comma-separated; default all)')
    parser.add_argument('--markdown', default=None, help='write the table here')
    args = parser.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    sys.path.insert(0, str(ROOT / 'scripts'))
    import compare_priors

    missions = load(args.paths, None if args.seeds is None
                    else {int(v) for v in args.seeds.split(',')})
    if not missions:
        parser.error('no run with its steps\' records (compare_priors.py --trace, or a '
                     'summary.json)')
    done = []
    for path in args.paths:
        if path.endswith('.jsonl'):
            done += [json.loads(line) for line in Path(path).read_text().splitlines()
                     if line.strip()]
    oracle = {**compare_priors.measured_oracle(done, whole=False),
              **compare_priors.oracle_medians(),
              **compare_priors.measured_oracle(done, whole=True)}
    text = budget_table(missions, oracle, compare_priors.kind_of, miss=args.miss,
                        turn=args.turn, progress=args.progress)
    print(text)
    if args.markdown:
        Path(args.markdown).write_text(text + '\n')


if __name__ == '__main__':
    main()
