#!/usr/bin/env python3
"""``make bench``: every benchmark of the project, one after the other, with its defaults.

Each benchmark runs as its own process (a crash or a hang in one does not stop the others)
and prints its own figures; this prints a line per benchmark with its exit status and wall
time, and exits non-zero if any failed. ``--only NAME ...`` runs some of them, ``--list``
names them. Pass a benchmark its own options with ``--args NAME='--gaits 10'``.
Figures, never pass/fail on speed: a benchmark fails only if it cannot run.
"""
import argparse
import shlex
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
#: name -> arguments: the DDS benchmark has two modes, both run.
BENCHMARKS = {
    'bench_sela_step': [],
    'bench_hexapod': [],
    'bench_map_elites': [],
    'bench_hexapod_experiment': [],
    'bench_physics': [],
    'bench_planning': [],
    'bench_detection_policy': [],
    'bench_restarts': [],
    'bench_state_file': [],
    'bench_ros overhead': ['overhead'],
    'bench_ros long': ['long'],
}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--only', nargs='+', choices=sorted(BENCHMARKS), metavar='NAME')
    parser.add_argument('--list', action='store_true', help='name the benchmarks and exit')
    parser.add_argument('--args', action='append', default=[], metavar="NAME='OPTIONS'",
                        help='extra options for one benchmark')
    args = parser.parse_args(argv)
    if args.list:
        print('\n'.join(BENCHMARKS))
        return 0
    extra = {}
    for item in args.args:
        name, _, options = item.partition('=')
        if name not in BENCHMARKS:
            parser.error(f'--args: unknown benchmark {name!r}; one of {sorted(BENCHMARKS)}')
        extra[name] = shlex.split(options)
    missing = sorted({n.split()[0] for n in BENCHMARKS} -
                     {p.stem for p in HERE.glob('bench_*.py')})
    if missing:
        parser.error(f'benchmark scripts missing: {missing}')
    results = []
    for name in args.only or BENCHMARKS:
        script = HERE / f'{name.split()[0]}.py'
        print(f'=== {name}', flush=True)
        start = time.monotonic()
        code = subprocess.call([sys.executable, str(script), *BENCHMARKS[name],
                                *extra.get(name, [])])
        results.append((name, code, time.monotonic() - start))
    print('=== summary')
    for name, code, wall in results:
        print(f'{name:28s} {"ok" if code == 0 else f"FAILED ({code})":12s} {wall:7.1f} s')
    return 0 if all(code == 0 for _, code, _ in results) else 1


if __name__ == '__main__':
    sys.exit(main())
