"""The leave-one-out comparison's bookkeeping: its cases, the tables each case is run with,
the oracle's medians taken from its own runs."""
import numpy as np
import pytest
from script_modules import load_script

from sela_ros.core.learning import DamagePriors
from sela_ros.core.learning.damage_priors import load_damage_priors
from sim_bridge.damage import parse_damage


@pytest.fixture(scope='module')
def compare():
    return load_script('compare_priors')


def test_every_condition_of_the_plan_is_a_case_then_the_damages_between(compare):
    plan = load_script('build_library').conditions()
    cases = compare.library_cases()
    labels = [c[0] for c in cases]
    assert len(set(labels)) == len(labels)
    assert labels[:len(plan)] == [f'{n}/own-left-out' for n in plan]
    # Each measured with its own table out of whatever priors the method uses.
    assert all(own for _, _, own in cases[:len(plan)])
    held = {parse_damage(n).canonical() for n in plan}
    between = [c[1] for c in cases[len(plan):]]
    assert 'shorten:front_left:0.5' in between
    assert not {parse_damage(d).canonical() for d in between} & held


def test_a_damage_foreseen_keeps_its_table_and_the_same_damage_unforeseen_does_not(
        compare, tmp_path):
    rng = np.random.default_rng(0)
    names = ('remove:front_left', 'remove:rear_left', 'remove:front_left,remove:rear_left')
    whole = DamagePriors(names, rng.normal(0, 0.3, (3, 50, 3)), np.zeros((3, 50), bool), 'x')
    foreseen = next(c for c in compare.FORESEEN if c[1] == 'remove:front_left')
    unforeseen = next(c for c in compare.UNFORESEEN if c[0] == 'remove:front_left/own-left-out')
    library = compare.library_priors(whole, (unforeseen, foreseen), tmp_path)
    assert library[foreseen[0]][1] == []
    assert load_damage_priors(library[foreseen[0]][0]).names == names
    assert library[unforeseen[0]][1] == ['remove:front_left']
    assert load_damage_priors(library[unforeseen[0]][0]).names == names[1:]



def test_the_whole_library_foresees_its_own_conditions_only(compare):
    """``library-own`` runs a condition with its own table in (foreseen); a damage between
    the grid points has none, and any other method's own-left-out case is unforeseen."""
    assert compare.is_foreseen('block:front_left.knee=0.0/own-left-out', 'library-own')
    assert compare.is_foreseen('block:front_left.knee=0.0/own-left-out', 'library-own-caution')
    assert not compare.is_foreseen('shorten:front_left:0.5', 'library-own-caution')
    assert compare.METHODS['library-own-caution']['acquisition.caution'] \
        == compare.METHODS['caution']['acquisition.caution']
    assert not compare.is_foreseen('shorten:front_left:0.5', 'library-own')
    assert not compare.is_foreseen('block:front_left.knee=0.0/own-left-out', 'library')
    assert not compare.is_foreseen('remove:front_left/own-left-out', 'mixture')
    assert compare.is_foreseen('remove:front_left', 'mixture')

def test_a_near_duplicate_of_the_damage_is_left_out_with_it(compare):
    rng = np.random.default_rng(1)
    gr = rng.normal(0, 0.3, (3, 50, 3))
    gr[2] = gr[0] + 0.01  # within the chaining error of the first table
    names = ('shorten:front_left:0.3', 'remove:rear_left', 'remove:front_left')
    kept, out = compare.leave_out(DamagePriors(names, gr, np.zeros((3, 50), bool), 'x'),
                                  'shorten:front_left:0.3')
    assert out == ['shorten:front_left:0.3', 'remove:front_left']
    assert kept.names == ('remove:rear_left',)


def test_the_oracles_medians_come_from_its_runs(compare):
    runs = [{'method': 'oracle', 'damage': 'remove:rear_left,remove:front_left',
             'goal': [2, 2], 'steps': s, 'oracle_table': 'whole table (shipped)'}
            for s in (6, 8, 9)]
    runs.append({'method': 'oracle', 'damage': 'remove:front_left', 'goal': [2, 2],
                 'steps': 7, 'oracle_table': 'the 4000 gaits the library evaluated'})
    runs.append({'method': 'library', 'damage': 'remove:front_left,remove:rear_left',
                 'goal': [2, 2], 'steps': 30})
    pair = (parse_damage('remove:front_left,remove:rear_left').canonical(), (2.0, 2.0))
    assert compare.measured_oracle(runs, whole=True) == {pair: 8.0}
    assert compare.measured_oracle(runs, whole=False) == {('remove:front_left', (2.0, 2.0)): 7.0}
    assert len(compare.measured_oracle(runs)) == 2


def test_the_best_mixture_finds_the_weights_of_a_damage_the_tables_span(compare):
    rng = np.random.default_rng(2)
    intact = rng.normal(0, 0.3, (60, 3))
    tables = intact + rng.normal(0, 0.2, (3, 60, 3))
    truth = intact + 0.5 * (tables[0] - intact) + 0.25 * (tables[2] - intact)
    rows = np.arange(60) < 40  # fitted on 40 gaits, predicts the other 20
    scale = np.array([0.1, 0.1, 0.25])
    np.testing.assert_allclose(compare.best_mixture(intact, tables, truth, rows, scale), truth,
                               atol=1e-9)
    # A damage that undoes a table's deviation is out of reach: weights are never negative.
    # (Each table deviates on its own gaits here, so no other table explains any of it.)
    apart = np.repeat(intact[None], 3, axis=0)
    for k in range(3):
        apart[k, 20 * k:20 * k + 20] += rng.normal(0, 0.2, (20, 3))
    undo = intact - 0.5 * (apart[1] - intact)
    fitted = compare.best_mixture(intact, apart, undo, np.ones(60, bool), scale)
    np.testing.assert_allclose(fitted, intact, atol=1e-9)
    # Every linear combination: a weight of -0.5 undoes it.
    np.testing.assert_allclose(
        compare.best_mixture(intact, apart, undo, np.ones(60, bool), scale, signed=True), undo,
        atol=1e-9)


def test_a_bound_with_the_damages_own_table_counts_as_foreseen(compare):
    assert compare.is_foreseen('block:front_left.knee=0.0/own-left-out', 'bound-own')
    assert compare.is_foreseen('shorten:front_left:0.5', 'bound-own')
    assert not compare.is_foreseen('block:front_left.knee=0.0/own-left-out', 'bound-fit')
    assert not compare.is_foreseen('shorten:front_left:0.5', 'bound-fit-signed')


def test_the_second_tier_cases_are_the_shipped_library_tables_with_their_tables_in(compare):
    from sela_ros.core.learning import resolve_priors
    from sela_ros.core.storage import default_archive_path, load_archive

    shipped = resolve_priors('auto', default_archive_path(),
                             load_archive(default_archive_path()).params)
    cases = compare.second_tier_cases()
    assert [c[1] for c in cases] == list(shipped.names[len(shipped.first_tier()):])
    assert len(cases) == 84 and sum(d.count('remove:') == 2 for _, d, _ in cases) == 15
    assert all(label == damage and not own for label, damage, own in cases)
    assert all(compare.is_foreseen(label, 'caution') for label, _, _ in cases)
    assert not compare.is_foreseen('block:front_left.knee=0.0/own-left-out', 'caution')
