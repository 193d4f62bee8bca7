"""MAP-Elites over a grid: fills the behaviour-performance map that SELA starts from.

pyribs-like parts, each swappable:

- :class:`GridArchive` keeps the best solution (elite) of each cell of a grid over the
  behaviour descriptor space.
- :class:`MapElitesEmitter` proposes solutions with ``ask()``: a random batch first, then
  random elites varied by iso-line variation (Vassiliades & Mouret 2018) or polynomial
  mutation, clipped to ``[0, 1]``; every random choice comes from its own seeded
  ``np.random.default_rng``.
- An *evaluation function* is any picklable callable ``params (36,) -> EvaluationResult``:
  :class:`HexapodEvaluator` (PyBullet, through ``sim_bridge.hexapod.evaluate_gait``) or the
  cheap :class:`SyntheticEvaluator` used by tests and benchmarks.
- An *executor* evaluates a batch in order: :class:`SerialEvaluator`,
  :class:`ProcessPoolEvaluator` (default, one process per core) or :class:`DaskEvaluator`
  (a ``distributed`` scheduler, for more than one machine).
- :class:`MapElites` composes them: ask/tell, a run loop with a progress bar, and
  checkpoints written atomically every K batches plus a per-batch journal, so a run killed
  at any moment (even by SIGKILL) resumes without losing a finished batch and continues the
  same random stream, ending exactly where an uninterrupted run ends.

Descriptor and fitness (see docs/archive.md): the descriptor is the final ``(x, y)`` of one
gait in the start frame, the fitness is minus the angle between the final yaw and the
heading of the circular arc that joins the start to that point (Cully et al. 2015;
Chatzilygeroudis et al. 2018, reset-free trial and error).
"""
from __future__ import annotations

import json
import multiprocessing
import os
import sys
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from sela_ros.core.archive import Archive, atomic_savez, make_metadata
from sela_ros.core.geometry import wrap_angle

CHECKPOINT_FORMAT_VERSION = 1
VARIATIONS = ('iso_line', 'polynomial')

#: Behaviour descriptors: the final (x, y) in the start frame (2-D), and the paper's 8-D
#: one that adds the six duty factors (legs in ``sim_bridge.damage.LEG_NAMES`` order).
DESCRIPTORS = {'final_xy': 2, 'final_xy_duty_factors': 8}


class EvaluationResult(NamedTuple):
    """What one evaluation tells MAP-Elites.

    Attributes:
        valid: False for a gait to discard (the robot fell).
        fitness: quality, higher is better.
        descriptor: ``(d,)`` raw behaviour descriptor.
        generic_reward: ``(3,)`` ``(dx, dy, dyaw)`` in the start frame.
    """

    valid: bool
    fitness: float
    descriptor: np.ndarray
    generic_reward: np.ndarray


def arc_fitness(generic_reward) -> np.ndarray:
    """Minus the angle between the final yaw and the yaw of the joining circular arc.

    A circular arc that leaves the origin heading along +x and ends at ``(x, y)`` arrives
    with heading ``2 atan2(y, x)``; a gait that follows such an arc is easy to chain and to
    predict. The fitness is ``-|wrap(dyaw - 2 atan2(dy, dx))|`` in ``[-pi, 0]``, 0 is best.
    Walking straight backwards without turning is an arc too (``2 atan2(0, -1) = 2 pi``).

    Args:
        generic_reward: ``(..., 3)`` array of ``(dx, dy, dyaw)``.
    """
    gr = np.asarray(generic_reward, dtype=np.float64)
    arc_yaw = 2.0 * np.arctan2(gr[..., 1], gr[..., 0])
    return -np.abs(wrap_angle(gr[..., 2] - arc_yaw))


# --------------------------------------------------------------------------- archive


class GridArchive:
    """Elites on a regular grid over the descriptor space.

    Args:
        dims: cells per descriptor dimension, e.g. ``(64, 64)``.
        bounds: ``(low, high)`` per dimension, e.g. ``[(-1, 1), (-1, 1)]``; a descriptor
            outside is filed into the edge cell (as pyribs does).
        solution_dim: length of a solution (36 controller parameters).
        extra_fields: name -> length of extra per-elite data, stored with the elite.

    Raises:
        ValueError: on inconsistent dims/bounds.
    """

    def __init__(self, dims: Sequence[int], bounds: Sequence[Sequence[float]],
                 solution_dim: int = 36, extra_fields: dict[str, int] | None = None):
        dims = tuple(int(n) for n in dims)
        bounds = np.asarray(bounds, dtype=np.float64)
        if not dims or any(n < 1 for n in dims):
            raise ValueError(f'dims must be positive cell counts, e.g. (64, 64); got {dims}')
        if bounds.shape != (len(dims), 2):
            raise ValueError(f'bounds must have one (low, high) pair per dimension, i.e. shape '
                             f'({len(dims)}, 2); got shape {bounds.shape}')
        if not np.all(np.isfinite(bounds)) or np.any(bounds[:, 1] <= bounds[:, 0]):
            raise ValueError(f'bounds must be finite with low < high; got {bounds.tolist()}')
        if solution_dim < 1:
            raise ValueError(f'solution_dim must be >= 1, got {solution_dim}')
        self.dims = dims
        self.bounds = bounds
        self.solution_dim = int(solution_dim)
        self.extra_fields = dict(extra_fields or {'generic_reward': 3})
        n = int(np.prod(dims))
        self.occupied = np.zeros(n, dtype=bool)
        self.solutions = np.zeros((n, self.solution_dim))
        self.objectives = np.full(n, -np.inf)
        self.measures = np.zeros((n, len(dims)))
        self.extras = {name: np.zeros((n, size)) for name, size in self.extra_fields.items()}

    @property
    def cells(self) -> int:
        """Number of cells in the grid."""
        return self.occupied.size

    @property
    def num_elites(self) -> int:
        """Number of filled cells."""
        return int(np.count_nonzero(self.occupied))

    @property
    def coverage(self) -> float:
        """Fraction of filled cells."""
        return self.num_elites / self.cells

    @property
    def qd_score(self) -> float:
        """Sum of the elites' objectives."""
        return float(self.objectives[self.occupied].sum())

    def index_of(self, measures) -> np.ndarray:
        """Flat cell index of each descriptor row of ``measures`` ``(n, d)``."""
        measures = np.atleast_2d(np.asarray(measures, dtype=np.float64))
        if measures.shape[1] != len(self.dims):
            raise ValueError(f'measures must have {len(self.dims)} columns, got '
                             f'{measures.shape[1]}')
        low, high = self.bounds[:, 0], self.bounds[:, 1]
        dims = np.asarray(self.dims)
        grid = np.floor((measures - low) / (high - low) * dims).astype(np.int64)
        grid = np.clip(grid, 0, dims - 1)
        return np.ravel_multi_index(tuple(grid.T), self.dims)

    def add(self, solutions, objectives, measures, **extras) -> np.ndarray:
        """Insert a batch; each cell keeps the best solution it has seen.

        Within a batch candidates are considered in order, so ties keep the earlier one.

        Args:
            solutions: ``(n, solution_dim)``.
            objectives: ``(n,)``, higher is better; non-finite entries are rejected.
            measures: ``(n, d)`` raw descriptors.
            **extras: one ``(n, size)`` array per extra field.

        Returns:
            ``(n,)`` status: 0 not added, 1 improved an elite, 2 filled a new cell.
        """
        solutions = np.atleast_2d(np.asarray(solutions, dtype=np.float64))
        objectives = np.atleast_1d(np.asarray(objectives, dtype=np.float64))
        measures = np.atleast_2d(np.asarray(measures, dtype=np.float64))
        n = solutions.shape[0]
        if solutions.shape != (n, self.solution_dim):
            raise ValueError(f'solutions must have shape (n, {self.solution_dim}), got '
                             f'{solutions.shape}')
        if objectives.shape != (n,) or measures.shape != (n, len(self.dims)):
            raise ValueError(f'expected objectives ({n},) and measures ({n}, {len(self.dims)}), '
                             f'got {objectives.shape} and {measures.shape}')
        if set(extras) != set(self.extra_fields):
            raise ValueError(f'extras must be exactly {sorted(self.extra_fields)}, got '
                             f'{sorted(extras)}')
        extras = {k: np.asarray(v, dtype=np.float64).reshape(n, self.extra_fields[k])
                  for k, v in extras.items()}
        status = np.zeros(n, dtype=np.int8)
        if n == 0:
            return status
        finite = np.isfinite(objectives) & np.all(np.isfinite(measures), axis=1)
        indices = np.zeros(n, dtype=np.int64)
        indices[finite] = self.index_of(measures[finite])
        for i in np.flatnonzero(finite):
            cell = indices[i]
            if self.occupied[cell] and objectives[i] <= self.objectives[cell]:
                continue
            status[i] = 1 if self.occupied[cell] else 2
            self.occupied[cell] = True
            self.solutions[cell] = solutions[i]
            self.objectives[cell] = objectives[i]
            self.measures[cell] = measures[i]
            for name, values in extras.items():
                self.extras[name][cell] = values[i]
        return status

    def sample_elites(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """``(n, solution_dim)`` elites drawn uniformly with replacement."""
        filled = np.flatnonzero(self.occupied)
        if filled.size == 0:
            raise ValueError('cannot sample elites from an empty archive')
        return self.solutions[filled[rng.integers(0, filled.size, size=n)]]

    def state_dict(self) -> dict[str, np.ndarray]:
        """Arrays that restore this archive exactly (see :meth:`load_state_dict`)."""
        state = {'occupied': self.occupied, 'solutions': self.solutions,
                 'objectives': self.objectives, 'measures': self.measures}
        state.update({f'extra_{k}': v for k, v in self.extras.items()})
        return state

    def load_state_dict(self, state: dict[str, np.ndarray]) -> None:
        """Restore what :meth:`state_dict` returned (same dims and fields)."""
        if state['occupied'].shape != self.occupied.shape:
            raise ValueError(f'state is for {state["occupied"].size} cells, this grid has '
                             f'{self.cells}')
        self.occupied = np.array(state['occupied'], dtype=bool)
        self.solutions = np.array(state['solutions'], dtype=np.float64)
        self.objectives = np.array(state['objectives'], dtype=np.float64)
        self.measures = np.array(state['measures'], dtype=np.float64)
        self.extras = {k: np.array(state[f'extra_{k}'], dtype=np.float64)
                       for k in self.extra_fields}

    def elites(self) -> dict[str, np.ndarray]:
        """The filled cells, in cell order: solutions, objectives, measures, extras, index."""
        filled = np.flatnonzero(self.occupied)
        out = {'index': filled, 'solutions': self.solutions[filled],
               'objectives': self.objectives[filled], 'measures': self.measures[filled]}
        out.update({k: v[filled] for k, v in self.extras.items()})
        return out


# --------------------------------------------------------------------------- emitter


class MapElitesEmitter:
    """Proposes solutions: random at first, then varied copies of random elites.

    Args:
        archive: where elites are drawn from.
        batch_size: default number of solutions per ``ask()``.
        n_initial: the first ``n_initial`` solutions are uniform in ``[0, 1]^D``.
        variation: ``'iso_line'`` (``x + iso_sigma N(0, I) + line_sigma N(0, 1) (y - x)``
            for two random elites x, y) or ``'polynomial'`` (Deb's polynomial mutation).
        iso_sigma: isotropic Gaussian step of iso-line variation.
        line_sigma: step along the line joining the two elites.
        eta: distribution index of polynomial mutation (larger = smaller steps).
        mutation_rate: per-gene probability of polynomial mutation (default 1/D).
        seed: seed of this emitter's ``np.random.default_rng``.
    """

    def __init__(self, archive: GridArchive, batch_size: int = 100, n_initial: int | None = None,
                 variation: str = 'iso_line', iso_sigma: float = 0.01, line_sigma: float = 0.2,
                 eta: float = 10.0, mutation_rate: float | None = None, seed: int | None = None):
        if batch_size < 1:
            raise ValueError(f'batch_size must be >= 1, got {batch_size}')
        if variation not in VARIATIONS:
            raise ValueError(f'variation must be one of {VARIATIONS}, got {variation!r}')
        if iso_sigma < 0 or line_sigma < 0 or eta <= 0:
            raise ValueError('iso_sigma and line_sigma must be >= 0 and eta > 0, got '
                             f'{iso_sigma}, {line_sigma}, {eta}')
        self.archive = archive
        self.solution_dim = archive.solution_dim
        self.batch_size = int(batch_size)
        self.n_initial = self.batch_size if n_initial is None else int(n_initial)
        if self.n_initial < 0:
            raise ValueError(f'n_initial must be >= 0, got {n_initial}')
        self.variation = variation
        self.iso_sigma = float(iso_sigma)
        self.line_sigma = float(line_sigma)
        self.eta = float(eta)
        self.mutation_rate = (1.0 / self.solution_dim if mutation_rate is None
                              else float(mutation_rate))
        if not 0.0 < self.mutation_rate <= 1.0:
            raise ValueError(f'mutation_rate must be in (0, 1], got {self.mutation_rate}')
        self.seed = seed
        self.rng = np.random.default_rng(seed)
        self.n_asked = 0

    def ask(self, n: int | None = None) -> np.ndarray:
        """``(n, solution_dim)`` solutions in ``[0, 1]`` to evaluate next."""
        n = self.batch_size if n is None else int(n)
        n_random = max(0, min(n, self.n_initial - self.n_asked))
        if self.archive.num_elites == 0:
            n_random = n
        parts = []
        if n_random:
            parts.append(self.rng.random((n_random, self.solution_dim)))
        if n - n_random:
            parts.append(self._vary(n - n_random))
        self.n_asked += n
        return np.concatenate(parts) if parts else np.empty((0, self.solution_dim))

    def tell(self, solutions, objectives, measures, status=None) -> None:
        """Feedback on the last batch (this emitter does not adapt; kept for ask/tell)."""

    def _vary(self, n: int) -> np.ndarray:
        x = self.archive.sample_elites(n, self.rng)
        if self.variation == 'iso_line':
            y = self.archive.sample_elites(n, self.rng)
            iso = self.rng.normal(0.0, self.iso_sigma, size=x.shape)
            line = self.rng.normal(0.0, self.line_sigma, size=(n, 1))
            children = x + iso + line * (y - x)
        else:
            children = self._polynomial_mutation(x)
        return np.clip(children, 0.0, 1.0)

    def _polynomial_mutation(self, x: np.ndarray) -> np.ndarray:
        mutate = self.rng.random(x.shape) < self.mutation_rate
        u = self.rng.random(x.shape)
        power = 1.0 / (self.eta + 1.0)
        delta = np.where(u < 0.5, (2.0 * u) ** power - 1.0, 1.0 - (2.0 * (1.0 - u)) ** power)
        return np.where(mutate, x + delta, x)

    def state_dict(self) -> dict[str, Any]:
        """JSON-serialisable state: configuration, RNG state and solutions asked so far."""
        return {'batch_size': self.batch_size, 'n_initial': self.n_initial,
                'variation': self.variation, 'iso_sigma': self.iso_sigma,
                'line_sigma': self.line_sigma, 'eta': self.eta,
                'mutation_rate': self.mutation_rate, 'seed': self.seed,
                'n_asked': self.n_asked, 'rng_state': self.rng.bit_generator.state}

    def load_state_dict(self, state: dict[str, Any]) -> None:
        """Restore the RNG stream and counters saved by :meth:`state_dict`."""
        self.n_asked = int(state['n_asked'])
        self.rng.bit_generator.state = state['rng_state']


# --------------------------------------------------------------------------- evaluation


class SyntheticEvaluator:
    """A cheap, deterministic stand-in for the hexapod (tests, benchmarks, dry runs).

    Maps 36 parameters to a smooth, non-linear ``(dx, dy, dyaw)`` that covers roughly
    ``[-1, 1]^2 x [-1.5, 1.5]``; parameters 0 and 1 both above 0.95 count as a fall. The
    8-D descriptor adds six "duty factors" in ``[0, 1]`` (the amplitudes' mean per leg).

    Args:
        delay: seconds to sleep per evaluation, to emulate a simulator's cost.
        descriptor: a key of :data:`DESCRIPTORS`.
    """

    def __init__(self, delay: float = 0.0, descriptor: str = 'final_xy'):
        if descriptor not in DESCRIPTORS:
            raise ValueError(f'descriptor must be one of {sorted(DESCRIPTORS)}, got '
                             f'{descriptor!r}')
        self.delay = float(delay)
        self.descriptor = descriptor
        weights = np.random.default_rng(20180219).normal(size=(3, 36))
        self.weights = weights

    def __call__(self, params) -> EvaluationResult:
        if self.delay:
            time.sleep(self.delay)
        p = np.asarray(params, dtype=np.float64) - 0.5
        z = 3.0 * (self.weights @ p)
        gr = np.array([np.tanh(z[0]) + 0.1 * np.sin(12.0 * p[3]),
                       np.tanh(z[1]) + 0.1 * np.cos(9.0 * p[7]),
                       1.5 * np.tanh(z[2])])
        fallen = params[0] > 0.95 and params[1] > 0.95
        desc = gr[:2].copy()
        if self.descriptor == 'final_xy_duty_factors':
            duty = (np.asarray(params, dtype=np.float64).reshape(6, 6)[:, ::3]).mean(axis=1)
            desc = np.concatenate([desc, duty])
        return EvaluationResult(not fallen, float(arc_fitness(gr)), desc, gr)

    def settings(self, dt: float = 1.0 / 240.0, gait_duration: float = 3.0) -> dict:
        """Settings recorded in an archive built with this function."""
        return {'dt': dt, 'gait_duration': gait_duration,
                'controller_version': 'synthetic', 'model_version': 'synthetic'}


class HexapodEvaluator:
    """One gait on the simulated hexapod: descriptor final ``(x, y)`` (+ duty factors), arc.

    Picklable: each worker process imports PyBullet and builds its own simulator.

    Args:
        dt: physics time step (s); fix it before building an archive.
        gait_duration: how long one gait runs (s).
        damage: damage spec understood by ``sim_bridge`` (``'intact'`` for an archive).
        solver_iterations: PyBullet constraint-solver iterations per step.
        descriptor: a key of :data:`DESCRIPTORS`.
    """

    def __init__(self, dt: float = 1.0 / 240.0, gait_duration: float = 3.0,
                 damage: str = 'intact', solver_iterations: int = 50,
                 descriptor: str = 'final_xy'):
        if dt <= 0 or gait_duration <= 0:
            raise ValueError(f'dt and gait_duration must be > 0, got {dt}, {gait_duration}')
        if descriptor not in DESCRIPTORS:
            raise ValueError(f'descriptor must be one of {sorted(DESCRIPTORS)}, got '
                             f'{descriptor!r}')
        self.dt = float(dt)
        self.gait_duration = float(gait_duration)
        self.damage = damage
        self.solver_iterations = int(solver_iterations)
        self.descriptor = descriptor

    def __call__(self, params) -> EvaluationResult:
        from sim_bridge.hexapod import evaluate_gait

        outcome = evaluate_gait(np.asarray(params, dtype=np.float64), damage=self.damage,
                                dt=self.dt, gait_duration=self.gait_duration,
                                solver_iterations=self.solver_iterations)
        gr = np.asarray(outcome.generic_reward, dtype=np.float64)
        valid = not bool(outcome.fallen) and bool(np.all(np.isfinite(gr)))
        desc = gr[:2].copy()
        if self.descriptor == 'final_xy_duty_factors':
            desc = np.concatenate([desc, np.asarray(outcome.duty_factors, dtype=np.float64)])
        return EvaluationResult(valid, float(arc_fitness(gr)) if valid else -np.inf, desc, gr)

    def settings(self) -> dict:
        """The simulator settings an archive built with this evaluator must record."""
        from sim_bridge.hexapod import simulator_settings

        return dict(simulator_settings(self.dt, self.gait_duration, self.solver_iterations))


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
        methods = multiprocessing.get_all_start_methods()
        context = multiprocessing.get_context('forkserver' if 'forkserver' in methods
                                              else 'spawn')
        self._pool = ProcessPoolExecutor(max_workers=workers, mp_context=context)

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


# --------------------------------------------------------------------------- scheduler


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
        run.n_evaluations = int(state['n_evaluations'])
        run.n_batches = int(state['n_batches'])
        run.n_invalid = int(state['n_invalid'])
        run.elapsed = float(state['elapsed'])
        run.info = dict(state.get('info', {}))
        run._replay_journal()
        return run

    def to_archive(self, **metadata: Any) -> Archive:
        """The elites as an :class:`~sela_ros.core.archive.Archive` (for SELA, or to save).

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


def elapsed_rate(run: MapElites) -> float:
    """Evaluations per second of wall time spent in batches so far (0 when none)."""
    return run.n_evaluations / run.elapsed if run.elapsed > 0 else 0.0


__all__ = ['EvaluationResult', 'GridArchive', 'MapElitesEmitter', 'MapElites',
           'SyntheticEvaluator', 'HexapodEvaluator', 'SerialEvaluator',
           'ProcessPoolEvaluator', 'DaskEvaluator', 'arc_fitness', 'wrap_angle',
           'default_run', 'elapsed_rate']
