"""MAP-Elites over a CVT archive with pyribs: the paper's 8-D behaviour-performance map.

pyribs supplies the archive (:class:`ribs.archives.CVTArchive`: one elite per Voronoi cell
around fixed centroids), the iso-line emitters (Vassiliades & Mouret 2018) and the
ask/tell :class:`ribs.schedulers.Scheduler`. What pyribs lacks comes from this package:
the executors (:mod:`~sela_ros.qd.executors`: serial, process pool, Dask), the evaluation
functions (:mod:`~sela_ros.qd.evaluators`), the run loop with its progress bar, and the
per-batch journal beside an atomic checkpoint (:mod:`~sela_ros.qd.map_elites`). A
checkpoint is a pickle of the whole scheduler (archive, emitters and every random
generator in them), so a run killed at any moment, even by SIGKILL, resumes from its
checkpoint and journal and ends exactly where an uninterrupted run ends; the file carries
everything, so it resumes on another machine too (same pyribs version). Only load
checkpoints you made: unpickling runs code.

pyribs is an optional dependency (``requirements-qd.txt``): only the map builder imports
this module, never the nodes.
"""
from __future__ import annotations

import pickle
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from sela_ros.core.storage import Archive, atomic_write, make_metadata
from sela_ros.qd.evaluators import EvaluationResult
from sela_ros.qd.map_elites import CHECKPOINT_FORMAT_VERSION, MapElites

#: Default descriptor ranges of the 8-D map: final (x, y) in metres, six duty factors.
XY_DUTY_BOUNDS = ((-0.45, 0.45), (-0.45, 0.45)) + ((0.0, 1.0),) * 6

# Fitness (arc_fitness) lies in [-pi, 0]: anything above THRESHOLD_MIN may fill an empty cell,
# an invalid gait is told with INVALID_OBJECTIVE and never does.
THRESHOLD_MIN = -4.0
INVALID_OBJECTIVE = -1e9


def _ribs():
    try:
        import ribs  # noqa: F401
        from ribs.archives import CVTArchive
        from ribs.emitters import IsoLineEmitter
        from ribs.schedulers import Scheduler
    except ImportError as exc:
        raise ImportError('the CVT map builder needs pyribs: pip install -r '
                          'requirements-qd.txt (ribs==0.12.0)') from exc
    return CVTArchive, IsoLineEmitter, Scheduler


def disc_samples(bounds: Sequence[Sequence[float]], n: int, rng: np.random.Generator,
                 disc_dims: int = 2) -> np.ndarray:
    """``n`` points for k-means: uniform in the disc inscribed in the first two ranges
    (where a 3 s gait can end: the box's corners are out of reach) and uniform in the
    other ranges, so that no centroid is wasted on a corner no gait reaches.
    """
    bounds = np.asarray(bounds, dtype=np.float64)
    points = rng.uniform(bounds[:, 0], bounds[:, 1], size=(n, len(bounds)))
    if disc_dims:
        centre = bounds[:disc_dims].mean(axis=1)
        half = (bounds[:disc_dims, 1] - bounds[:disc_dims, 0]) / 2.0
        direction = rng.normal(size=(n, disc_dims))
        direction /= np.linalg.norm(direction, axis=1, keepdims=True)
        radius = rng.random(n) ** (1.0 / disc_dims)
        points[:, :disc_dims] = centre + direction * radius[:, None] * half
    return points


def make_centroids(cells: int, bounds: Sequence[Sequence[float]], seed: int = 0,
                   samples: int | None = None, disc: bool = True,
                   iterations: int = 20) -> np.ndarray:
    """``(cells, d)`` CVT centroids: k-means (pyribs) over :func:`disc_samples`.

    Args:
        cells: number of centroids.
        bounds: ``(low, high)`` per descriptor dimension.
        seed: seed of the samples and of k-means.
        samples: points k-means runs over (default ``max(5 cells, 20000)``).
        disc: sample the first two dimensions in their inscribed disc (else the box).
        iterations: Lloyd iterations of k-means.
    """
    from ribs.archives import k_means_centroids

    bounds = np.asarray(bounds, dtype=np.float64)
    if cells < 1:
        raise ValueError(f'cells must be >= 1, got {cells}')
    n = samples if samples is not None else max(5 * cells, 20000)
    points = disc_samples(bounds, n, np.random.default_rng(seed), 2 if disc else 0)
    # 20 Lloyd iterations: the cells need not be perfectly even, and 20,000 of them over
    # 100,000 samples then take minutes on one core, not the better part of an hour.
    centroids = k_means_centroids(centroids=cells, ranges=bounds.tolist(), samples=points,
                                  seed=seed, k_means_kwargs={'max_iter': int(iterations)})
    if isinstance(centroids, tuple):  # some versions also return the samples
        centroids = centroids[0]
    return np.asarray(centroids, dtype=np.float64)


class CVTMapElites(MapElites):
    """MAP-Elites on a pyribs scheduler (CVT archive, iso-line emitters), with checkpoints.

    Args:
        centroids: ``(cells, d)`` centroids of the CVT (see :func:`make_centroids`).
        bounds: ``(low, high)`` per descriptor dimension (what ``descriptor_bounds`` says).
        evaluate: picklable ``params -> EvaluationResult`` with a ``d``-long descriptor.
        executor: evaluates batches (default serial).
        batch_size: solutions per emitter and batch.
        emitters: number of iso-line emitters (each proposes ``batch_size`` per batch).
        n_initial: uniform random solutions of the first batch (per emitter).
        iso_sigma, line_sigma: iso-line variation steps.
        seed: seeds the archive and each emitter (``np.random.default_rng`` streams).
        checkpoint_path, checkpoint_every: as :class:`~sela_ros.qd.map_elites.MapElites`.

    Raises:
        ValueError: on inconsistent centroids/bounds or a non-positive size.
    """

    def __init__(self, centroids, bounds, evaluate: Callable, executor=None,
                 batch_size: int = 100, emitters: int = 1, n_initial: int | None = None,
                 iso_sigma: float = 0.01, line_sigma: float = 0.2, seed: int = 0,
                 checkpoint_path=None, checkpoint_every: int = 10, solution_dim: int = 36):
        CVTArchive, IsoLineEmitter, Scheduler = _ribs()
        centroids = np.asarray(centroids, dtype=np.float64)
        bounds = np.asarray(bounds, dtype=np.float64)
        if centroids.ndim != 2 or bounds.shape != (centroids.shape[1], 2):
            raise ValueError(f'centroids must be (cells, d) and bounds (d, 2); got '
                             f'{centroids.shape} and {bounds.shape}')
        if not np.all(bounds[:, 1] > bounds[:, 0]):
            raise ValueError(f'bounds must have low < high, got {bounds.tolist()}')
        if batch_size < 1 or emitters < 1:
            raise ValueError(f'batch_size and emitters must be >= 1, got {batch_size}, '
                             f'{emitters}')
        n_initial = batch_size if n_initial is None else int(n_initial)
        seeds = np.random.SeedSequence(seed).generate_state(emitters + 2)
        archive = CVTArchive(solution_dim=solution_dim, centroids=centroids,
                             ranges=bounds.tolist(), seed=int(seeds[0]),
                             learning_rate=1.0, threshold_min=THRESHOLD_MIN,
                             extra_fields={'generic_reward': ((3,), np.float64)})
        init_rng = np.random.default_rng(int(seeds[1]))
        emitter_list = [
            IsoLineEmitter(archive, iso_sigma=iso_sigma, line_sigma=line_sigma,
                           initial_solutions=init_rng.random((n_initial, solution_dim)),
                           bounds=[(0.0, 1.0)] * solution_dim, batch_size=batch_size,
                           seed=int(s))
            for s in seeds[2:]]
        scheduler = Scheduler(archive, emitter_list)
        super().__init__(archive, None, evaluate, executor, checkpoint_path, checkpoint_every)
        self.scheduler = scheduler
        self.bounds = bounds
        self.seed = int(seed)
        self.config = {'batch_size': int(batch_size), 'emitters': int(emitters),
                       'n_initial': n_initial, 'iso_sigma': float(iso_sigma),
                       'line_sigma': float(line_sigma), 'seed': int(seed)}

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
        before = self.scheduler.archive.stats.num_elites
        self.scheduler.tell(objectives, measures, generic_reward=rewards)
        self.n_evaluations += n
        self.n_invalid += int(np.count_nonzero(~valid))
        self.n_batches += 1
        self._pending = None
        return self.scheduler.archive.stats.num_elites - before

    def _next_batch_size(self, remaining: int) -> int:
        return self.config['batch_size'] * self.config['emitters']

    def progress_info(self) -> dict[str, Any]:
        stats = self.scheduler.archive.stats
        return {'elites': stats.num_elites, 'coverage': f'{stats.coverage:.1%}'}

    # checkpoints -----------------------------------------------------------------------
    def state(self) -> dict[str, Any]:
        """Counters and configuration (the scheduler itself is pickled beside them)."""
        import ribs

        return {'format_version': CHECKPOINT_FORMAT_VERSION, 'kind': 'cvt',
                'ribs_version': ribs.__version__, 'config': self.config,
                'bounds': self.bounds.tolist(), 'n_evaluations': self.n_evaluations,
                'n_batches': self.n_batches, 'n_invalid': self.n_invalid,
                'elapsed': self.elapsed, 'info': self.info}

    def _write_checkpoint(self, path: Path) -> None:
        payload = {'state': self.state(), 'scheduler': self.scheduler}
        atomic_write(path, lambda handle: pickle.dump(payload, handle,
                                                      protocol=pickle.HIGHEST_PROTOCOL))

    def _rng_snapshot(self) -> Any:
        return pickle.dumps(self.scheduler, protocol=pickle.HIGHEST_PROTOCOL)

    def _rng_restore(self, snapshot: Any) -> None:
        self.scheduler = pickle.loads(snapshot)
        self.archive = self.scheduler.archive

    @classmethod
    def resume(cls, checkpoint_path, evaluate: Callable, executor=None,
               checkpoint_every: int = 10) -> CVTMapElites:
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
                state.get('kind') != 'cvt':
            raise ValueError(f'{checkpoint_path} is not a CVT checkpoint of format '
                             f'{CHECKPOINT_FORMAT_VERSION}; start a fresh run')
        run = cls.__new__(cls)
        MapElites.__init__(run, scheduler.archive, None, evaluate, executor, checkpoint_path,
                           checkpoint_every)
        run.scheduler = scheduler
        run.bounds = np.asarray(state['bounds'], dtype=np.float64)
        run.config = dict(state['config'])
        run.seed = int(run.config['seed'])
        return run.resumed(state)

    def regrid(self, centroids) -> int:
        """Go on in a finer CVT: a new archive on ``centroids`` (more cells than now), the
        elites found so far carried into it (nothing is evaluated again; in 8-D, elites of
        neighbouring cells often fall in one new cell, which keeps the better), and new
        iso-line emitters over it.

        A CVT of ``k`` cells in 8-D fills slowly once its reachable cells are taken; more
        cells keep the same evaluations finding new elites. The emitters are seeded from the
        run's seed and batch count, so a run regridded at the same point is the same run.

        Returns:
            The number of elites in the new archive.

        Raises:
            ValueError: ``centroids`` of another dimension, or not more cells than now.
        """
        CVTArchive, IsoLineEmitter, Scheduler = _ribs()
        old = self.scheduler.archive
        centroids = np.asarray(centroids, dtype=np.float64)
        if centroids.ndim != 2 or centroids.shape[1] != self.bounds.shape[0]:
            raise ValueError(f'centroids must be (cells, {self.bounds.shape[0]}), got '
                             f'{centroids.shape}')
        if len(centroids) <= old.cells:
            raise ValueError(f'a regrid takes more cells than the {old.cells} of the run, got '
                             f'{len(centroids)}')
        c = self.config
        seeds = np.random.SeedSequence([c['seed'], self.n_batches]).generate_state(
            c['emitters'] + 1)
        archive = CVTArchive(solution_dim=old.solution_dim, centroids=centroids,
                             ranges=self.bounds.tolist(), seed=int(seeds[0]),
                             learning_rate=1.0, threshold_min=THRESHOLD_MIN,
                             extra_fields={'generic_reward': ((3,), np.float64)})
        data = old.data(['solution', 'objective', 'measures', 'generic_reward'])
        if len(data['objective']):
            archive.add(data['solution'], data['objective'], data['measures'],
                        generic_reward=data['generic_reward'])
        emitters = [IsoLineEmitter(archive, iso_sigma=c['iso_sigma'], line_sigma=c['line_sigma'],
                                   bounds=[(0.0, 1.0)] * old.solution_dim,
                                   batch_size=c['batch_size'], seed=int(s),
                                   initial_solutions=np.random.default_rng(int(s)).random(
                                       (c['n_initial'], old.solution_dim)))
                   for s in seeds[1:]]
        self.scheduler = Scheduler(archive, emitters)
        self.archive = archive
        self._pending = None
        self.info.setdefault('regrids', []).append(
            {'at_evaluations': self.n_evaluations, 'from_cells': int(old.cells),
             'to_cells': int(archive.cells), 'elites_before': int(old.stats.num_elites),
             'elites_after': int(archive.stats.num_elites)})
        return int(archive.stats.num_elites)

    def to_archive(self, **metadata: Any) -> Archive:
        """The elites as an :class:`~sela_ros.core.storage.Archive`, centroids included.

        Args:
            **metadata: simulator settings, descriptor/fitness names, ...; the CVT, bounds
                and counters are filled in from this run.
        """
        archive = self.scheduler.archive
        data = archive.data(['solution', 'objective', 'measures', 'generic_reward', 'index'])
        order = np.argsort(data['index'])
        meta = make_metadata(archive_kind='cvt', cells=int(archive.cells),
                             descriptor_bounds=self.bounds.tolist(),
                             n_evaluations=self.n_evaluations, n_invalid=self.n_invalid,
                             seed=self.seed, emitter='iso_line', emitters=self.config['emitters'],
                             batch_size=self.config['batch_size'])
        meta.update(metadata)
        return Archive(params=np.clip(data['solution'][order], 0.0, 1.0),
                       descriptors=data['measures'][order],
                       generic_reward=data['generic_reward'][order],
                       fitness=data['objective'][order], metadata=meta,
                       centroids=np.asarray(archive.centroids, dtype=np.float64))


__all__ = ['CVTMapElites', 'XY_DUTY_BOUNDS', 'disc_samples', 'make_centroids']
