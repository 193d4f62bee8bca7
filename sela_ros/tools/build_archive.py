"""``sela-build-archive``: build a robot's behaviour-performance map with MAP-Elites.

Example (the shipped archive, see docs/archive.md)::

    sela-build-archive --evaluations 30000 --batch-size 200 --workers 2 --seed 1 \\
        --out sela_ros/data/hexapod_archive.npz --figure docs/figures/archive.png

Both maps are built with pyribs (``requirements-qd.txt``): a grid archive for the 2-D one, a
CVT archive for the paper's 8-D map (final x, y + six duty factors, physics
``sim_bridge.settings.FAST_SETTINGS``)::

    sela-build-archive --descriptor 8d --cells 60000 --evaluations 200000 --workers 1 \\
        --checkpoint ~/.cache/sela_ros/mapbuild/map8d.checkpoint.pkl \\
        --out ~/.cache/sela_ros/mapbuild/map8d.npz

Another robot's map: ``--robot NAME`` (a description of ``sim_bridge.robots``, or
``package.module:DESCRIPTION``); its parameter count, duty factors (one per leg) and
descriptor bounds come from its description (docs/robots.md).

(``scripts/build_map8d.sh``; 60,000 cells because part of the 8-D box holds (x, y, duty)
combinations no gait reaches, and the map should hold 10,000 elites or more; ``--resume
--regrid CELLS`` moves a run to a finer CVT, its elites carried over.)

Before it starts, it times a few gaits here and prints how long the run will take. It
checkpoints every ``--checkpoint-every`` batches (journalling the batches in between); after
a crash or a kill, run the same command with ``--resume`` (the checkpoint, with its
``.journal`` folder beside it, may be carried to another machine and resumed there, also
with ``--dask-scheduler``).
"""
from __future__ import annotations

import argparse
import json
import math
import os
import signal
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from sela_ros.core.storage import Archive
from sela_ros.qd.evaluators import RobotEvaluator, SyntheticEvaluator
from sela_ros.qd.executors import DaskEvaluator, ProcessPoolEvaluator, SerialEvaluator
from sela_ros.qd.map_elites import GridMapElites, default_run

DEFAULT_GRID = (64, 64)
DEFAULT_BOUNDS = (-0.6, 0.6, -0.6, 0.6)
FITNESS_NAME = 'arc_yaw_error'
#: --descriptor choices: the 2-D grid map and the paper's CVT map over final x, y and the
#: duty factors (8-D on the hexapod; ``duty`` names it on any robot).
DESCRIPTOR_NAMES = {'2d': 'final_xy', '8d': 'final_xy_duty_factors',
                    'duty': 'final_xy_duty_factors'}

# Thresholds of the gait families that docs/archive.md and the summary count.
FORWARD_DX, SIDEWAYS_DY, TURNING_DYAW = 0.1, 0.1, 0.5


def _positive_int(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f'must be a positive integer, got {text}')
    return value


def _positive_float(text: str) -> float:
    value = float(text)
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f'must be a positive number, got {text}')
    return value


def make_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog='sela-build-archive',
        description='Build the behaviour-performance map (MAP-Elites over final (x, y), '
                    'arc fitness) of a simulated intact robot (the hexapod by default).')
    parser.add_argument('--robot', default='hexapod',
                        help='the robot: hexapod (default), a1, toy, or '
                             'package.module:DESCRIPTION (docs/robots.md)')
    parser.add_argument('--evaluations', type=_positive_int, required=True,
                        help='total number of gait evaluations')
    parser.add_argument('--batch-size', type=_positive_int, default=200,
                        help='gaits per batch (default 200)')
    parser.add_argument('--workers', type=_positive_int, default=os.cpu_count() or 1,
                        help='local worker processes (default: all cores)')
    parser.add_argument('--seed', type=int, default=0, help='emitter seed (default 0)')
    parser.add_argument('--out', type=Path, required=True, help='archive file (.npz) to write')
    parser.add_argument('--figure', type=Path, default=None,
                        help='also write a heat-map PNG of the archive here')
    parser.add_argument('--checkpoint', type=Path, default=None,
                        help='checkpoint file (default: OUT with suffix .checkpoint.pkl)')
    parser.add_argument('--checkpoint-every', type=_positive_int, default=5,
                        help='full checkpoint every K batches (default 5; batches in between '
                             'are journalled, so none is lost)')
    parser.add_argument('--resume', action='store_true',
                        help='continue from the checkpoint (same RNG stream)')
    parser.add_argument('--export', action='store_true',
                        help='only write OUT from the checkpoint and its journal as they are: '
                             'no evaluation, no checkpoint written, so it is safe beside the '
                             'build that is still running')
    parser.add_argument('--descriptor', choices=sorted(DESCRIPTOR_NAMES), default='2d',
                        help='2d: final (x, y) on a grid; 8d (or duty): final (x, y) + one duty '
                             'factor per leg on a CVT archive (the paper\'s map; default 2d)')
    parser.add_argument('--cells', type=_positive_int, default=10000,
                        help='CVT cells of the 8d map (default 10000)')
    parser.add_argument('--regrid', type=_positive_int, default=None, metavar='CELLS',
                        help='with --resume (8d): go on in a finer CVT of CELLS cells, every '
                             'elite found so far carried into it; nothing happens when the '
                             'run already has CELLS cells')
    parser.add_argument('--emitters', type=_positive_int, default=1,
                        help='iso-line emitters; a batch is emitters x batch-size gaits '
                             '(default 1)')
    parser.add_argument('--dask-scheduler', default=None, metavar='ADDR',
                        help='evaluate on a Dask distributed scheduler, e.g. '
                             'tcp://127.0.0.1:8786, instead of local processes')
    parser.add_argument('--grid', type=_positive_int, nargs=2, default=DEFAULT_GRID,
                        metavar=('NX', 'NY'), help='grid cells in x and y (default 64 64)')
    parser.add_argument('--bounds', type=float, nargs=4, default=DEFAULT_BOUNDS,
                        metavar=('XMIN', 'XMAX', 'YMIN', 'YMAX'),
                        help='descriptor bounds in metres (default -0.6 0.6 -0.6 0.6)')
    parser.add_argument('--initial', type=_positive_int, default=None,
                        help='random gaits of the first batch, per emitter (default 5 '
                             'batches, or the whole budget when it is smaller)')
    parser.add_argument('--dt', type=_positive_float, default=None,
                        help='physics time step in s (default 1/240 for 2d, 1/120 for 8d)')
    parser.add_argument('--solver-iterations', type=_positive_int, default=None,
                        help='PyBullet solver iterations per step (default 50 for 2d, 30 for '
                             '8d: see benchmarks/bench_physics.py)')
    parser.add_argument('--gait-duration', type=_positive_float, default=3.0,
                        help='duration of one gait in s (default 3)')
    parser.add_argument('--synthetic', action='store_true',
                        help='use the cheap synthetic evaluation function (tests, dry runs)')
    parser.add_argument('--synthetic-delay', type=float, default=0.0,
                        help='seconds per synthetic evaluation (emulates the simulator)')
    parser.add_argument('--no-progress', action='store_true', help='no progress bar')
    return parser


def _check_args(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    xmin, xmax, ymin, ymax = args.bounds
    if not all(math.isfinite(v) for v in args.bounds) or xmin >= xmax or ymin >= ymax:
        parser.error(f'--bounds must be finite with XMIN < XMAX and YMIN < YMAX, got '
                     f'{args.bounds}')
    if args.synthetic_delay < 0:
        parser.error('--synthetic-delay must be >= 0')
    if (args.resume or args.export) and not _checkpoint_path(args).exists():
        option = '--export' if args.export else '--resume'
        parser.error(f'{option}: no checkpoint at {_checkpoint_path(args)}')
    if args.regrid is not None and (not _is_cvt(args) or not args.resume):
        parser.error('--regrid takes an 8d run to resume: add --descriptor 8d --resume')
    args.resume = args.resume or args.export
    # The random first batch counts in the budget: never more than it.
    budget = max(1, args.evaluations // args.emitters)
    if args.initial is not None and args.initial > budget:
        parser.error(f'--initial {args.initial} random gaits per emitter exceed the budget '
                     f'(--evaluations {args.evaluations} over {args.emitters} emitter(s): '
                     f'{budget} each)')
    args.initial = args.initial or min(5 * args.batch_size, budget)
    if args.out.suffix != '.npz':
        parser.error(f'--out must end in .npz, got {args.out}')
    # The map, its checkpoint and its journal are written there: said now, not after the
    # first batch of evaluations.
    for option, path in (('--out', args.out), ('--checkpoint', _checkpoint_path(args))):
        problem = _unwritable(path.parent)
        if problem:
            parser.error(f'{option}: cannot write in {path.parent}: {problem}')


def _unwritable(folder: Path) -> str | None:
    """Why nothing can be written in ``folder`` (created if missing), or None."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as exc:
        return exc.strerror or str(exc)
    return None


def _is_cvt(args: argparse.Namespace) -> bool:
    """The duty-factor map (a CVT archive), whatever name ``--descriptor`` gave it."""
    return DESCRIPTOR_NAMES[args.descriptor] == 'final_xy_duty_factors'


def _checkpoint_path(args: argparse.Namespace) -> Path:
    if args.checkpoint is not None:
        return args.checkpoint
    return args.out.with_name(args.out.stem + '.checkpoint.pkl')


def _physics(args: argparse.Namespace) -> tuple[float, int]:
    """dt and solver iterations: the options, else the defaults of the descriptor's map."""
    from sim_bridge.settings import FAST_SETTINGS, SIM_DEFAULTS

    defaults = FAST_SETTINGS if _is_cvt(args) else SIM_DEFAULTS
    dt = args.dt if args.dt is not None else defaults['dt']
    iterations = (args.solver_iterations if args.solver_iterations is not None
                  else defaults['solver_iterations'])
    return dt, iterations


def _format_duration(seconds: float) -> str:
    seconds = max(0.0, seconds)
    if seconds < 90:
        return f'{seconds:.0f} s'
    if seconds < 5400:
        return f'{seconds / 60:.1f} min'
    return f'{seconds / 3600:.1f} h'


def time_per_evaluation(evaluate, n: int = 3, seed: int = 12345) -> float:
    """Seconds per evaluation here, measured on ``n`` random gaits after one warm-up."""
    rng = np.random.default_rng(seed)
    n_params = evaluate.n_params
    evaluate(rng.random(n_params))  # builds the simulator (URDF, PyBullet) once per process
    start = time.perf_counter()
    for _ in range(n):
        evaluate(rng.random(n_params))
    return (time.perf_counter() - start) / n


def gait_family_counts(archive: Archive) -> dict[str, int]:
    """Elites walking forward, backward, sideways and turning (thresholds in the module)."""
    gr = archive.generic_reward
    return {'forward': int(np.count_nonzero(gr[:, 0] > FORWARD_DX)),
            'backward': int(np.count_nonzero(gr[:, 0] < -FORWARD_DX)),
            'sideways': int(np.count_nonzero(np.abs(gr[:, 1]) > SIDEWAYS_DY)),
            'turning': int(np.count_nonzero(np.abs(gr[:, 2]) > TURNING_DYAW))}


def archive_figure(archive: Archive, path: str | os.PathLike) -> Path:
    """Heat-maps over the descriptor grid: fitness and dyaw of each elite."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    from ribs.archives import GridArchive

    # The builder's own binning, so that each elite is drawn in its cell.
    grid = GridArchive(solution_dim=1, dims=archive.metadata['grid_shape'],
                       ranges=archive.descriptor_bounds.tolist())
    cells = grid.index_of(archive.descriptors)
    fitness = np.full(grid.cells, np.nan)
    dyaw = np.full(grid.cells, np.nan)
    fitness[cells] = archive.fitness
    dyaw[cells] = archive.generic_reward[:, 2]
    (xmin, xmax), (ymin, ymax) = archive.descriptor_bounds
    extent = (xmin, xmax, ymin, ymax)
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.8), constrained_layout=True)
    panels = [(fitness, 'fitness: -|yaw - arc yaw| (rad)', 'viridis', (-np.pi, 0)),
              (dyaw, 'dyaw of the elite (rad)', 'twilight_shifted', (-np.pi, np.pi))]
    for ax, (values, title, cmap, (vmin, vmax)) in zip(axes, panels):
        image = ax.imshow(values.reshape(tuple(grid.dims)).T, origin='lower', extent=extent,
                          cmap=cmap, vmin=vmin, vmax=vmax, interpolation='nearest')
        ax.set_xlabel('final x (m, forward)')
        ax.set_ylabel('final y (m, left)')
        ax.set_title(title)
        fig.colorbar(image, ax=ax, shrink=0.85)
    meta = archive.metadata
    fig.suptitle(f'{len(archive)} elites / {grid.cells} cells, {meta["n_evaluations"]} '
                 f'evaluations, dt {meta["dt"]:.5f} s, {meta["gait_duration"]} s gaits')
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _cvt_bounds(evaluate):
    """Descriptor ranges of the duty-factor map: the robot's (its reach, one duty factor per
    leg), the hexapod's for the synthetic evaluation."""
    from sela_ros.qd.cvt import XY_DUTY_BOUNDS

    if isinstance(evaluate, RobotEvaluator):
        return evaluate.description().descriptor_bounds()
    return XY_DUTY_BOUNDS


def _new_cvt_run(args, evaluate, executor, checkpoint: Path):
    """A fresh CVT run: centroids by k-means (minutes for 10,000 cells, once; they are in
    the checkpoint from then on), a CVT archive and iso-line emitters."""
    from sela_ros.qd.cvt import CVTMapElites, make_centroids

    bounds = _cvt_bounds(evaluate)
    start = time.perf_counter()
    centroids = make_centroids(args.cells, bounds, seed=args.seed)
    print(f'{args.cells} CVT centroids in {time.perf_counter() - start:.0f} s', flush=True)
    return CVTMapElites(centroids, bounds, evaluate, executor,
                        batch_size=args.batch_size, emitters=args.emitters,
                        n_initial=args.initial,
                        seed=args.seed, checkpoint_path=checkpoint,
                        checkpoint_every=args.checkpoint_every)


def _regrid(parser, run, cells: int, seed: int) -> None:
    """``--regrid``: the resumed CVT run goes on in a CVT of ``cells`` cells (written to its
    checkpoint at once, so that the next resume starts from it)."""
    from sela_ros.qd.cvt import make_centroids

    current = int(run.scheduler.archive.cells)
    if cells == current:
        return
    if cells < current:
        parser.error(f'--regrid {cells}: the run has {current} cells already; a coarser CVT '
                     'would drop elites')
    start = time.perf_counter()
    # Fewer samples and Lloyd iterations than a fresh run's: minutes, not an hour, for tens
    # of thousands of cells (the cells need not be perfectly even).
    centroids = make_centroids(cells, run.bounds, seed=seed, samples=2 * cells,
                               iterations=10)
    before = run.progress_info()
    elites = run.regrid(centroids)
    run.save_checkpoint()
    print(f'regridded from {current} to {cells} cells ({time.perf_counter() - start:.0f} s): '
          f'{before["elites"]} elites carried into {elites} cells', flush=True)


def _exit_on_sigterm(signum, frame):
    # Unwind through `finally` so the worker pool is shut down, not orphaned.
    sys.exit(128 + signum)


def main(argv: list[str] | None = None) -> int:
    signal.signal(signal.SIGTERM, _exit_on_sigterm)
    parser = make_parser()
    args = parser.parse_args(argv)
    _check_args(parser, args)
    checkpoint = _checkpoint_path(args)

    descriptor = DESCRIPTOR_NAMES[args.descriptor]
    dt, iterations = _physics(args)
    if args.synthetic:
        evaluate = SyntheticEvaluator(delay=args.synthetic_delay, descriptor=descriptor)
        settings = evaluate.settings(dt, args.gait_duration)
    else:
        try:
            evaluate = RobotEvaluator(dt=dt, gait_duration=args.gait_duration,
                                      solver_iterations=iterations, descriptor=descriptor,
                                      robot=args.robot)
            settings = evaluate.settings()
        except ValueError as exc:
            parser.error(str(exc))

    seconds = 0.0 if args.export else time_per_evaluation(evaluate)
    if args.export:
        executor = SerialEvaluator()
    elif args.dask_scheduler:
        executor = DaskEvaluator(args.dask_scheduler)
    elif args.workers == 1:
        executor = SerialEvaluator()
    else:
        executor = ProcessPoolEvaluator(args.workers)
    try:
        parallel = executor.workers
        if not args.dask_scheduler:  # more processes than cores do not go faster
            parallel = min(parallel, os.cpu_count() or 1)
        if args.resume and checkpoint.exists():
            if _is_cvt(args):
                from sela_ros.qd.cvt import CVTMapElites

                resume = CVTMapElites.resume
            else:
                resume = GridMapElites.resume
            try:
                run = resume(checkpoint, evaluate, executor, args.checkpoint_every)
            except ValueError as exc:
                parser.error(f'--resume: {exc}')
            stored = run.info.get('settings')
            if stored is not None and stored != settings:
                parser.error(f'--resume: checkpoint {checkpoint} was made with simulator '
                             f'settings {stored}, this run uses {settings}; start afresh')
            print(f'resuming from {checkpoint}: {run.n_evaluations} evaluations done, '
                  f'{run.progress_info()}', flush=True)
            if args.regrid is not None and not args.export:
                _regrid(parser, run, args.regrid, args.seed)
        elif _is_cvt(args):
            run = _new_cvt_run(args, evaluate, executor, checkpoint)
            run.info = {'settings': settings, 'seed': args.seed}
        else:
            run = default_run(evaluate, dims=args.grid,
                              bounds=np.reshape(args.bounds, (2, 2)),
                              batch_size=args.batch_size,
                              n_initial=args.initial, seed=args.seed,
                              executor=executor, checkpoint_path=checkpoint,
                              checkpoint_every=args.checkpoint_every,
                              emitters=args.emitters, solution_dim=evaluate.n_params)
            run.info = {'settings': settings, 'seed': args.seed}
        remaining = 0 if args.export else max(0, args.evaluations - run.n_evaluations)
        start = time.perf_counter()
        if args.export:
            run.checkpoint_path = None  # read only: the build may still be writing it
        else:
            print(f'{seconds:.3f} s per evaluation on one core here; {remaining} evaluations '
                  f'on {parallel} worker(s) will take about '
                  f'{_format_duration(remaining * seconds / parallel)}', flush=True)
            run.run(args.evaluations, progress=not args.no_progress)
        wall = time.perf_counter() - start
    finally:
        executor.close()

    archive = run.to_archive(**settings, descriptor_name=descriptor,
                             fitness_name=FITNESS_NAME, seed=run.info.get('seed', args.seed),
                             damage='intact', batch_size=run.config['batch_size'],
                             evaluator='synthetic' if args.synthetic else evaluate.robot)
    archive.save(args.out)
    size = args.out.stat().st_size
    # run.elapsed and the counters survive resumes, so these are figures of the whole build.
    summary = {'evaluations': run.n_evaluations, 'this_session_evaluations': remaining,
               'this_session_wall_s': round(wall, 1), 'batch_time_s': round(run.elapsed, 1),
               'evals_per_s': round(run.n_evaluations / run.elapsed, 2) if run.elapsed else None,
               'filled_cells': len(archive),
               'cells': archive.metadata.get('cells') or int(np.prod(archive.metadata.get(
                   'grid_shape', [0]))),
               'fallen': run.n_invalid, **gait_family_counts(archive),
               'file_bytes': size, 'out': str(args.out)}
    if args.figure is not None and args.descriptor == '2d':
        summary['figure'] = str(archive_figure(archive, args.figure))
    print(json.dumps(summary), flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
