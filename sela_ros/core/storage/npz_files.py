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


class NpzTooLarge(ValueError):
    """An ``.npz`` that would inflate beyond the limit: refused before it is read."""


def check_npz_size(path, max_bytes=MAX_NPZ_BYTES):
    """Raise :class:`NpzTooLarge` if the members of the ``.npz`` at ``path`` add up to more
    than ``max_bytes`` once inflated; returns that total. A file that is not a zip (an
    ``.npy``, a corrupt file) is left to ``numpy.load`` to refuse."""
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
