"""``sela-experiment campaign``: the hexapod experiment over many damages, goals and maps.

One command regenerates the damage-recovery tables::

    sela-experiment campaign --replicates 20 --workers 2 --out docs/results/campaign \\
        --archive sela_ros/data/hexapod_archive.npz --archive OTHER.npz \\
        --damages 'single-legs;two-legs;shorten:front_left:0.5;block:rear_right.knee=0.3' \\
        --goals 2,2 -2,1.5 1.5,-2

Every (archive, damage, goal) cell is one run of :mod:`sela_ros.experiments.hexapod` (SELA,
the IT&E baselines and the oracle, whose table is cached per damage), written to
``OUT/<archive>/<damage>/<goal>/results.json`` as soon as it is done. A cell whose results
are already there is not run again, so a campaign interrupted (or spread over several
sessions) resumes where it stopped. At the end ``OUT/campaign.md`` holds a table per damage
(success, median steps, ratio to the oracle's median on the same map, falls per run) and
``OUT/figure.png`` SELA's steps per damage and map.
"""
from __future__ import annotations

import argparse
import copy
import functools
import json
import os
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from sela_ros.core.learning import SELAConfig
from sela_ros.core.planning import DEFAULT_INFLATION, PlanningError
from sela_ros.core.storage import atomic_write_bytes
from sela_ros.experiments import arguments, hexapod, workers

LEGS = ('front_left', 'middle_left', 'rear_left', 'front_right', 'middle_right', 'rear_right')
GROUPS = {
    'single-legs': [f'remove:{leg}' for leg in LEGS],
    'two-legs': ['remove:front_left,remove:rear_right', 'remove:middle_left,remove:middle_right'],
}
DEFAULT_DAMAGES = 'single-legs'
DEFAULT_GOALS = ('2,2', '-2,1.5', '1.5,-2')


def damage_list(text):
    """Damages separated by ``;``: groups (``single-legs``, ``two-legs``) or specs of the
    damage grammar, where a comma joins damages into one (``remove:front_left,remove:rear_right``
    is ONE two-leg damage). Each is parsed in the names of each archive's robot by
    :func:`finish_arguments`."""
    out = []
    for item in [t.strip() for t in text.split(';') if t.strip()]:
        out.extend(GROUPS.get(item, [item]))
    if not out:
        raise argparse.ArgumentTypeError(f'no damage in {text!r}')
    return out


def finish_arguments(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """After parsing, before any cell runs: every damage in the names of every archive's
    robot (``args.damages`` becomes their canonical forms), every goal on the planner's
    map, and the oracle's cache."""
    from sim_bridge.damage import DamageSpecError
    from sim_bridge.robots import get_robot, robot_of

    canonical = None
    for archive in args.archive or [args.default_archive]:
        robot = robot_of(_load_archive(os.path.abspath(archive)).metadata)
        try:
            description = get_robot(robot)
        except ValueError as err:
            parser.error(f'--archive {archive}: {err}')
        damages = []
        for damage in args.damages:
            try:
                damages.append(description.parse_damage(damage).canonical())
            except DamageSpecError as err:
                parser.error(f'--damages: {damage!r} on {Path(archive).name}, a map of the '
                             f'{description.name}: {err}')
        canonical = canonical or damages
    args.damages = canonical
    for goal in args.goals:  # each cell walks from the start to one goal
        try:
            hexapod.check_goals([goal], None, DEFAULT_INFLATION,
                                hint='every cell runs on that map: give goals on it')
        except PlanningError as err:
            parser.error(f'--goals: {err}')
    hexapod.check_oracle_cache(parser, args)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from sela_ros.core.storage import default_archive_path

    parser.add_argument('--archive', action='append', type=hexapod.archive_argument, default=None,
                        help='a map to compare (repeat for several; default: the shipped one)')
    parser.add_argument('--damages', type=damage_list, default=damage_list(DEFAULT_DAMAGES),
                        help="';'-separated damage specs in the names of each archive's robot, "
                             f"or the hexapod's groups: {', '.join(GROUPS)} (default "
                             f'{DEFAULT_DAMAGES})')
    parser.add_argument('--goals', type=arguments.goal, nargs='+',
                        default=[arguments.goal(g) for g in DEFAULT_GOALS],
                        help=f'goals X,Y (default: {" ".join(DEFAULT_GOALS)})')
    parser.add_argument('--methods', type=arguments.method_list,
                        default=list(hexapod.HEXAPOD_METHODS),
                        help='comma-separated methods (default: %(default)s)')
    parser.add_argument('--noise-std', type=arguments.noise_std,
                        default=arguments.DEFAULT_NOISE_STD, help=arguments.NOISE_HELP)
    parser.add_argument('--lookahead', type=arguments.positive_float,
                        default=hexapod.DEFAULT_LOOKAHEAD, help='waypoint distance (m)')
    parser.add_argument('--fall-risk', type=arguments.positive_float, default=None,
                        help='fall.risk.threshold of SELA (default: its default)')
    parser.add_argument('--kernel-sigma', type=arguments.kernel_sigma, default=None,
                        help="gp.kernel.sigma on normalised descriptors (default: each "
                             "archive's: 0.1 for the 2-D map, 0.3 for the 8-D map)")
    parser.add_argument('--fall-cost', type=arguments.non_negative_float, default=None,
                        help="fall.risk.cost of SELA (default: its default)")
    parser.add_argument('--fall-kernel-sigma', type=arguments.kernel_sigma, default=None,
                        help="fall.kernel.sigma: kernel length of the fall GP (default: the "
                             "archive's: 0.1 on a 2-D map, 0.12 on the 8-D map)")
    parser.add_argument('--alpha', type=arguments.non_negative_float,
                        default=SELAConfig().acquisition_ucb_alpha,
                        help="acquisition.ucb.alpha of SELA (default %(default)s, the paper's)")
    hexapod.add_priors_arguments(parser)
    parser.add_argument('--max-steps', type=arguments.positive_int, default=100)
    parser.add_argument('--oracle-cache', default=None,
                        help='directory of cached oracle tables')
    parser.set_defaults(default_archive=str(default_archive_path()))


def progress_total(args) -> int:
    return len(args.archive or [args.default_archive]) * len(args.damages) * len(args.goals)


def _slug(text) -> str:
    return ''.join(c if c.isalnum() or c in '.-' else '_' for c in str(text))


def cell_dir(out, archive, damage, goal) -> Path:
    goal_text = f'{goal[0]:g},{goal[1]:g}'
    return Path(out) / _slug(Path(archive).stem) / _slug(damage) / _slug(goal_text)


#: What a parameter missing from a cell's results.json was: the cells from before it existed
#: ran one step ahead. (Other parameters missing are not compared.)
ABSENT_MEANS = {'planner.horizon': 1.0}
#: Parameters only SELA uses (the baselines run one step ahead over the intact map).
SELA_ONLY = ('planner.horizon', 'priors.max.misfit', 'priors.max.misfit.reproduced')


class CellMismatch(ValueError):
    """A cell already in ``--out`` was run with other parameters than those asked."""


#: What ``sela-experiment`` reports as a usage error (exit 2) instead of a traceback.
ARGUMENT_ERRORS = (CellMismatch, *hexapod.ARGUMENT_ERRORS)


def _expected_parameters(archive_path, args) -> dict:
    from sim_bridge.experiment_env import archive_checksum

    archive = _load_archive(archive_path)
    config = hexapod.sela_config(archive, args.lookahead,
                                 kernel_sigma=args.kernel_sigma, alpha=args.alpha,
                                 fall_risk=args.fall_risk,
                                 fall_kernel_sigma=args.fall_kernel_sigma,
                                 horizon=args.horizon,
                                 fall_cost=args.fall_cost).to_dict()
    expected = {k: config[k] for k in hexapod.RECORDED_SELA_PARAMETERS}
    expected.update(noise_std=args.noise_std, max_steps=args.max_steps,
                    lookahead=args.lookahead, archive_checksum=archive_checksum(archive.params))
    return expected


@functools.lru_cache(maxsize=4)
def _load_archive(path):
    from sela_ros.core.storage import load_archive

    return load_archive(path)


@functools.lru_cache(maxsize=4)
def _load_priors(value, archive_path):
    return workers.load_priors(value, archive_path, _load_archive(archive_path))


def _priors_names(archive_path, args, damage):
    """The damage priors a cell's SELA runs with (None: none), as results.json records
    (the file is read once per archive, not once per cell)."""
    priors = _load_priors(args.priors, archive_path)
    if priors is not None and args.priors_leave_out_own:
        priors = priors.without(damage)
    return None if priors is None else list(priors.names)


def _check_cell(path, done, args, expected, priors) -> None:
    """Refuse to read back (or add methods to) a cell run with other parameters (a cell
    from before damage priors existed ran without them)."""
    have = dict(ABSENT_MEANS, **done.get('parameters', {}), replicates=done.get('replicates'),
                seed=done.get('seed'))
    wanted = dict(expected, replicates=args.replicates, seed=args.seed)
    sela = 'sela' in done.get('methods', {}) or 'sela' in args.methods
    if not sela:  # what only SELA uses does not matter to the other methods' cells
        wanted = {k: v for k, v in wanted.items() if k not in SELA_ONLY}
    differ = [f'{k} {have[k]!r} (asked {v!r})' for k, v in wanted.items()
              if have.get(k) is not None and have[k] != v]
    if sela and have.get('damage_priors') != priors:
        differ.append(f'damage priors {have.get("damage_priors")} (asked {priors})')
    if differ:
        raise CellMismatch(f'{path} was run with {", ".join(differ)}; use another --out '
                           'for other parameters, or remove that cell to run it again')


def _merge_cell(done: dict, new: dict) -> dict:
    """A cell's results with the methods of ``new`` added to those ``done`` had (the
    parameters of both were checked alike by :func:`_check_cell`)."""
    merged = copy.deepcopy(done)
    merged['methods'].update(new['methods'])
    merged.setdefault('summary', {}).update(new.get('summary', {}))
    merged.setdefault('timing', {}).setdefault('methods', {}).update(
        new.get('timing', {}).get('methods', {}))
    if 'oracle' in new['methods']:
        merged['parameters']['oracle_gaits_that_fall'] = \
            new['parameters']['oracle_gaits_that_fall']
        merged['timing']['oracle_table_seconds'] = new['timing']['oracle_table_seconds']
    return merged


def run(args, progress=None) -> dict:
    archives = [os.path.abspath(a) for a in (args.archive or [args.default_archive])]
    cells = []
    expected = {}  # per archive: the parameters its cells must have been run with
    for archive in archives:
        for damage in args.damages:
            for goal in args.goals:
                where = cell_dir(args.out, archive, damage, goal)
                path = where / 'results.json'
                done = json.loads(path.read_text()) if path.exists() else None
                if done:
                    if archive not in expected:  # loads the archive: once per archive
                        expected[archive] = _expected_parameters(archive, args)
                    _check_cell(path, done, args, expected[archive],
                                _priors_names(archive, args, damage))
                have = list(done['methods']) if done else []
                missing = [m for m in args.methods if m not in have]
                if missing:
                    cell_args = SimpleNamespace(
                        archive=archive, damage=damage, goal=goal, noise_std=args.noise_std,
                        lookahead=args.lookahead,
                        kernel_sigma=args.kernel_sigma,
                        fall_kernel_sigma=args.fall_kernel_sigma, fall_cost=args.fall_cost,
                        alpha=args.alpha, priors=args.priors, horizon=args.horizon,
                        priors_leave_out_own=args.priors_leave_out_own,
                        fall_risk=args.fall_risk or SELAConfig().fall_risk_threshold,
                        methods=missing, method_slots=have + missing,
                        max_steps=args.max_steps,
                        ite_iterations=hexapod.ITE_MAX_ITERATIONS,
                        oracle_cache=args.oracle_cache, replicates=args.replicates,
                        seed=args.seed, workers=args.workers)
                    doc = hexapod.run(cell_args)
                    if done:  # keep what the cell had; its new methods join it
                        doc = _merge_cell(done, doc)
                    atomic_write_bytes(path, json.dumps(doc, indent=1).encode())
                else:
                    doc = done
                cells.append({'archive': Path(archive).stem, 'damage': damage,
                              'goal': list(goal), 'methods': doc['methods'],
                              'replicates': doc['replicates']})
                if progress:
                    progress()
    table = summarise(cells)
    doc = {'scenario': 'campaign', 'replicates': args.replicates, 'seed': args.seed,
           'cells': cells, 'table': table}
    Path(args.out, 'campaign.md').write_text(markdown(table, args))
    return doc


def summarise(cells) -> list:
    """One row per (damage, archive, method): pooled over goals, plus per-goal medians."""
    rows = []
    key = {}
    for cell in cells:
        oracle = cell['methods'].get('oracle')
        oracle_median = float(np.median(oracle['steps'])) if oracle else None
        for name, m in cell['methods'].items():
            k = (cell['damage'], cell['archive'], name)
            if k not in key:
                key[k] = {'damage': k[0], 'archive': k[1], 'method': name, 'runs': 0,
                          'successes': 0, 'steps': [], 'falls': [], 'ratios': []}
                rows.append(key[k])
            row = key[k]
            row['runs'] += len(m['success'])
            row['successes'] += int(sum(m['success']))
            row['steps'].extend(int(s) + int(li) for s, li in
                                zip(m['steps'], m['learning_iterations']))
            row['falls'].extend(int(f) for f in m['falls'])
            if oracle_median:
                median = float(np.median(np.add(m['steps'], m['learning_iterations'])))
                row['ratios'].append(median / oracle_median)
    for row in rows:
        row['median_steps'] = float(np.median(row['steps']))
        row['median_falls'] = float(np.median(row['falls']))
        row['worst_goal_ratio'] = max(row['ratios']) if row['ratios'] else None
    return rows


def markdown(table, args) -> str:
    goals = ' '.join(f'({g[0]:g}, {g[1]:g})' for g in args.goals)
    lines = [f'# Damage recovery campaign: {args.replicates} replicates per goal, goals {goals}',
             '', 'Steps include IT&E learning trials. "worst ratio": the largest, over the '
             "goals, of the method's median steps over the oracle's median on the same map. "
             'Falls: per run (the robot is righted where it lies).', '']
    for damage in dict.fromkeys(r['damage'] for r in table):
        lines += [f'## {damage}', '',
                  '| map | method | success | median steps | worst ratio | median falls/run '
                  '| falls (all runs) |', '|---|---|---|---|---|---|---|']
        for r in (r for r in table if r['damage'] == damage):
            ratio = '-' if r['worst_goal_ratio'] is None else f'{r["worst_goal_ratio"]:.2f}x'
            lines.append(f'| {r["archive"]} | {r["method"]} | {r["successes"]}/{r["runs"]} | '
                         f'{r["median_steps"]:g} | {ratio} | {r["median_falls"]:g} | '
                         f'{sum(r["falls"])} |')
        lines.append('')
    return '\n'.join(lines)


def plot(doc, path) -> None:
    """SELA's and the oracle's steps per damage, one box per map."""
    from sela_ros.experiments.figures import plt

    rows = [r for r in doc['table'] if r['method'] in ('sela', 'oracle')]
    labels = [f'{r["damage"].replace("remove:", "-")}\n{r["archive"]}\n{r["method"]}'
              for r in rows]
    fig, ax = plt.subplots(figsize=(max(6.4, 0.55 * len(rows)), 4.2), dpi=100)
    ax.boxplot([r['steps'] for r in rows], widths=0.6, flierprops={'markersize': 3})
    ax.set_xticks(np.arange(1, len(rows) + 1))
    ax.set_xticklabels(labels, fontsize=6, rotation=90)
    ax.set_ylabel('steps to the goal')
    ax.grid(axis='y', alpha=0.3)
    ax.set_title(f'campaign: {doc["replicates"]} replicates per goal', fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
