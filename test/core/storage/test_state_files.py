"""State files that cannot be used are set aside with the reason; saves are acknowledged only
once durable."""
import json
import os
import stat
import threading

import numpy as np
import pytest

from sela_ros.core.learning import SELA, SE2Motion
from sela_ros.core.storage.persistence import (
    StateError,
    StateStore,
    atomic_write_json,
    learned_on,
    load_state,
    path_problem,
    resume_state,
    state_document,
)

SIZE = 20


def _good():
    return {'format': 1, 'archive_size': SIZE, 'mission': {'steps': 2},
            'sela': {'num_candidates': SIZE, 'gr_dim': 3, 'goal': [1.0, 1.0],
                     'indices': [3, 7], 'generic_rewards': [[0.1, 0.0, 0.2], [0.0, -0.1, 0.0]]}}


def _broken(edit):
    state = _good()
    edit(state)
    return state


BAD_STATES = {
    'missing generic rewards': (lambda s: s['sela'].pop('generic_rewards'), 'must be lists'),
    'missing mission': (lambda s: s.pop('mission'), "no 'mission' section"),
    'index past the archive': (lambda s: s['sela'].update(indices=[3, SIZE]),
                               r'indices\[1\] is 20, expected an integer in \[0, 20\)'),
    'negative index': (lambda s: s['sela'].update(indices=[-1, 2]), r'indices\[0\] is -1'),
    'boolean index': (lambda s: s['sela'].update(indices=[True, 2]), r'indices\[0\] is True'),
    'short reward': (lambda s: s['sela']['generic_rewards'].__setitem__(1, [0.1]),
                     r'generic_rewards\[1\]'),
    'string reward': (lambda s: s['sela']['generic_rewards'].__setitem__(0, ['a', 0, 0]),
                      r'generic_rewards\[0\]'),
    'lengths differ': (lambda s: s['sela'].update(indices=[3]), '1 indices but 2'),
    'bad goal': (lambda s: s['sela'].update(goal=[1.0]), 'goal is'),
    'standing flags short': (lambda s: s['sela'].update(standing_starts=[True]),
                             r'standing_starts is \[True\], expected 2 booleans'),
    'standing flag not a boolean': (lambda s: s['sela'].update(standing_starts=[1, 0]),
                                    'standing_starts is'),
    'other archive': (lambda s: s['sela'].update(num_candidates=5), 'num_candidates is 5'),
}


@pytest.mark.parametrize('name', sorted(BAD_STATES))
def test_inconsistent_state_is_refused_with_the_reason(tmp_path, name):
    edit, match = BAD_STATES[name]
    path = tmp_path / 'state.json'
    atomic_write_json(path, _broken(edit))
    with pytest.raises(StateError, match=match):
        load_state(path, SIZE)


@pytest.mark.parametrize('text', [
    '{"format": 1, "archive_size": 20, "sela": {"indices": [NaN]}, "mission": {}}',
    '{"format": 1, "archive_size": Infinity}', '[1, 2', '', '\x00\xff'])
def test_nan_infinity_or_garbage_is_unreadable(tmp_path, text):
    path = tmp_path / 'state.json'
    path.write_text(text, errors='surrogateescape')
    with pytest.raises(StateError, match='unreadable|not a sela_ros'):
        load_state(path, SIZE)


def test_a_good_state_restores_and_replays_into_sela(tmp_path):
    path = tmp_path / 'state.json'
    sela = SELA(np.random.default_rng(0).random((SIZE, 2)), np.zeros((SIZE, 3)), SE2Motion())
    state = _good()
    state['sela'] = dict(sela.state_dict(), indices=[3, 7],
                         generic_rewards=[[0.1, 0.0, 0.2], [0.0, -0.1, 0.0]],
                         standing_starts=[True, False])
    atomic_write_json(path, state)
    restored, message = resume_state(path, SIZE, lambda s: sela.load_state_dict(s['sela']))
    assert message is None and restored['mission'] == {'steps': 2}
    assert sela.observations[0].tolist() == [3, 7]
    assert sela.state_dict()['standing_starts'] == [True, False]
    # A file from before standing starts were recorded: none of its steps claims one.
    del state['sela']['standing_starts']
    atomic_write_json(path, state)
    resume_state(path, SIZE, lambda s: sela.load_state_dict(s['sela']))
    assert sela.state_dict()['standing_starts'] == [False, False]


@pytest.mark.parametrize('name', sorted(BAD_STATES) + ['restore raises'])
def test_an_unusable_state_is_set_aside_once_never_a_crash_loop(tmp_path, name):
    path = tmp_path / 'state.json'
    if name == 'restore raises':
        atomic_write_json(path, _good())
    else:
        atomic_write_json(path, _broken(BAD_STATES[name][0]))

    def restore(state):
        state['mission']['goal']  # a key the caller needs and the file lacks: KeyError

    for attempt in range(2):  # the second start finds no file: it starts afresh, silently
        restored, message = resume_state(path, SIZE, restore)
        assert restored is None
        if attempt == 0:
            assert message and 'kept it as' in message and 'started afresh' in message
            kept = next(tmp_path.glob('state.json.unusable-*[0-9]'))
            assert json.loads(kept.read_text())  # the file itself is kept, untouched
            why = kept.with_name(kept.name + '.why').read_text()
            assert why.strip() == message.split('; kept it as')[0]
        else:
            assert message is None
        assert not path.exists()


def test_what_a_simulator_taught_does_not_resume_on_a_robot_nor_the_other_way(tmp_path):
    path = tmp_path / 'state.json'
    simulated, robot = learned_on('sim_bridge'), learned_on('')
    assert (simulated, robot) == ('simulator sim_bridge', 'robot')
    atomic_write_json(path, state_document(SIZE, {k: v for k, v in _good().items()
                                                  if k in ('sela', 'mission')}, simulated))
    assert load_state(path, SIZE, learned_on=simulated)['learned_on'] == simulated
    assert load_state(path, SIZE)['mission'] == {'steps': 2}  # asked nothing: resumes
    with pytest.raises(StateError, match="learned on the simulator 'sim_bridge', and this "
                                         r'adapter learns on a robot \(no simulator node\)'):
        load_state(path, SIZE, learned_on=robot)
    restored, message = resume_state(path, SIZE, lambda s: None, learned_on=robot)
    assert restored is None and 'kept it as' in message  # set aside: nothing learned lost
    kept = next(tmp_path.glob('state.json.unusable-*[0-9]'))
    # sound, only another learner's: the message says how to resume it where it belongs
    assert f'state_file:={kept} resumes it with the archive and the learner' in message
    assert json.loads(kept.read_text())['learned_on'] == simulated
    # A file that does not say what it was learned on resumes anywhere.
    atomic_write_json(path, _good())
    assert load_state(path, SIZE, learned_on=robot)['mission'] == {'steps': 2}


def test_another_archives_state_is_kept_to_be_resumed_with_that_archive(tmp_path):
    path = tmp_path / 'state.json'
    atomic_write_json(path, _good())
    restored, message = resume_state(path, SIZE + 1, lambda s: None)
    assert restored is None and not path.exists()
    kept = next(tmp_path.glob('state.json.unusable-*[0-9]'))
    assert 'written for an archive of 20 behaviours, the loaded archive has 21' in message
    assert f'state_file:={kept} resumes it' in message
    assert resume_state(kept, SIZE, lambda s: None)[0]['mission'] == {'steps': 2}
    # a broken file is not said to be resumable anywhere
    path.write_text('{"format": 1')
    assert 'resumes it' not in resume_state(path, SIZE, lambda s: None)[1]


def test_older_unusable_files_are_never_overwritten(tmp_path):
    path = tmp_path / 'state.json'
    for n in range(3):
        path.write_text(f'broken {n}')
        assert resume_state(path, SIZE, lambda s: None)[1]
    assert sorted(p.read_text() for p in tmp_path.glob('state.json.unusable-*')
                  if not p.name.endswith('.why')) == ['broken 0', 'broken 1', 'broken 2']


def test_announcements_wait_for_the_saves_before_them(tmp_path):
    released = threading.Event()
    store = StateStore(tmp_path / 'state.json', on_released=released.set)
    gate = threading.Event()
    store._writer.submit(gate.wait)  # hold the writer: the saves below stay in flight
    store.save({'step': 1})
    store.after_saves('step 1 announced')
    store.save({'step': 2})
    store.after_saves('step 2 announced')
    assert store.released() == []  # nothing announced before it is on disk
    gate.set()
    store.flush(timeout=30)
    assert released.wait(30)
    assert store.released() == [(['step 1 announced'], None), (['step 2 announced'], None)]
    assert json.loads((tmp_path / 'state.json').read_text()) == {'step': 2}
    store.after_saves('nothing in flight')  # released at once
    assert store.released() == [(['nothing in flight'], None)]
    store.close()


def test_a_failed_save_is_released_with_its_error(tmp_path):
    blocker = tmp_path / 'not_a_directory'
    blocker.write_text('a file where the state folder should be')
    store = StateStore(blocker / 'state.json')
    gate = threading.Event()
    store._writer.submit(gate.wait)  # the save stays in flight until it has its announcement
    store.save({'step': 1})
    store.after_saves('step 1 announced')
    gate.set()
    store.flush(timeout=30)
    [(items, error)] = store.released()
    assert items == ['step 1 announced'] and 'could not save the learned state' in error
    store.save({'x': float('nan')})  # never written as a file JSON cannot read back
    store.flush(timeout=30)
    [(items, error)] = store.released()
    assert items == [] and 'could not save' in error and store.failures == 2
    store.close()


def test_a_fifo_or_a_directory_as_state_file_is_refused_at_once_and_left_alone(tmp_path):
    fifo = tmp_path / 'state.json'
    os.mkfifo(fifo)  # reading it would wait for a writer forever
    assert 'is a FIFO, expected a regular file' in path_problem(fifo)
    with pytest.raises(StateError, match='is a FIFO'):
        load_state(fifo, SIZE)
    state, problem = resume_state(fifo, SIZE, lambda s: None)
    assert state is None and 'is a FIFO' in problem and 'left as it is' in problem
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)  # not set aside, not replaced
    assert 'is a directory' in path_problem(tmp_path)
    assert path_problem(tmp_path / 'none yet.json') is None
    # Through a link too.
    link = tmp_path / 'link.json'
    link.symlink_to(fifo)
    assert 'is a FIFO' in path_problem(link)


def test_a_symlinked_state_file_stays_a_link_and_its_target_is_written(tmp_path):
    target = tmp_path / 'elsewhere' / 'state.json'
    atomic_write_json(target, _good())
    link = tmp_path / 'state.json'
    link.symlink_to(target)
    assert path_problem(link) is None
    store = StateStore(link)
    state = _good()
    state['mission']['steps'] = 7
    store.save(state)
    store.flush(timeout=30)
    store.close()
    assert link.is_symlink() and os.readlink(link) == str(target)
    assert load_state(link, SIZE)['mission']['steps'] == 7
    assert json.loads(target.read_text())['mission']['steps'] == 7


_HOLDER = '''
import sys, time
from sela_ros.core.storage.persistence import StateStore
store = StateStore(sys.argv[1])
print(store.claim(), flush=True)
sys.stdin.read()  # held until the test closes our stdin
'''


def test_a_state_file_has_one_writer_and_a_second_store_neither_reads_nor_writes_it(tmp_path):
    import subprocess
    import sys

    path = tmp_path / 'state.json'
    atomic_write_json(path, _good())
    holder = subprocess.Popen([sys.executable, '-c', _HOLDER, str(path)], text=True,
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE)
    try:
        assert holder.stdout.readline().strip() == 'None'  # it holds the file
        second = StateStore(path)
        why = second.claim()
        assert why is not None and f'pid {holder.pid}' in why and 'own state_file' in why
        second.save({'erased': True})
        second.flush(timeout=30)
        [(items, error)] = second.released()
        assert items == [] and 'in use by another process' in error
        assert load_state(path, SIZE) == _good()  # the holder's file untouched
        second.close()
    finally:
        holder.stdin.close()
        holder.wait(timeout=30)
    # Its holder gone, the file can be claimed again: a restarted adapter takes it back.
    third = StateStore(path)
    assert third.claim() is None
    third.save({'step': 3})
    third.flush(timeout=30)
    third.close()
    assert json.loads(path.read_text()) == {'step': 3}


def test_each_namespace_has_its_own_default_state_file(monkeypatch, tmp_path):
    from sela_ros.core.storage.persistence import default_state_file

    monkeypatch.setenv('ROS_HOME', str(tmp_path))
    root = tmp_path / 'sela_ros'
    assert default_state_file() == root / 'sela_adapter_state.json'
    assert default_state_file('/sela_adapter') == root / 'sela_adapter_state.json'
    assert default_state_file('/robot1/sela_adapter') == \
        root / 'robot1' / 'sela_adapter_state.json'
    assert default_state_file('/fleet/robot2/adapter') == \
        root / 'fleet' / 'robot2' / 'adapter_state.json'
