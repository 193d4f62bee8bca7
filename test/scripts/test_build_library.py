"""The damage library's build plan: its conditions, its covering gaits, the gaits inferred."""
import numpy as np
import pytest
from script_modules import load_script

from sim_bridge.damage import parse_damage


@pytest.fixture(scope='module')
def lib():
    return load_script('build_library')


def test_the_plan_spans_the_kinds_parses_and_fits_the_budget(lib):
    names = lib.conditions()
    assert len(set(names)) == len(names)
    specs = [parse_damage(n) for n in names]  # every one a valid damage
    assert sum(len(s.removed) == 2 for s in specs) == 15  # every pair of legs removed
    assert {s.shortened[0][1] for s in specs if len(s.shortened) == 1} == \
        set(lib.SHORTEN_FACTORS)
    assert any(s.blocked for s in specs) and any(s.weakened for s in specs)
    _, evaluations, hours, _ = lib.plan(12442, lib.DEFAULT_GAITS)
    assert evaluations == len(names) * lib.DEFAULT_GAITS and hours <= lib.BUDGET_CORE_HOURS
    singles = [n for n in names if n.startswith('remove:') and ',' not in n]
    _, shipped_whole, _, _ = lib.plan(12442, lib.DEFAULT_GAITS, shipped=singles)
    assert shipped_whole == evaluations - len(singles) * lib.DEFAULT_GAITS


def test_the_gaits_evaluated_cover_the_map(lib):
    rng = np.random.default_rng(0)
    descriptors = rng.random((2000, 3))
    subset = lib.gait_subset(descriptors, 200)
    assert len(set(subset.tolist())) == 200
    np.testing.assert_array_equal(subset, lib.gait_subset(descriptors, 200))  # resumable
    gap = np.min(np.linalg.norm(descriptors[:, None] - descriptors[subset][None], axis=2),
                 axis=1)
    random = rng.choice(2000, 200, replace=False)
    gap_random = np.min(np.linalg.norm(descriptors[:, None] - descriptors[random][None],
                                       axis=2), axis=1)
    assert gap.max() < gap_random.max()


def test_after_the_covering_gaits_come_the_fastest_and_the_order_is_kept(lib):
    rng = np.random.default_rng(2)
    descriptors = rng.random((1000, 3))
    speed = rng.random(1000)
    covering = lib.gait_subset(descriptors, 100)
    subset = lib.gait_subset(descriptors, 300, speed, covering=100)
    # A longer plan resumes a shorter one: its first gaits are the covering ones, in order.
    np.testing.assert_array_equal(subset[:100], covering)
    rest = subset[100:]
    assert len(set(subset.tolist())) == 300
    others = np.setdiff1d(np.arange(1000), covering)
    fastest = others[np.argsort(-speed[others])][:200]
    np.testing.assert_array_equal(np.sort(rest), np.sort(fastest))
    assert np.all(np.diff(speed[rest]) <= 0)


def test_the_gaits_not_evaluated_are_inferred_from_their_neighbours(lib):
    rng = np.random.default_rng(1)
    descriptors = rng.random((1500, 2))
    base = np.column_stack([descriptors, np.zeros(1500)])
    # A damage that takes a smooth share of every gait's displacement, and tips over the
    # gaits of one corner.
    truth = base * (0.3 + 0.4 * descriptors[:, :1])
    falls = (descriptors[:, 0] > 0.8) & (descriptors[:, 1] > 0.8)
    subset = lib.gait_subset(descriptors, 300)
    gr, fallen = lib.infer(descriptors, base, subset, truth[subset], falls[subset], 0.1)
    np.testing.assert_array_equal(gr[subset], truth[subset])
    assert np.abs(gr - truth).max() < 0.05
    assert np.mean(fallen == falls) > 0.97


class _Map:
    """What the build reads of an archive: gaits, descriptors, generic rewards."""

    def __init__(self, rng, size=400):
        self.params = rng.random((size, 36))
        self._descriptors = rng.random((size, 2))
        self.generic_reward = np.column_stack([self._descriptors, np.zeros(size)]) * 0.3
        self.kernel_sigma = 0.3
        self.simulator_settings = {'dt': 1.0 / 120.0, 'gait_duration': 3.0,
                                   'solver_iterations': 30}

    def __len__(self):
        return len(self.params)

    def normalised_descriptors(self):
        return self._descriptors


def test_assembly_takes_whole_shipped_tables_and_infers_the_rest(lib, tmp_path):
    from sela_ros.core.learning import DamagePriors, params_checksum
    from sela_ros.core.learning.damage_priors import load_damage_priors

    archive = _Map(np.random.default_rng(3))
    m = len(archive)
    checksum = params_checksum(archive.params)
    runs = np.zeros((1, m), int)
    runs[0, 5] = 4
    falls = np.zeros((1, m), int)
    falls[0, 5] = 1
    whole = archive.generic_reward * 0.5
    shipped = DamagePriors(('remove:front_left',), whole[None], np.zeros((1, m), bool),
                           checksum, runs, falls)
    pair = 'remove:front_left,remove:rear_right'
    subset = lib.archive_subset(archive, 100)
    folder = tmp_path / lib._slug(pair)
    folder.mkdir()
    truth = archive.generic_reward * 0.25
    np.savez(folder / '000000.npz', gaits=subset[:60], generic_reward=truth[subset[:60]],
             fallen=np.zeros(60, bool))
    out = tmp_path / 'library.npz'
    only = {'remove:front_left', pair, 'remove:middle_left,remove:middle_right'}
    with pytest.raises(SystemExit, match='60 of 100'):
        lib.assemble(archive, tmp_path, 100, out, shipped, only)
    lib.assemble(archive, tmp_path, 100, out, shipped, only, partial=True)
    library = load_damage_priors(out, archive.params)
    # Nothing evaluated on both middle legs: left out, not made up.
    assert library.names == ('remove:front_left', pair)
    np.testing.assert_allclose(library.generic_reward[0], whole, atol=1e-6)
    gaits, chained_runs, chained_falls = library.chained(0)
    assert gaits.tolist() == [5] and chained_runs.tolist() == [4] and chained_falls.tolist() == [1]
    inferred = library.generic_reward[1]
    np.testing.assert_allclose(inferred[subset[:60]], truth[subset[:60]], atol=1e-6)
    # Flagged: the shipped table simulated every gait, the pair only the 60 evaluated.
    assert library.inferred(0) is None
    assert np.flatnonzero(~library.inferred(1)).tolist() == sorted(subset[:60].tolist())
    # The gaits not evaluated: nearer the damaged robot's outcomes than the intact map.
    rest = np.setdiff1d(np.arange(m), subset[:60])
    assert np.abs(inferred[rest] - truth[rest]).mean() < \
        0.5 * np.abs(archive.generic_reward[rest] - truth[rest]).mean()


def test_the_oracle_knows_a_whole_table_where_there_is_one_else_the_gaits_evaluated(lib, tmp_path):
    from sela_ros.core.learning import DamagePriors, params_checksum
    from sim_bridge.experiment_env import oracle_cache_path

    archive = _Map(np.random.default_rng(4))
    m, settings = len(archive), archive.simulator_settings
    whole = archive.generic_reward * 0.5
    fallen = np.zeros(m, bool)
    fallen[7] = True
    shipped = DamagePriors(('remove:front_left',), whole[None], fallen[None],
                           params_checksum(archive.params))
    cache = tmp_path / 'oracle'
    gr, falls, known, source = lib.known_outcomes(archive, 'remove:front_left', tmp_path, 100,
                                                  shipped, cache)
    assert known.all() and 'shipped' in source
    np.testing.assert_allclose(gr, whole)
    assert falls.tolist() == fallen.tolist()
    # Cut to the plan's gaits: what an oracle would know from the library alone.
    _, _, known, source = lib.known_outcomes(archive, 'remove:front_left', tmp_path, 100,
                                             shipped, cache, restrict=True)
    assert sorted(np.flatnonzero(known)) == sorted(lib.archive_subset(archive, 100))
    assert 'cut to the 100 gaits' in source
    # A table the experiments cached (sela-experiment's oracle) counts as whole.
    pair = 'remove:front_left,remove:rear_right'
    path = oracle_cache_path(archive.params, pair, cache, settings['dt'],
                             settings['gait_duration'], settings['solver_iterations'])
    path.parent.mkdir(parents=True)
    np.savez(path, generic_reward=whole * 0.5, fallen=np.zeros(m, bool))
    gr, _, known, source = lib.known_outcomes(archive, pair, tmp_path, 100, shipped, cache)
    assert known.all() and 'oracle cache' in source
    np.testing.assert_allclose(gr, whole * 0.5)
    # Else the gaits the library's build evaluated, and nothing made up for the others.
    blocked = 'block:rear_left.knee=0.4'
    subset = lib.archive_subset(archive, 100)
    folder = tmp_path / lib._slug(blocked)
    folder.mkdir()
    np.savez(folder / '000000.npz', gaits=subset[:30], generic_reward=whole[subset[:30]] * 2,
             fallen=np.arange(30) == 3)
    gr, falls, known, source = lib.known_outcomes(archive, blocked, tmp_path, 100, shipped,
                                                  cache)
    assert sorted(np.flatnonzero(known)) == sorted(subset[:30])
    np.testing.assert_allclose(gr[subset[:30]], whole[subset[:30]] * 2)
    assert np.flatnonzero(falls).tolist() == [subset[3]] and '30 gaits' in source
    assert lib.known_outcomes(archive, 'remove:middle_left', tmp_path, 100, shipped,
                              cache) is None


def test_a_damage_outside_the_library_is_evaluated_for_its_oracle(lib, tmp_path, monkeypatch):
    """``--oracle-only``: the gaits of a damage no condition holds (the ground's friction)
    are simulated, covering the map then the fastest, and the oracle reads them."""
    from sela_ros.core.storage import default_archive_path, load_archive

    archive = load_archive(default_archive_path())
    monkeypatch.setattr(lib, 'ORACLE_OUT', tmp_path)
    assert lib.known_outcomes(archive, 'friction:0.3') is None
    assert lib.build(archive, tmp_path, 3, 2, 1, specs=['friction:0.3'], covering=2) == 2
    gr, fallen, known, source = lib.known_outcomes(archive, 'friction:0.3')
    speed = np.hypot(archive.generic_reward[:, 0], archive.generic_reward[:, 1])
    chosen = np.flatnonzero(known)
    assert len(chosen) == 3 and '3 gaits' in source
    # Two cover the map; the third is the fastest gait of the intact robot.
    assert int(np.argmax(speed)) in chosen
    assert np.abs(gr[chosen]).sum() > 0 and not np.abs(gr[~known]).any()
    assert lib.build(archive, tmp_path, 3, 2, 1, specs=['friction:0.3'], covering=2) == 0


def test_the_second_tier_adds_library_tables_after_the_whole_ones(lib, tmp_path):
    """``--second-tier``: the shipped whole tables first, then the library's tables named,
    flagged, with the gaits the build simulated (its checkpoints; the rest inferred); a
    second-tier table is no whole table for an oracle (the library infers most of it), and
    a damage the library lacks, the first tier holds or the checkpoints do not is refused."""
    from sela_ros.core.learning import DamagePriors, params_checksum, priors_path
    from sela_ros.core.learning.damage_priors import load_damage_priors

    archive = _Map(np.random.default_rng(5))
    m = len(archive)
    checksum = params_checksum(archive.params)
    whole = archive.generic_reward * 0.5
    runs = np.zeros((1, m), int)
    runs[0, 9] = 3
    shipped = DamagePriors(('remove:front_left',), whole[None], np.zeros((1, m), bool),
                           checksum, runs, np.zeros((1, m), int))
    pair = 'remove:front_left,remove:rear_right'
    library = DamagePriors(('remove:front_left', pair, 'block:rear_left.knee=0.4'),
                           np.stack([whole, whole * 0.5, whole * 2]), np.zeros((3, m), bool),
                           checksum)
    library.save(tmp_path / 'library.npz')
    map_path = tmp_path / 'map.npz'
    out = tmp_path / 'checkpoints'
    with pytest.raises(SystemExit, match='no gait of remove:front_left,remove:rear_right '
                                         'evaluated'):
        lib.write_second_tier(map_path, archive, shipped, pair, tmp_path / 'library.npz', out)
    simulated = np.array([3, 7, 20])
    (out / lib._slug(pair)).mkdir(parents=True)
    np.savez(out / lib._slug(pair) / '000000.npz', gaits=simulated,
             generic_reward=whole[simulated] * 0.5, fallen=np.zeros(3, bool))
    lib.write_second_tier(map_path, archive, shipped, pair, tmp_path / 'library.npz', out)
    written = load_damage_priors(priors_path(map_path), archive.params)
    assert written.names == ('remove:front_left', pair)
    assert written.second_tier.tolist() == [False, True]
    assert written.inferred(0) is None
    assert np.flatnonzero(~written.inferred(1)).tolist() == [3, 7, 20]
    np.testing.assert_allclose(written.generic_reward[1], whole * 0.5, atol=1e-6)
    assert written.chained(0)[0].tolist() == [9] and not written.chained(1)[0].size
    # Written again over itself: the second tier is replaced, not stacked.
    lib.write_second_tier(map_path, archive, written, pair, tmp_path / 'library.npz', out)
    again = load_damage_priors(priors_path(map_path))
    assert again.names == written.names
    assert np.array_equal(again.simulated, written.simulated)
    assert lib.known_outcomes(archive, pair, tmp_path, 100, written,
                              tmp_path / 'oracle') is None
    with pytest.raises(SystemExit, match='remove:middle_left,remove:rear_right is no table'):
        lib.write_second_tier(map_path, archive, shipped, 'remove:middle_left,remove:rear_right',
                              tmp_path / 'library.npz', out)
    with pytest.raises(SystemExit, match='already a whole table'):
        lib.write_second_tier(map_path, archive, shipped, 'remove:front_left',
                              tmp_path / 'library.npz', out)
    # 'library': every table of the library the first tier does not hold, in its order.
    with pytest.raises(SystemExit, match='no gait of block:rear_left.knee=0.4 evaluated'):
        lib.write_second_tier(map_path, archive, shipped, 'library', tmp_path / 'library.npz',
                              out)
    (out / lib._slug('block:rear_left.knee=0.4')).mkdir(parents=True)
    np.savez(out / lib._slug('block:rear_left.knee=0.4') / '000000.npz', gaits=simulated[:2],
             generic_reward=whole[simulated[:2]] * 2, fallen=np.zeros(2, bool))
    lib.write_second_tier(map_path, archive, shipped, 'library', tmp_path / 'library.npz', out)
    everything = load_damage_priors(priors_path(map_path), archive.params)
    assert everything.names == ('remove:front_left', pair, 'block:rear_left.knee=0.4')
    assert everything.second_tier.tolist() == [False, True, True]
    assert np.flatnonzero(~everything.inferred(2)).tolist() == [3, 7]
