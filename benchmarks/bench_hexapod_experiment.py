"""Wall time of the hexapod experiment, and its share in simulation versus learning.

Run::

    .venv/bin/python benchmarks/bench_hexapod_experiment.py [--replicates 4] [--workers 2]
        [--archive PATH] [--from-results results.json]

Without ``--from-results`` it runs ``--replicates`` replicates of all four methods (the
paper's case: remove:middle_right, goal (2, 2)) and extrapolates linearly to 50 replicates;
with it, it reports the figures of a finished run (e.g. the 50-replicate one). The split:
"simulation" is the time inside ``env.execute`` (PyBullet), "learning and deciding" is the
rest of each method's run (GP updates, UCB, planning, Python overhead). Prints figures
only; tests never assert on timings.
"""
import argparse
import json
import os

from sela_ros import single_blas_thread  # noqa: E402

single_blas_thread()  # before numpy

import tempfile  # noqa: E402
import time  # noqa: E402

from sela_ros.core.storage import default_archive_path  # noqa: E402
from sela_ros.experiments.cli import main as cli_main  # noqa: E402


def report(doc, measured_wall, label):
    t = doc['timing']
    reps = doc['replicates']
    print(f'{label}: {reps} replicates, {t["workers"]} worker(s), '
          f'{doc["parameters"]["num_behaviours"]} behaviours, wall {measured_wall:.1f} s '
          f'(oracle table {t["oracle_table_seconds"]:.1f} s, replicates '
          f'{t["wall_seconds"]:.1f} s)')
    total_sim = total = 0.0
    for name, m in t['methods'].items():
        gaits = sum(doc['methods'][name]['steps']) + sum(
            doc['methods'][name]['learning_iterations'])
        sim, wall = m['sim_seconds'], m['wall_seconds']
        total_sim += sim
        total += wall
        print(f'  {name:16s} {gaits:5d} gaits  {wall:8.1f} s worker wall  simulation '
              f'{100 * sim / wall:5.1f}%  learning+deciding {100 * (wall - sim) / wall:5.1f}%'
              f'  ({1000 * sim / max(gaits, 1):.0f} ms/gait)')
    print(f'  all methods: simulation {100 * total_sim / total:.1f}%, learning+deciding '
          f'{100 * (total - total_sim) / total:.1f}% of {total:.1f} s summed over workers')
    if reps != 50:
        total50 = t['oracle_table_seconds'] + 50 * t['wall_seconds'] / reps
        print(f'  extrapolated 50-replicate wall time: {total50:.0f} s ({total50 / 60:.1f} min;'
              ' linear in replicates, same machine load)')


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--replicates', type=int, default=4)
    parser.add_argument('--workers', type=int, default=2)
    parser.add_argument('--archive', default=str(default_archive_path()))
    parser.add_argument('--max-steps', type=int, default=None,
                        help="steps per mission (default: the experiment's)")
    parser.add_argument('--methods', default=None,
                        help="comma-separated methods (default: the experiment's)")
    parser.add_argument('--from-results', default=None,
                        help='report a finished run instead of running one')
    args = parser.parse_args()
    if args.from_results:
        with open(args.from_results) as f:
            doc = json.load(f)
        report(doc, doc['timing']['wall_seconds'] + doc['timing']['oracle_table_seconds'],
               'measured')
        return
    with tempfile.TemporaryDirectory() as out:
        start = time.perf_counter()
        cli_main(['hexapod', '--replicates', str(args.replicates), '--workers',
                  str(args.workers), '--archive', args.archive, '--out', out, '--quiet',
                  '--oracle-cache', os.path.join(out, 'cache')]
                 + ([] if args.max_steps is None else ['--max-steps', str(args.max_steps)])
                 + ([] if args.methods is None else ['--methods', args.methods]))
        wall = time.perf_counter() - start
        with open(os.path.join(out, 'results.json')) as f:
            doc = json.load(f)
    report(doc, wall, 'measured (oracle table computed, not cached)')


if __name__ == '__main__':
    main()
