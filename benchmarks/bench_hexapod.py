"""Benchmark of the PyBullet hexapod: gait speed, controller overhead, process-pool speed-up.

Run from the repository root: ``.venv/bin/python benchmarks/bench_hexapod.py [--gaits 40]``.
Targets: real-time factor >= 15x on one core, controller + bookkeeping overhead <= 15 %
over bare ``stepSimulation``, 2-process pool speed-up >= 1.6x.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pybullet as p

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), '..'))

from sim_bridge import hexapod as hx  # noqa: E402
from sim_bridge.controller import tripod_gait  # noqa: E402
from sim_bridge.evaluation import evaluate_gait  # noqa: E402


def _best(fn, repeats):
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def _warm_worker():
    evaluate_gait(tripod_gait())


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--gaits', type=int, default=40, help='gaits for the pool test')
    parser.add_argument('--repeats', type=int, default=5)
    parser.add_argument('--workers', type=int, default=2)
    args = parser.parse_args(argv)

    print(f'cpus: {os.cpu_count()}, load average: {os.getloadavg()[0]:.2f} (others share them)')
    sim = hx.Hexapod()
    gait = tripod_gait()

    def one_gait():
        sim.reset()
        sim.execute(gait)

    def bare():
        # Same model, same number of steps, same trajectory: time only stepSimulation
        # inside the gait loop (a bare loop without motors would collapse the robot and
        # simulate different contacts).
        step = p.stepSimulation
        spent = [0.0]

        def timed_step(*a, **kw):
            start = time.perf_counter()
            step(*a, **kw)
            spent[0] += time.perf_counter() - start

        p.stepSimulation = timed_step
        try:
            one_gait()
        finally:
            p.stepSimulation = step
        return spent[0]

    one_gait()
    t_gait = _best(one_gait, args.repeats)
    t_bare = min(bare() for _ in range(args.repeats))
    print(f'one {sim.gait_duration:.0f} s gait ({sim.n_steps} steps at dt={sim.dt:.6g} s): '
          f'{t_gait * 1e3:.1f} ms wall, real-time factor {sim.gait_duration / t_gait:.1f}x')
    print(f'bare stepSimulation, same model and steps: {t_bare * 1e3:.1f} ms; controller + '
          f'bookkeeping overhead {100 * (t_gait - t_bare) / t_bare:.1f} %')
    sim.close()

    rng = np.random.default_rng(0)
    params = [rng.random(36) for _ in range(args.gaits)]
    evaluate_gait(params[0])
    start = time.perf_counter()
    serial = [evaluate_gait(x) for x in params]
    t_serial = time.perf_counter() - start
    with ProcessPoolExecutor(args.workers) as pool:
        # Warm every worker (import + build + settle) so that only evaluation is timed.
        for f in [pool.submit(_warm_worker) for _ in range(args.workers * 2)]:
            f.result()
        start = time.perf_counter()
        pooled = list(pool.map(evaluate_gait, params, chunksize=1))
        t_pool = time.perf_counter() - start
    identical = all(np.array_equal(a.end_pose, b.end_pose) for a, b in zip(serial, pooled))
    print(f'{args.gaits} random gaits: 1 process {t_serial:.2f} s, {args.workers}-process pool '
          f'{t_pool:.2f} s, speed-up {t_serial / t_pool:.2f}x (results identical: {identical})')
    return 0


if __name__ == '__main__':
    sys.exit(main())
