"""One plausibility check for every way data comes in: a live outcome in the stepper, a
resumed state file, a loaded archive, the damage-prior tables, and an archive's size."""
import json
import re
import zipfile

import numpy as np
import pytest
from stepper_driver import Driver, of, only

from sela_ros.core.learning.damage_priors import DamagePriorError, load_damage_priors, priors_path
from sela_ros.core.mission.stepper_io import OutcomeReceived, Report, SendGait, State
from sela_ros.core.storage import ArchiveError, default_archive_path, load_archive, persistence
from sela_ros.core.storage.npz_files import MAX_NPZ_BYTES, check_npz_size
from sela_ros.core.validation import OutcomeLimits


def test_the_stepper_refuses_an_outcome_its_own_poses_contradict():
    d = Driver(adapt_on_start=True)
    gait = only(d.plan(d.start()), SendGait)
    still = (0.0, 0.0, 0.0)  # the pose did not move, the reward says 1.9 m forward
    for start in (still, None):  # the outcome's start pose, or the one the step started from
        out = d(OutcomeReceived(gait.behavior_id, (1.9, 0.0, 0.0), still, start_pose=start),
                dt=1.0)
        report = only(out, Report)
        assert 'refused, not learnt' in report.message, report
        assert 'does not match its own poses' in report.message
        assert d.state is State.EXECUTING and not len(d.stepper.sela.observations[0])
    # The real outcome of the same command is learnt.
    out = d.outcome(gait)
    assert not of(out, Report) and len(d.stepper.sela.observations[0]) == 1


def _state(tmp_path, rewards):
    path = tmp_path / 'state.json'
    sela = {'num_candidates': 10, 'gr_dim': 3, 'indices': list(range(len(rewards))),
            'generic_rewards': rewards, 'standing_starts': [False] * len(rewards),
            'goal': None}
    persistence.atomic_write_json(path, persistence.state_document(10, {'sela': sela,
                                                                        'mission': {}}))
    return path


@pytest.mark.parametrize('reward, why', [
    (1e308, r'the largest: row 1, 1e\+308 m'), (5.0, 'row 1, 5 m'), (-2.5, 'row 1, 2.5 m')])
def test_a_state_file_with_rewards_no_gait_can_give_is_set_aside_not_resumed(
        tmp_path, reward, why):
    path = _state(tmp_path, [[0.1, 0.0, 0.0], [reward, 0.0, 0.0]])
    restored = []
    state, problem = persistence.resume_state(path, 10, restored.append)
    assert state is None and not restored
    assert 'more than outcome.max_displacement 2 m' in problem and 'kept it as' in problem
    assert re.search(why, problem), problem
    assert not path.exists()  # set aside, with the reason beside it: nothing is deleted
    kept = list(tmp_path.glob('state.json.unusable-*'))
    assert any(p.suffix == '.why' for p in kept) and len(kept) == 2
    # A limit of the node's own (outcome.max_displacement 6 m) accepts the 5 m one.
    if reward == 5.0:
        path = _state(tmp_path, [[0.1, 0.0, 0.0], [reward, 0.0, 0.0]])
        state, problem = persistence.resume_state(path, 10, restored.append,
                                                  limits=OutcomeLimits(6.0))
        assert problem is None and restored


def _copy_npz(source, target, change):
    with np.load(source, allow_pickle=False) as npz:
        arrays = {k: npz[k] for k in npz.files}
    change(arrays)
    np.savez_compressed(target, **arrays)
    return target


def test_an_archive_with_rewards_scaled_by_1e300_is_refused(tmp_path):
    def scale(arrays):
        arrays['generic_reward'] = arrays['generic_reward'] * 1e300
    path = _copy_npz(default_archive_path(), tmp_path / 'scaled.npz', scale)
    with pytest.raises(ArchiveError, match='generic_reward: .* row.* move the robot more '
                       'than outcome.max_displacement 2 m'):
        load_archive(path)


def test_damage_priors_with_rewards_scaled_by_1e300_are_refused(tmp_path):
    source = priors_path(default_archive_path())

    def scale(arrays):  # as doubles: the shipped tables are float32, where 1e300 is inf
        arrays['generic_reward'] = arrays['generic_reward'].astype(float) * 1e300
    path = _copy_npz(source, tmp_path / 'priors.npz', scale)
    with pytest.raises(DamagePriorError, match='damage priors: generic_reward: .* more than '
                       'outcome.max_displacement 2 m'):
        load_damage_priors(path)
    assert len(load_damage_priors(source)) >= 1  # the shipped ones pass


def _zip_bomb(path, inflated):
    # One member that inflates to ``inflated`` bytes of zeros, written in chunks: small on
    # disk and in this process.
    chunk = bytes(2 ** 20)
    with zipfile.ZipFile(path, 'w', compression=zipfile.ZIP_DEFLATED) as npz:
        with npz.open('generic_reward.npy', 'w', force_zip64=True) as member:
            for _ in range(inflated // len(chunk)):
                member.write(chunk)
    return path


def test_an_archive_that_would_inflate_beyond_the_limit_is_refused_before_reading(tmp_path):
    bomb = _zip_bomb(tmp_path / 'bomb.npz', MAX_NPZ_BYTES + 2 ** 20)
    assert bomb.stat().st_size < 4 * 2 ** 20
    with pytest.raises(ArchiveError, match='MiB once inflated, more than the 512 MiB'):
        load_archive(bomb)
    with pytest.raises(DamagePriorError, match='once inflated'):
        load_damage_priors(bomb)
    assert check_npz_size(default_archive_path()) < 16 * 2 ** 20
    assert check_npz_size(tmp_path / 'missing.npz') is None


def test_the_shipped_state_round_trip_keeps_rewards_within_limits(tmp_path):
    path = _state(tmp_path, [[0.3, -0.1, 0.2], [-0.45, 0.0, 3.1]])
    assert persistence.load_state(path, 10)['sela']['generic_rewards'][1][0] == -0.45
    json.loads(path.read_text())  # plain JSON, no NaN
