#!/usr/bin/env python3
"""Build a library of damage priors that spans the damage space, resumably, in bounded time.

The shipped damage priors (``make priors``) are six single-leg removals, every gait of the
map each. This library covers the kinds a robot meets (legs removed, alone and in pairs;
legs shortened at several lengths; joints blocked at several angles; motors gone limp), each
condition evaluated on a subset of the map's gaits: 2,000 chosen to cover its behaviour
space (farthest-point sampling over the normalised descriptors), then the gaits that take
the intact robot farthest, which are the ones SELA picks most (a mission wants long steps
toward its waypoint: docs/priors_combination.md); the other gaits inferred by a GP over the
same descriptors (prior mean: the intact map; what is learnt: each condition's deviation
from it, and its falls). The single legs removed are not built: their whole tables ship
beside the map (``make priors``) and the library takes them from there. The result is a
damage-priors file (``DamagePriors``) beside the map, which SELA mixes
(``sela_ros.core.learning.prior_mixture``) or chooses from, as ``priors.tables: library``
(docs/damage_library.md).

    .venv/bin/python scripts/build_library.py --plan              # conditions, cost, size
    nice -n 15 .venv/bin/python scripts/build_library.py --workers 2
    .venv/bin/python scripts/build_library.py --assemble          # -> <map>_library.npz

Resumable after any interruption, on this machine or another: every ``--chunk`` gaits of a
condition are written atomically to ``--out`` (``<condition>/<first gait>.npz``) and a run
skips the chunks already there; the gait subset is a deterministic function of the archive
and ``--gaits``, so another machine with the same archive resumes the same plan (the
default ``--out`` is in the repository: commit it, or copy it across). ``--assemble`` needs
every chunk (``--partial``: what there is), and only reads them.
"""
from __future__ import annotations

import argparse
import itertools
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from sela_ros.core.learning.table_inference import gait_subset, infer  # noqa: E402

LEGS = ('front_left', 'middle_left', 'rear_left', 'front_right', 'middle_right', 'rear_right')
SHORTEN_FACTORS = (0.3, 0.6, 0.8)
BLOCKED = (('knee', -0.4), ('knee', 0.0), ('knee', 0.4), ('hip_pitch', -0.3),
           ('hip_pitch', 0.3))
#: Motors weakened: the hip pitch limp (the motors have torque to spare: at 0.3 of it the
#: fastest gaits move as on the intact robot; docs/hexapod.md).
WEAKENED = (('hip_pitch', 0.0),)
#: One gait from a standing start on one core, seconds: 0.04 measured by this build on a
#: loaded 2-core machine (100-gait chunks in 4-7 s); the plan counts 0.05.
SECONDS_PER_GAIT = 0.05
DEFAULT_GAITS = 4000
#: The first gaits of the subset cover the behaviour space; the rest are the fastest.
COVERING_GAITS = 2000
DEFAULT_CHUNK = 100
BUDGET_CORE_HOURS = 6.0


def conditions():
    """The library's damage conditions (specs of ``sim_bridge.damage``), in build order:
    the kinds a leg loses first (singles), then pairs."""
    out = [f'remove:{leg}' for leg in LEGS]
    out += [f'shorten:{leg}:{f}' for leg in LEGS for f in SHORTEN_FACTORS]
    out += [f'block:{leg}.{joint}={a}' for leg in LEGS for joint, a in BLOCKED]
    out += [f'weaken:{leg}.{joint}={s}' for leg in LEGS for joint, s in WEAKENED]
    out += [f'remove:{a},remove:{b}' for a, b in itertools.combinations(LEGS, 2)]
    # Two legs shortened on one side or across, at the middle length.
    out += [f'shorten:{a}:0.6,shorten:{b}:0.6' for a, b in itertools.combinations(LEGS, 2)]
    return out


def archive_subset(archive, count):
    """The gaits a build evaluates on ``archive``: :func:`gait_subset` with the intact
    robot's distances."""
    gr = archive.generic_reward
    return gait_subset(archive.normalised_descriptors(), count, np.hypot(gr[:, 0], gr[:, 1]),
                       COVERING_GAITS)


def plan(num_gaits, gaits, shipped=()):
    """``(conditions, evaluations, core-hours, MB on disk)`` of a build; the conditions in
    ``shipped`` (whole tables beside the map) cost nothing."""
    names = conditions()
    evaluations = sum(n not in shipped for n in names) * min(gaits, num_gaits)
    hours = evaluations * SECONDS_PER_GAIT / 3600.0
    # The assembled file: float32 (dx, dy, dyaw) and a fall flag per gait and condition,
    # compressed about as the shipped priors (0.85 MB for 6 x 12,442 gaits).
    megabytes = len(names) * num_gaits * 0.85 / (6 * 12442)
    return names, evaluations, hours, megabytes


def _slug(spec):
    return ''.join(c if c.isalnum() or c in '.-' else '_' for c in spec)


def _evaluate(job):
    spec, gaits, params, settings = job
    from sim_bridge.evaluation import evaluate_gait

    gr = np.empty((len(gaits), 3))
    fallen = np.empty(len(gaits), bool)
    for i, p in enumerate(params):
        outcome = evaluate_gait(p, spec, settings['dt'], settings['gait_duration'],
                                settings['solver_iterations'])
        gr[i], fallen[i] = outcome.generic_reward, outcome.fallen
    return spec, gaits, gr, fallen


def build(archive, out, gaits, chunk, workers, only=None, skip=(), specs=None, covering=None):
    """Evaluate every chunk not on disk yet (conditions in ``skip`` not at all: their whole
    table ships); returns how many were evaluated now. ``specs``: these damages instead of
    the library's conditions (for their oracles), on ``gaits`` gaits of which ``covering``
    cover the map and the rest are the fastest (None: the library's split)."""
    from sela_ros.core.storage import atomic_write

    if covering is None:
        subset = archive_subset(archive, gaits)
    else:
        gr = archive.generic_reward
        subset = gait_subset(archive.normalised_descriptors(), gaits,
                             np.hypot(gr[:, 0], gr[:, 1]), covering=covering)
    settings = archive.simulator_settings
    jobs = []
    for spec in (conditions() if specs is None else specs):
        if (only and spec not in only) or spec in skip:
            continue
        for start in range(0, len(subset), chunk):
            path = Path(out) / _slug(spec) / f'{start:06d}.npz'
            if not path.is_file():
                part = subset[start:start + chunk]
                jobs.append((spec, part, archive.params[part], settings))
    print(f'{len(jobs)} chunks to evaluate', flush=True)
    begin = time.perf_counter()

    def save(result, n):
        spec, part, gr, fallen = result
        first = int(np.flatnonzero(subset == part[0])[0])
        atomic_write(Path(out) / _slug(spec) / f'{first:06d}.npz', lambda h: np.savez_compressed(
            h, gaits=part.astype(np.int32), generic_reward=gr.astype(np.float32),
            fallen=fallen, damage=np.array(spec)))
        spent = time.perf_counter() - begin
        print(f'[{n}/{len(jobs)}] {spec} gaits {first}-{first + len(part) - 1} '
              f'({spent:.0f} s, about {spent / n * (len(jobs) - n) / 60:.0f} min left)',
              flush=True)

    if workers <= 1:
        for n, job in enumerate(jobs, 1):
            save(_evaluate(job), n)
    else:
        with ProcessPoolExecutor(max_workers=workers) as pool:
            for n, result in enumerate(pool.map(_evaluate, jobs), 1):
                save(result, n)
    return len(jobs)


def check_inference(archive, shipped, gaits):
    """How well the gaits a build does not evaluate are inferred: each whole shipped table
    inferred from its own gaits of the plan, the error on the others printed against the
    intact map's (rms of dx, dy in m and dyaw in rad; fall flags right)."""
    subset = archive_subset(archive, gaits)
    rest = np.setdiff1d(np.arange(len(archive)), subset)
    descriptors = archive.normalised_descriptors()
    for i, name in enumerate(shipped.names):
        truth, falls = shipped.generic_reward[i], shipped.fallen[i]
        gr, fallen = infer(descriptors, archive.generic_reward, subset, truth[subset],
                           falls[subset], archive.kernel_sigma)
        inferred = np.sqrt(np.mean((gr[rest] - truth[rest]) ** 2, axis=0))
        intact = np.sqrt(np.mean((archive.generic_reward[rest] - truth[rest]) ** 2, axis=0))
        print(f'{name}: {len(rest)} gaits inferred from {len(subset)}: rms error '
              f'{np.array2string(inferred, precision=3)} (intact map '
              f'{np.array2string(intact, precision=3)}), falls right '
              f'{np.mean(fallen[rest] == falls[rest]):.1%}', flush=True)


def _evaluated(out, spec):
    """``(gaits, generic rewards, fallen)`` of every chunk of ``spec`` on disk."""
    data = [np.load(p) for p in sorted((Path(out) / _slug(spec)).glob('*.npz'))]
    if not data:
        return np.zeros(0, int), np.zeros((0, 3)), np.zeros(0, bool)
    return tuple(np.concatenate([d[key] for d in data])
                 for key in ('gaits', 'generic_reward', 'fallen'))


#: Where the outcomes of damages that are no condition of the library are evaluated for
#: their oracles (``--oracle-only``), when the library's checkpoints hold none.
ORACLE_OUT = ROOT / 'mapbuild' / 'oracles'


def known_outcomes(archive, spec, out=None, gaits=DEFAULT_GAITS, shipped=None,
                   cache_dir=None, restrict=False):
    """What is known of ``spec``'s true outcomes, for an oracle: ``(generic_reward (M, 3),
    fallen (M,), known (M,), source)``. A whole table where one is (the map's own damage
    priors, ``shipped``, or an oracle table cached by the experiments), else the gaits the
    library's build evaluated (the checkpoints in ``out``); ``restrict``: a whole table cut
    to the gaits of the build's plan, to measure what an oracle loses with those alone.
    None when nothing is known."""
    from sim_bridge.damage import parse_damage
    from sim_bridge.experiment_env import cached_oracle_table

    m = len(archive)
    canonical = parse_damage(spec).canonical()
    # The second tier ships the library's own tables, partly inferred: no whole table.
    shipped = shipped.first_tier() if shipped is not None else None
    names = [parse_damage(n).canonical() for n in shipped.names] if shipped is not None else []
    if canonical in names:
        i = names.index(canonical)
        whole = shipped.generic_reward[i][:, :3].astype(float), shipped.fallen[i].astype(bool)
        source = 'whole table (shipped)'
    else:
        settings = archive.simulator_settings
        whole = cached_oracle_table(archive.params, spec, cache_dir, settings['dt'],
                                    settings['gait_duration'], settings['solver_iterations'])
        source = 'whole table (oracle cache)'
    if whole is not None and not restrict:
        return whole[0], whole[1], np.ones(m, bool), source
    known = np.zeros(m, bool)
    if whole is not None:
        gr, fallen = whole
        known[archive_subset(archive, gaits)] = True
        source = f'{source} cut to the {int(known.sum())} gaits of the plan'
    else:
        done, done_gr, done_fallen = _evaluated(out or ROOT / 'mapbuild' / 'library', spec)
        if not len(done) and out is None:
            done, done_gr, done_fallen = _evaluated(ORACLE_OUT, spec)
        if not len(done):
            return None
        gr, fallen = np.zeros((m, 3)), np.zeros(m, bool)
        gr[done], fallen[done], known[done] = done_gr, done_fallen, True
        source = f'the {len(done)} gaits the library evaluated'
    return gr, fallen, known, source


def assemble(archive, out, gaits, library, shipped=None, only=None, partial=False):
    """Write the library: every condition's table, the gaits not evaluated inferred and
    flagged so (``DamagePriors.simulated``: SELA trusts a table only where it simulated). A
    condition whose whole table ships (``shipped``, the map's own damage priors) is taken
    from there, chained runs included. ``partial``: conditions with only part of their gaits
    evaluated are inferred from those, conditions with none are left out (both listed)."""
    from sela_ros.core.learning import DamagePriors, params_checksum

    planned = len(archive_subset(archive, gaits))
    descriptors = archive.normalised_descriptors()
    shipped_names = tuple(shipped.names) if shipped is not None else ()
    names, tables, falls, runs, chained_falls, short, missing = [], [], [], [], [], [], []
    simulated = []
    for spec in conditions():
        if only and spec not in only:
            continue
        if spec in shipped_names:
            i = shipped_names.index(spec)
            gr, fallen = shipped.generic_reward[i], shipped.fallen[i]
            chained, runs_of, falls_of = shipped.chained(i)
            row_runs = np.zeros(len(archive), int)
            row_falls = np.zeros(len(archive), int)
            row_runs[chained], row_falls[chained] = runs_of, falls_of
            row_simulated = np.ones(len(archive), bool) if shipped.simulated is None \
                else shipped.simulated[i]
        else:
            done, done_gr, done_fallen = _evaluated(out, spec)
            if len(done) < planned and not partial:
                raise SystemExit(f'{spec}: {len(done)} of {planned} gaits evaluated; resume '
                                 'the build first (or --partial)')
            if not len(done):
                missing.append(spec)
                continue
            if len(done) < planned:
                short.append(f'{spec} ({len(done)})')
            gr, fallen = infer(descriptors, archive.generic_reward, done, done_gr,
                               done_fallen, archive.kernel_sigma)
            row_runs, row_falls = np.zeros(len(archive), int), np.zeros(len(archive), int)
            row_simulated = np.zeros(len(archive), bool)
            row_simulated[done] = True
        names.append(spec)
        tables.append(gr)
        falls.append(fallen)
        runs.append(row_runs)
        chained_falls.append(row_falls)
        simulated.append(row_simulated)
    DamagePriors(tuple(names), np.stack(tables), np.stack(falls),
                 params_checksum(archive.params), np.stack(runs),
                 np.stack(chained_falls), simulated=np.stack(simulated)).save(library)
    print(f'{library}: {len(names)} conditions, {Path(library).stat().st_size / 1e6:.1f} MB')
    if short:
        print(f'  inferred from fewer than {planned} gaits: {", ".join(short)}')
    if missing:
        kinds = {}
        for spec in missing:
            kinds[spec.split(':')[0]] = kinds.get(spec.split(':')[0], 0) + 1
        print(f'  left out, nothing evaluated: {len(missing)} conditions ('
              + ', '.join(f'{n} {kind}' for kind, n in kinds.items()) + ')')


def write_second_tier(path, archive, shipped, specs, library_path, out):
    """Write the map's damage priors (beside it) as its first tier (the whole tables that
    ship) followed by the library's tables of ``specs`` ('library': every one the first tier
    does not hold; 'remove-pairs': those of the 15 pairs of legs removed; or ';'-separated
    conditions),
    flagged as the second tier (``DamagePriors.reproduce_only``), with the gaits each
    simulated (the build's checkpoints in ``out``; the rest were inferred:
    ``DamagePriors.simulated``)."""
    from sela_ros.core.learning import DamagePriors, priors_path
    from sela_ros.core.learning.damage_priors import load_damage_priors
    from sim_bridge.damage import parse_damage

    if shipped is None:
        raise SystemExit(f'build_library.py: no damage priors beside {path} to add to '
                         '(make priors)')
    library = load_damage_priors(library_path, archive.params)
    first = shipped.first_tier()
    if specs == 'remove-pairs':  # a pair with a whole table in the first tier stays there
        wanted = [n for n in conditions() if n.startswith('remove:') and ',' in n
                  and n not in first.names]
    elif specs == 'library':  # every condition that has no whole table in the first tier
        wanted = [n for n in library.names if n not in first.names]
    else:
        wanted = [w.strip() for w in specs.split(';') if w.strip()]
    canonical = [parse_damage(n).canonical() for n in library.names]
    rows = []
    for spec in wanted:
        key = parse_damage(spec).canonical()
        if key not in canonical:
            raise SystemExit(f'build_library.py: {spec} is no table of {library_path}')
        if spec in first.names:
            raise SystemExit(f'build_library.py: {spec} is already a whole table of the '
                             'first tier')
        rows.append(canonical.index(key))
    rows = np.array(rows, dtype=int)
    simulated = np.zeros((len(rows), len(archive)), bool)
    for row, spec in zip(simulated, wanted):
        done = _evaluated(out, spec)[0]
        if not len(done):
            raise SystemExit(f'build_library.py: no gait of {spec} evaluated in {out}: which '
                             'of its outcomes were simulated is not known')
        row[done] = True

    def chained(first_rows, library_rows):
        if first_rows is None and library_rows is None:
            return None
        a = np.zeros(first.fallen.shape, int) if first_rows is None else first_rows
        b = np.zeros((len(rows), len(archive)), int) if library_rows is None \
            else np.asarray(library_rows)[rows]
        return np.concatenate([a, b])
    k = first.generic_reward.shape[2]
    priors = DamagePriors(
        tuple(first.names) + tuple(library.names[i] for i in rows),
        np.concatenate([first.generic_reward, library.generic_reward[rows][:, :, :k]]),
        np.concatenate([first.fallen, library.fallen[rows]]), first.archive_checksum,
        chained(first.chained_runs, library.chained_runs),
        chained(first.chained_falls, library.chained_falls),
        np.array([False] * len(first) + [True] * len(rows)),
        np.concatenate([np.ones(first.fallen.shape, bool) if first.simulated is None
                        else first.simulated, simulated]))
    target = priors_path(path)
    priors.save(target)
    print(f'{target}: {len(first)} whole tables, then {len(rows)} of the library as the '
          f'second tier ({", ".join(priors.names[len(first):])}; '
          f'{int(simulated.sum(axis=1).min())}-{int(simulated.sum(axis=1).max())} of '
          f'{len(archive)} gaits simulated each, the rest inferred)')


def main(argv=None):
    from sela_ros.core.learning import priors_path, resolve_priors
    from sela_ros.core.storage import load_archive, resolve_archive_path

    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--archive', default='8d', help="a map: '8d' (default), '2d' or a path")
    parser.add_argument('--gaits', type=int, default=DEFAULT_GAITS,
                        help='gaits evaluated per condition (default %(default)s)')
    parser.add_argument('--chunk', type=int, default=DEFAULT_CHUNK,
                        help='gaits per checkpointed chunk (default %(default)s)')
    parser.add_argument('--workers', type=int, default=1)
    parser.add_argument('--out', default=str(ROOT / 'mapbuild' / 'library'),
                        help='checkpoint directory (default: the repository\'s '
                             'mapbuild/library, committed so that a build resumes anywhere)')
    parser.add_argument('--only', default=None,
                        help="';'-separated conditions to build (default: all)")
    parser.add_argument('--kinds', default=None,
                        help="comma-separated damage kinds (remove, shorten, block, weaken): "
                             "only the conditions made of these")
    parser.add_argument('--oracle-only', default=None,
                        help="';'-separated damages that are no condition of the library: "
                             'evaluate --gaits gaits of each (--covering of them covering the '
                             'map, the rest the fastest) into mapbuild/oracles, for their '
                             "oracles (compare_priors.py's oracle reads them)")
    parser.add_argument('--covering', type=int, default=500,
                        help='with --oracle-only: gaits that cover the map (default '
                             '%(default)s)')
    parser.add_argument('--plan', action='store_true', help='print the plan, build nothing')
    parser.add_argument('--assemble', action='store_true',
                        help='infer the gaits not evaluated and write --library')
    parser.add_argument('--library', default=None,
                        help="the assembled damage-priors file (default: beside the archive, "
                             "<archive>_library.npz: what priors.tables: library reads)")
    parser.add_argument('--check-inference', action='store_true',
                        help='infer the shipped tables from the gaits of the plan and print '
                             'the error on the others')
    parser.add_argument('--partial', action='store_true',
                        help='assemble what is evaluated so far (conditions listed)')
    parser.add_argument('--second-tier', default=None, metavar='SPECS',
                        help="add these tables of the assembled library (--library) to the "
                             "map's damage priors as a second tier, used only once one of "
                             "them reproduced the robot's standing starts: 'library' (every "
                             "condition the first tier does not hold: what `make priors` "
                             "ships), 'remove-pairs' (the 15 pairs of legs removed) or "
                             "';'-separated conditions")
    args = parser.parse_args(argv)
    path = resolve_archive_path(args.archive)
    archive = load_archive(path)
    if args.oracle_only:
        from sim_bridge.damage import parse_damage

        specs = [parse_damage(s).canonical() for s in args.oracle_only.split(';')]
        build(archive, ORACLE_OUT, args.gaits, args.chunk, args.workers, specs=specs,
              covering=args.covering)
        return
    shipped = resolve_priors('auto', path, archive.params)
    if args.second_tier:
        write_second_tier(path, archive, shipped, args.second_tier,
                          args.library or priors_path(path, library=True), args.out)
        return
    # Whole tables ship as the first tier; the second is the library's own.
    shipped = shipped.first_tier() if shipped is not None else None
    skip = tuple(shipped.names) if shipped is not None else ()
    names, evaluations, hours, megabytes = plan(len(archive), args.gaits, skip)
    print(f'{len(names)} conditions ({len(names) - len(set(skip) & set(names))} to build, the '
          f'others ship whole) x {min(args.gaits, len(archive))} gaits = {evaluations} '
          f'evaluations, about {hours:.1f} core-hours at {SECONDS_PER_GAIT} s per gait '
          f'(budget {BUDGET_CORE_HOURS:g}), about {megabytes:.1f} MB assembled')
    if args.plan:
        for kind in ('remove', 'shorten', 'block', 'weaken'):
            picked = [n for n in names if n.startswith(kind)]
            print(f'  {kind}: {len(picked)} ({", ".join(picked[:3])}, ...)')
        return
    if hours > BUDGET_CORE_HOURS and args.only is None:
        print(f'warning: over the {BUDGET_CORE_HOURS:g} core-hour budget', file=sys.stderr)
    only = set(args.only.split(';')) if args.only else None
    if args.kinds:
        kinds = set(args.kinds.split(','))
        picked = {n for n in names if {item.split(':')[0] for item in n.split(',')} <= kinds}
        only = picked if only is None else only & picked
    if args.check_inference:
        if shipped is None:
            parser.error(f'no damage priors beside {path} to check against')
        check_inference(archive, shipped, args.gaits)
        return
    if args.assemble:
        library = args.library or priors_path(path, library=True)
        assemble(archive, args.out, args.gaits, library, shipped, only, args.partial)
        return
    build(archive, args.out, args.gaits, args.chunk, args.workers, only, skip)


if __name__ == '__main__':
    main()
