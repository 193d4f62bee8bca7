#!/usr/bin/env python3
"""The product against the experiment runner, on the same damages, goals and noise seeds.

For every damage, goal and seed it runs the mission twice: once as a user runs it
(``sela-demo``: the four nodes as processes over DDS, loopback only) and once through the
experiment runner (``sela-experiment hexapod``'s SELA replicate, in process, with the
``sim_bridge`` node's noise seed). Both take the shipped map, its damage priors and the
shipped ``config/sela.yaml`` defaults. Prints one row per run and a table per cell, and writes
``runs.json`` and ``table.md`` under ``--out``; runs already there are kept (resumable).

    .venv/bin/python scripts/compare_product.py --out docs/results/product_vs_runner
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

DAMAGES = ('remove:front_left,remove:rear_right', 'remove:rear_left', 'shorten:front_right:0.5')
GOALS = ('1.6,-1.0', '-1.4,1.2')


def _runner(damage, goal, seed):
    from sela_ros.core.storage import default_archive_path
    from sela_ros.experiments.hexapod import Job, run_method

    job = Job('sela', np.random.SeedSequence(seed), str(default_archive_path()), damage,
              tuple(goal), noise_seed=seed)
    out = run_method(job)
    return {key: out[key] for key in ('success', 'steps', 'falls', 'behaviors')}


def _product(damage, goal, seed, out_dir, timeout, domain_id):
    from sela_ros.tools.ros_env import package_prefix

    demo = Path(sys.executable).parent / 'sela-demo'
    if not demo.exists():
        demo = package_prefix() / 'bin' / 'sela-demo'
    cmd = [str(demo), '--damage', damage, '--goal', f'{goal[0]},{goal[1]}', '--seed', str(seed),
           '--out', str(out_dir), '--timeout', str(timeout), '--domain-id', str(domain_id)]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout + 120)
    summary_path = out_dir / 'summary.json'
    if not summary_path.exists():
        return {'success': False, 'steps': None, 'falls': None, 'exit': done.returncode,
                'error': done.stderr.strip().splitlines()[-1:]}
    summary = json.loads(summary_path.read_text())
    falls = sum(s.get('fallen') == 'True' for s in summary['steps_detail'])
    return {'success': summary['success'], 'steps': summary['steps'], 'falls': falls,
            'exit': done.returncode, 'behaviors': summary['behaviors']}


def _claim_domain_id():
    """A ROS_DOMAIN_ID that no test run holds (they take 10..99 with the same locks)."""
    import fcntl

    lock_dir = Path(tempfile.gettempdir()) / 'sela_ros_domain_ids'
    lock_dir.mkdir(exist_ok=True)
    for domain_id in range(100, 102):
        handle = open(lock_dir / f'{domain_id}.lock', 'w')  # noqa: SIM115
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            handle.close()
            continue
        return domain_id, handle
    raise RuntimeError('no free ROS_DOMAIN_ID in 100..101')


def _median(values):
    values = [v for v in values if v is not None]
    return float(np.median(values)) if values else float('nan')


def _side(rs, key):
    """One side's cell text and median steps (runs that got home)."""
    steps = [r[key]['steps'] for r in rs if r[key]['success']]
    return (f"{sum(r[key]['success'] for r in rs)}/{len(rs)}, {_median(steps):g} "
            f"({min(steps, default=0)}-{max(steps, default=0)}), "
            f"{sum(r[key]['falls'] or 0 for r in rs)}"), _median(steps)


def table(runs):
    lines = ['| damage | goal | product: home, median steps (range), falls | runner: home, '
             'median steps (range), falls | product / runner | same gaits |',
             '| --- | --- | --- | --- | --- | --- |']
    cells = {}
    for r in runs:
        cells.setdefault((r['damage'], tuple(r['goal'])), []).append(r)
    for (damage, goal), rs in cells.items():
        product, p = _side(rs, 'product')
        runner, q = _side(rs, 'runner')
        same = sum(r['product'].get('behaviors') == r['runner']['behaviors'] for r in rs)
        lines.append(f'| {damage} | ({goal[0]:g}, {goal[1]:g}) | {product} | {runner} | '
                     f'{p / q:.2f} | {same}/{len(rs)} |')
    return '\n'.join(lines)


def main(argv=None):
    from sela_ros.experiments.arguments import take_negative_points

    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--damages', default=';'.join(DAMAGES), help='";"-separated damages')
    parser.add_argument('--goals', nargs='+', default=list(GOALS), help='goals X,Y')
    parser.add_argument('--seeds', type=int, default=10, help='seeds 0..N-1 (default 10)')
    parser.add_argument('--timeout', type=float, default=300.0, help='per demo run (s)')
    parser.add_argument('--out', type=Path, required=True)
    take_negative_points(parser)  # --goals 2.5,0.5 -2,-1.5
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    store = args.out / 'runs.json'
    runs = json.loads(store.read_text()) if store.exists() else []
    done = {(r['damage'], tuple(r['goal']), r['seed']) for r in runs}
    domain_id, _lock = _claim_domain_id()
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    for damage in args.damages.split(';'):
        for goal in (tuple(float(v) for v in g.split(',')) for g in args.goals):
            for seed in range(args.seeds):
                if (damage, goal, seed) in done:
                    continue
                with tempfile.TemporaryDirectory() as tmp:
                    product = _product(damage, goal, seed, Path(tmp), args.timeout, domain_id)
                runner = _runner(damage, goal, seed)
                row = {'damage': damage, 'goal': list(goal), 'seed': seed, 'product': product,
                       'runner': runner}
                runs.append(row)
                store.write_text(json.dumps(runs, indent=1))
                print(f"{damage:40s} ({goal[0]:+.1f}, {goal[1]:+.1f}) seed {seed}: product "
                      f"{'home' if product['success'] else 'FAILED'} {product['steps']} steps, "
                      f"{product['falls']} falls; runner "
                      f"{'home' if runner['success'] else 'FAILED'} {runner['steps']} steps, "
                      f"{runner['falls']} falls", flush=True)
    text = table(runs)
    (args.out / 'table.md').write_text(text + '\n')
    print(text)
    return 0


if __name__ == '__main__':
    sys.exit(main())
