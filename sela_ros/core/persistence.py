"""Crash-safe files: atomic writes, and the adapter's learned state. ROS-free.

A write goes to a temporary file beside the target, is fsync'ed, then renamed over it, so a
crash (even SIGKILL) leaves the old file or the new one, never a partial one.
"""
import json
import os
import tempfile
from pathlib import Path

STATE_FORMAT = 1


class StateError(ValueError):
    """A state file that cannot be used (corrupt, or for another archive)."""


def atomic_write(path, write):
    """Call ``write(binary_handle)`` on a temporary file beside ``path``, fsync, rename over.

    The file gets the usual permissions (``mkstemp`` makes 0600), and the directory entry
    is fsync'ed too, so the rename itself survives a power cut.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(prefix=f'.{path.name}.', suffix='.tmp', dir=path.parent)
    try:
        os.fchmod(fd, 0o666 & ~_umask())
        with os.fdopen(fd, 'wb') as handle:
            write(handle)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp_name, path)
    except BaseException:
        try:
            os.unlink(tmp_name)
        except FileNotFoundError:
            pass
        raise
    dir_fd = os.open(path.parent, os.O_RDONLY)
    try:
        os.fsync(dir_fd)
    finally:
        os.close(dir_fd)


def _umask():
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def atomic_write_bytes(path, data):
    atomic_write(path, lambda handle: handle.write(data))


def atomic_write_json(path, obj):
    atomic_write_bytes(path, json.dumps(obj, indent=1, allow_nan=False).encode())


def load_state(path, archive_size):
    """Read an adapter state file written for an archive of ``archive_size`` behaviours.

    Returns None when there is no file. Raises StateError when it is unreadable or was
    written for another archive.
    """
    path = Path(path)
    if not path.exists():
        return None
    try:
        state = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise StateError(f'state file {path} is unreadable: {exc}') from exc
    if not isinstance(state, dict) or state.get('format') != STATE_FORMAT:
        raise StateError(f'state file {path} is not a sela_ros adapter state (format '
                         f'{STATE_FORMAT})')
    size = state.get('archive_size')
    if size != archive_size:
        raise StateError(f'state file {path} was written for an archive of {size} behaviours, '
                         f'the loaded archive has {archive_size}')
    for key in ('sela', 'mission'):
        if not isinstance(state.get(key), dict):
            raise StateError(f'state file {path} has no {key!r} section')
    return state


def set_aside(path):
    """Keep an unusable state file under a new name instead of overwriting it."""
    path = Path(path)
    target = path.with_name(path.name + '.unusable')
    os.replace(path, target)
    return target
