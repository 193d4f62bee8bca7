"""MAP-Elites with pyribs: fills the behaviour-performance map that SELA starts from.

pyribs supplies the archive (:class:`ribs.archives.GridArchive` here: one elite per cell of a
regular grid over the descriptor space; :mod:`sela_ros.qd.cvt` the CVT one), the iso-line
emitters (Vassiliades & Mouret 2018) and the ask/tell :class:`ribs.schedulers.Scheduler`.
What pyribs lacks comes from this package: the executors (:mod:`~sela_ros.qd.executors`:
serial, process pool, Dask), the evaluation functions (:mod:`~sela_ros.qd.evaluators`), the
run loop with its progress bar, and checkpoints. A checkpoint is a pickle of the whole
scheduler (archive, emitters and every random generator in them), written atomically every
K batches, with a per-batch journal in between, so a run killed at any moment (even by
SIGKILL) resumes without losing a finished batch and ends exactly where an uninterrupted run
ends; the file carries everything, so it resumes on another machine too (same pyribs
version). Only load checkpoints you made: unpickling runs code.

pyribs is an optional dependency (``requirements-qd.txt``): only the map builder imports
this module, never the nodes.
"""
from __future__ import annotations

import pickle
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from sela_ros.core.storage import Archive, atomic_savez, atomic_write, make_metadata
from sela_ros.qd.evaluators import EvaluationResult
from sela_ros.qd.executors import SerialEvaluator

CHECKPOINT_FORMAT_VERSION = 1

# Fitness (arc_fitness) lies in [-pi, 0]: anything above THRESHOLD_MIN may fill an empty cell,
# an invalid gait is told with INVALID_OBJECTIVE and never does. With a learning rate of 1,
# the threshold of a filled cell is its elite's objective: plain MAP-Elites.
THRESHOLD_MIN = -4.0
INVALID_OBJECTIVE = -1e9
EXTRA_FIELDS = {'generic_reward': ((3,), np.float64)}


def ribs_parts():
    """pyribs' ``(GridArchive, CVTArchive, IsoLineEmitter, Scheduler)``."""
    try:
        from ribs.archives import CVTArchive, GridArchive
        from ribs.emitters import IsoLineEmitter
        from ribs.schedulers import Scheduler
    except ImportError as exc:
        raise ImportError('the map builder needs pyribs: pip install -r requirements-qd.txt '
                          '(ribs==0.12.0)') from exc
    return GridArchive, CVTArchive, IsoLineEmitter, Scheduler


def iso_line_emitters(archive, seeds, config, initial_rng=None) -> list:
    """One pyribs ``IsoLineEmitter`` per seed, over solutions in ``[0, 1]``; each starts
    from ``config['n_initial']`` uniform random solutions, drawn from ``initial_rng`` (in
    turn) or else from a generator of the emitter's own seed."""
    _, _, IsoLineEmitter, _ = ribs_parts()
    dim = archive.solution_dim
    return [IsoLineEmitter(archive, iso_sigma=config['iso_sigma'],
                           line_sigma=config['line_sigma'], bounds=[(0.0, 1.0)] * dim,
                           batch_size=config['batch_size'], seed=int(s),
                           initial_solutions=(initial_rng or np.random.default_rng(int(s)))
                           .random((config['n_initial'], dim)))
            for s in seeds]


class MapElites:
    """MAP-Elites on a pyribs scheduler, with executors, checkpoints and a journal.

    A subclass says which archive (:meth:`_make_archive`) and what its saved map holds
    (:meth:`to_archive`); :data:`KIND` names it in checkpoints.

    Args:
        bounds: ``(low, high)`` per descriptor dimension (what ``descriptor_bounds`` says).
        evaluate: picklable ``params -> EvaluationResult`` with a ``d``-long descriptor.
        executor: evaluates batches (default :class:`SerialEvaluator`).
        batch_size: solutions per emitter and batch.
        emitters: number of iso-line emitters (each proposes ``batch_size`` per batch).
        n_initial: uniform random solutions of the first batch (per emitter).
        iso_sigma, line_sigma: iso-line variation steps.
        seed: seeds the archive and each emitter (``np.random.default_rng`` streams).
        checkpoint_path: where to write checkpoints (``None``: no checkpoints).
        checkpoint_every: write a full checkpoint every K batches; the batches in between
            are journalled one file each, so no finished batch is lost.

    Raises:
        ValueError: on inconsistent bounds or a non-positive size.
    """

    KIND = None

    def __init__(self, bounds, evaluate: Callable, executor=None, batch_size: int = 100,
                 emitters: int = 1, n_initial: int | None = None, iso_sigma: float = 0.01,
                 line_sigma: float = 0.2, seed: int = 0, checkpoint_path=None,
                 checkpoint_every: int = 10, solution_dim: int | None = None):
        _, _, _, Scheduler = ribs_parts()
        if solution_dim is None:  # the robot's gait parameters, as its evaluator says
            solution_dim = getattr(evaluate, 'n_params', None)
            if solution_dim is None:
                raise ValueError('solution_dim: give the number of gait parameters (the '
                                 'evaluation function has no n_params)')
        bounds = np.asarray(bounds, dtype=np.float64)
        if bounds.ndim != 2 or bounds.shape[1] != 2 or not np.all(np.isfinite(bounds)) \
                or not np.all(bounds[:, 1] > bounds[:, 0]):
            raise ValueError(f'bounds must be finite (low, high) pairs with low < high, got '
                             f'{bounds.tolist()}')
        if batch_size < 1 or emitters < 1 or solution_dim < 1:
            raise ValueError(f'batch_size, emitters and solution_dim must be >= 1, got '
                             f'{batch_size}, {emitters}, {solution_dim}')
        self.bounds = bounds
        self.seed = int(seed)
        self.config = {'batch_size': int(batch_size), 'emitters': int(emitters),
                       'n_initial': int(batch_size if n_initial is None else n_initial),
                       'iso_sigma': float(iso_sigma), 'line_sigma': float(line_sigma),
                       'seed': int(seed)}
        seeds = np.random.SeedSequence(seed).generate_state(emitters + 2)
        archive = self._make_archive(solution_dim, int(seeds[0]))
        self.scheduler = Scheduler(archive, iso_line_emitters(
            archive, seeds[2:], self.config, np.random.default_rng(int(seeds[1]))))
        self._start(evaluate, executor, checkpoint_path, checkpoint_every)

    def _start(self, evaluate, executor, checkpoint_path, checkpoint_every):
        if checkpoint_every < 1:
            raise ValueError(f'checkpoint_every must be >= 1, got {checkpoint_every}')
        self.evaluate = evaluate
        self.executor = executor if executor is not None else SerialEvaluator()
        self.checkpoint_path = Path(checkpoint_path) if checkpoint_path else None
        self.checkpoint_every = int(checkpoint_every)
        self.n_evaluations = 0
        self.n_batches = 0
        self.n_invalid = 0
        self.elapsed = 0.0
        #: Free-form JSON-serialisable facts saved with checkpoints (e.g. simulator settings).
        self.info: dict[str, Any] = {}
        self._pending: np.ndarray | None = None

    def _make_archive(self, solution_dim: int, seed: int):
        raise NotImplementedError

    @property
    def archive(self):
        """The pyribs archive of elites."""
        return self.scheduler.archive

    # ask/tell ------------------------------------------------------------------------
    def ask(self, n: int | None = None) -> np.ndarray:
        """The next batch: every emitter's ``batch_size`` solutions (``n`` is ignored).

        pyribs emitters ask whole batches, so a run ends on the first batch that reaches
        its budget instead of shortening the last one.
        """
        self._pending = np.asarray(self.scheduler.ask(), dtype=np.float64)
        return self._pending

    def tell(self, solutions: np.ndarray, results: Sequence[EvaluationResult]) -> int:
        """Insert evaluated solutions; invalid ones (falls) are kept out of the archive.

        Returns:
            The number of cells this batch filled.
        """
        solutions = np.asarray(solutions, dtype=np.float64)
        if self._pending is None or solutions.shape != self._pending.shape \
                or not np.array_equal(solutions, self._pending):
            raise ValueError('tell() must follow ask() with the solutions it returned')
        if len(results) != len(solutions):
            raise ValueError(f'got {len(results)} results for {len(solutions)} solutions')
        n = len(solutions)
        d = self.bounds.shape[0]
        valid = np.array([bool(r.valid) for r in results], dtype=bool)
        objectives = np.array([float(r.fitness) if r.valid else 0.0 for r in results])
        measures = np.array([np.asarray(r.descriptor, dtype=np.float64)
                             for r in results]).reshape(n, d)
        rewards = np.array([np.asarray(r.generic_reward, dtype=np.float64)
                            for r in results]).reshape(n, 3)
        valid &= np.isfinite(objectives) & np.all(np.isfinite(measures), axis=1)
        # The scheduler wants a result for every solution it asked; an invalid one (a fall)
        # is told with an objective below the archive's threshold_min, so it takes no cell,
        # and with a finite stand-in measure.
        objectives[~valid] = INVALID_OBJECTIVE
        measures[~valid] = self.bounds[:, 0]
        rewards[~np.all(np.isfinite(rewards), axis=1)] = 0.0
        before = self.archive.stats.num_elites
        self.scheduler.tell(objectives, measures, generic_reward=rewards)
        self.n_evaluations += n
        self.n_invalid += int(np.count_nonzero(~valid))
        self.n_batches += 1
        self._pending = None
        return self.archive.stats.num_elites - before

    def step(self) -> int:
        """Ask, evaluate on the executor, tell, and checkpoint/journal as configured."""
        solutions = self.ask()
        results = self.executor.map(self.evaluate, solutions)
        filled = self.tell(solutions, results)
        if self.checkpoint_path is not None:
            if self.n_batches % self.checkpoint_every == 0:
                self.save_checkpoint()
            else:
                self._journal(solutions, results)
        return filled

    def run(self, n_evaluations: int, progress: bool = True):
        """Evaluate until ``n_evaluations`` in total (counting those before a resume).

        Args:
            n_evaluations: total budget; the batch that reaches it is the last.
            progress: show a tqdm bar (evaluations/s, elites, coverage) on stderr.
        """
        if n_evaluations < 0:
            raise ValueError(f'n_evaluations must be >= 0, got {n_evaluations}')
        bar = None
        if progress:
            from tqdm import tqdm

            tty = sys.stderr.isatty()
            bar = tqdm(total=n_evaluations, initial=self.n_evaluations, unit='eval',
                       dynamic_ncols=True, mininterval=0.5 if tty else 30.0,
                       desc='MAP-Elites', file=sys.stderr)
        try:
            while self.n_evaluations < n_evaluations:
                start = time.perf_counter()
                before = self.n_evaluations
                self.step()
                self.elapsed += time.perf_counter() - start
                if bar is not None:
                    bar.set_postfix(**self.progress_info(), refresh=False)
                    bar.update(self.n_evaluations - before)
            if self.checkpoint_path is not None and self.n_batches % self.checkpoint_every:
                self.save_checkpoint()
        finally:
            if bar is not None:
                bar.close()
        return self.archive

    def progress_info(self) -> dict[str, Any]:
        """Figures shown beside the progress bar."""
        stats = self.archive.stats
        return {'elites': stats.num_elites, 'coverage': f'{stats.coverage:.1%}'}

    # checkpoints -----------------------------------------------------------------------
    @property
    def journal_dir(self) -> Path:
        """Directory of per-batch journal files beside the checkpoint."""
        return self.checkpoint_path.with_name(self.checkpoint_path.name + '.journal')

    def state(self) -> dict[str, Any]:
        """Counters and configuration (the scheduler itself is pickled beside them)."""
        import ribs

        return {'format_version': CHECKPOINT_FORMAT_VERSION, 'kind': self.KIND,
                'ribs_version': ribs.__version__, 'config': self.config,
                'bounds': self.bounds.tolist(), 'n_evaluations': self.n_evaluations,
                'n_batches': self.n_batches, 'n_invalid': self.n_invalid,
                'elapsed': self.elapsed, 'info': self.info}

    def save_checkpoint(self, path=None) -> Path:
        """Write the scheduler and counters atomically; prune the journal."""
        path = Path(path) if path is not None else self.checkpoint_path
        if path is None:
            raise ValueError('no checkpoint path: pass one or set checkpoint_path')
        payload = {'state': self.state(), 'scheduler': self.scheduler}
        atomic_write(path, lambda handle: pickle.dump(payload, handle,
                                                      protocol=pickle.HIGHEST_PROTOCOL))
        if self.checkpoint_path is not None and path == self.checkpoint_path:
            self._prune_journal()
        return path

    def _journal(self, solutions: np.ndarray, results: Sequence[EvaluationResult]) -> None:
        n = len(results)
        atomic_savez(
            self.journal_dir / f'batch_{self.n_batches:09d}.npz',
            solutions=solutions,
            valid=np.array([bool(r.valid) for r in results]),
            fitness=np.array([r.fitness for r in results], dtype=float),
            descriptor=np.array([np.asarray(r.descriptor, float) for r in results]).reshape(n, -1),
            generic_reward=np.array([np.asarray(r.generic_reward, float)
                                     for r in results]).reshape(n, 3),
        )

    def _prune_journal(self) -> None:
        if not self.journal_dir.is_dir():
            return
        for entry in self.journal_dir.glob('batch_*.npz'):
            if int(entry.stem.split('_')[1]) <= self.n_batches:
                entry.unlink(missing_ok=True)

    def _replay_journal(self) -> int:
        """Re-tell journalled batches newer than the checkpoint; returns how many."""
        if not self.journal_dir.is_dir():
            return 0
        replayed = 0
        while True:
            entry = self.journal_dir / f'batch_{self.n_batches + 1:09d}.npz'
            if not entry.is_file():
                break
            with np.load(entry, allow_pickle=False) as npz:
                data = {k: npz[k] for k in npz.files}
            snapshot = pickle.dumps(self.scheduler, protocol=pickle.HIGHEST_PROTOCOL)
            solutions = self.ask()
            if not np.array_equal(solutions, data['solutions']):
                # Not this run's batch (e.g. settings changed): undo the ask, stop replaying.
                self.scheduler = pickle.loads(snapshot)
                self._pending = None
                break
            results = [EvaluationResult(bool(v), float(f), d, g) for v, f, d, g in
                       zip(data['valid'], data['fitness'], data['descriptor'],
                           data['generic_reward'])]
            self.tell(solutions, results)
            replayed += 1
        return replayed

    @classmethod
    def resume(cls, checkpoint_path, evaluate: Callable, executor=None,
               checkpoint_every: int = 10) -> MapElites:
        """Rebuild a run from its checkpoint (any path: it may have been carried) and the
        journal beside it, ready to ``run()`` on.

        Raises:
            ValueError: the checkpoint is missing, unreadable or of another kind.
        """
        checkpoint_path = Path(checkpoint_path)
        try:
            with open(checkpoint_path, 'rb') as handle:
                payload = pickle.load(handle)
            state, scheduler = payload['state'], payload['scheduler']
        except Exception as exc:
            raise ValueError(f'cannot resume from {checkpoint_path}: {type(exc).__name__}: '
                             f'{exc}; start a fresh run without --resume') from None
        if state.get('format_version') != CHECKPOINT_FORMAT_VERSION or \
                state.get('kind') != cls.KIND:
            raise ValueError(f'{checkpoint_path} is not a {cls.KIND} checkpoint of format '
                             f'{CHECKPOINT_FORMAT_VERSION}; start a fresh run')
        run = cls.__new__(cls)
        run.scheduler = scheduler
        run.bounds = np.asarray(state['bounds'], dtype=np.float64)
        run.config = dict(state['config'])
        run.seed = int(run.config['seed'])
        run._start(evaluate, executor, checkpoint_path, checkpoint_every)
        run.n_evaluations = int(state['n_evaluations'])
        run.n_batches = int(state['n_batches'])
        run.n_invalid = int(state['n_invalid'])
        run.elapsed = float(state['elapsed'])
        run.info = dict(state.get('info', {}))
        run._replay_journal()
        return run

    def _elites(self) -> dict[str, np.ndarray]:
        """The elites in cell order: solution, objective, measures, generic_reward."""
        data = self.archive.data(['solution', 'objective', 'measures', 'generic_reward',
                                  'index'])
        order = np.argsort(data['index'])
        return {k: np.asarray(v)[order] for k, v in data.items()}

    def _metadata(self, **values: Any) -> dict:
        return make_metadata(descriptor_bounds=self.bounds.tolist(),
                             n_evaluations=self.n_evaluations, n_invalid=self.n_invalid,
                             seed=self.seed, emitter='iso_line', emitters=self.config['emitters'],
                             batch_size=self.config['batch_size'], **values)

    def to_archive(self, **metadata: Any) -> Archive:
        raise NotImplementedError


class GridMapElites(MapElites):
    """MAP-Elites on a pyribs ``GridArchive``: one elite per cell of a regular grid.

    Args:
        dims: cells per descriptor dimension, e.g. ``(64, 64)``.
        bounds: ``(low, high)`` per dimension; a descriptor outside is filed into the edge
            cell.
        Others: as :class:`MapElites`.
    """

    KIND = 'grid'

    def __init__(self, dims: Sequence[int], bounds, evaluate: Callable, executor=None,
                 **kwargs):
        self.dims = tuple(int(n) for n in dims)
        if not self.dims or any(n < 1 for n in self.dims):
            raise ValueError(f'dims must be positive cell counts, e.g. (64, 64); got {dims}')
        if np.shape(bounds) != (len(self.dims), 2):
            raise ValueError(f'bounds must have one (low, high) pair per dimension, i.e. '
                             f'shape ({len(self.dims)}, 2); got shape {np.shape(bounds)}')
        super().__init__(bounds, evaluate, executor, **kwargs)

    def _make_archive(self, solution_dim: int, seed: int):
        GridArchive, _, _, _ = ribs_parts()
        return GridArchive(solution_dim=solution_dim, dims=self.dims,
                           ranges=self.bounds.tolist(), seed=seed, learning_rate=1.0,
                           threshold_min=THRESHOLD_MIN, extra_fields=EXTRA_FIELDS)

    @classmethod
    def resume(cls, checkpoint_path, evaluate: Callable, executor=None,
               checkpoint_every: int = 10) -> GridMapElites:
        run = super().resume(checkpoint_path, evaluate, executor, checkpoint_every)
        run.dims = tuple(int(n) for n in run.archive.dims)
        return run

    def to_archive(self, **metadata: Any) -> Archive:
        """The elites as an :class:`~sela_ros.core.storage.Archive` (for SELA, or to save).

        Args:
            **metadata: simulator settings, descriptor/fitness names, ...; the grid shape,
                bounds and counters are filled in from this run.
        """
        elites = self._elites()
        meta = self._metadata(grid_shape=list(self.dims))
        meta.update(metadata)
        return Archive(params=np.clip(elites['solution'], 0.0, 1.0),
                       descriptors=elites['measures'], generic_reward=elites['generic_reward'],
                       fitness=elites['objective'], metadata=meta)


def default_run(evaluate: Callable, dims: Sequence[int] = (64, 64),
                bounds: Sequence[Sequence[float]] = ((-1.0, 1.0), (-1.0, 1.0)),
                batch_size: int = 100, n_initial: int | None = None, seed: int = 0,
                executor=None, checkpoint_path=None, checkpoint_every: int = 10,
                emitters: int = 1, solution_dim: int | None = None) -> GridMapElites:
    """A fresh 2-D :class:`GridMapElites` with the project's defaults (iso-line emitters)."""
    return GridMapElites(dims, bounds, evaluate, executor=executor, batch_size=batch_size,
                         emitters=emitters, n_initial=n_initial, seed=seed,
                         checkpoint_path=checkpoint_path, checkpoint_every=checkpoint_every,
                         solution_dim=solution_dim)


__all__ = ['CHECKPOINT_FORMAT_VERSION', 'GridMapElites', 'MapElites', 'default_run']
