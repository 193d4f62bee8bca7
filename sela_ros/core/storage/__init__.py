"""What is kept in files: the behaviour-performance map (archive), the adapter's state file,
atomic writes, the size limit on ``.npz`` files."""
from sela_ros.core.storage.archive import (
    SETTING_DEFAULTS,
    Archive,
    ArchiveError,
    atomic_savez,
    check_settings,
    default_archive_path,
    load_archive,
    make_metadata,
    resolve_archive_path,
    shipped_archive_path,
)
from sela_ros.core.storage.npz_files import NotAnNpz, NpzRefused, NpzTooLarge, check_npz_size
from sela_ros.core.storage.persistence import (
    StateError,
    StateStore,
    atomic_write,
    atomic_write_bytes,
    atomic_write_json,
)

__all__ = ['SETTING_DEFAULTS', 'Archive', 'ArchiveError', 'NotAnNpz', 'NpzRefused',
           'NpzTooLarge', 'StateError',
           'StateStore', 'atomic_savez', 'atomic_write', 'atomic_write_bytes',
           'atomic_write_json', 'check_npz_size', 'check_settings', 'default_archive_path',
           'load_archive', 'make_metadata', 'resolve_archive_path', 'shipped_archive_path']
