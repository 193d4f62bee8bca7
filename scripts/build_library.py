#!/usr/bin/env python3
"""Build a library of damage priors that spans the damage space, resumably, in bounded time.

The shipped damage priors (``make priors``) are six single-leg removals, every gait of the
map each. This library covers the kinds a robot meets (legs removed, alone and in pairs; legs
shortened at several lengths; joints blocked at several angles), each condition evaluated on
a subset of the map's gaits chosen to cover its behaviour space (farthest-point sampling over
the normalised descriptors), the other gaits inferred by a GP over the same descriptors
(prior mean: the intact map; what is learnt: each condition's deviation from it, and its
falls). The result is a damage-priors file (``DamagePriors``) that SELA mixes
(``sela_ros.core.learning.prior_mixture``) or chooses from, as ``priors: <path>``.

    .venv/bin/python scripts/build_library.py --plan              # conditions, cost, size
    nice -n 15 .venv/bin/python scripts/build_library.py --workers 2 --out /work/library
    .venv/bin/python scripts/build_library.py --assemble --out /work/library \\
        --library sela_ros/data/hexapod_archive_library.npz

Resumable after any interruption, on this machine or another: every ``--chunk`` gaits of a
condition are written atomically to ``--out`` (``<condition>/<first gait>.npz``) and a run
skips the chunks already there; the gait subset is a deterministic function of the archive
and ``--gaits``, so another machine with the same archive resumes the same plan (copy
``--out`` across). ``--assemble`` needs every chunk, and only reads them.
"""
from __future__ import annotations

import argparse
import itertools
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

LEGS = ('front_left', 'middle_left', 'rear_left', 'front_right', 'middle_right', 'rear_right')
SHORTEN_FACTORS = (0.3, 0.6, 0.8)
BLOCKED = (('knee', -0.4), ('knee', 0.0), ('knee', 0.4), ('hip_pitch', -0.3),
           ('hip_pitch', 0.3))
#: One gait from a standing start on one core, seconds: the shipped tables took 14-21
#: minutes for 12,442 gaits (0.07-0.10 s); the plan counts the upper end.
SECONDS_PER_GAIT = 0.1
DEFAULT_GAITS = 2000
DEFAULT_CHUNK = 100
BUDGET_CORE_HOURS = 6.0


def conditions():
    """The library's damage conditions (specs of ``sim_bridge.damage``), in build order:
    the kinds a leg loses first (singles), then pairs."""
    out = [f'remove:{leg}' for leg in LEGS]
    out += [f'shorten:{leg}:{f}' for leg in LEGS for f in SHORTEN_FACTORS]
    out += [f'block:{leg}.{joint}={a}' for leg in LEGS for joint, a in BLOCKED]
    out += [f'remove:{a},remove:{b}' for a, b in itertools.combinations(LEGS, 2)]
    # Two legs shortened on one side or across, at the middle length.
    out += [f'shorten:{a}:0.6,shorten:{b}:0.6' for a, b in itertools.combinations(LEGS, 2)]
    return out


def gait_subset(descriptors, count, first=0):
    """``count`` gait indices that cover the descriptors: farthest-point sampling from gait
    ``first`` (deterministic), so that every gait is near an evaluated one."""
    descriptors = np.asarray(descriptors, dtype=float)
    count = min(int(count), len(descriptors))
    chosen = [int(first)]
    gap = np.sum((descriptors - descriptors[first]) ** 2, axis=1)
    for _ in range(count - 1):
        nxt = int(np.argmax(gap))
        chosen.append(nxt)
        np.minimum(gap, np.sum((descriptors - descriptors[nxt]) ** 2, axis=1), out=gap)
    return np.array(chosen, dtype=int)


def plan(num_gaits, gaits):
    """``(conditions, evaluations, core-hours, MB on disk)`` of a build."""
    names = conditions()
    evaluations = len(names) * min(gaits, num_gaits)
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


def build(archive, out, gaits, chunk, workers, only=None):
    """Evaluate every chunk not on disk yet; returns how many were evaluated now."""
    from sela_ros.core.storage import atomic_write

    subset = gait_subset(archive.normalised_descriptors(), gaits)
    settings = archive.simulator_settings
    jobs = []
    for spec in conditions():
        if only and spec not in only:
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
        atomic_write(Path(out) / _slug(spec) / f'{first:06d}.npz', lambda h: np.savez(
            h, gaits=part, generic_reward=gr, fallen=fallen, damage=np.array(spec)))
        print(f'[{n}/{len(jobs)}] {spec} gaits {first}-{first + len(part) - 1} '
              f'({time.perf_counter() - begin:.0f} s)', flush=True)

    if workers <= 1:
        for n, job in enumerate(jobs, 1):
            save(_evaluate(job), n)
    else:
        with ProcessPoolExecutor(max_workers=workers) as pool:
            for n, result in enumerate(pool.map(_evaluate, jobs), 1):
                save(result, n)
    return len(jobs)


def infer(descriptors, base, gaits, gr, fallen, sigma, noise_ratio=0.1, rows=2000):
    """Every gait's generic reward and fall flag on one condition from the gaits evaluated:
    the GP posterior mean of the deviation from the intact map ``base`` and of the fall
    label (prior 0), exponential kernel of length ``sigma`` over the descriptors."""
    from scipy.linalg import cho_factor, cho_solve

    from sela_ros.core.learning import exponential_kernel

    x = descriptors[gaits]
    targets = np.column_stack([gr - base[gaits], fallen.astype(float)])
    scale = targets.std(axis=0)
    scale[scale == 0] = 1.0
    k = exponential_kernel(x, x, sigma) + noise_ratio * np.eye(len(gaits))
    alpha = cho_solve(cho_factor(k), targets / scale)
    mean = np.empty((len(descriptors), targets.shape[1]))
    for i in range(0, len(descriptors), rows):
        mean[i:i + rows] = exponential_kernel(descriptors[i:i + rows], x, sigma) @ alpha
    mean *= scale
    out_gr = base + mean[:, :3]
    out_fallen = mean[:, 3] > 0.5
    out_gr[gaits], out_fallen[gaits] = gr, fallen  # the evaluated ones as they are
    return out_gr, out_fallen


def assemble(archive, out, gaits, library, only=None):
    from sela_ros.core.learning import DamagePriors, params_checksum

    subset = gait_subset(archive.normalised_descriptors(), gaits)
    descriptors = archive.normalised_descriptors()
    names, tables, falls = [], [], []
    for spec in conditions():
        if only and spec not in only:
            continue
        parts = sorted((Path(out) / _slug(spec)).glob('*.npz'))
        if not parts:
            raise SystemExit(f'{spec}: no chunk in {out}; run the build first')
        data = [np.load(p) for p in parts]
        done = np.concatenate([d['gaits'] for d in data])
        if len(done) != len(subset):
            raise SystemExit(f'{spec}: {len(done)} of {len(subset)} gaits evaluated; resume '
                             'the build first')
        gr, fallen = infer(descriptors, archive.generic_reward, done,
                           np.concatenate([d['generic_reward'] for d in data]),
                           np.concatenate([d['fallen'] for d in data]), archive.kernel_sigma)
        names.append(spec)
        tables.append(gr)
        falls.append(fallen)
    DamagePriors(tuple(names), np.stack(tables), np.stack(falls),
                 params_checksum(archive.params)).save(library)
    print(f'{library}: {len(names)} conditions, {Path(library).stat().st_size / 1e6:.1f} MB')


def main(argv=None):
    from sela_ros.core.storage import load_archive, resolve_archive_path

    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--archive', default='8d', help="a map: '8d' (default), '2d' or a path")
    parser.add_argument('--gaits', type=int, default=DEFAULT_GAITS,
                        help='gaits evaluated per condition (default %(default)s)')
    parser.add_argument('--chunk', type=int, default=DEFAULT_CHUNK,
                        help='gaits per checkpointed chunk (default %(default)s)')
    parser.add_argument('--workers', type=int, default=1)
    parser.add_argument('--out', default='library_build', help='checkpoint directory')
    parser.add_argument('--only', default=None,
                        help="';'-separated conditions to build (default: all)")
    parser.add_argument('--plan', action='store_true', help='print the plan, build nothing')
    parser.add_argument('--assemble', action='store_true',
                        help='infer the gaits not evaluated and write --library')
    parser.add_argument('--library', default=None, help='the assembled damage-priors file')
    args = parser.parse_args(argv)
    archive = load_archive(resolve_archive_path(args.archive))
    names, evaluations, hours, megabytes = plan(len(archive), args.gaits)
    print(f'{len(names)} conditions x {min(args.gaits, len(archive))} gaits = {evaluations} '
          f'evaluations, about {hours:.1f} core-hours at {SECONDS_PER_GAIT} s per gait '
          f'(budget {BUDGET_CORE_HOURS:g}), about {megabytes:.1f} MB assembled')
    if args.plan:
        for kind in ('remove', 'shorten', 'block'):
            picked = [n for n in names if n.startswith(kind)]
            print(f'  {kind}: {len(picked)} ({", ".join(picked[:3])}, ...)')
        return
    if hours > BUDGET_CORE_HOURS and args.only is None:
        print(f'warning: over the {BUDGET_CORE_HOURS:g} core-hour budget', file=sys.stderr)
    only = set(args.only.split(';')) if args.only else None
    if args.assemble:
        if not args.library:
            parser.error('--assemble needs --library')
        assemble(archive, args.out, args.gaits, args.library, only)
        return
    build(archive, args.out, args.gaits, args.chunk, args.workers, only)


if __name__ == '__main__':
    main()
