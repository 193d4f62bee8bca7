"""Executors: evaluate a batch of solutions, in order, with an evaluation function.

:class:`SerialEvaluator` (this process), :class:`ProcessPoolEvaluator` (default, one process
per core) or :class:`DaskEvaluator` (a ``distributed`` scheduler, for more than one machine).
The batch travels in a few chunks per worker.
"""
from __future__ import annotations

import os
from collections.abc import Callable

import numpy as np

from sela_ros.qd.evaluators import EvaluationResult
from sim_bridge.evaluation import worker_pool


def _evaluate_chunk(evaluate: Callable, chunk: np.ndarray) -> list[EvaluationResult]:
    return [evaluate(row) for row in chunk]


class SerialEvaluator:
    """Evaluates a batch in this process (debugging, tiny runs, the SIGKILL test)."""

    workers = 1

    def map(self, evaluate: Callable, solutions: np.ndarray) -> list[EvaluationResult]:
        """Results of ``evaluate`` on each row of ``solutions``, in order."""
        return _evaluate_chunk(evaluate, solutions)

    def close(self) -> None:
        """Nothing to release."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class ProcessPoolEvaluator(SerialEvaluator):
    """Evaluates a batch on a pool of local processes (default: one per core).

    Workers start from a fresh ``forkserver`` (``spawn`` where unavailable), never from a
    fork of a process that may hold threads (tqdm, Dask) or a PyBullet connection.

    Args:
        workers: number of processes (default ``os.cpu_count()``).
    """

    def __init__(self, workers: int | None = None):
        workers = (os.cpu_count() or 1) if workers is None else int(workers)
        if workers < 1:
            raise ValueError(f'workers must be >= 1, got {workers}')
        self.workers = workers
        self._pool = worker_pool(workers)

    def map(self, evaluate: Callable, solutions: np.ndarray) -> list[EvaluationResult]:
        chunks = _chunks(solutions, self.workers)
        results = []
        for part in self._pool.map(_evaluate_chunk, [evaluate] * len(chunks), chunks):
            results.extend(part)
        return results

    def close(self) -> None:
        self._pool.shutdown(wait=True, cancel_futures=True)


class DaskEvaluator(SerialEvaluator):
    """Evaluates a batch on a Dask ``distributed`` cluster.

    Args:
        scheduler_address: e.g. ``'tcp://127.0.0.1:8786'``; ignored when ``client`` is given.
        client: an existing ``distributed.Client`` (not closed by :meth:`close`).
    """

    def __init__(self, scheduler_address: str | None = None, client=None):
        if client is None:
            if not scheduler_address:
                raise ValueError('DaskEvaluator needs a scheduler_address such as '
                                 "'tcp://127.0.0.1:8786' or a distributed.Client")
            from distributed import Client

            client = Client(scheduler_address)
            self._owns_client = True
        else:
            self._owns_client = False
        self.client = client

    @property
    def workers(self) -> int:
        """Number of threads the cluster offers (at least 1)."""
        info = self.client.scheduler_info().get('workers', {})
        return max(1, sum(int(w.get('nthreads', 1)) for w in info.values()))

    def map(self, evaluate: Callable, solutions: np.ndarray) -> list[EvaluationResult]:
        chunks = _chunks(solutions, self.workers)
        futures = [self.client.submit(_evaluate_chunk, evaluate, chunk, pure=False)
                   for chunk in chunks]
        results = []
        for part in self.client.gather(futures):
            results.extend(part)
        return results

    def close(self) -> None:
        if self._owns_client:
            self.client.close()


def _chunks(solutions: np.ndarray, workers: int) -> list[np.ndarray]:
    # A few chunks per worker balance load without paying per-gait IPC overhead.
    n = len(solutions)
    if n == 0:
        return []
    n_chunks = min(n, 4 * workers)
    return [c for c in np.array_split(solutions, n_chunks) if len(c)]
