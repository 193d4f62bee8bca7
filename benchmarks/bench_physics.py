"""What the physics settings cost and what they change: evaluations/s per core vs fidelity.

Run from the repository root: ``.venv/bin/python benchmarks/bench_physics.py``.

Every setting runs the SAME gaits (``--random`` uniform ones and ``--elites`` drawn from the
shipped archive) from the same standing start, in this one process, so the rates are CPU
seconds of one core and their ratios come from one run. Fidelity compares each gait's
outcome with its outcome under the defaults (dt 1/240 s, 50 solver iterations): distance
between the final (x, y), |dyaw| difference, the largest duty-factor difference of the six
feet, and the fraction of gaits whose fall flag flips. A third column of figures compares
both with a fine reference (dt 1/1000 s, 100 iterations) on the first ``--reference``
gaits: the defaults are not the truth either, and a candidate is faithful when it is about
as far from the reference as the defaults are.
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), '..'))

from sim_bridge import hexapod as hx  # noqa: E402
from sim_bridge.settings import FAST_SETTINGS, SIM_DEFAULTS  # noqa: E402

BASELINE = {'dt': SIM_DEFAULTS['dt'], 'solver_iterations': SIM_DEFAULTS['solver_iterations']}
REFERENCE = {'dt': 1.0 / 1000.0, 'solver_iterations': 100}
CANDIDATES = (
    {'dt': 1.0 / 240.0, 'solver_iterations': 20},
    {'dt': 1.0 / 120.0, 'solver_iterations': 50},
    {'dt': 1.0 / 120.0, 'solver_iterations': 30},
    {'dt': 1.0 / 120.0, 'solver_iterations': 20},
)


def label(settings: dict) -> str:
    return f'dt 1/{1.0 / settings["dt"]:.0f} s, {settings["solver_iterations"]} iterations'


def evaluate(gaits: np.ndarray, settings: dict) -> tuple[float, np.ndarray]:
    """(evaluations per CPU second, outcomes (n, 10): dx, dy, dyaw, 6 duty factors, fallen)."""
    with hx.Hexapod(**settings) as sim:
        rows = np.empty((len(gaits), 10))
        start = time.process_time()
        for i, params in enumerate(gaits):
            sim.reset()
            outcome = sim.execute(params)
            rows[i, :3] = outcome.generic_reward
            rows[i, 3:9] = outcome.duty_factors
            rows[i, 9] = float(outcome.fallen)
        spent = time.process_time() - start
    return len(gaits) / spent, rows


def fidelity(rows: np.ndarray, base: np.ndarray) -> dict:
    """Differences between two outcome tables of the same gaits."""
    distance = np.hypot(rows[:, 0] - base[:, 0], rows[:, 1] - base[:, 1])
    dyaw = np.abs(np.remainder(rows[:, 2] - base[:, 2] + np.pi, 2 * np.pi) - np.pi)
    duty = np.abs(rows[:, 3:9] - base[:, 3:9]).max(axis=1)
    return {'disp_med_cm': 100 * np.median(distance),
            'disp_p90_cm': 100 * np.percentile(distance, 90),
            'dyaw_med': np.median(dyaw),
            'duty_med': np.median(duty), 'duty_p90': np.percentile(duty, 90),
            'fall_flips': np.mean(rows[:, 9] != base[:, 9])}


def _row(name, rate, ratio, fid):
    return (f'{name:30s} {rate:6.2f} {ratio:5.2f}x  {fid["disp_med_cm"]:5.1f} '
            f'{fid["disp_p90_cm"]:5.1f}  {fid["dyaw_med"]:5.3f}  {fid["duty_med"]:5.3f} '
            f'{fid["duty_p90"]:5.3f}  {100 * fid["fall_flips"]:5.1f}')


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--random', type=int, default=200, help='uniform random gaits')
    parser.add_argument('--elites', type=int, default=100, help='gaits of the shipped archive')
    parser.add_argument('--reference', type=int, default=40,
                        help='gaits also run with the fine reference (0: skip it)')
    parser.add_argument('--seed', type=int, default=0)
    args = parser.parse_args(argv)

    from sela_ros.core.storage import default_archive_path

    rng = np.random.default_rng(args.seed)
    with np.load(default_archive_path(), allow_pickle=False) as npz:
        shipped = npz['params']
    picks = rng.choice(len(shipped), size=min(args.elites, len(shipped)), replace=False)
    gaits = np.concatenate([rng.random((args.random, 36)), shipped[picks]])
    groups = {'random': slice(0, args.random), 'elites': slice(args.random, len(gaits))}
    print(f'{len(gaits)} gaits ({args.random} random, {len(picks)} elites of the shipped '
          f'archive); cpus {os.cpu_count()}, load {os.getloadavg()[0]:.2f}; rates are '
          'evaluations per CPU second of one core', flush=True)

    base_rate, base = evaluate(gaits, BASELINE)
    n_ref = min(args.reference, len(gaits))
    reference = evaluate(gaits[:n_ref], REFERENCE)[1] if n_ref else None
    header = (f'{"setting":30s} {"ev/s":>6s} {"ratio":>6s}  {"disp med/p90 cm":>11s}  '
              f'{"dyaw":>5s}  {"duty med/p90":>11s}  {"falls flip %":>5s}')
    results = {label(BASELINE): (base_rate, base)}
    for settings in CANDIDATES:
        results[label(settings)] = evaluate(gaits, settings)

    for group, part in groups.items():
        print(f'\n{group} gaits, compared with the defaults ({label(BASELINE)}):')
        print(header)
        for name, (rate, rows) in results.items():
            print(_row(name, rate, rate / base_rate, fidelity(rows[part], base[part])))
    if reference is not None:
        print(f'\nfirst {n_ref} gaits compared with the fine reference ({label(REFERENCE)}):')
        print(header)
        for name, (rate, rows) in results.items():
            print(_row(name, rate, rate / base_rate, fidelity(rows[:n_ref], reference)))
    print(f'\nfalls under the defaults: {int(base[:, 9].sum())} of {len(gaits)}')
    chosen = {'dt': FAST_SETTINGS['dt'],
              'solver_iterations': FAST_SETTINGS['solver_iterations']}
    rate = results[label(chosen)][0] if label(chosen) in results else evaluate(gaits, chosen)[0]
    print(f'before: {base_rate:.2f} evaluations/s per core ({label(BASELINE)}); after: '
          f'{rate:.2f} evaluations/s per core ({label(chosen)}, the 8-D map\'s settings): '
          f'{rate / base_rate:.2f}x')
    return 0


if __name__ == '__main__':
    sys.exit(main())
