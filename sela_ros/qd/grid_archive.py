"""The grid archive of MAP-Elites: the best solution (elite) of each cell of a regular grid
over the behaviour descriptor space (pyribs' ``GridArchive``, in numpy)."""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np


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
