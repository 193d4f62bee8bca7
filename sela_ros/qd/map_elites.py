"""MAP-Elites: fills the behaviour-performance map that SELA starts from.

pyribs-like parts, each swappable: an archive (:mod:`sela_ros.qd.grid_archive`), an emitter
(:mod:`sela_ros.qd.emitter`), an evaluation function (:mod:`sela_ros.qd.evaluators`) and an
executor (:mod:`sela_ros.qd.executors`). :class:`MapElites` composes them: ask/tell, a run
loop with a progress bar, and checkpoints written atomically every K batches plus a
per-batch journal, so a run killed at any moment (even by SIGKILL) resumes without losing a
finished batch and continues the same random stream, ending exactly where an uninterrupted
run ends.
"""
from __future__ import annotations

import json
import os
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from sela_ros.core.storage import Archive, atomic_savez, make_metadata
from sela_ros.qd.emitter import MapElitesEmitter
from sela_ros.qd.evaluators import EvaluationResult
from sela_ros.qd.executors import SerialEvaluator
from sela_ros.qd.grid_archive import GridArchive

CHECKPOINT_FORMAT_VERSION = 1


class MapElites:
    """MAP-Elites: an archive, an emitter and an evaluation function, with checkpoints.

    Args:
        archive: the grid of elites.
        emitter: proposes solutions.
        evaluate: picklable ``params -> EvaluationResult``.
        executor: evaluates batches (default :class:`SerialEvaluator`).
        checkpoint_path: where to write checkpoints (``None``: no checkpoints).
        checkpoint_every: write a full checkpoint every K batches; the batches in between
            are journalled one file each, so no finished batch is lost.
    """

    def __init__(self, archive: GridArchive, emitter: MapElitesEmitter, evaluate: Callable,
                 executor=None, checkpoint_path: str | os.PathLike | None = None,
                 checkpoint_every: int = 10):
        if checkpoint_every < 1:
            raise ValueError(f'checkpoint_every must be >= 1, got {checkpoint_every}')
        self.archive = archive
        self.emitter = emitter
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

    # ask/tell ------------------------------------------------------------------------
    def ask(self, n: int | None = None) -> np.ndarray:
        """The next batch of solutions to evaluate."""
        self._pending = self.emitter.ask(n)
        return self._pending

    def tell(self, solutions: np.ndarray, results: Sequence[EvaluationResult]) -> np.ndarray:
        """Insert evaluated solutions; invalid ones (falls) are discarded.

        Returns:
            ``(n,)`` insertion status (see :meth:`GridArchive.add`).
        """
        solutions = np.asarray(solutions, dtype=np.float64)
        if len(results) != len(solutions):
            raise ValueError(f'got {len(results)} results for {len(solutions)} solutions')
        n = len(solutions)
        valid = np.array([bool(r.valid) for r in results], dtype=bool)
        d = len(self.archive.dims)
        objectives = np.array([r.fitness if r.valid else -np.inf for r in results], dtype=float)
        measures = np.array([np.asarray(r.descriptor, dtype=float) for r in results]).reshape(n, d)
        rewards = np.array([np.asarray(r.generic_reward, dtype=float)
                            for r in results]).reshape(n, 3)
        objectives[~valid] = -np.inf
        status = self.archive.add(solutions, objectives, measures, generic_reward=rewards)
        self.emitter.tell(solutions, objectives, measures, status)
        self.n_evaluations += n
        self.n_invalid += int(np.count_nonzero(~valid))
        self.n_batches += 1
        self._pending = None
        return status

    def step(self, n: int | None = None) -> np.ndarray:
        """Ask, evaluate on the executor, tell, and checkpoint/journal as configured."""
        solutions = self.ask(n)
        results = self.executor.map(self.evaluate, solutions)
        status = self.tell(solutions, results)
        if self.checkpoint_path is not None:
            if self.n_batches % self.checkpoint_every == 0:
                self.save_checkpoint()
            else:
                self._journal(solutions, results)
        return status

    def run(self, n_evaluations: int, progress: bool = True) -> GridArchive:
        """Evaluate until ``n_evaluations`` in total (counting those before a resume).

        Args:
            n_evaluations: total budget; the last batch is shortened to hit it exactly.
            progress: show a tqdm bar (evaluations/s, filled cells) on stderr.
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
                self.step(self._next_batch_size(n_evaluations - self.n_evaluations))
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

    def _next_batch_size(self, remaining: int) -> int:
        """Solutions to ask for next; the last batch is shortened to end on the budget."""
        return min(self.emitter.batch_size, remaining)

    def progress_info(self) -> dict[str, Any]:
        """Figures shown beside the progress bar."""
        return {'cells': self.archive.num_elites, 'coverage': f'{self.archive.coverage:.1%}'}

    # checkpoints -----------------------------------------------------------------------
    @property
    def journal_dir(self) -> Path:
        """Directory of per-batch journal files beside the checkpoint."""
        return self.checkpoint_path.with_name(self.checkpoint_path.name + '.journal')

    def state(self) -> dict[str, Any]:
        """JSON-serialisable run state (everything but the archive's arrays)."""
        return {'format_version': CHECKPOINT_FORMAT_VERSION,
                'dims': list(self.archive.dims), 'bounds': self.archive.bounds.tolist(),
                'solution_dim': self.archive.solution_dim,
                'extra_fields': self.archive.extra_fields,
                'emitter': self.emitter.state_dict(),
                'n_evaluations': self.n_evaluations, 'n_batches': self.n_batches,
                'n_invalid': self.n_invalid, 'elapsed': self.elapsed, 'info': self.info}

    def save_checkpoint(self, path: str | os.PathLike | None = None) -> Path:
        """Write archive + emitter RNG state + counters atomically; prune the journal."""
        path = Path(path) if path is not None else self.checkpoint_path
        if path is None:
            raise ValueError('no checkpoint path: pass one or set checkpoint_path')
        self._write_checkpoint(path)
        if self.checkpoint_path is not None and path == self.checkpoint_path:
            self._prune_journal()
        return path

    def _write_checkpoint(self, path: Path) -> None:
        arrays = dict(self.archive.state_dict())
        arrays['state'] = np.array(json.dumps(self.state()))
        atomic_savez(path, **arrays)

    def _rng_snapshot(self) -> Any:
        """Whatever :meth:`ask` changes, so that an ask can be undone."""
        return self.emitter.rng.bit_generator.state, self.emitter.n_asked

    def _rng_restore(self, snapshot: Any) -> None:
        self.emitter.rng.bit_generator.state, self.emitter.n_asked = snapshot

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
            snapshot = self._rng_snapshot()
            solutions = self.ask(len(data['solutions']))
            if not np.array_equal(solutions, data['solutions']):
                # Not this run's batch (e.g. settings changed): undo the ask, stop replaying.
                self._rng_restore(snapshot)
                self._pending = None
                break
            results = [EvaluationResult(bool(v), float(f), d, g) for v, f, d, g in
                       zip(data['valid'], data['fitness'], data['descriptor'],
                           data['generic_reward'])]
            self.tell(solutions, results)
            replayed += 1
        return replayed

    @classmethod
    def resume(cls, checkpoint_path: str | os.PathLike, evaluate: Callable, executor=None,
               checkpoint_every: int = 10) -> MapElites:
        """Rebuild a run from its checkpoint and journal, ready to ``run()`` on.

        Raises:
            ValueError: the checkpoint is missing or unreadable.
        """
        checkpoint_path = Path(checkpoint_path)
        try:
            with np.load(checkpoint_path, allow_pickle=False) as npz:
                arrays = {k: npz[k] for k in npz.files}
            state = json.loads(str(arrays.pop('state')))
        except Exception as exc:
            raise ValueError(f'cannot resume from {checkpoint_path}: {type(exc).__name__}: '
                             f'{exc}; start a fresh run without --resume') from None
        if state.get('format_version') != CHECKPOINT_FORMAT_VERSION:
            raise ValueError(f'{checkpoint_path} has checkpoint format '
                             f'{state.get("format_version")!r}, expected '
                             f'{CHECKPOINT_FORMAT_VERSION}; start a fresh run')
        archive = GridArchive(state['dims'], state['bounds'], state['solution_dim'],
                              state['extra_fields'])
        archive.load_state_dict(arrays)
        es = state['emitter']
        emitter = MapElitesEmitter(archive, batch_size=es['batch_size'],
                                   n_initial=es['n_initial'], variation=es['variation'],
                                   iso_sigma=es['iso_sigma'], line_sigma=es['line_sigma'],
                                   eta=es['eta'], mutation_rate=es['mutation_rate'],
                                   seed=es['seed'])
        emitter.load_state_dict(es)
        run = cls(archive, emitter, evaluate, executor, checkpoint_path, checkpoint_every)
        return run.resumed(state)

    def resumed(self, state):
        """Take the counters of a checkpoint's ``state``, then replay the batches the
        journal holds beyond it; returns this run."""
        self.n_evaluations = int(state['n_evaluations'])
        self.n_batches = int(state['n_batches'])
        self.n_invalid = int(state['n_invalid'])
        self.elapsed = float(state['elapsed'])
        self.info = dict(state.get('info', {}))
        self._replay_journal()
        return self

    def to_archive(self, **metadata: Any) -> Archive:
        """The elites as an :class:`~sela_ros.core.storage.Archive` (for SELA, or to save).

        Args:
            **metadata: simulator settings, descriptor/fitness names, seed, ...; the grid
                shape, bounds and evaluation count are filled in from this run.
        """
        elites = self.archive.elites()
        meta = make_metadata(grid_shape=list(self.archive.dims),
                             descriptor_bounds=self.archive.bounds.tolist(),
                             n_evaluations=self.n_evaluations,
                             n_invalid=self.n_invalid,
                             seed=self.emitter.seed,
                             emitter=self.emitter.variation)
        meta.update(metadata)
        return Archive(params=elites['solutions'], descriptors=elites['measures'],
                       generic_reward=elites['generic_reward'], fitness=elites['objectives'],
                       metadata=meta)


def default_run(evaluate: Callable, dims: Sequence[int] = (64, 64),
                bounds: Sequence[Sequence[float]] = ((-1.0, 1.0), (-1.0, 1.0)),
                batch_size: int = 100, n_initial: int | None = None, seed: int | None = None,
                executor=None, checkpoint_path=None, checkpoint_every: int = 10,
                variation: str = 'iso_line') -> MapElites:
    """A fresh :class:`MapElites` with the project's defaults (grid, iso-line emitter)."""
    archive = GridArchive(dims, bounds)
    emitter = MapElitesEmitter(archive, batch_size=batch_size, n_initial=n_initial,
                               variation=variation, seed=seed)
    return MapElites(archive, emitter, evaluate, executor, checkpoint_path, checkpoint_every)


__all__ = ['MapElites', 'default_run', 'CHECKPOINT_FORMAT_VERSION']
