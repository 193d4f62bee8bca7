"""Crash-safe files: atomic writes, and the adapter's learned state. ROS-free.

A write goes to a temporary file beside the target, is fsync'ed, then renamed over it, so a
crash (even SIGKILL) leaves the old file or the new one, never a partial one.
"""
import fcntl
import json
import math
import os
import stat
import tempfile
import threading
import time
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from sela_ros.core.validation import ImplausibleOutcome, check_generic_rewards

STATE_FORMAT = 1


class StateError(ValueError):
    """A state file that cannot be used (corrupt, or for another archive)."""


class OtherLearnersState(StateError):
    """A sound state of another archive, or learned on another kind of learner (a simulator,
    a robot): set aside to be resumed where it belongs."""


class NotAStateFile(StateError):
    """Something other than a regular file where the state file should be: left alone."""


def atomic_write(path, write, sync=True):
    """Call ``write(binary_handle)`` on a temporary file beside ``path``, fsync, rename over.

    The file gets the usual permissions (``mkstemp`` makes 0600), and the directory entry
    is fsync'ed too, so the rename itself survives a power cut. With ``sync=False`` there is
    no fsync: the rename still makes the new file appear whole or not at all to any process
    (a SIGKILL cannot leave half of it), but a power cut may bring back the previous one.

    A symbolic link stays one: the file it points to is the one written.
    """
    path = Path(path)
    if path.is_symlink():
        path = Path(os.path.realpath(path))
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(prefix=f'.{path.name}.', suffix='.tmp', dir=path.parent)
    try:
        os.fchmod(fd, 0o666 & ~_umask())
        with os.fdopen(fd, 'wb') as handle:
            write(handle)
            handle.flush()
            if sync:
                os.fsync(handle.fileno())
        os.replace(tmp_name, path)
    except BaseException:
        try:
            os.unlink(tmp_name)
        except FileNotFoundError:
            pass
        raise
    if not sync:
        return
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


def atomic_write_json(path, obj, sync=True):
    data = json.dumps(obj, indent=1, allow_nan=False).encode()
    atomic_write(path, lambda handle: handle.write(data), sync=sync)


def default_state_file(node_name='/sela_adapter'):
    """Where the adapter ``node_name`` (fully qualified) keeps what it learned when
    ``state_file`` is not set: ``$ROS_HOME/sela_ros/<namespace>/<name>_state.json``, so that
    stacks in their own namespaces (two robots in one domain) each keep their own."""
    *namespace, name = [part for part in str(node_name).split('/') if part] or ['sela_adapter']
    return Path(os.environ.get('ROS_HOME', os.path.expanduser('~/.ros'))).joinpath(
        'sela_ros', *namespace, f'{name}_state.json')


def path_problem(path):
    """Why ``path`` cannot be a state file (something other than a regular file is there,
    through any symbolic link: a FIFO would hang the read, a device would be overwritten),
    or None (a regular file, or nothing yet)."""
    try:
        mode = os.stat(path).st_mode
    except (FileNotFoundError, NotADirectoryError):
        # Nothing there: a folder that cannot hold it fails each save, which says so.
        return None
    except OSError as exc:
        return f'{path} cannot be looked at: {exc}'
    if stat.S_ISREG(mode):
        return None
    kinds = ((stat.S_ISFIFO, 'a FIFO'), (stat.S_ISDIR, 'a directory'),
             (stat.S_ISSOCK, 'a socket'), (stat.S_ISCHR, 'a device'), (stat.S_ISBLK, 'a device'))
    kind = next((name for test, name in kinds if test(mode)), 'not a regular file')
    return f'{path} is {kind}, expected a regular file (or none yet)'


def state_document(archive_size, snapshot, learned_on=None):
    """The state file's content: ``snapshot`` (``sela`` and ``mission`` sections) tagged with
    the format, the size of the archive it was learned on and, where given, what it was
    learned on (``learned_on``: :func:`learned_on`)."""
    document = {'format': STATE_FORMAT, 'archive_size': int(archive_size), **snapshot}
    if learned_on is not None:
        document['learned_on'] = learned_on
    return document


def learned_on(simulator_node):
    """What an adapter learns on: ``simulator <name>`` where it checks its archive against a
    simulator node, ``robot`` where it has none to check (a real robot)."""
    return f'simulator {simulator_node}' if simulator_node else 'robot'


def _no_constant(name):
    raise ValueError(f'{name} is not a number JSON allows')


def load_state(path, archive_size, gr_dim=3, limits=None, learned_on=None):
    """Read an adapter state file written for an archive of ``archive_size`` behaviours (and,
    where ``learned_on`` is given, learned on it: a file learned on a simulator does not
    resume on a real robot, nor the other way; a file that does not say resumes anywhere).

    Everything the learner will replay is checked here, before any of it is used: the
    format, the archive size, the observations (integer indices inside the archive, one
    finite generic reward of ``gr_dim`` values each, within what one gait can do:
    ``limits``, :class:`~sela_ros.core.validation.OutcomeLimits`, as live outcomes), the
    learning set aside and the goal; NaN or infinity anywhere in the file makes it unusable.
    Returns None when there is no file.

    Raises:
        StateError: the file is unreadable, incomplete, inconsistent or for another archive;
            the message says which and where.
    """
    path = Path(path)
    problem = path_problem(path)
    if problem:
        raise NotAStateFile(f'state file {problem}')
    try:
        if not path.exists():
            return None
        state = json.loads(path.read_text(), parse_constant=_no_constant)
    except (OSError, UnicodeDecodeError, ValueError) as exc:  # JSONDecodeError is a ValueError
        raise StateError(f'state file {path} is unreadable: {exc}') from exc
    if not isinstance(state, dict) or state.get('format') != STATE_FORMAT:
        raise StateError(f'state file {path} is not a sela_ros adapter state (format '
                         f'{STATE_FORMAT})')
    size = state.get('archive_size')
    if size != archive_size:
        raise OtherLearnersState(f'state file {path} was written for an archive of {size} '
                                 f'behaviours, the loaded archive has {archive_size}')
    source = state.get('learned_on')
    if learned_on is not None and source is not None and source != learned_on:
        raise OtherLearnersState(f'state file {path} was learned on {_said(source)}, and this '
                                 f'adapter learns on {_said(learned_on)}: what one taught would '
                                 'mislead the other')
    for key in ('sela', 'mission'):
        if not isinstance(state.get(key), dict):
            raise StateError(f'state file {path} has no {key!r} section')
    problem = _learner_problem(state['sela'], archive_size, gr_dim, limits)
    if problem:
        raise StateError(f'state file {path}: sela.{problem}')
    return state


def _said(source):
    """A ``learned_on`` value as a sentence says it."""
    if source == 'robot':
        return 'a robot (no simulator node)'
    kind, _, name = str(source).partition(' ')
    return f'the simulator {name!r}' if kind == 'simulator' and name else repr(source)


def _learner_problem(sela, archive_size, gr_dim, limits=None):
    """What is wrong with the learner's section (``SELA.state_dict``), or None."""
    if sela.get('num_candidates') != archive_size:
        return (f'num_candidates is {sela.get("num_candidates")!r}, the archive has '
                f'{archive_size}')
    problem = _observations_problem(sela, archive_size, gr_dim, limits)
    if problem:
        return problem
    episodes = sela.get('set_aside', [])
    if not isinstance(episodes, list):
        return f'set_aside is {type(episodes).__name__}, expected a list'
    for n, episode in enumerate(episodes):
        problem = (_observations_problem(episode, archive_size, gr_dim, limits)
                   if isinstance(episode, dict) else 'expected an object')
        if problem:
            return f'set_aside[{n}].{problem}'
    goal = sela.get('goal')
    if goal is not None and not (isinstance(goal, list) and len(goal) == 2
                                 and all(_is_number(v) for v in goal)):
        return f'goal is {goal!r}, expected null or [x, y]'
    return None


def _observations_problem(sela, archive_size, gr_dim, limits):
    """What is wrong with a list of observations (indices, generic rewards, standing
    starts), or None."""
    indices, rewards = sela.get('indices'), sela.get('generic_rewards')
    if not isinstance(indices, list) or not isinstance(rewards, list):
        return 'indices and generic_rewards must be lists'
    if len(indices) != len(rewards):
        return f'{len(indices)} indices but {len(rewards)} generic_rewards'
    for n, (index, reward) in enumerate(zip(indices, rewards)):
        if not _is_int(index) or not 0 <= index < archive_size:
            return f'indices[{n}] is {index!r}, expected an integer in [0, {archive_size})'
        if not (isinstance(reward, list) and len(reward) == gr_dim
                and all(_is_number(v) for v in reward)):
            return f'generic_rewards[{n}] is {reward!r}, expected {gr_dim} finite numbers'
    standing = sela.get('standing_starts', [False] * len(indices))
    if not (isinstance(standing, list) and len(standing) == len(indices)
            and all(isinstance(v, bool) for v in standing)):
        return (f'standing_starts is {standing!r}, expected {len(indices)} booleans (one per '
                'index)')
    try:
        check_generic_rewards(rewards, limits, 'generic_rewards')
    except ImplausibleOutcome as exc:
        return str(exc)
    return None


def _is_int(value):
    return isinstance(value, int) and not isinstance(value, bool)


def _is_number(value):
    return isinstance(value, (int, float)) and not isinstance(value, bool) \
        and math.isfinite(value)


def set_aside(path, reason=None):
    """Keep an unusable state file under a new name (never overwriting an older one), with
    the reason in ``<new name>.why``, instead of overwriting it or failing on it again."""
    path = Path(path)
    stamp = time.strftime('%Y%m%dT%H%M%S')
    target = path.with_name(f'{path.name}.unusable-{stamp}')
    n = 1
    while target.exists():
        n += 1
        target = path.with_name(f'{path.name}.unusable-{stamp}-{n}')
    os.replace(path, target)
    if reason:
        try:
            target.with_name(target.name + '.why').write_text(f'{reason}\n')
        except OSError:
            pass  # the file is out of the way: that is what matters
    return target


def resume_state(path, archive_size, restore, gr_dim=3, limits=None, learned_on=None):
    """Read the state file and hand it to ``restore(state)``; never fails on a bad file.

    A file that cannot be used, for any reason (:func:`load_state` refuses it, or ``restore``
    raises on a missing key or a wrong type), is set aside with the reason and the caller
    starts afresh: an unusable file is reported once, never a crash at every start.
    ``restore`` must change nothing when it raises (build new objects, then swap them in).

    Returns:
        ``(state, None)`` when restored, ``(None, None)`` when there is no file, and
        ``(None, message)`` when it was set aside (the message says why and where it is).
    """
    try:
        state = load_state(path, archive_size, gr_dim, limits, learned_on)
        if state is None:
            return None, None
        restore(state)
        return state, None
    except NotAStateFile as exc:
        return None, f'{exc}; left as it is, started afresh'
    except Exception as exc:  # noqa: BLE001 - whatever the file holds, the node starts
        reason = str(exc) if isinstance(exc, StateError) else (
            f'state file {path} cannot be used: {type(exc).__name__}: {exc}')
        belongs_elsewhere = isinstance(exc, OtherLearnersState)
    try:
        kept = set_aside(path, reason)
    except OSError as exc:
        return None, f'{reason}; could not set it aside ({exc}); started afresh'
    if belongs_elsewhere:  # nothing wrong with it: to be resumed where it belongs
        return None, (f'{reason}; kept it as {kept} and started afresh (state_file:={kept} '
                      'resumes it with the archive and the learner it was written for)')
    return None, f'{reason}; kept it as {kept} and started afresh'


class StateStore:
    """The adapter's state file, written in order off the caller's thread.

    "Acknowledged means durable": what announces a step (its status, its reward) is passed
    to :meth:`after_saves` and released only once every snapshot saved before it is on disk
    (fsync'ed, renamed); a failed write is released with its error so the caller says so.
    The write itself (about 25 ms with both fsyncs here) stays off the step's critical path.

    Args:
        path: the state file.
        on_released: called (from the writer thread) whenever something is released: e.g.
            a guard condition's ``trigger`` so that the node's executor calls
            :meth:`released` on its own thread.
    """

    def __init__(self, path, on_released=None):
        self.path = Path(path)
        self._on_released = on_released
        self._lock = threading.Lock()
        self._writer = ThreadPoolExecutor(max_workers=1, thread_name_prefix='state_store')
        self._waiting = deque()  # (save number, items) held until that save has landed
        self._submitted = 0
        self._landed = 0
        self._out = deque()  # (items, error) ready for the caller
        self.failures = 0
        self._lock_file = None  # held while this store owns the file (claim)
        self._refused = None  # why this store may not write the file (claim)

    def claim(self):
        """Make this store the file's only writer on this machine, for as long as this
        process lives (an advisory lock on a file beside it, released by the kernel even on
        SIGKILL). Returns None, or why not: another process holds it (e.g. a second adapter
        given the same file), and then this store never reads nor writes it, so that
        neither adapter erases what the other learned."""
        real = Path(os.path.realpath(self.path))
        lock_path = real.with_name(f'.{real.name}.lock')
        try:
            lock_path.parent.mkdir(parents=True, exist_ok=True)
            handle = open(lock_path, 'a+')  # noqa: SIM115 - held for the store's life
        except OSError:
            return None  # nowhere to lock: every save says why it fails
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            handle.seek(0)
            holder = handle.read().strip()
            handle.close()
            self._refused = (f'state file {self.path} is in use by another process'
                             f'{f" (pid {holder})" if holder.isdigit() else ""}: this adapter '
                             'neither resumes from it nor saves to it; give each adapter its '
                             'own state_file')
            return self._refused
        handle.seek(0)
        handle.truncate()
        handle.write(str(os.getpid()))
        handle.flush()
        self._lock_file = handle
        return None

    def save(self, state, sync=True):
        """Queue a snapshot (taken by the caller, not touched afterwards) for writing
        (``sync=False``: safe against a crash of this process, not a power cut; about 1 ms
        instead of 25 here)."""
        with self._lock:
            self._submitted += 1
            number = self._submitted
        self._writer.submit(self._write, number, state, sync)

    def after_saves(self, item):
        """Release ``item`` once every save queued so far has landed (at once if none)."""
        with self._lock:
            if self._landed >= self._submitted:
                self._out.append(([item], None))
                release = True
            else:
                if self._waiting and self._waiting[-1][0] == self._submitted:
                    self._waiting[-1][1].append(item)
                else:
                    self._waiting.append((self._submitted, [item]))
                release = False
        if release and self._on_released is not None:
            self._on_released()

    def released(self):
        """``[(items, error)]`` released since the last call (error: None, or why the save
        before them failed)."""
        with self._lock:
            out = list(self._out)
            self._out.clear()
        return out

    def flush(self, timeout=None):
        """Wait for every queued save (e.g. before shutdown)."""
        self._writer.submit(lambda: None).result(timeout=timeout)

    def close(self):
        self._writer.shutdown(wait=True)
        if self._lock_file is not None:
            self._lock_file.close()  # the lock goes with it
            self._lock_file = None

    def _write(self, number, state, sync=True):
        error = None
        try:
            if self._refused:
                raise OSError(self._refused)
            atomic_write_json(self.path, state, sync=sync)
        except (OSError, ValueError, TypeError) as exc:
            error = f'could not save the learned state to {self.path}: {exc}'
        with self._lock:
            self._landed = number
            self.failures += error is not None
            released = False
            while self._waiting and self._waiting[0][0] <= number:
                self._out.append((self._waiting.popleft()[1], error))
                released = True
            if error and not released:
                self._out.append(([], error))  # nothing was waiting: the error alone
            release = released or error is not None
        if release and self._on_released is not None:
            self._on_released()
