"""Where the shipped archives live, and what an ``archive`` parameter's value names."""
from __future__ import annotations

from pathlib import Path

from sela_ros.core.archive import ArchiveError

#: The archives shipped inside the package (``sela_ros/data``), by short name: the default is
#: the paper's 8-D map (final x, y + six duty factors); ``2d`` is the first, 2-D map (final
#: x, y), kept to compare with (docs/archive.md).
SHIPPED_ARCHIVES = {'8d': 'hexapod_archive.npz', '2d': 'hexapod_archive_2d.npz'}


def default_archive_path() -> Path:
    """Path of the archive shipped inside the installed package (``sela_ros/data``)."""
    return shipped_archive_path('8d')


def resolve_archive_path(value: str) -> str:
    """An ``archive`` parameter's value as a path: '' is the default shipped archive, ``8d``
    and ``2d`` the shipped ones by name, anything else a path as given."""
    value = (value or '').strip() or '8d'
    return str(shipped_archive_path(value)) if value in SHIPPED_ARCHIVES else value


def shipped_archive_path(name: str) -> Path:
    """Path of a shipped archive by short name (:data:`SHIPPED_ARCHIVES`)."""
    if name not in SHIPPED_ARCHIVES:
        raise ArchiveError(f'no shipped archive {name!r}; shipped: {sorted(SHIPPED_ARCHIVES)}')
    return Path(__file__).resolve().parent.parent / 'data' / SHIPPED_ARCHIVES[name]
