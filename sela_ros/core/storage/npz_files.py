"""Sizes of a ``.npz`` file checked before anything in it is read. ROS-free.

``numpy.load`` inflates each array in full: a small file can declare gigabytes (a zip bomb)
and take the process's memory before any check on its content runs. The zip directory says
how large every member is once inflated, and the inflater never reads past that, so summing
it first bounds what loading can take.
"""
import zipfile

#: What an ``.npz`` this package reads may hold once inflated: the paper's archive of a
#: million 8-D gaits is about 450 MB (parameters, descriptors, rewards, fitness, centroids).
MAX_NPZ_BYTES = 512 * 2 ** 20


#: How every zip file, and so every ``.npz``, starts.
ZIP_MAGIC = b'PK\x03\x04'


class NpzRefused(ValueError):
    """A file refused before anything in it is read (its message starts with its path)."""


class NpzTooLarge(NpzRefused):
    """An ``.npz`` that would inflate beyond the limit: refused before it is read."""


class NotAnNpz(NpzRefused):
    """A file that is no zip at all (text, an ``.npy``, empty): no ``.npz``. Left alone,
    ``numpy.load`` would take it for a pickle and advise loading it unsafely."""


def check_npz_size(path, max_bytes=MAX_NPZ_BYTES):
    """Raise :class:`NpzTooLarge` if the members of the ``.npz`` at ``path`` add up to more
    than ``max_bytes`` once inflated, :class:`NotAnNpz` if it does not start as a zip does;
    returns that total. A corrupt zip, or a file that cannot be read, is left to
    ``numpy.load`` to refuse."""
    try:
        with open(path, 'rb') as handle:
            head = handle.read(len(ZIP_MAGIC))
    except OSError:
        return None
    if head != ZIP_MAGIC:
        raise NotAnNpz(f'{path} is not an .npz file: it does not start as a zip does')
    try:
        with zipfile.ZipFile(path) as npz:
            total = sum(max(0, info.file_size) for info in npz.infolist())
    except (zipfile.BadZipFile, OSError, ValueError, EOFError):
        return None
    if total > max_bytes:
        raise NpzTooLarge(f'{path} would take {total / 2 ** 20:.1f} MiB once inflated, more '
                          f'than the {max_bytes / 2 ** 20:.0f} MiB an archive may hold: '
                          'refused before reading it')
    return total
