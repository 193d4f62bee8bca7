"""Unit and property tests of the damage specification grammar."""
import pytest
from hypothesis import given
from hypothesis import strategies as st

from sim_bridge.damage import (
    JOINT_LIMITS,
    JOINT_NAMES,
    LEG_NAMES,
    DamageSpec,
    DamageSpecError,
    parse_damage,
)


@pytest.mark.parametrize('text', ['', 'intact', ' INTACT ', None, 'none'])
def test_intact(text):
    spec = parse_damage(text)
    assert spec == DamageSpec() and spec.is_intact and spec.canonical() == 'intact'


def test_combination_and_defaults():
    spec = parse_damage('remove:middle_right, block:front_left.knee,shorten:rear_left')
    assert spec.removed == ('middle_right',)
    assert spec.shortened == (('rear_left', 0.5),)
    assert spec.blocked == (('front_left', 'knee', 0.0),)
    assert spec.canonical() == ('remove:middle_right,shorten:rear_left:0.5,'
                                'block:front_left.knee=0.0')
    assert hash(spec) == hash(parse_damage(spec.canonical()))


def test_a_weakened_motor_gives_a_share_of_its_torque():
    spec = parse_damage('weaken:rear_right.hip_pitch=0.25,weaken:front_left.knee')
    assert spec.weakened == (('front_left', 'knee', 0.1), ('rear_right', 'hip_pitch', 0.25))
    assert spec.torque_share('rear_right', 'hip_pitch') == 0.25
    assert spec.torque_share('rear_right', 'knee') == 1.0 and not spec.is_intact
    assert spec.canonical() == 'weaken:front_left.knee=0.1,weaken:rear_right.hip_pitch=0.25'


def test_friction_and_payload_combine_with_the_other_kinds():
    spec = parse_damage('remove:rear_left, friction:0.5, payload:1.0@0.08,0.05')
    assert spec.removed == ('rear_left',) and spec.friction == 0.5
    assert spec.payload == (1.0, 0.08, 0.05) and not spec.is_intact
    assert spec.canonical() == 'remove:rear_left,friction:0.5,payload:1.0@0.08,0.05'
    # The comma inside the payload's position belongs to it, wherever the item stands.
    assert parse_damage('payload:1.0@0.08,0.05,shorten:front_right:0.5,friction:0.3') == \
        parse_damage('friction:0.3,shorten:front_right:0.5,payload:1@0.08,0.05')
    assert parse_damage('payload:0.4').payload == (0.4, 0.0, 0.0)
    assert parse_damage('friction:0.3').canonical() == 'friction:0.3'


@pytest.mark.parametrize('text, reason', [
    ('friction:-0.5', 'friction coefficient'), ('friction:0', 'friction coefficient'),
    ('friction:nan', 'finite'), ('friction:inf', 'finite'), ('friction:', 'number'),
    ('friction:50', 'friction coefficient'), ('friction:0.5,friction:0.3', 'twice'),
    ('payload:-1', 'payload mass'), ('payload:0', 'payload mass'),
    ('payload:nan@0,0', 'finite'), ('payload:500', 'robot weighs'),
    ('payload:1.0@0.08', '<x>,<y>'), ('payload:1.0@0.5,0.0', 'on the body'),
    ('payload:1.0@0.0,-0.2', 'on the body'), ('payload:1.0@x,0', 'payload x'),
    ('payload:1.0,payload:2.0', 'one payload'),
])
def test_a_bad_friction_or_payload_is_refused_with_the_reason(text, reason):
    with pytest.raises(DamageSpecError, match=reason):
        parse_damage(text)


@pytest.mark.parametrize('text, form', [
    ('block:front_left:knee:0.3', r'block:<leg>\.<joint>\[=<angle>\]'),
    ('weaken:front_left:0.5', r'weaken:<leg>\.<joint>\[=<share>\]'),
    ('remove:front_left:0.5', 'remove:<leg>'), ('shorten:left:0.5', r'shorten:<leg>\[:<factor>\]'),
])
def test_a_leg_not_found_says_the_form_of_its_item(text, form):
    """A separator mistaken (``:`` for ``.`` or ``=``) leaves no leg: the error says the
    item's form beside the valid legs."""
    with pytest.raises(DamageSpecError, match=f'expected {form}.*valid legs: front_left'):
        parse_damage(text)


def test_order_does_not_matter():
    a = parse_damage('remove:rear_right,remove:front_left,block:middle_left.hip_yaw=0.2')
    b = parse_damage('block:middle_left.hip_yaw=0.2,remove:front_left,remove:rear_right')
    assert a == b and a.canonical() == b.canonical()


@pytest.mark.parametrize('text, names', [
    ('remove:middle_rigth', LEG_NAMES),
    ('shorten:leg7', LEG_NAMES),
    ('block:front_left.ankle', JOINT_NAMES),
    ('block:front_left', JOINT_NAMES),
    ('break:front_left', ('remove', 'shorten', 'block', 'weaken', 'friction', 'payload')),
    ('weaken:front_left.ankle=0.2', JOINT_NAMES),
])
def test_unknown_names_list_valid_ones(text, names):
    with pytest.raises(DamageSpecError) as info:
        parse_damage(text)
    for name in names:
        assert name in str(info.value)
    assert isinstance(info.value, ValueError)


@pytest.mark.parametrize('text', [
    'shorten:front_left:0', 'shorten:front_left:1.5', 'shorten:front_left:x',
    'block:front_left.knee=1.0', 'block:front_left.knee=nan',
    'remove:front_left,shorten:front_left', 'remove:rear_left,block:rear_left.knee',
    'block:front_left.knee=0.1,block:front_left.knee=0.2',
    'weaken:front_left.knee=1.0', 'weaken:front_left.knee=-0.1', 'weaken:front_left.knee=x',
    'remove:front_left,weaken:front_left.knee', 'block:rear_left.knee,weaken:rear_left.knee',
    'weaken:front_left.knee=0.1,weaken:front_left.knee=0.2',
])
def test_bad_values(text):
    with pytest.raises(DamageSpecError):
        parse_damage(text)


def test_not_a_string():
    with pytest.raises(DamageSpecError, match='string'):
        parse_damage(3)


_legs = st.sampled_from(LEG_NAMES)
_item = st.one_of(
    _legs.map(lambda leg: f'remove:{leg}'),
    st.tuples(_legs, st.floats(0.05, 1.0)).map(lambda t: f'shorten:{t[0]}:{t[1]!r}'),
    st.tuples(_legs, st.sampled_from(JOINT_NAMES), st.floats(-0.7, 0.7)).map(
        lambda t: f'block:{t[0]}.{t[1]}={t[2]!r}'),
    st.tuples(_legs, st.sampled_from(JOINT_NAMES), st.floats(0.0, 0.99)).map(
        lambda t: f'weaken:{t[0]}.{t[1]}={t[2]!r}'),
    st.floats(0.05, 5.0).map(lambda f: f'friction:{f!r}'),
    st.tuples(st.floats(0.01, 5.0), st.floats(-0.12, 0.12), st.floats(-0.1, 0.1)).map(
        lambda t: f'payload:{t[0]!r}@{t[1]!r},{t[2]!r}'),
)


@given(st.lists(_item, max_size=5))
def test_canonical_round_trip(items):
    text = ','.join(items)
    try:
        spec = parse_damage(text)
    except DamageSpecError:
        return  # contradictions (same leg removed and shortened, ...) are rejected
    again = parse_damage(spec.canonical())
    assert again == spec and again.canonical() == spec.canonical()
    for _leg, joint, angle in spec.blocked:
        assert abs(angle) <= JOINT_LIMITS[joint]


def test_every_leg_removed_is_refused_with_the_reason():
    with pytest.raises(DamageSpecError, match='every leg is removed.*at least one must remain'):
        parse_damage(','.join(f'remove:{leg}' for leg in LEG_NAMES))
    five = parse_damage(','.join(f'remove:{leg}' for leg in LEG_NAMES[1:]))
    assert len(five.removed) == 5  # one left: a damage, however bad


@pytest.mark.parametrize('text', ['intact,remove:front_left', 'remove:front_left, none',
                                  'friction:0.5,INTACT'])
def test_intact_with_a_damage_is_a_contradiction_refused(text):
    with pytest.raises(DamageSpecError, match='undamaged and cannot be combined with a damage'):
        parse_damage(text)
    assert parse_damage('intact,,intact').is_intact  # said twice: still no damage
