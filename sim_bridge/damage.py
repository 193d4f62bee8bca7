"""Damage specifications: a small grammar users can type, over a robot's own names.

Grammar (items joined with ``,``; whitespace ignored; case-insensitive)::

    intact | <empty>                 no damage
    remove:<leg>                     the leg is gone (links, mass and contacts)
    shorten:<leg>[:<factor>]         tibia and foot scaled by factor in (0, 1], default 0.5
    block:<leg>.<joint>[=<angle>]    joint locked at angle (rad, within its limits), default 0
    weaken:<leg>.<joint>[=<share>]   the joint's motor gives only this share of its torque,
                                     in [0, 1), default 0.1 (a failing servo)
    friction:<coefficient>           the ground's friction coefficient, in
                                     [MIN_FRICTION, MAX_FRICTION] (the map was built on 1.0)
    payload:<kg>[@<x>,<y>]           a mass in (0, MAX_PAYLOAD] kg fixed on top of the body,
                                     <x>, <y> metres from its centre (within the body's
                                     footprint), default at the centre

``<leg>`` and ``<joint>`` are names of the robot's :class:`Vocabulary` (the hexapod's:
:data:`LEG_NAMES`, :data:`JOINT_NAMES`; another robot's description brings its own, and the
kinds it takes). Example: ``remove:middle_right,block:front_left.knee``;
``remove:rear_left,friction:0.5``; ``payload:1.0@0.08,0.05`` (the comma inside a payload's
position belongs to it).
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

LEG_NAMES = ('front_left', 'middle_left', 'rear_left',
             'front_right', 'middle_right', 'rear_right')
JOINT_NAMES = ('hip_yaw', 'hip_pitch', 'knee')
JOINT_LIMITS = {'hip_yaw': math.pi / 2, 'hip_pitch': math.pi / 4, 'knee': math.pi / 4}
DEFAULT_SHORTEN_FACTOR = 0.5
DEFAULT_WEAKEN_SHARE = 0.1
KINDS = ('intact', 'remove', 'shorten', 'block', 'weaken', 'friction', 'payload')
# Friction below 0.05 is ice on which no gait moves; above 5 no ground grips a foot.
MIN_FRICTION, MAX_FRICTION = 0.05, 5.0
# The robot weighs 2.5 kg and its motors give 2.5 N m: more than 5 kg it cannot stand under.
MAX_PAYLOAD = 5.0
# The payload sits on the body (sim_bridge.model.BODY_SIZE): its centre within the footprint.
PAYLOAD_X_LIMIT, PAYLOAD_Y_LIMIT = 0.12, 0.10


@dataclass(frozen=True)
class Vocabulary:
    """The names one robot's damages take.

    Attributes:
        legs: leg names, in the robot's leg order (duty factors follow it).
        joints: joint names within a leg.
        limits: ``(lower, upper)`` radians of each joint (a blocked joint's angle is in them).
        block_default: angle a joint is blocked at when the spec gives none (default 0).
        kinds: the damage kinds this robot takes (``intact`` always).
    """

    legs: tuple[str, ...]
    joints: tuple[str, ...]
    limits: Mapping[str, tuple[float, float]]
    block_default: Mapping[str, float] = field(default_factory=dict)
    kinds: tuple[str, ...] = KINDS


#: The hexapod's legs and joints.
HEXAPOD = Vocabulary(LEG_NAMES, JOINT_NAMES,
                     {joint: (-limit, limit) for joint, limit in JOINT_LIMITS.items()})


class DamageSpecError(ValueError):
    """A damage specification that does not parse; the message lists the valid names."""


def _fmt(x: float) -> str:
    return repr(float(x))


@dataclass(frozen=True)
class DamageSpec:
    """Parsed damage: removed legs, shortened legs, blocked joints, weakened motors, the
    ground's friction and a payload (sorted, hashable).

    Attributes:
        removed: leg names removed.
        shortened: ``(leg, factor)`` pairs.
        blocked: ``(leg, joint, angle)`` triples.
        weakened: ``(leg, joint, share of the motor's torque)`` triples.
        friction: the ground's friction coefficient, ``None`` for the nominal ground.
        payload: ``(kg, x, y)`` of a mass fixed on the body, ``None`` for none.
    """

    removed: tuple[str, ...] = ()
    shortened: tuple[tuple[str, float], ...] = ()
    blocked: tuple[tuple[str, str, float], ...] = ()
    weakened: tuple[tuple[str, str, float], ...] = ()
    friction: float | None = None
    payload: tuple[float, float, float] | None = None

    @property
    def is_intact(self) -> bool:
        return not (self.removed or self.shortened or self.blocked or self.weakened
                    or self.friction is not None or self.payload is not None)

    def canonical(self) -> str:
        """Canonical text form; ``parse_damage(s.canonical()) == s``."""
        if self.is_intact:
            return 'intact'
        items = [f'remove:{leg}' for leg in self.removed]
        items += [f'shorten:{leg}:{_fmt(f)}' for leg, f in self.shortened]
        items += [f'block:{leg}.{joint}={_fmt(a)}' for leg, joint, a in self.blocked]
        items += [f'weaken:{leg}.{joint}={_fmt(s)}' for leg, joint, s in self.weakened]
        if self.friction is not None:
            items.append(f'friction:{_fmt(self.friction)}')
        if self.payload is not None:
            kg, x, y = self.payload
            items.append(f'payload:{_fmt(kg)}@{_fmt(x)},{_fmt(y)}')
        return ','.join(items)

    def shorten_factor(self, leg: str) -> float:
        for name, factor in self.shortened:
            if name == leg:
                return factor
        return 1.0

    def blocked_angle(self, leg: str, joint: str) -> float | None:
        for name, j, angle in self.blocked:
            if name == leg and j == joint:
                return angle
        return None

    def torque_share(self, leg: str, joint: str) -> float:
        """The share of its torque the joint's motor gives (1 unless weakened)."""
        for name, j, share in self.weakened:
            if name == leg and j == joint:
                return share
        return 1.0

    def __str__(self) -> str:
        return self.canonical()


#: The form of each kind of item that names a leg, for an error that cannot find the leg.
LEG_FORMS = {'remove': 'remove:<leg>', 'shorten': 'shorten:<leg>[:<factor>]',
             'block': 'block:<leg>.<joint>[=<angle>]', 'weaken': 'weaken:<leg>.<joint>[=<share>]'}


def _leg(name: str, item: str, vocabulary: Vocabulary = HEXAPOD) -> str:
    if name not in vocabulary.legs:
        form = LEG_FORMS[item.partition(':')[0]]
        raise DamageSpecError(f'unknown leg {name!r} in damage item {item!r} (expected '
                              f'{form}); valid legs: {", ".join(vocabulary.legs)}')
    return name


def _number(text: str, what: str, item: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise DamageSpecError(f'{what} in damage item {item!r} must be a number, '
                              f'got {text!r}') from None
    if not math.isfinite(value):
        raise DamageSpecError(f'{what} in damage item {item!r} must be finite, got {text!r}')
    return value


def _joint(rest: str, item: str, kind: str, what: str,
           vocabulary: Vocabulary = HEXAPOD) -> tuple[str, str, str]:
    """``(leg, joint, value text)`` of ``<leg>.<joint>[=<value>]``."""
    target, _, value_text = rest.partition('=')
    name, dot, joint = target.partition('.')
    leg = _leg(name, item, vocabulary)
    if not dot or joint not in vocabulary.joints:
        raise DamageSpecError(
            f'unknown joint {joint!r} in damage item {item!r}; expected '
            f'{kind}:<leg>.<joint>[=<{what}>] with joint one of '
            f'{", ".join(vocabulary.joints)}')
    return leg, joint, value_text


def _examples(vocabulary: Vocabulary) -> str:
    if vocabulary is HEXAPOD:
        return ('e.g. remove:middle_right, shorten:front_left:0.5, block:rear_right.knee=0.2, '
                'weaken:front_left.knee=0.3, friction:0.5, payload:1.0@0.08,0.05')
    leg, joint = vocabulary.legs[0], vocabulary.joints[-1]
    examples = {'remove': f'remove:{leg}', 'shorten': f'shorten:{leg}:0.5',
                'block': f'block:{leg}.{joint}', 'weaken': f'weaken:{leg}.{joint}=0.3',
                'friction': 'friction:0.5', 'payload': 'payload:1.0'}
    return 'e.g. ' + ', '.join(examples[k] for k in vocabulary.kinds if k in examples)


def _items(text: str) -> list[str]:
    """Split on commas, except the one inside a payload's ``@<x>,<y>``."""
    items: list[str] = []
    for raw in text.split(','):
        if items and items[-1].startswith('payload:') and '@' in items[-1] \
                and ',' not in items[-1].partition('@')[2] and ':' not in raw:
            items[-1] += ',' + raw
        else:
            items.append(raw)
    return items


def _friction(rest: str, item: str) -> float:
    value = _number(rest, 'friction coefficient', item)
    if not MIN_FRICTION <= value <= MAX_FRICTION:
        raise DamageSpecError(f'friction coefficient in {item!r} must be in '
                              f'[{MIN_FRICTION}, {MAX_FRICTION}], got {value}')
    return value


def _payload(rest: str, item: str) -> tuple[float, float, float]:
    mass_text, at, where = rest.partition('@')
    kg = _number(mass_text, 'payload mass (kg)', item)
    if not 0.0 < kg <= MAX_PAYLOAD:
        raise DamageSpecError(f'payload mass in {item!r} must be in (0, {MAX_PAYLOAD}] kg '
                              f'(the robot weighs 2.5 kg), got {kg}')
    x = y = 0.0
    if at:
        x_text, comma, y_text = where.partition(',')
        if not comma:
            raise DamageSpecError(f'payload position in {item!r} must be <x>,<y> in metres '
                                  f'from the body\'s centre, e.g. payload:1.0@0.08,0.05')
        x = _number(x_text, 'payload x (m)', item)
        y = _number(y_text, 'payload y (m)', item)
        if abs(x) > PAYLOAD_X_LIMIT or abs(y) > PAYLOAD_Y_LIMIT:
            raise DamageSpecError(
                f'payload position in {item!r} must lie on the body: |x| <= {PAYLOAD_X_LIMIT}'
                f' m and |y| <= {PAYLOAD_Y_LIMIT} m, got ({x}, {y})')
    return kg, x + 0.0, y + 0.0


def parse_damage(spec, vocabulary: Vocabulary = HEXAPOD, robot: str = '') -> DamageSpec:
    """Parse a damage specification (a string, ``None`` or a :class:`DamageSpec`) over the
    names of ``vocabulary`` (the hexapod's by default); ``robot``, its name, words the error
    of a kind of the grammar that this robot does not take.

    Raises:
        DamageSpecError: unknown kind, leg or joint, a bad number, or a contradiction
            (e.g. the same leg removed and shortened).
    """
    if isinstance(spec, DamageSpec):
        return spec
    if spec is None:
        return DamageSpec()
    if not isinstance(spec, str):
        raise DamageSpecError(f'damage must be a string such as "remove:middle_right", '
                              f'got {type(spec).__name__}')
    removed: set[str] = set()
    shortened: dict[str, float] = {}
    blocked: dict[tuple[str, str], float] = {}
    weakened: dict[tuple[str, str], float] = {}
    friction: float | None = None
    payload: tuple[float, float, float] | None = None
    items = _items(spec.replace(' ', '').replace('\t', '').lower())
    said_intact = [item for item in items if item in ('intact', 'none')]
    if said_intact and any(item not in ('', 'intact', 'none') for item in items):
        raise DamageSpecError(f'{said_intact[0]!r} says the robot is undamaged and cannot be '
                              f'combined with a damage: drop it or the rest, got {spec!r}')
    for item in items:
        if item in ('', 'intact', 'none'):
            continue
        kind, _, rest = item.partition(':')
        if kind not in vocabulary.kinds:
            kind = f'{kind} '  # an unknown kind for this robot: the error below
        if kind == 'remove':
            leg = _leg(rest, item, vocabulary)
            removed.add(leg)
        elif kind == 'shorten':
            name, _, factor_text = rest.partition(':')
            leg = _leg(name, item, vocabulary)
            factor = (DEFAULT_SHORTEN_FACTOR if factor_text == ''
                      else _number(factor_text, 'shorten factor', item))
            if not 0.0 < factor <= 1.0:
                raise DamageSpecError(
                    f'shorten factor in {item!r} must be in (0, 1], got {factor}')
            if leg in shortened and shortened[leg] != factor:
                raise DamageSpecError(f'leg {leg} shortened twice with different factors')
            shortened[leg] = factor
        elif kind == 'block':
            leg, joint, angle_text = _joint(rest, item, 'block', 'angle', vocabulary)
            angle = (vocabulary.block_default.get(joint, 0.0) if angle_text == ''
                     else _number(angle_text, 'block angle', item))
            lower, upper = vocabulary.limits[joint]
            if not lower - 1e-12 <= angle <= upper + 1e-12:
                raise DamageSpecError(
                    f'block angle {angle} for {leg}.{joint} is outside its limits '
                    f'[{lower:.4f}, {upper:.4f}] rad')
            if (leg, joint) in blocked and blocked[(leg, joint)] != angle:
                raise DamageSpecError(f'joint {leg}.{joint} blocked twice at different angles')
            blocked[(leg, joint)] = angle
        elif kind == 'weaken':
            leg, joint, share_text = _joint(rest, item, 'weaken', 'share', vocabulary)
            share = (DEFAULT_WEAKEN_SHARE if share_text == ''
                     else _number(share_text, 'weaken share', item))
            if not 0.0 <= share < 1.0:
                raise DamageSpecError(f'weaken share in {item!r} must be in [0, 1) (the share '
                                      f'of the motor\'s torque left), got {share}')
            if weakened.get((leg, joint), share) != share:
                raise DamageSpecError(f'joint {leg}.{joint} weakened twice to different shares')
            weakened[(leg, joint)] = share
        elif kind == 'friction':
            value = _friction(rest, item)
            if friction is not None and friction != value:
                raise DamageSpecError('the ground\'s friction given twice with different '
                                      'coefficients')
            friction = value
        elif kind == 'payload':
            value = _payload(rest, item)
            if payload is not None and payload != value:
                raise DamageSpecError('payload given twice differently (one payload at most)')
            payload = value
        else:
            kind = kind.strip()
            problem = (f'the {robot or "robot"} does not take damage kind {kind!r} (in '
                       f'{item!r})' if kind in KINDS
                       else f'unknown damage kind {kind!r} in {item!r}')
            raise DamageSpecError(f'{problem}; valid kinds: {", ".join(vocabulary.kinds)} '
                                  f'({_examples(vocabulary)})')
    if removed and len(removed) == len(vocabulary.legs):
        raise DamageSpecError(f'every leg is removed ({", ".join(vocabulary.legs)}): at least '
                              'one must remain for the robot to stand on')
    for leg in removed:
        if leg in shortened or any(b[0] == leg for b in blocked) or \
                any(w[0] == leg for w in weakened):
            raise DamageSpecError(f'leg {leg} is removed; it cannot also be shortened, blocked '
                                  'or weakened')
    for leg, joint in weakened:
        if (leg, joint) in blocked:
            raise DamageSpecError(f'joint {leg}.{joint} is blocked; it cannot also be weakened')
    order = {name: i for i, name in enumerate(vocabulary.legs)}
    jorder = {name: i for i, name in enumerate(vocabulary.joints)}
    return DamageSpec(
        removed=tuple(sorted(removed, key=order.__getitem__)),
        shortened=tuple(sorted(shortened.items(), key=lambda kv: order[kv[0]])),
        blocked=tuple(sorted(((leg, joint, a) for (leg, joint), a in blocked.items()),
                             key=lambda b: (order[b[0]], jorder[b[1]]))),
        weakened=tuple(sorted(((leg, joint, s) for (leg, joint), s in weakened.items()),
                              key=lambda w: (order[w[0]], jorder[w[1]]))),
        friction=friction,
        payload=payload,
    )
