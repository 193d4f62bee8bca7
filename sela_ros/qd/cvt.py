"""MAP-Elites over a CVT archive with pyribs: the paper's 8-D behaviour-performance map.

pyribs' :class:`ribs.archives.CVTArchive` keeps one elite per Voronoi cell around fixed
centroids; the run itself (iso-line emitters, scheduler, executors, checkpoints and journal)
is :class:`~sela_ros.qd.map_elites.MapElites`'s. A CVT grows finer without losing what it
holds (:meth:`CVTMapElites.regrid`).

pyribs is an optional dependency (``requirements-qd.txt``): only the map builder imports
this module, never the nodes.
"""
from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from sela_ros.core.storage import Archive
from sela_ros.qd.map_elites import (
    EXTRA_FIELDS,
    THRESHOLD_MIN,
    MapElites,
    iso_line_emitters,
    ribs_parts,
)

#: Default descriptor ranges of the 8-D map: final (x, y) in metres, six duty factors.
XY_DUTY_BOUNDS = ((-0.45, 0.45), (-0.45, 0.45)) + ((0.0, 1.0),) * 6


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
    """MAP-Elites on a pyribs ``CVTArchive`` (iso-line emitters), with checkpoints.

    Args:
        centroids: ``(cells, d)`` centroids of the CVT (see :func:`make_centroids`).
        bounds: ``(low, high)`` per descriptor dimension (what ``descriptor_bounds`` says).
        Others: as :class:`~sela_ros.qd.map_elites.MapElites`.

    Raises:
        ValueError: on inconsistent centroids/bounds or a non-positive size.
    """

    KIND = 'cvt'

    def __init__(self, centroids, bounds, evaluate, executor=None, **kwargs):
        self.centroids = np.asarray(centroids, dtype=np.float64)
        if self.centroids.ndim != 2 or np.shape(bounds) != (self.centroids.shape[1], 2):
            raise ValueError(f'centroids must be (cells, d) and bounds (d, 2); got '
                             f'{self.centroids.shape} and {np.shape(bounds)}')
        super().__init__(bounds, evaluate, executor, **kwargs)

    def _make_archive(self, solution_dim: int, seed: int):
        _, CVTArchive, _, _ = ribs_parts()
        return CVTArchive(solution_dim=solution_dim, centroids=self.centroids,
                          ranges=self.bounds.tolist(), seed=seed, learning_rate=1.0,
                          threshold_min=THRESHOLD_MIN, extra_fields=EXTRA_FIELDS)

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
        _, _, _, Scheduler = ribs_parts()
        old = self.archive
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
        self.centroids = centroids
        archive = self._make_archive(old.solution_dim, int(seeds[0]))
        data = old.data(['solution', 'objective', 'measures', 'generic_reward'])
        if len(data['objective']):
            archive.add(data['solution'], data['objective'], data['measures'],
                        generic_reward=data['generic_reward'])
        self.scheduler = Scheduler(archive, iso_line_emitters(archive, seeds[1:], c))
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
        elites = self._elites()
        meta = self._metadata(archive_kind='cvt', cells=int(self.archive.cells))
        meta.update(metadata)
        return Archive(params=np.clip(elites['solution'], 0.0, 1.0),
                       descriptors=elites['measures'], generic_reward=elites['generic_reward'],
                       fitness=elites['objective'], metadata=meta,
                       centroids=np.asarray(self.archive.centroids, dtype=np.float64))


__all__ = ['CVTMapElites', 'XY_DUTY_BOUNDS', 'disc_samples', 'make_centroids']
