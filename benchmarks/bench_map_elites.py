"""Throughput of MAP-Elites' own machinery (archive insertion, emitter, checkpoint) and of a
short hexapod run, to see what is overhead and what is simulation.

Run: ``.venv/bin/python benchmarks/bench_map_elites.py [--gaits 40] [--workers 2]``.
Prints figures only; tests never assert on timings.
"""
import argparse
import os
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), '..'))

from sela_ros.qd.evaluators import HexapodEvaluator, SyntheticEvaluator  # noqa: E402
from sela_ros.qd.executors import ProcessPoolEvaluator, SerialEvaluator  # noqa: E402
from sela_ros.qd.map_elites import default_run  # noqa: E402


def bench_overhead(n=20000, batch=200):
    run = default_run(SyntheticEvaluator(), dims=(100, 100), bounds=((-0.6, 0.6),) * 2,
                      batch_size=batch, seed=0)
    start = time.perf_counter()
    run.run(n, progress=False)
    seconds = time.perf_counter() - start
    print(f'synthetic MAP-Elites (ask + evaluate + tell): {n / seconds:,.0f} evals/s, '
          f'{run.archive.stats.num_elites} cells filled')
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        run.save_checkpoint(os.path.join(tmp, 'ck.pkl'))
        print(f'checkpoint of a 100x100 grid: {time.perf_counter() - start:.3f} s, '
              f'{os.path.getsize(os.path.join(tmp, "ck.pkl")) / 1e6:.2f} MB')


def bench_hexapod(gaits, workers):
    evaluate = HexapodEvaluator()
    rng = np.random.default_rng(0)
    evaluate(rng.random(36))
    batch = rng.random((gaits, 36))
    start = time.perf_counter()
    SerialEvaluator().map(evaluate, batch)
    serial = time.perf_counter() - start
    print(f'hexapod, 1 process: {gaits / serial:.1f} gaits/s')
    with ProcessPoolEvaluator(workers) as pool:
        pool.map(evaluate, batch[:workers])  # start workers, build their simulators
        start = time.perf_counter()
        pool.map(evaluate, batch)
        pooled = time.perf_counter() - start
    print(f'hexapod, {workers} processes: {gaits / pooled:.1f} gaits/s '
          f'(speed-up {serial / pooled:.2f}x)')


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument('--gaits', type=int, default=40)
    parser.add_argument('--workers', type=int, default=os.cpu_count() or 1)
    parser.add_argument('--evals', type=int, default=20000,
                        help='evaluations of the synthetic run')
    args = parser.parse_args()
    bench_overhead(args.evals)
    bench_hexapod(args.gaits, args.workers)


if __name__ == '__main__':
    main()
