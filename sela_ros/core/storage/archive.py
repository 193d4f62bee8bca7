"""The behaviour-performance map ("archive") SELA consumes: atomic save, validated load, and
where the shipped archives live.

An :class:`Archive` is what MAP-Elites leaves behind (see :mod:`sela_ros.qd.map_elites`): for
each of its ``M`` elites the robot's controller parameters, the raw behaviour descriptor, the
generic reward ``(dx, dy, dyaw)`` it produced on the simulated intact robot and its fitness,
plus a metadata dict that says how the map was built. SELA uses the generic reward as the
prior mean of its GPs and the normalised descriptors as their inputs.

On disk an archive is one compressed ``.npz`` holding the four arrays and the metadata as a
JSON string (a CVT archive, ``metadata['archive_kind'] == 'cvt'``, also holds its
``centroids``, so that gaits can be filed into the same cells later); it is written
atomically (temporary file in the same directory, fsync,
``os.replace``) so that a reader never sees half a file. :func:`load_archive` checks
everything a consumer relies on and raises :class:`ArchiveError` with a message that says
what is wrong, what was expected and how to fix it.
"""
from __future__ import annotations

import datetime
import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sela_ros.core.storage.npz_files import NotAnNpz, NpzTooLarge, check_npz_size
from sela_ros.core.storage.persistence import atomic_write
from sela_ros.core.validation import ImplausibleOutcome, check_generic_rewards

#: Version of the on-disk layout; bump it when keys or meanings change.
ARCHIVE_FORMAT_VERSION = 1

#: Simulator settings an archive was built with; a consumer's settings must match them.
SIMULATOR_SETTING_KEYS = ('dt', 'gait_duration', 'controller_version', 'model_version',
                          'solver_iterations')

#: Settings added after archives existed: an archive without the key was built with this.
SETTING_DEFAULTS = {'solver_iterations': 50}

#: Metadata keys every archive carries (see docs/archive.md).
REQUIRED_METADATA_KEYS = tuple(k for k in SIMULATOR_SETTING_KEYS
                               if k not in SETTING_DEFAULTS) + (
    'descriptor_name',
    'descriptor_bounds',
    'fitness_name',
    'grid_shape',  # a CVT archive has 'cells' instead
    'n_evaluations',
    'seed',
    'created',
    'sela_ros_version',
    'format_version',
)

_ARRAY_KEYS = ('params', 'descriptors', 'generic_reward', 'fitness')
_REBUILD_HINT = (
    'Rebuild the archive with `sela-build-archive --out PATH` (see docs/archive.md), '
    'or point the consumer at a matching archive.'
)


#: Kernel length (on normalised descriptors) that suits a map with no ``gp_kernel_sigma`` in
#: its metadata: the paper's 0.1 for a 2-D map; 0.3 in higher dimensions, where 0.1 links far
#: fewer gaits (measured on the 8-D map: docs/archive.md, "Kernel length for the 8-D map").
KERNEL_SIGMA_2D = 0.1
KERNEL_SIGMA_HIGHER = 0.3
#: Kernel length of the fall GP on a map of more than 2 dimensions: on the 8-D map a gait
#: 0.2 away from one seen upright still falls almost as often as any (docs/archive.md).
FALL_KERNEL_SIGMA_HIGHER = 0.12
#: Steps SELA looks ahead on a map of more than two descriptor dimensions: two (each gait is
#: chosen for where it leaves the robot to take the next one from; docs/archive.md).
PLANNER_HORIZON_HIGHER = 2


#: ``descriptor_name`` of the paper's 8-D map: final (x, y) then the six duty factors.
DUTY_FACTOR_DESCRIPTOR = 'final_xy_duty_factors'


class ArchiveError(ValueError):
    """An archive file or object is unusable: corrupt, incomplete or built for other settings."""


def _sela_ros_version() -> str:
    from sela_ros import __version__

    return __version__


def make_metadata(**values: Any) -> dict:
    """Metadata dict with the bookkeeping keys filled in (created, versions).

    Args:
        **values: the other metadata values (simulator settings, descriptor, grid, ...).

    Returns:
        A new dict; ``created`` (UTC, ISO 8601), ``sela_ros_version`` and ``format_version``
        are set unless given.
    """
    metadata = {
        'created': datetime.datetime.now(datetime.UTC).isoformat(timespec='seconds'),
        'sela_ros_version': _sela_ros_version(),
        'format_version': ARCHIVE_FORMAT_VERSION,
    }
    metadata.update(values)
    return metadata


@dataclass
class Archive:
    """A behaviour-performance map.

    Attributes:
        params: ``(M, n)`` controller parameters in ``[0, 1]`` (``n`` the robot's: 36 for the
            hexapod).
        descriptors: ``(M, d)`` raw behaviour descriptors (the default descriptor is the final
            ``(x, y)`` in metres, in the robot's frame at the start of the gait).
        generic_reward: ``(M, 3)`` displacement ``(dx, dy, dyaw)`` on the intact robot, in the
            start frame (metres, metres, radians).
        fitness: ``(M,)`` the quality MAP-Elites maximised (higher is better).
        metadata: how the map was built; keys in :data:`REQUIRED_METADATA_KEYS`.
        centroids: ``(cells, d)`` centroids of a CVT archive (``archive_kind`` ``'cvt'``),
            else ``None``.

    Raises:
        ArchiveError: on wrong shapes, non-finite values or missing metadata.
    """

    params: np.ndarray
    descriptors: np.ndarray
    generic_reward: np.ndarray
    fitness: np.ndarray
    metadata: dict = field(default_factory=dict)
    centroids: np.ndarray | None = None

    def __post_init__(self):
        self.params = np.asarray(self.params, dtype=np.float64)
        self.descriptors = np.asarray(self.descriptors, dtype=np.float64)
        self.generic_reward = np.asarray(self.generic_reward, dtype=np.float64)
        self.fitness = np.asarray(self.fitness, dtype=np.float64)
        self.metadata = dict(self.metadata)
        if self.centroids is not None:
            self.centroids = np.asarray(self.centroids, dtype=np.float64)
        _validate(self)

    def __len__(self) -> int:
        return self.params.shape[0]

    @property
    def descriptor_bounds(self) -> np.ndarray:
        """``(d, 2)`` lower and upper bound of each descriptor dimension (from metadata)."""
        return np.asarray(self.metadata['descriptor_bounds'], dtype=np.float64)

    @property
    def kernel_sigma(self) -> float:
        """The GP kernel length this map is meant to be used with: its metadata's
        ``gp_kernel_sigma``, else :data:`KERNEL_SIGMA_2D` for a 2-D map and
        :data:`KERNEL_SIGMA_HIGHER` for more descriptor dimensions."""
        return self._length('gp_kernel_sigma', KERNEL_SIGMA_HIGHER)

    @property
    def fall_kernel_sigma(self) -> float:
        """The fall GP's kernel length for this map: metadata ``fall_kernel_sigma``, else
        :data:`KERNEL_SIGMA_2D` for a 2-D map and :data:`FALL_KERNEL_SIGMA_HIGHER` for more
        descriptor dimensions."""
        return self._length('fall_kernel_sigma', FALL_KERNEL_SIGMA_HIGHER)

    @property
    def planner_horizon(self) -> int:
        """Steps SELA looks ahead with this map: metadata ``planner_horizon`` (1 or 2), else
        1 (the paper's) for a 2-D map and :data:`PLANNER_HORIZON_HIGHER` for more descriptor
        dimensions."""
        value = self.metadata.get('planner_horizon')
        if value in (1, 2) and not isinstance(value, bool):
            return int(value)
        return 1 if self.descriptors.shape[1] <= 2 else PLANNER_HORIZON_HIGHER

    def _length(self, key, higher):
        """A kernel length: metadata ``key`` if usable, else the 2-D or ``higher`` default."""
        value = self.metadata.get(key)
        if isinstance(value, (int, float)) and not isinstance(value, bool) \
                and math.isfinite(value) and value > 0:
            return float(value)
        return KERNEL_SIGMA_2D if self.descriptors.shape[1] <= 2 else higher

    @property
    def stability(self) -> np.ndarray | None:
        """``(M,)`` what makes each gait less likely to tip a damaged robot over, for the
        fall model (:class:`~sela_ros.core.learning.FallRisk`): on a map whose descriptor
        holds the six duty factors, the gait's support (their sum, the mean number of feet
        on the ground); None for other maps."""
        if self.metadata.get('descriptor_name') != DUTY_FACTOR_DESCRIPTOR \
                or self.descriptors.shape[1] < 3:
            return None
        return self.descriptors[:, 2:].sum(axis=1)

    @property
    def simulator_settings(self) -> dict:
        """The simulator settings (:data:`SIMULATOR_SETTING_KEYS`), old defaults filled in."""
        return {key: _setting(self.metadata, key) for key in SIMULATOR_SETTING_KEYS}

    def normalised_descriptors(self) -> np.ndarray:
        """Descriptors scaled to ``[0, 1]^d`` with the metadata bounds (clipped at the edges).

        MAP-Elites files a gait that lands outside the bounds into the edge cell, so such a
        descriptor is clipped to the edge, exactly where the grid keeps it.
        """
        bounds = self.descriptor_bounds
        scaled = (self.descriptors - bounds[:, 0]) / (bounds[:, 1] - bounds[:, 0])
        return np.clip(scaled, 0.0, 1.0)

    def save(self, path: str | os.PathLike) -> Path:
        """Write the archive as a compressed ``.npz``, atomically.

        Args:
            path: destination file; its directory is created if needed.

        Returns:
            The path written.
        """
        path = Path(path)
        arrays = {key: getattr(self, key) for key in _ARRAY_KEYS}
        if self.centroids is not None:
            arrays['centroids'] = self.centroids
        arrays['metadata'] = np.array(json.dumps(self.metadata, sort_keys=True))
        atomic_savez(path, **arrays)
        return path


def atomic_savez(path: str | os.PathLike, **arrays: np.ndarray) -> None:
    """``np.savez_compressed`` to a temporary file beside ``path``, fsync, then rename over it.

    A crash (even SIGKILL) leaves either the old file or the new one, never a partial one.
    """
    atomic_write(path, lambda handle: np.savez_compressed(handle, **arrays))



def _validate(archive: Archive) -> None:
    params, desc = archive.params, archive.descriptors
    reward, fitness = archive.generic_reward, archive.fitness
    if params.ndim != 2 or params.shape[1] < 1:
        raise ArchiveError(f'params must have shape (M, n) with n >= 1 (the robot\'s gait '
                           f'parameters), got {params.shape}')
    m = params.shape[0]
    if desc.ndim != 2 or desc.shape[0] != m or desc.shape[1] < 1:
        raise ArchiveError(f'descriptors must have shape ({m}, d) with d >= 1, got {desc.shape}')
    if reward.shape != (m, 3):
        raise ArchiveError(f'generic_reward must have shape ({m}, 3), got {reward.shape}')
    if fitness.shape != (m,):
        raise ArchiveError(f'fitness must have shape ({m},), got {fitness.shape}')
    for name in _ARRAY_KEYS:
        values = getattr(archive, name)
        if not np.all(np.isfinite(values)):
            bad = int(np.count_nonzero(~np.isfinite(values)))
            raise ArchiveError(f'{name} holds {bad} NaN or infinite value(s); expected finite')
    if np.any(params < 0.0) or np.any(params > 1.0):
        raise ArchiveError('params must lie in [0, 1] (controller parameters)')
    cvt = archive.metadata.get('archive_kind', 'grid') == 'cvt'
    required = [k.replace('grid_shape', 'cells') if cvt else k for k in REQUIRED_METADATA_KEYS]
    missing = [key for key in required if key not in archive.metadata]
    if missing:
        raise ArchiveError(f'metadata lacks key(s) {missing}; expected all of {required}')
    try:
        bounds = np.asarray(archive.metadata['descriptor_bounds'], dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ArchiveError(f'metadata descriptor_bounds is not numeric: {exc}') from None
    d = desc.shape[1]
    if bounds.shape != (d, 2) or not np.all(np.isfinite(bounds)):
        raise ArchiveError(f'metadata descriptor_bounds must be finite with shape ({d}, 2) '
                           f'(low, high per descriptor dimension), got {bounds.tolist()}')
    if np.any(bounds[:, 1] <= bounds[:, 0]):
        raise ArchiveError(f'metadata descriptor_bounds must have low < high, got '
                           f'{bounds.tolist()}')
    centroids = archive.centroids
    if centroids is not None or cvt:
        cells = archive.metadata.get('cells')
        if not cvt or centroids is None:
            raise ArchiveError("centroids go with metadata archive_kind 'cvt' (and back): got "
                               f"archive_kind {archive.metadata.get('archive_kind')!r} and "
                               f"{'no ' if centroids is None else ''}centroids")
        if centroids.shape != (cells, d) or not np.all(np.isfinite(centroids)):
            raise ArchiveError(f'centroids must be finite with shape (cells, d) = ({cells}, '
                               f'{d}), got {centroids.shape}')


def _setting(metadata: dict, key: str) -> Any:
    """``metadata[key]``, or what an archive that predates the key was built with."""
    return metadata[key] if key in metadata else SETTING_DEFAULTS[key]


def _settings_equal(a: Any, b: Any) -> bool:
    if isinstance(a, int | float) and isinstance(b, int | float) and not isinstance(a, bool):
        return math.isclose(float(a), float(b), rel_tol=1e-9, abs_tol=1e-12)
    return a == b


def check_settings(metadata: dict, expected_settings: dict, source: str = 'archive') -> None:
    """Raise :class:`ArchiveError` when ``metadata`` was built with other simulator settings.

    Args:
        metadata: an archive's metadata.
        expected_settings: the consumer's settings, e.g. ``simulator_settings(dt, duration)``;
            only the keys in :data:`SIMULATOR_SETTING_KEYS` are compared.
        source: how to name the archive in the message (its path).
    """
    mismatches = []
    for key in SIMULATOR_SETTING_KEYS:
        if key not in expected_settings:
            continue
        if key not in metadata and key not in SETTING_DEFAULTS:
            mismatches.append(f'{key}: archive has none, expected {expected_settings[key]!r}')
        elif not _settings_equal(_setting(metadata, key), expected_settings[key]):
            mismatches.append(f'{key}: archive has {_setting(metadata, key)!r}, '
                              f'expected {expected_settings[key]!r}')
    if mismatches:
        raise ArchiveError(f'{source} was built with other simulator settings ('
                           + '; '.join(mismatches) + '). Its generic rewards would not match '
                           'what this simulator does. ' + _REBUILD_HINT)


def load_archive(path: str | os.PathLike, expected_settings: dict | None = None) -> Archive:
    """Load and validate an archive written by :meth:`Archive.save`.

    Args:
        path: the ``.npz`` file.
        expected_settings: simulator settings the archive must have been built with (keys
            ``dt``, ``gait_duration``, ``controller_version``, ``model_version``; others are
            ignored), e.g. ``sim_bridge.settings.simulator_settings(dt, gait_duration)``.
            ``None`` skips the check.

    Returns:
        The archive.

    Raises:
        ArchiveError: the file is missing, truncated or corrupt, lacks a key, has wrong shapes,
            dtypes or NaNs, or was built with other simulator settings.
    """
    path = Path(path)
    try:
        exists = path.is_file()
    except (OSError, ValueError) as exc:  # a name too long for the file system, a NUL byte
        raise ArchiveError(f'archive path {str(path)[:200]!r} cannot be used: '
                           f'{getattr(exc, "strerror", None) or exc}') from None
    if not exists:
        raise ArchiveError(f'no archive file at {path}. ' + _REBUILD_HINT)
    try:
        check_npz_size(path)
    except NotAnNpz as exc:
        raise ArchiveError(f'{exc}. ' + _REBUILD_HINT) from None
    except NpzTooLarge as exc:
        raise ArchiveError(str(exc)) from None
    try:
        with np.load(path, allow_pickle=False) as npz:
            present = set(npz.files)
            missing = [key for key in _ARRAY_KEYS + ('metadata',) if key not in present]
            if missing:
                raise ArchiveError(f'{path} lacks key(s) {missing}; an archive holds '
                                   f'{list(_ARRAY_KEYS) + ["metadata"]}. ' + _REBUILD_HINT)
            arrays = {key: npz[key] for key in _ARRAY_KEYS}
            if 'centroids' in present:
                arrays['centroids'] = npz['centroids']
            metadata_text = npz['metadata']
    except ArchiveError:
        raise
    except Exception as exc:  # BadZipFile, EOFError, zlib.error, ValueError: all corruption
        raise ArchiveError(f'{path} is not a readable archive (truncated or corrupt: '
                           f'{type(exc).__name__}: {exc}). ' + _REBUILD_HINT) from None

    for key, values in arrays.items():
        if not np.issubdtype(values.dtype, np.floating):
            raise ArchiveError(f'{path}: {key} has dtype {values.dtype}, expected a float '
                               'array. ' + _REBUILD_HINT)
    if metadata_text.shape != () or metadata_text.dtype.kind != 'U':
        raise ArchiveError(f'{path}: metadata must be a JSON string, got an array of dtype '
                           f'{metadata_text.dtype} and shape {metadata_text.shape}. '
                           + _REBUILD_HINT)
    try:
        metadata = json.loads(str(metadata_text))
    except json.JSONDecodeError as exc:
        raise ArchiveError(f'{path}: metadata is not valid JSON ({exc}). '
                           + _REBUILD_HINT) from None
    if not isinstance(metadata, dict):
        raise ArchiveError(f'{path}: metadata must be a JSON object, got '
                           f'{type(metadata).__name__}. ' + _REBUILD_HINT)
    version = metadata.get('format_version')
    if version != ARCHIVE_FORMAT_VERSION:
        raise ArchiveError(f'{path} has archive format version {version!r}, this sela_ros '
                           f'reads version {ARCHIVE_FORMAT_VERSION}. ' + _REBUILD_HINT)
    try:
        archive = Archive(metadata=metadata, **arrays)
    except ArchiveError as exc:
        raise ArchiveError(f'{path}: {exc}. ' + _REBUILD_HINT) from None
    try:
        # What the archive says a gait does becomes the GPs' prior mean: bounded as outcomes.
        check_generic_rewards(archive.generic_reward, what=f'{path}: generic_reward')
    except ImplausibleOutcome as exc:
        raise ArchiveError(str(exc)) from None
    if expected_settings is not None:
        check_settings(metadata, expected_settings, source=str(path))
    return archive


#: The archives shipped inside the package (``sela_ros/data``), by short name: the default is
#: the hexapod's, the paper's 8-D map (final x, y + six duty factors); ``2d`` is its first, 2-D
#: map (final x, y), kept to compare with (docs/archive.md); ``a1`` is the Unitree A1's
#: (docs/robots.md).
SHIPPED_ARCHIVES = {'8d': 'hexapod_archive.npz', '2d': 'hexapod_archive_2d.npz',
                    'a1': 'a1_archive.npz'}


def default_archive_path() -> Path:
    """Path of the archive shipped inside the installed package (``sela_ros/data``)."""
    return shipped_archive_path('8d')


def resolve_archive_path(value: str) -> str:
    """An ``archive`` parameter's value as a path: '' is the default shipped archive, ``8d``,
    ``2d`` and ``a1`` the shipped ones by name, anything else a path as given."""
    value = (value or '').strip() or '8d'
    return str(shipped_archive_path(value)) if value in SHIPPED_ARCHIVES else value


def shipped_archive_path(name: str) -> Path:
    """Path of a shipped archive by short name (:data:`SHIPPED_ARCHIVES`)."""
    if name not in SHIPPED_ARCHIVES:
        raise ArchiveError(f'no shipped archive {name!r}; shipped: {sorted(SHIPPED_ARCHIVES)}')
    return Path(__file__).resolve().parents[2] / 'data' / SHIPPED_ARCHIVES[name]
