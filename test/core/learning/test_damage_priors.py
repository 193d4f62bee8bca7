"""Damage priors: choosing the prior that explains the steps seen, and SELA over it."""
import json
import subprocess
import sys

import numpy as np
import pytest

from sela_ros.core.learning import SELA, CandidateSetGP, SE2Motion, SELAConfig
from sela_ros.core.learning.damage_priors import (
    DamagePriorError,
    DamagePriors,
    load_damage_priors,
    params_checksum,
    priors_path,
    resolve_priors,
)
from sela_ros.core.learning.sela import HEDGED

M = 300


def world(seed=0):
    """An intact map and two damage tables over the same M gaits."""
    rng = np.random.default_rng(seed)
    candidates = rng.random((M, 4))
    intact = np.column_stack([rng.uniform(-0.6, 0.6, (M, 2)), rng.uniform(-0.5, 0.5, M)])
    halved = intact * [0.5, 0.5, 0.5]               # every gait half as far
    mirrored = intact * [1.0, -1.0, -1.0] * 0.6     # turns the other way
    fallen = np.zeros((2, M), bool)
    # On the first damage the 30 gaits that would land nearest (0.6, 0) fall.
    fallen[0, np.argsort(np.hypot(halved[:, 0] - 0.6, halved[:, 1]))[:30]] = True
    fallen[0, 200:203] = False
    params = rng.random((M, 36))
    priors = DamagePriors(('remove:front_left', 'remove:rear_left'),
                          np.stack([halved, mirrored]), fallen, params_checksum(params))
    return candidates, intact, priors, params


def test_the_table_that_explains_the_steps_is_chosen_and_a_poor_fit_is_not():
    _, intact, priors, _ = world()
    rng = np.random.default_rng(1)
    idx = rng.choice(M, 5, replace=False)
    # Steps seen on a robot that moves as the second table says, give or take 3 cm.
    seen = priors.generic_reward[1][idx] + rng.normal(0, 0.03, (5, 3))
    chosen = priors.select(intact, idx, seen)
    assert (chosen.index, chosen.name) == (1, 'remove:rear_left') and chosen.misfit < 0.6
    assert priors.select(intact, idx, intact[idx]).name == 'intact'
    assert priors.select(intact, [], np.zeros((0, 3))).name == 'intact'
    # Nothing foreseen: the steps are far from every table (four times the first's), so
    # the nearest table still explains them badly and the intact map is kept.
    far = intact[idx] * [-2.0, 2.0, 1.0]
    assert priors.select(intact, idx, far).name == 'intact'
    assert priors.select(intact, idx, seen, max_misfit=None).name == 'intact'


def test_one_surprise_in_the_first_two_steps_does_not_set_the_right_table_aside():
    """The misfit is the lower median: a first step the table explains exactly and a
    second one chained from an odd posture (far off every prior) keep the table; two
    steps both far off do not."""
    _, intact, priors, _ = world()
    idx = np.flatnonzero(~priors.fallen[0])[:2]
    exact = priors.generic_reward[0][idx[0]]
    odd = priors.generic_reward[0][idx[1]] + [0.6, -0.5, 1.5]
    chosen = priors.select(intact, idx, np.vstack([exact, odd]))
    assert chosen.name == 'remove:front_left' and chosen.misfit < 0.1
    both_odd = priors.generic_reward[0][idx] + [0.6, -0.5, 1.5]
    assert priors.select(intact, idx, both_odd).name == 'intact'


def test_a_table_that_reproduced_the_standing_start_is_kept_through_chained_surprises():
    """The first step from a standing start is the table's own experiment: the table that
    repeats it (up to the noise) is used with chained steps off by up to twice the chaining
    error (``priors.max.misfit.reproduced``), where otherwise it would be set aside; one
    that did not reproduce it gets no such exception, nor does a cap of 0 (never)."""
    _, intact, priors, _ = world()
    idx = np.flatnonzero(~priors.fallen[0])[:3]
    table = priors.generic_reward[0][idx]
    chained = [0.11, -0.11, 0.27]  # about 1.2 per output in units of the chaining error
    seen = np.vstack([table[0], table[1:] + chained])
    standing = [True, False, False]
    assert priors.select(intact, idx, seen).name == 'intact'
    kept = priors.select(intact, idx, seen, standing=standing)
    assert kept.name == 'remove:front_left' and 1.0 < kept.misfit < 2.0 and kept.reproduced
    assert priors.select(intact, idx, seen, standing=standing,
                         max_misfit_reproduced=1.0).name == 'intact'
    assert priors.select(intact, idx, seen, max_misfit=None, standing=standing).name == 'intact'
    # Off by 5 cm from a standing start: not reproduced, no exception.
    missed = seen + [[0.05, 0.05, 0.0], [0, 0, 0], [0, 0, 0]]
    assert priors.select(intact, idx, missed, standing=standing).name == 'intact'
    # Chained steps off by more than the exception allows.
    far = np.vstack([table[0], table[1:] + np.multiply(chained, 1.6)])
    assert priors.select(intact, idx, far, standing=standing).name == 'intact'
    with pytest.raises(ValueError, match='standing has 2 flags for 3 steps'):
        priors.select(intact, idx, seen, standing=[True, False])


def test_a_fall_counts_for_the_tables_where_that_gait_falls():
    _, intact, priors, _ = world()
    tied = DamagePriors(priors.names, np.stack([intact * 0.5, intact * 0.5]),
                        priors.fallen, priors.archive_checksum)
    idx = np.flatnonzero(~priors.fallen[0])[:2]
    seen = intact[idx] * 0.5
    falls = int(np.flatnonzero(priors.fallen[0])[0])
    assert not priors.fallen[0][idx].any()
    # Same displacements in both tables: a fall of a gait that falls only in the first
    # table picks that one.
    assert tied.select(intact, idx, seen, [idx[0], falls], [False, True]).index == 0
    assert tied.select(intact, idx, seen, [idx[0], falls], [False, False]).index == 1
    # A gait that fell: its (tumbling) displacement is not held against any table.
    odd = np.vstack([seen, [[5.0, -5.0, 3.0]]])
    assert tied.select(intact, [*idx, falls], odd, [falls], [True]).index == 0


def test_the_posterior_under_another_prior_is_that_of_a_gp_built_on_it():
    candidates, intact, priors, _ = world()
    gp = CandidateSetGP(candidates, intact, sigma=0.3, noise=0.01)
    other = CandidateSetGP(candidates, priors.generic_reward[0], sigma=0.3, noise=0.01)
    rng = np.random.default_rng(2)
    assert np.allclose(gp.mean_columns_with_prior(priors.generic_reward[0]),
                       priors.generic_reward[0].T)
    for i in rng.choice(M, 6, replace=False):
        y = rng.normal(0, 0.3, 3)
        gp.add_sample(int(i), y)
        other.add_sample(int(i), y)
    assert np.allclose(gp.mean_columns_with_prior(priors.generic_reward[0]),
                       other.query_columns()[0], atol=1e-9)
    with pytest.raises(ValueError, match='shape'):
        gp.mean_columns_with_prior(intact[:, :2])


def test_sela_walks_on_the_table_that_fits_and_keeps_off_its_falls():
    candidates, intact, priors, _ = world()
    config = SELAConfig(gp_kernel_sigma=0.3, acquisition_ucb_alpha=0.0)
    true = priors.generic_reward[0]
    sela = SELA(candidates, intact, SE2Motion(), goal=(5.0, 0.0), config=config,
                priors=priors)
    plain = SELA(candidates, intact, SE2Motion(), goal=(5.0, 0.0), config=config)
    assert sela.ask(np.zeros(3), map_trusted=True).prior == 'intact'
    assert sela.ask(np.zeros(3)).prior == HEDGED  # the first step of an adaptation
    for model in (sela, plain):
        for i in (200, 201, 202):
            model.tell_fall(i, False)
            model.tell(i, true[i])
    decision = sela.ask(np.zeros(3), waypoint=(0.6, 0.0))
    assert decision.prior == 'remove:front_left'
    # The steps seen are the table's exactly, so the posterior is the table: the gait taken
    # is the one the table (not the intact map) lands nearest the waypoint, among those the
    # table does not see falling.
    land = np.hypot(true[:, 0] - 0.6, true[:, 1])
    assert np.argmin(land) in np.flatnonzero(priors.fallen[0])  # the best one falls
    land[priors.fallen[0]] = np.inf
    assert decision.index == np.argmin(land)
    assert decision.index != np.argmin(np.hypot(intact[:, 0] - 0.6, intact[:, 1]))
    assert plain.ask(np.zeros(3), waypoint=(0.6, 0.0)).prior == 'intact'
    # The prediction is the table's where nothing was tried.
    mu, _ = sela.predict()
    far = np.argmax(np.linalg.norm(candidates - candidates[200], axis=1))
    assert np.allclose(mu[far], true[far], atol=0.05)
    # What is learnt is kept when the choice goes back to the intact map.
    state = sela.state_dict()
    again = SELA(candidates, intact, SE2Motion(), config=config, priors=priors)
    again.load_state_dict(state)
    assert again.select_prior().name == 'remove:front_left'


def test_the_first_step_is_hedged_over_the_intact_map_and_the_tables():
    """Before any step shows the damage, the first gait is the one that lands nearest the
    waypoint on average over every prior, not the intact map's best, which the damaged
    robots cannot do; a gait a table sees falling counts that against it."""
    candidates, intact, priors, _ = world()
    config = SELAConfig(gp_kernel_sigma=0.3, acquisition_ucb_alpha=0.0, fall_risk_cost=0.0)
    sela = SELA(candidates, intact, SE2Motion(), goal=(5.0, 0.0), config=config,
                priors=priors)
    waypoint = np.array([0.6, 0.0])
    tables = [intact, *priors.generic_reward]
    mean = np.mean([np.hypot(t[:, 0] - 0.6, t[:, 1]) for t in tables], axis=0)
    trusted = sela.ask(np.zeros(3), waypoint=waypoint, map_trusted=True)
    assert trusted.index == np.argmin(np.hypot(intact[:, 0] - 0.6, intact[:, 1]))
    hedged = sela.ask(np.zeros(3), waypoint=waypoint)
    assert hedged.prior == HEDGED and hedged.index != trusted.index
    # A gait one table of the three priors sees falling has a risk of 1/3, above the 0.3
    # accepted: the nearest on average is one of those, and it is not taken.
    falls = priors.fallen.sum(axis=0) > 0
    assert falls[np.argmin(mean)]
    assert hedged.index == np.argmin(np.where(falls, np.inf, mean))
    assert np.isclose(hedged.reward, -mean[hedged.index])
    # Once a step is learnt, the choice is the usual one, on the prior that fits.
    sela.tell_fall(hedged.index, False)
    sela.tell(hedged.index, priors.generic_reward[0][hedged.index])
    assert sela.ask(np.zeros(3), waypoint=waypoint).prior != HEDGED


def test_sela_refuses_tables_for_another_archive():
    candidates, intact, priors, _ = world()
    with pytest.raises(ValueError, match='damage priors are for 300 behaviours'):
        SELA(candidates[:10], intact[:10], SE2Motion(), priors=priors)


def test_a_save_that_fails_leaves_the_file_it_would_replace_whole(tmp_path, monkeypatch):
    _, _, priors, params = world()
    path = tmp_path / 'map_priors.npz'
    priors.save(path)
    before = path.read_bytes()

    def interrupted(handle, **arrays):
        handle.write(b'half a file')
        raise KeyboardInterrupt

    monkeypatch.setattr(np, 'savez_compressed', interrupted)
    with pytest.raises(KeyboardInterrupt):
        priors.without('remove:front_left').save(path)
    assert path.read_bytes() == before and sorted(tmp_path.iterdir()) == [path]


def test_files_round_trip_and_bad_files_are_named(tmp_path):
    _, _, priors, params = world()
    archive = tmp_path / 'map.npz'
    path = priors_path(archive)
    assert path.name == 'map_priors.npz'
    assert resolve_priors('auto', archive, params) is None  # none shipped beside it
    priors.save(path)
    back = resolve_priors('auto', archive, params)
    assert back.names == priors.names and np.array_equal(back.fallen, priors.fallen)
    assert np.allclose(back.generic_reward, priors.generic_reward, atol=1e-6)
    assert resolve_priors('none', archive, params) is None
    assert resolve_priors(str(path), archive, params).names == priors.names
    assert back.without('remove:front_left').names == ('remove:rear_left',)
    with pytest.raises(DamagePriorError, match='another archive'):
        resolve_priors('auto', archive, params[:, ::-1].copy())
    with pytest.raises(DamagePriorError, match='no such file'):
        resolve_priors(str(tmp_path / 'missing.npz'), archive, params)
    # The damage library: its own file beside the archive, said to be missing when it is.
    library = priors_path(archive, library=True)
    assert library.name == 'map_library.npz'
    with pytest.raises(DamagePriorError, match='no damage library.*make library'):
        resolve_priors('library', archive, params)
    priors.without('remove:front_left').save(library)
    assert resolve_priors('library', archive, params).names == ('remove:rear_left',)
    assert resolve_priors('auto', archive, params).names == priors.names
    bad = tmp_path / 'bad.npz'
    bad.write_bytes(path.read_bytes()[:1000])
    with pytest.raises(DamagePriorError, match='unreadable'):
        load_damage_priors(bad)
    bad.write_text('names, tables')
    with pytest.raises(DamagePriorError, match='bad.npz is not an .npz file') as refused:
        load_damage_priors(bad)
    assert 'pickle' not in str(refused.value)
    with pytest.raises(DamagePriorError, match='do not match'):
        DamagePriors(('a',), np.zeros((2, M, 3)), np.zeros((2, M), bool), 'x')
    with pytest.raises(DamagePriorError, match='NaN'):
        DamagePriors(('a',), np.full((1, M, 3), np.nan), np.zeros((1, M), bool), 'x')


def test_chained_runs_round_trip_and_are_checked(tmp_path):
    """A table's chained runs (the gaits run right after others: how often, how often they
    fell) travel with it; a file without them has none; nonsense counts are refused."""
    _, _, priors, params = world()
    runs, falls = np.zeros((2, M), int), np.zeros((2, M), int)
    runs[0, [5, 9]], falls[0, [5, 9]] = 4, [0, 3]
    chained = DamagePriors(priors.names, priors.generic_reward, priors.fallen,
                           priors.archive_checksum, runs, falls)
    gaits, n, f = chained.chained(0)
    assert gaits.tolist() == [5, 9] and n.tolist() == [4, 4] and f.tolist() == [0, 3]
    assert chained.chained(1)[0].size == 0 and priors.chained(0)[0].size == 0
    path = tmp_path / 'p.npz'
    chained.save(path)
    back = load_damage_priors(path, params)
    assert np.array_equal(back.chained_runs, runs) and np.array_equal(back.chained_falls, falls)
    assert back.without('remove:front_left').chained(0)[0].size == 0  # the rear left's: none
    assert back.without('remove:rear_left').chained(0)[0].tolist() == [5, 9]
    priors.save(path)  # written without them, as files from before
    assert load_damage_priors(path, params).chained(0)[0].size == 0
    for bad in (falls + runs + 1, -runs, runs[:, :5]):
        with pytest.raises(DamagePriorError, match='chained runs'):
            DamagePriors(priors.names, priors.generic_reward, priors.fallen,
                         priors.archive_checksum, runs, bad)


def test_sela_takes_the_chained_runs_of_the_table_it_walks_on():
    """Under a table with chained runs that reproduced the standing start, a gait that
    never fell chained is less feared than the support model alone says, and one that always
    fell more; a table that did not reproduce it (another damage, maybe) and the intact map
    give none."""
    candidates, intact, priors, _ = world()
    stability = np.linspace(-1.0, 1.0, M)
    runs, falls = np.zeros((2, M), int), np.zeros((2, M), int)
    safe, fragile = 10, 11  # little support: the support model fears both alike
    runs[0, [safe, fragile]], falls[0, [safe, fragile]] = 4, [0, 4]
    chained = DamagePriors(priors.names, priors.generic_reward, priors.fallen,
                           priors.archive_checksum, runs, falls)
    sela = SELA(candidates, intact, SE2Motion(), goal=(1.0, 0.0), stability=stability,
                priors=chained)
    table = chained.select(intact, [3], intact[[3]] * 0.5, standing=[True])
    assert table.name == 'remove:front_left' and table.reproduced
    unsure = chained.select(intact, [3], intact[[3]] * 0.5)
    assert unsure.name == 'remove:front_left' and not unsure.reproduced
    assert sela._posterior(unsure)[2][2] is None
    _, _, fall_prior = sela._posterior(table)
    with_runs = sela.fall_risk.risk(*fall_prior)
    without = sela.fall_risk.risk(*fall_prior[:2])
    assert with_runs[safe] < 0.5 * without[safe] and with_runs[fragile] > 0.7
    others = np.setdiff1d(np.arange(M), [safe, fragile])
    assert np.array_equal(with_runs[others], without[others])
    assert sela._posterior(chained.select(intact, [], np.zeros((0, 3))))[2] == ()


def test_experiments_use_the_tables_beside_the_archive_and_refuse_other_cells(tmp_path):
    from archive_fixtures import tiny_archive

    from sela_ros.core.storage import load_archive
    from sela_ros.experiments.campaign import cell_dir

    archive = tiny_archive(tmp_path / 'tiny.npz')
    params = load_archive(archive).params
    n = len(params)
    DamagePriors(('remove:middle_right', 'remove:front_left'), np.zeros((2, n, 3)),
                 np.zeros((2, n), bool), params_checksum(params)).save(priors_path(archive))

    def campaign(out, *extra, status=0):
        args = ['campaign', '--replicates', '1', '--out', str(out), '--quiet', '--archive',
                str(archive), '--methods', 'sela', '--goals', '0.3,0', '--damages',
                'remove:middle_right', '--max-steps', '2', *extra]
        proc = subprocess.run([sys.executable, '-m', 'sela_ros.experiments.cli', *args],
                              capture_output=True, text=True, timeout=600)
        assert proc.returncode == status, proc.stderr
        return proc.stderr

    campaign(tmp_path / 'a')
    cell = json.loads((cell_dir(tmp_path / 'a', archive, 'remove:middle_right', [0.3, 0.0])
                       / 'results.json').read_text())
    assert cell['parameters']['damage_priors'] == ['remove:middle_right', 'remove:front_left']
    assert cell['parameters']['priors.max.misfit'] == 0.6
    for extra, named in ((['--priors', 'none'], "damage priors ['remove:middle_right', "
                          "'remove:front_left'] (asked None)"),
                         (['--priors-leave-out-own'], "(asked ['remove:front_left'])")):
        error = campaign(tmp_path / 'a', *extra, status=2)
        assert named in error and 'Traceback' not in error
    campaign(tmp_path / 'b', '--priors-leave-out-own')
    error = campaign(tmp_path / 'c', '--priors', str(tmp_path / 'nope.npz'), status=2)
    assert 'nope.npz: no such file' in error and 'Traceback' not in error


def test_cells_without_sela_do_not_care_about_sela_only_parameters(tmp_path):
    from archive_fixtures import tiny_archive

    from sela_ros.core.storage import load_archive

    archive = tiny_archive(tmp_path / 'tiny.npz')
    params = load_archive(archive).params
    n = len(params)

    def campaign(methods, *extra, status=0):
        args = ['campaign', '--replicates', '1', '--out', str(tmp_path / 'a'), '--quiet',
                '--archive', str(archive), '--methods', methods, '--goals', '0.3,0',
                '--damages', 'remove:middle_right', '--max-steps', '2',
                '--oracle-cache', str(tmp_path / 'cache'), *extra]
        proc = subprocess.run([sys.executable, '-m', 'sela_ros.experiments.cli', *args],
                              capture_output=True, text=True, timeout=600)
        assert proc.returncode == status, proc.stderr
        return proc.stderr

    campaign('ite_uncertainty')  # no tables beside the archive yet
    DamagePriors(('remove:front_left',), np.zeros((1, n, 3)), np.zeros((1, n), bool),
                 params_checksum(params)).save(priors_path(archive))
    campaign('ite_uncertainty', '--horizon', '1')  # read back: IT&E uses neither
    error = campaign('ite_uncertainty,sela', status=2)  # SELA would run with the tables
    assert "damage priors None (asked ['remove:front_left'])" in error
    campaign('ite_uncertainty,sela', '--priors', 'none')


def tiered(priors, second):
    """``priors`` with a third table, ``second`` (M, 3), as the second tier."""
    return DamagePriors((*priors.names, 'remove:front_left,remove:rear_left'),
                        np.concatenate([priors.generic_reward, second[None]]),
                        np.concatenate([priors.fallen, np.zeros((1, M), bool)]),
                        priors.archive_checksum, None, None, np.array([False, False, True]))


def test_a_second_tier_round_trips_and_its_tables_come_last(tmp_path):
    _, intact, priors, _ = world()
    both = tiered(priors, intact * 0.2)
    assert list(both.second_tier) == [False, False, True]
    assert both.first_tier().names == priors.names
    assert np.array_equal(both.first_tier().generic_reward, priors.generic_reward)
    assert priors.first_tier() is priors and not priors.second_tier.any()
    path = tmp_path / 'p.npz'
    both.save(path)
    again = load_damage_priors(path)
    assert list(again.second_tier) == [False, False, True]
    assert list(again.without('remove:front_left').second_tier) == [False, True]
    priors.save(path)  # a file without the field: no second tier
    assert not load_damage_priors(path).second_tier.any()
    with pytest.raises(DamagePriorError, match='reproduce-only tables must come after'):
        DamagePriors(both.names, both.generic_reward, both.fallen, both.archive_checksum,
                     None, None, np.array([True, False, False]))
    with pytest.raises(DamagePriorError, match='reproduce_only must be 3 flags'):
        DamagePriors(both.names, both.generic_reward, both.fallen, both.archive_checksum,
                     None, None, np.array([0, 0, 1]))


def test_the_second_tier_is_used_only_once_it_reproduced_the_standing_starts():
    """Two legs lost: the second tier's table is neither hedged over on the first step nor
    mixed; it is the prior once it has reproduced the robot's standing start, and not on a
    robot it does not reproduce, where the choice is the first tier's alone."""
    candidates, intact, priors, _ = world()
    pair = intact * [0.15, 0.15, 0.15]
    both = tiered(priors, pair)
    config = SELAConfig(gp_kernel_sigma=0.3, acquisition_ucb_alpha=0.0, fall_risk_cost=0.0)
    waypoint = np.array([0.6, 0.0])
    first = SELA(candidates, intact, SE2Motion(), goal=(5.0, 0.0), config=config,
                 priors=priors)
    sela = SELA(candidates, intact, SE2Motion(), goal=(5.0, 0.0), config=config, priors=both)
    hedged = sela.ask(np.zeros(3), waypoint=waypoint)
    assert hedged.prior == HEDGED
    assert hedged.index == first.ask(np.zeros(3), waypoint=waypoint).index
    # On the robot the second tier holds: one step it reproduced from a standing start is
    # not enough (the hedged first gait is a cautious one that many damages move alike);
    # from the second step on its table is the prior.
    sela.tell_fall(hedged.index, False)
    sela.tell(hedged.index, pair[hedged.index], standing_start=True)
    second = sela.ask(np.zeros(3), waypoint=waypoint)
    assert second.prior != 'remove:front_left,remove:rear_left'
    sela.tell_fall(second.index, False)
    sela.tell(second.index, pair[second.index])
    decision = sela.ask(np.zeros(3), waypoint=waypoint)
    assert decision.prior == 'remove:front_left,remove:rear_left'
    assert np.allclose(sela.predict()[0][decision.index], pair[decision.index], atol=0.05)
    # On the first damage's robot the second tier is never used: every choice is the one
    # the first tier alone makes.
    true = priors.generic_reward[0]
    sela = SELA(candidates, intact, SE2Motion(), goal=(5.0, 0.0), config=config, priors=both)
    first = SELA(candidates, intact, SE2Motion(), goal=(5.0, 0.0), config=config,
                 priors=priors)
    for step in range(4):
        picks = [model.ask(np.zeros(3), waypoint=waypoint) for model in (sela, first)]
        assert picks[0].index == picks[1].index and picks[0].prior == picks[1].prior
        for model in (sela, first):
            model.tell_fall(picks[0].index, False)
            model.tell(picks[0].index, true[picks[0].index], standing_start=step == 0)
    assert picks[0].prior == 'remove:front_left'


def test_a_second_tier_table_stops_telling_the_fall_model_this_robot_rarely_falls_once_it_fell():
    """A second-tier table in use on a few standing starts may be another damage than the
    robot's (a leg shortened for a leg lost): once the robot has fallen on a gait the table
    says stands, the gaits it says fall are feared as before, but its support prior (that
    gaits rarely fall on its damage) is no longer given to the fall model; a first-tier
    table gives both."""
    candidates, intact, priors, _ = world()
    stability = np.linspace(-1.0, 1.0, M)
    pair = intact * 0.15
    fallen = np.zeros((3, M), bool)
    fallen[:2] = priors.fallen
    fallen[2, 250:255] = True  # five gaits of little use fall on the second tier's damage
    both = DamagePriors((*priors.names, 'remove:front_left,remove:rear_left'),
                        np.concatenate([priors.generic_reward, pair[None]]), fallen,
                        priors.archive_checksum, None, None, np.array([False, False, True]))
    config = SELAConfig(gp_kernel_sigma=0.3, acquisition_ucb_alpha=0.0, fall_risk_cost=0.0)
    waypoint = np.array([0.6, 0.0])
    sela = SELA(candidates, intact, SE2Motion(), goal=(5.0, 0.0), config=config,
                priors=both, stability=stability)
    first_tier = sela._posterior(both.first_tier().select(intact, [3], intact[[3]] * 0.5,
                                                          standing=[True]))[2]
    assert first_tier[1] is not None  # a first-tier table's support prior is given
    for standing in (True, False):
        decision = sela.ask(np.zeros(3), waypoint=waypoint)
        sela.tell_fall(decision.index, False)
        sela.tell(decision.index, pair[decision.index], standing_start=standing)
    decision = sela.ask(np.zeros(3), waypoint=waypoint)
    assert decision.prior == 'remove:front_left,remove:rear_left'
    falls, support, _ = sela._posterior(sela.select_prior())[2]
    assert support == sela.fall_risk.table_support(fallen[2])  # no fall yet: the table's
    # The robot falls on a gait the table says stands.
    sela.tell_fall(decision.index, True)
    decision = sela.ask(np.zeros(3), waypoint=waypoint)
    assert decision.prior == 'remove:front_left,remove:rear_left'
    falls, support, _ = sela._posterior(sela.select_prior())[2]
    assert support is None and np.array_equal(falls, fallen[2])
    risk = sela.fall_risk.risk(falls, support)
    assert decision.fall_risk == pytest.approx(risk[decision.index])
    # What the table's support prior would have gone on saying: that the fragile gaits
    # (the less stable half) rarely fall either.
    supported = sela.fall_risk.risk(falls, sela.fall_risk.table_support(falls))
    fragile = np.arange(M // 2)
    assert np.all(supported[fragile] < risk[fragile])
    assert np.mean(risk[fragile]) > 1.5 * np.mean(supported[fragile])


def test_a_share_of_the_standing_starts_reproduced_is_enough():
    """A damage that tips the robot makes even a standing start vary: the table that
    reproduced a third of the standing starts has reproduced them (the misfit cap of a
    reproduced table applies); a quarter is not enough."""
    _, intact, priors, _ = world()
    idx = np.flatnonzero(~priors.fallen[0])[:4]
    table = priors.generic_reward[0][idx]
    off = [0.15, -0.15, 0.3]  # about 2 per output, in units of the chaining error
    seen = np.vstack([table[0], table[1:] + off])
    third = priors.select(intact, idx[:3], seen[:3], standing=[True, True, True])
    assert third.name == 'remove:front_left' and third.reproduced
    quarter = priors.select(intact, idx, seen, standing=[True, True, True, True])
    assert not quarter.reproduced


def test_which_gaits_a_table_simulated_round_trips_and_is_checked(tmp_path):
    _, intact, priors, _ = world()
    simulated = np.ones((3, M), bool)
    simulated[2, 100:] = False
    both = DamagePriors((*priors.names, 'remove:front_left,remove:rear_left'),
                        np.concatenate([priors.generic_reward, intact[None] * 0.2]),
                        np.concatenate([priors.fallen, np.zeros((1, M), bool)]),
                        priors.archive_checksum, None, None, np.array([False, False, True]),
                        simulated)
    assert both.inferred(0) is None and np.flatnonzero(both.inferred(2)).tolist() == list(
        range(100, M))
    assert both.first_tier().inferred(1) is None and both.first_tier().simulated.shape == (2, M)
    assert both.without('remove:front_left').inferred(1).sum() == M - 100
    both.save(tmp_path / 'p.npz')
    again = load_damage_priors(tmp_path / 'p.npz')
    assert np.array_equal(again.simulated, simulated) and again.inferred(0) is None
    priors.save(tmp_path / 'whole.npz')  # no field: every gait simulated
    assert load_damage_priors(tmp_path / 'whole.npz').inferred(1) is None
    with pytest.raises(DamagePriorError, match=r'simulated must be \(2, 300\) flags'):
        DamagePriors(priors.names, priors.generic_reward, priors.fallen,
                     priors.archive_checksum, simulated=np.ones((2, M), int))
    with pytest.raises(DamagePriorError, match="simulated no gait: .'remove:rear_left'"):
        DamagePriors(priors.names, priors.generic_reward, priors.fallen,
                     priors.archive_checksum, simulated=np.array([[True] * M, [False] * M]))


def test_while_a_partly_inferred_table_is_the_prior_only_its_simulated_gaits_are_chosen():
    """The damage library's tables infer most gaits from those they simulated: while such a
    table is the prior, SELA chooses among the gaits it simulated and those the robot has
    tried, though an inferred one is predicted to land nearer the waypoint."""
    candidates, intact, priors, _ = world()
    pair = intact * 0.15
    waypoint = np.array([0.6, 0.0])
    config = SELAConfig(gp_kernel_sigma=0.3, acquisition_ucb_alpha=0.0, fall_risk_cost=0.0)

    def third_step(simulated):
        both = DamagePriors((*priors.names, 'remove:front_left,remove:rear_left'),
                            np.concatenate([priors.generic_reward, pair[None]]),
                            np.concatenate([priors.fallen, np.zeros((1, M), bool)]),
                            priors.archive_checksum, None, None,
                            np.array([False, False, True]), simulated)
        sela = SELA(candidates, intact, SE2Motion(), goal=(5.0, 0.0), config=config,
                    priors=both)
        tried = []
        for standing in (True, False):
            decision = sela.ask(np.zeros(3), waypoint=waypoint)
            sela.tell_fall(decision.index, False)
            sela.tell(decision.index, pair[decision.index], standing_start=standing)
            tried.append(decision.index)
        decision = sela.ask(np.zeros(3), waypoint=[0.0, 0.6])  # where no gait tried goes
        assert decision.prior == 'remove:front_left,remove:rear_left'
        return decision.index, tried

    best, tried = third_step(None)
    assert best not in tried
    simulated = np.ones((3, M), bool)
    simulated[2, best] = False
    pick, again = third_step(simulated)
    assert again == tried and pick != best and pick not in tried
    # A gait the robot has tried stays in the running, inferred or not.
    simulated[2, tried] = False
    pick, _ = third_step(simulated)
    assert pick != best


def test_the_shipped_library_flags_the_gaits_each_built_table_simulated():
    """The library's built tables simulated 4,000 gaits each and inferred the rest; the
    whole tables it takes from the shipped priors simulated every gait."""
    from sela_ros.core.storage import default_archive_path

    library = load_damage_priors(priors_path(default_archive_path(), library=True))
    shipped = load_damage_priors(priors_path(default_archive_path()))
    whole = [n for i, n in enumerate(library.names) if library.inferred(i) is None]
    assert sorted(whole) == sorted(shipped.first_tier().names)
    counts = {int((~library.inferred(i)).sum()) for i, n in enumerate(library.names)
              if n not in whole}
    assert counts == {4000} and len(library.names) - len(whole) == 84
