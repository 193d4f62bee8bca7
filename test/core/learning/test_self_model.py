"""The self-model: lost legs read from the feet, their damage simulated into a table."""
import numpy as np
import pytest

from sela_ros.core.learning import SELA, DamagePriors, SE2Motion, SELAConfig
from sela_ros.core.learning.self_model import (
    PREFIX,
    LostLegs,
    SelfModel,
    SelfModelConfig,
    alternatives,
    choose,
    farthest_by_heading,
    hypothesis,
    legs_of,
)
from sela_ros.core.learning.table_inference import gait_subset, infer

LEGS = ('a', 'b', 'c', 'd')


def _map(m=200, seed=0):
    rng = np.random.default_rng(seed)
    duty = rng.uniform(0.0, 1.0, (m, len(LEGS)))
    descriptors = np.column_stack([rng.uniform(0, 1, (m, 2)), duty])
    # Where a gait goes is a smooth function of its descriptor, as on a map.
    gr = np.column_stack([0.8 * descriptors[:, 0] - 0.4, 0.6 * descriptors[:, 1] - 0.3,
                          np.sin(3 * descriptors[:, 2])])
    return descriptors, gr, duty


def _feet(duty, lost=()):
    """What a robot whose legs ``lost`` are gone measures: those feet never touch."""
    out = np.array(duty, float)
    for leg in lost:
        out[LEGS.index(leg)] = 0.0
    return out


def test_a_leg_is_lost_only_after_steps_that_lean_on_it_never_touch():
    _, _, duty = _map()
    feet = LostLegs(duty, LEGS)
    leaning = np.flatnonzero((duty[:, 0] > 0.5) & (duty[:, 1] > 0.5))
    feet.observe(leaning[0], _feet(duty[leaning[0]], ('a',)))
    assert feet.lost() == ()  # one step is no evidence
    feet.observe(leaning[1], _feet(duty[leaning[1]], ('a',)), fallen=True)
    assert feet.lost() == ()  # a tumble's feet tell nothing
    feet.observe(leaning[2], _feet(duty[leaning[2]], ('a',)))
    assert feet.lost() == ('a',)
    # The leg touches once where a gait leans on it: it is there (shortened, say).
    feet.observe(leaning[3], duty[leaning[3]])
    assert feet.lost() == ()


def test_a_gait_that_does_not_lean_on_a_leg_says_nothing_of_it():
    _, _, duty = _map()
    feet = LostLegs(duty, LEGS)
    light = np.flatnonzero(duty[:, 2] < 0.1)[:5]
    for g in light:
        feet.observe(g, _feet(duty[g], ('c',)))
    assert 'c' not in feet.lost()
    feet.observe(0, [np.nan, 0, 0, 0])  # a malformed measure is ignored
    feet.observe(0, [0.0, 0.0])
    for g in light:  # feet not measured (every one zero): no leg is lost
        feet.observe(g, np.zeros(len(LEGS)))
    assert feet.leaned.sum() == sum(int((duty[g] >= 0.3).sum()) for g in light)


def test_the_farthest_gaits_are_taken_in_turn_from_every_direction():
    angle = np.linspace(-np.pi, np.pi, 64, endpoint=False) + 0.01
    speed = np.where(np.cos(angle) > 0, 1.0, 0.1) * (1 + 0.001 * np.arange(64))
    gr = np.column_stack([speed * np.cos(angle), speed * np.sin(angle), np.zeros(64)])
    allowed = np.ones(64, bool)
    allowed[np.argmax(speed)] = False
    picked = farthest_by_heading(gr, allowed, 8, headings=8)
    # One gait of each of the eight sectors, the farthest of each, the slow ones included.
    sector = np.floor((np.arctan2(gr[:, 1], gr[:, 0]) + np.pi) / (np.pi / 4)).astype(int) % 8
    assert sorted(sector[picked]) == list(range(8)) and np.argmax(speed) not in picked
    for g in picked:
        same = np.flatnonzero((sector == sector[g]) & allowed)
        assert speed[g] == speed[same].max()
    assert len(farthest_by_heading(gr, allowed, 100)) == 63
    assert farthest_by_heading(gr, np.zeros(64, bool), 5).size == 0


def test_no_refinement_when_refine_is_zero():
    model, gr, duty = _model(SelfModelConfig(gaits=50, covering=25, refine=0))
    steps = np.flatnonzero(duty[:, 0] > 0.5)[:2]
    for g in steps:
        model.observe(g, _feet(duty[g], ('a',)))
    damage, gaits, _ = model.request(None)
    out = model.install(None, damage, gaits, *_robot(gr, damage, gaits))
    assert out.names == (PREFIX + 'remove:a',) and model.request(out) is None


def test_the_delay_of_a_request_is_in_proportion_to_its_gaits():
    config = SelfModelConfig(gaits=600, delay_steps=5)
    assert (config.delay(602), config.delay(200), config.delay(10)) == (5, 2, 1)
    assert SelfModelConfig(delay_steps=0).delay(600) == 0


def test_hypothesis_names_the_legs_removed():
    assert hypothesis(()) is None
    assert hypothesis(('a', 'c')) == 'remove:a,remove:c'


@pytest.mark.parametrize('value', [-1, 1.5, True, 'x'])
def test_a_bad_config_is_refused(value):
    with pytest.raises(ValueError):
        SelfModelConfig(delay_steps=value)
    with pytest.raises(ValueError):
        SelfModelConfig(refine=value)
    with pytest.raises(ValueError):
        SelfModelConfig(gaits=0)


def test_inference_keeps_the_simulated_gaits_and_moves_their_neighbours():
    descriptors, gr, _ = _map()
    truth = gr * (0.2 + 0.6 * descriptors[:, 2:3])  # slower where leg a leans less
    gaits = gait_subset(descriptors, 80, np.hypot(gr[:, 0], gr[:, 1]), 40)
    assert len(set(gaits)) == 80
    table, fallen = infer(descriptors, gr, gaits, truth[gaits], np.zeros(80, bool), 0.3)
    np.testing.assert_allclose(table[gaits], truth[gaits])
    rest = np.setdiff1d(np.arange(len(gr)), gaits)
    assert np.mean(np.abs(table[rest] - truth[rest])) < np.mean(np.abs(gr[rest] - truth[rest]))
    assert not fallen.any()


def _robot(gr, damage, gaits):
    """The toy robot's simulator: a lost leg scales every step by 0.3."""
    return gr[gaits] * 0.3, np.zeros(len(gaits), bool)


def _model(config=None, m=200):
    descriptors, gr, duty = _map(m)
    model = SelfModel(descriptors, gr, duty, LEGS, 'sum', 0.3,
                      config or SelfModelConfig(gaits=50, covering=25))
    return model, gr, duty


def _priors(gr, names=('remove:b',)):
    k = len(names)
    return DamagePriors(tuple(names), np.stack([gr * 0.5] * k), np.zeros((k, len(gr)), bool),
                        'sum')


def test_a_table_is_asked_for_once_for_legs_no_table_holds_and_appended():
    model, gr, duty = _model()
    priors = _priors(gr)
    steps = np.flatnonzero(duty[:, 0] > 0.5)[:4]
    model.observe(steps[0], _feet(duty[steps[0]], ('a',)))
    assert model.request(priors) is None  # one step is no evidence
    model.observe(steps[1], _feet(duty[steps[1]], ('a',)))
    damage, gaits, feet = model.request(priors)
    assert damage == 'remove:a' and set(steps[:2]) <= set(gaits)  # the gaits run score it
    assert feet is not model.feet and feet.lost() == ('a',)  # a copy of the evidence
    assert len(gaits) >= 50
    model.observe(steps[2], _feet(duty[steps[2]], ('a',)))
    assert model.request(priors) is None  # asked already
    out = model.install(priors, damage, gaits, *_robot(gr, damage, gaits))
    assert out.names == ('remove:b', PREFIX + 'remove:a')
    assert out.second_tier.tolist() == [False, False]  # the first tier's last table
    assert out.simulated[1].sum() == len(gaits) and out.simulated[0].all()
    np.testing.assert_allclose(out.generic_reward[1][gaits], gr[gaits] * 0.3)
    assert model.simulated_gaits == len(gaits)
    # Then, once, the gaits its inferred part says go farthest, not simulated yet.
    again, more, feet = model.request(out)
    assert again == 'remove:a' and feet is None and len(more) == min(
        model.config.refine, len(gr) - len(gaits) - int(model.table[1].sum()))
    assert not set(more) & set(gaits)
    assert model.status() == f'remove:a simulated, {len(more)} more gaits of it simulating'
    assert model.request(out) is None  # under way
    out = model.install(out, again, more, *_robot(gr, again, more))
    assert out.names == ('remove:b', PREFIX + 'remove:a')  # the same table, grown
    assert out.simulated[1].sum() == len(gaits) + len(more)
    np.testing.assert_allclose(out.generic_reward[1][gaits], gr[gaits] * 0.3)
    np.testing.assert_allclose(out.generic_reward[1][more], gr[more] * 0.3)
    assert model.request(out) is None and model.simulated_gaits == len(gaits) + len(more)
    # Forgetting the learning drops the evidence and the table.
    assert model.forget(out).names == ('remove:b',) and model.feet.lost() == ()


def test_the_table_goes_first_tier_before_the_second_or_last_of_the_second():
    for first, names, second in ((True, ('remove:b', PREFIX + 'remove:a', 'remove:c'),
                                  [False, False, True]),
                                 (False, ('remove:b', 'remove:c', PREFIX + 'remove:a'),
                                  [False, True, True])):
        model, gr, duty = _model(SelfModelConfig(gaits=50, covering=25, first_tier=first))
        priors = _priors(gr, ('remove:b', 'remove:c'))
        priors = DamagePriors(priors.names, priors.generic_reward, priors.fallen, 'sum',
                              reproduce_only=np.array([False, True]))
        for g in np.flatnonzero(duty[:, 0] > 0.5)[:2]:
            model.observe(g, _feet(duty[g], ('a',)))
        damage, gaits, _ = model.request(priors)
        out = model.install(priors, damage, gaits, *_robot(gr, damage, gaits))
        assert out.names == names and out.second_tier.tolist() == second


def test_more_legs_lost_replace_the_table_and_a_stale_answer_is_dropped():
    model, gr, duty = _model()
    both = np.flatnonzero((duty[:, 0] > 0.5) & (duty[:, 1] > 0.5))
    only_a = np.flatnonzero((duty[:, 0] > 0.5) & (duty[:, 1] < 0.3))
    for g in only_a[:2]:
        model.observe(g, _feet(duty[g], ('a', 'b')))
    first = model.request(None)[:2]
    assert first[0] == 'remove:a'
    for g in both[:2]:
        model.observe(g, _feet(duty[g], ('a', 'b')))
    second = model.request(None)[:2]
    assert second[0] == 'remove:a,remove:b'
    assert model.install(None, *first, *_robot(gr, *first)) is None  # no longer asked
    out = model.install(None, *second, *_robot(gr, *second))
    assert out.names == (PREFIX + 'remove:a,remove:b',) and out.second_tier.tolist() == [False]


def test_a_failed_or_malformed_simulation_is_not_asked_again():
    model, gr, duty = _model()
    for g in np.flatnonzero(duty[:, 0] > 0.5)[:2]:
        model.observe(g, _feet(duty[g], ('a',)))
    damage, gaits, _ = model.request(None)
    with pytest.raises(ValueError, match='outcomes'):
        model.install(None, damage, gaits, np.zeros((3, 3)), np.zeros(3, bool))
    with pytest.raises(ValueError):
        model.install(None, damage, gaits, np.full((len(gaits), 3), np.nan),
                      np.zeros(len(gaits), bool))
    model.failed(damage)
    assert model.request(None) is None


def test_a_hypothesis_that_a_table_holds_adds_nothing():
    model, gr, duty = _model()
    priors = _priors(gr, ('remove:b,remove:a',))
    for g in np.flatnonzero((duty[:, 0] > 0.5) & (duty[:, 1] > 0.5))[:4]:
        model.observe(g, _feet(duty[g], ('a', 'b')))
        assert model.request(priors) is None


def test_sela_uses_the_table_once_it_reproduces_the_standing_starts():
    """Through SELA's second tier: the self-model's table is the prior once it explains the
    steps, and the choice then reads it."""
    model, gr, duty = _model(SelfModelConfig(gaits=120, covering=60))
    sela = SELA(model.descriptors, gr, SE2Motion(), goal=(2.0, 0.0),
                config=SELAConfig(gp_kernel_sigma=0.3), priors=_priors(gr, ('remove:d',)))
    pose = np.zeros(3)
    for _ in range(6):
        g = sela.ask(pose).index
        sela.tell(g, gr[g] * 0.3, standing_start=True)
        model.observe(g, _feet(duty[g], ('a',)))
        wanted = model.request(sela.priors)
        if wanted is not None:
            sela.priors = model.install(sela.priors, *wanted[:2], *_robot(gr, *wanted[:2]))
    assert PREFIX + 'remove:a' in sela.priors.names
    assert sela.select_prior().name == PREFIX + 'remove:a'


def test_the_status_says_where_it_stands():
    model, gr, duty = _model()
    assert model.status() == 'no leg lost'
    for g in np.flatnonzero(duty[:, 0] > 0.5)[:2]:
        model.observe(g, _feet(duty[g], ('a',)))
    assert model.request(_priors(gr, ('remove:a',))) is None
    assert model.status() == 'remove:a held by a table'
    damage, gaits, _ = model.request(None)
    assert model.status() == 'simulating remove:a'
    out = model.install(None, damage, gaits, *_robot(gr, damage, gaits))
    assert model.status() == 'remove:a simulated'
    _, more, _ = model.request(out)
    assert model.status() == f'remove:a simulated, {len(more)} more gaits of it simulating'
    model.forget(None)
    for g in np.flatnonzero(duty[:, 1] > 0.5)[:2]:
        model.observe(g, _feet(duty[g], ('b',)))
    model.failed(model.request(None)[0])
    assert model.status() == 'remove:b not simulated'


def _simulator_of_feet(duty, tilts):
    """A simulator of the toy map's feet: the legs a damage removes never touch, and with
    ``tilts``, leg 'b' removed tilts the body off leg 'c' in every gait."""
    def simulate(damage, gaits):
        feet = duty[gaits].copy()
        removed = legs_of(damage)
        for leg in removed:
            feet[:, LEGS.index(leg)] = 0.0
        if tilts and 'b' in removed:
            feet[:, LEGS.index('c')] = 0.0
        n = len(gaits)
        return np.zeros((n, 3)), np.zeros(n, bool), feet
    return simulate


def test_a_leg_the_others_tilt_off_the_ground_is_not_lost():
    model, gr, duty = _model()
    for g in np.flatnonzero((duty[:, 1] > 0.5) & (duty[:, 2] > 0.5))[:3]:
        feet = duty[g].copy()
        feet[[1, 2]] = 0.0
        model.observe(g, feet)
    assert model.feet.lost() == ('b', 'c')
    damage, gaits, feet = model.request(None)
    assert alternatives(damage) == ('remove:c', 'remove:b')
    # Leg 'b' removed keeps 'c' off the ground in the simulation too: 'b' alone explains it.
    assert choose(feet, damage, _simulator_of_feet(duty, tilts=True)) == 'remove:b'
    out = model.install(None, 'remove:b', gaits, *_robot(gr, 'remove:b', gaits), asked=damage)
    assert out.names == (PREFIX + 'remove:b',) and model.status() == 'remove:b simulated'
    # The feet's damage is answered: not asked again; the table answered is refined.
    assert model.request(out)[0] == 'remove:b'

    # A robot whose body does not tilt: each leg missing is lost.
    upright = _simulator_of_feet(duty, tilts=False)
    assert choose(feet, damage, upright) == damage
    assert choose(feet, 'remove:a', upright) == 'remove:a'  # a single leg: nothing smaller


def test_a_map_without_feet_or_a_robot_that_cannot_lose_a_leg_has_no_self_model():
    from types import SimpleNamespace

    from sela_ros.core.learning.self_model import from_archive

    descriptors, gr, _ = _map()
    archive = SimpleNamespace(metadata={'descriptor_name': 'final_xy_duty_factors'},
                              descriptors=descriptors, params=np.zeros((len(gr), 4)),
                              generic_reward=gr, kernel_sigma=0.3,
                              normalised_descriptors=lambda: descriptors)
    model = from_archive(archive, LEGS)
    assert model.feet.legs == LEGS and model.status() == 'no leg lost'
    with pytest.raises(ValueError, match="no damage kind 'remove'"):
        from_archive(archive, LEGS, kinds=('intact', 'shorten'))
    with pytest.raises(ValueError, match='duty factors'):
        from_archive(archive, LEGS[:3])
    flat = SimpleNamespace(**{**vars(archive), 'metadata': {'descriptor_name': 'final_xy'}})
    with pytest.raises(ValueError, match='duty factors'):
        from_archive(flat, LEGS)
