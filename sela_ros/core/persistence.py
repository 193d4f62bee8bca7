"""Crash-safe files: atomic writes, and the adapter's learned state. ROS-free.

A write goes to a temporary file beside the target, is fsync'ed, then renamed over it, so a
crash (even SIGKILL) leaves the old file or the new one, never a partial one.
"""
import json
import os
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from sela_ros.core.sela import Decision
from sela_ros.core.stepper_io import Level, PendingStep, Report, State

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


def default_state_file():
    """Where the adapter keeps what it learned when ``state_file`` is not set."""
    return Path(os.environ.get('ROS_HOME', os.path.expanduser('~/.ros'))) / 'sela_ros' / \
        'sela_adapter_state.json'


def state_document(archive_size, snapshot):
    """The state file's content: ``snapshot`` (``sela`` and ``mission`` sections) tagged with
    the format and the size of the archive it was learned on."""
    return {'format': STATE_FORMAT, 'archive_size': int(archive_size), **snapshot}


class StateWriter:
    """Writes state documents to ``path`` off the caller's thread, one at a time, in order
    (a later snapshot always lands after an earlier one); ``on_error(message)`` on failure."""

    def __init__(self, path, on_error):
        self.path = path
        self.on_error = on_error
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix='state_writer')

    def submit(self, document):
        self._pool.submit(self._write, document)

    def _write(self, document):
        try:
            atomic_write_json(self.path, document)
        except (OSError, ValueError) as exc:
            self.on_error(f'could not save the learned state to {self.path}: {exc}')

    def close(self):
        """Wait for the last write: it reaches the disk."""
        self._pool.shutdown(wait=True)


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


def mission_snapshot(stepper):
    """What a :class:`~sela_ros.core.stepper.MissionStepper` learned and where its mission
    stands, as JSON-able values (the ``sela`` and ``mission`` sections of the state file)."""
    p = stepper.pending
    pending = None
    if p is not None and p.decision is not None and stepper.state in (State.EXECUTING,
                                                                      State.VERDICT):
        d = p.decision
        pending = {'id': p.behavior_id, 'step': p.step, 'index': int(d.index),
                   'pose': _list(p.pose), 'waypoint': _list(d.waypoint),
                   'predicted_gr': _list(d.predicted_gr),
                   'predicted_pose': _list(d.predicted_pose), 'reward': d.reward,
                   'sigma': d.sigma}
    last = stepper.logic.last
    pose = stepper.current_pose()
    return {'sela': stepper.sela.state_dict(), 'mission': {
        'state': stepper.state.value, 'steps': stepper.steps,
        'failed_steps': stepper.failed_steps,
        'goal': None if stepper.goal is None else _list(stepper.goal),
        'pose': None if pose is None else _list(pose),
        'adapting': stepper.logic.adapting, 'adaptations': stepper.logic.adaptations,
        'last': None if last is None else [int(last[0]), _list(last[1])],
        'next_id': stepper.next_id, 'pending': pending, 'reset_needed': stepper.reset_needed}}


def restore_mission(stepper, snapshot, now):
    """Take back what :func:`mission_snapshot` saved into ``stepper``; returns the
    commands (reports) it gives. Raises KeyError, TypeError or ValueError on a bad one.

    What was learned always comes back. A mission in progress comes back only if the
    robot turns out to be where it was (the first odometry decides); a gait in flight
    waits for its outcome.
    """
    stepper.sela.load_state_dict(snapshot['sela'])
    m = snapshot['mission']
    stepper.logic.adapting = bool(m['adapting'])
    stepper.logic.adaptations = int(m['adaptations'])
    last = m['last']
    stepper.logic.last = None if last is None else (int(last[0]), np.array(last[1], float))
    stepper.next_id = int(m['next_id'])
    stepper.failed_steps = int(m.get('failed_steps', 0))
    state = State(m['state'])
    if m['goal'] is None or state in (State.IDLE, State.DONE):
        return []
    stepper.goal = np.array(m['goal'], dtype=float)
    stepper.sela.set_goal(stepper.goal)
    stepper.steps = int(m['steps'])
    stepper.reset_needed = bool(m.get('reset_needed', False))
    pending = m.get('pending')
    if pending is not None and state is State.EXECUTING:
        d = Decision(index=int(pending['index']), waypoint=np.array(pending['waypoint']),
                     predicted_gr=np.array(pending['predicted_gr']),
                     predicted_pose=np.array(pending['predicted_pose']),
                     reward=float(pending['reward']), sigma=float(pending['sigma']))
        stepper.pending = PendingStep(
            step=stepper.steps, pose=np.array(pending['pose']), t_start=now,
            deadline=now + stepper.config.outcome_timeout, waypoint=d.waypoint, decision=d,
            behavior_id=int(pending['id']), t_sent=now)
        stepper.resume = stepper.pending.pose
        stepper.state = State.EXECUTING  # the outcome may be waiting (it is latched)
        return [Report(Level.WARN, f'resuming: waiting for the outcome of command '
                       f"{pending['id']}")]
    if m['pose'] is None:
        stepper.goal = None
        return [Report(Level.ERROR, 'mission dropped: the state file has no pose to '
                       'check the robot against; send the goal again')]
    if pending is not None:
        stepper.last_id = int(pending['id'])  # a late verdict on it still counts
    stepper.resume = np.array(m['pose'], dtype=float)
    stepper.state = State.READY
    return [Report(Level.WARN, f'mission to ({stepper.goal[0]:.2f}, {stepper.goal[1]:.2f}) '
                   'restored: checking that the robot is where it was')]


def _list(values):
    return np.asarray(values, dtype=float).tolist()
