"""The MAP-Elites emitter: proposes solutions with ``ask()``.

A random batch first, then random elites varied by iso-line variation (Vassiliades & Mouret
2018) or polynomial mutation, clipped to ``[0, 1]``; every random choice comes from the
emitter's own seeded ``np.random.default_rng``, whose state a checkpoint saves.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from sela_ros.qd.grid_archive import GridArchive

VARIATIONS = ('iso_line', 'polynomial')


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
