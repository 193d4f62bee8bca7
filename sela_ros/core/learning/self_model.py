"""The robot's own simulator as a self-model: the legs it has lost, read from its feet.

Each step's outcome says how long each foot touched the ground (its duty factors). A leg that
never touches over steps whose gaits lean on it on the intact robot (an intact duty factor of
at least :data:`LEANING`) is lost: on the hexapod a removed leg's foot touches on none of
them, a leg shortened to 0.3 on about three in four, an intact one on all
(docs/learning_the_damage.md, "A self-model from the feet"). The legs lost are a damage
hypothesis that no table may hold (two neighbouring legs, say, with their table left out):
the self-model simulates it on gaits of the map (those the robot ran, which the table must
then reproduce, and :func:`~sela_ros.core.learning.table_inference.gait_subset`'s cover of the
map and its fastest gaits), infers the others
(:func:`~sela_ros.core.learning.table_inference.infer`) and hands SELA the table as a
damage prior, its inferred gaits never chosen (in the first tier by default:
:attr:`SelfModelConfig.first_tier`). Once it is in use, the gaits its inferred part says go
farthest are simulated too (:attr:`SelfModelConfig.refine`), and the table grows by them. A
hypothesis that is one of the tables already there adds nothing.

The simulation costs a simulated gait per gait (``SelfModelConfig.gaits`` of them, 0.05
core-seconds each on the hexapod: 30 core-seconds for 600); a robot runs it beside the
mission and uses the table ``SelfModelConfig.delay_steps`` steps after the hypothesis, which is
how the experiments
count it (:func:`sela_ros.core.mission.run_mission`). ROS-free, and no simulator here: the
caller runs it (:class:`~sela_ros.core.mission.stepper_io.SimulateDamage`).
"""
from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np

from sela_ros.core.learning.damage_priors import DamagePriors
from sela_ros.core.learning.table_inference import gait_subset, infer

#: A gait leans on a leg whose intact duty factor is at least this.
LEANING = 0.3
#: A foot whose measured duty factor is below this did not touch the ground.
NO_CONTACT = 0.02
#: Steps (that stood, on gaits that lean on the leg) with no contact before a leg is lost.
MIN_EVIDENCE = 2
#: A smaller damage explains a leg's missing contacts if, simulated on the gaits the robot
#: ran, that leg's foot missed the ground in at least this share of the steps where it
#: leaned on it and did not touch (two legs gone tilt the body: on the hexapod without its
#: left middle and rear legs, the right front foot touches in none of the first five gaits).
EXPLAINED = 0.8
#: The name of a self-model table: this, then the damage it simulated.
PREFIX = 'self-model '


@dataclass(frozen=True)
class SelfModelConfig:
    """Attributes:
        gaits: gaits simulated for a hypothesis besides those the robot ran.
        covering: of those, how many cover the map (the rest: its fastest gaits).
        delay_steps: steps from the hypothesis to its table in use, in the experiments: the
            simulation's wall time on the robot's computer, in steps (600 gaits at 0.05
            core-seconds each on two cores, 15 s: five gaits of 3 s).
        first_tier: the table joins the damage priors' first tier (mixed, chosen whenever it
            best explains the steps); False: the second (chosen only once it has reproduced
            the robot's standing starts).
        refine: once the table is in, gaits simulated next for it (0: none): those its
            inferred part predicts go farthest, in every direction (:func:`farthest_by_heading`);
            a damage's fast gaits are often not among the map's, and an inferred gait is
            never chosen.
    """

    gaits: int = 600
    covering: int = 300
    delay_steps: int = 5
    first_tier: bool = True
    refine: int = 200

    def __post_init__(self):
        if not isinstance(self.first_tier, (bool, np.bool_)):
            raise ValueError(f'self-model first_tier must be true or false, got '
                             f'{self.first_tier!r}')
        for name in ('gaits', 'covering', 'delay_steps', 'refine'):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
                raise ValueError(f'self-model {name} must be a whole number >= 0, got {value!r}')
        if self.gaits < 1:
            raise ValueError(f'self-model gaits must be >= 1, got {self.gaits}')

    def delay(self, gaits) -> int:
        """Steps from a request of ``gaits`` gaits to its table in use, in the experiments:
        :attr:`delay_steps` for :attr:`gaits` of them, in proportion for others (at least one
        step, unless :attr:`delay_steps` is 0)."""
        if not self.delay_steps:
            return 0
        return max(1, round(self.delay_steps * int(gaits) / self.gaits))


class LostLegs:
    """The legs whose feet have not touched the ground where the gaits leaned on them.

    Args:
        intact_duty: ``(M, L)`` each gait's duty factors on the intact robot (the map's).
        legs: the ``L`` leg names, in the order of the duty factors.
    """

    def __init__(self, intact_duty, legs):
        self.intact_duty = np.asarray(intact_duty, dtype=float)
        self.legs = tuple(legs)
        if self.intact_duty.ndim != 2 or self.intact_duty.shape[1] != len(self.legs):
            raise ValueError(f'intact duty factors {self.intact_duty.shape} for '
                             f'{len(self.legs)} legs')
        self.leaned = np.zeros(len(self.legs), int)  # stood steps that leaned on each leg
        self.touched = np.zeros(len(self.legs), bool)  # its foot touched in some step
        self.seen = {}  # gait -> its measured duty factors (the latest, of a step that stood)

    def observe(self, index, duty_factors, fallen=False) -> None:
        """One step: gait ``index``'s measured duty factors ``(L,)``; a fall tells nothing
        (the feet of a tumbling robot)."""
        duty = np.asarray(duty_factors, dtype=float).reshape(-1)
        # No foot touched at all: feet that are not measured (a robot without contact
        # sensing reports zeros), not six legs lost.
        if fallen or duty.size != len(self.legs) or not np.all(np.isfinite(duty)) \
                or not duty.any():
            return
        self.leaned += self.intact_duty[int(index)] >= LEANING
        self.touched |= duty >= NO_CONTACT  # a foot that touched once is there
        self.seen[int(index)] = duty

    def lost(self) -> tuple:
        """The legs lost so far (in the order of ``legs``): those whose foot never touched,
        over :data:`MIN_EVIDENCE` steps or more that leaned on them."""
        return tuple(leg for leg, n, t in zip(self.legs, self.leaned, self.touched)
                     if n >= MIN_EVIDENCE and not t)

    def unexplained(self, leg, gaits, simulated_duty) -> float:
        """The share of the steps whose gait leans on ``leg`` and whose foot did not touch
        in which the damage simulated (``simulated_duty`` ``(n, L)`` of ``gaits``) does not
        keep that foot off the ground either; 0 when there are none."""
        i = self.legs.index(leg)
        missed = [k for k, g in enumerate(gaits) if int(g) in self.seen
                  and self.intact_duty[int(g), i] >= LEANING and self.seen[int(g)][i] < NO_CONTACT]
        if not missed:
            return 0.0
        duty = np.asarray(simulated_duty, dtype=float)
        return float(np.mean(duty[missed, i] >= NO_CONTACT))


#: Directions of travel :func:`farthest_by_heading` shares its gaits between.
HEADINGS = 8


def farthest_by_heading(gr, allowed, count, headings=HEADINGS) -> np.ndarray:
    """Up to ``count`` gait indices of ``allowed`` ``(M,)`` that go farthest by ``gr``
    ``(M, >= 2)`` (planar displacement), taken in turn from ``headings`` equal sectors of
    the direction of travel, the farthest of each first: a robot that walks well one way
    only still has its best gaits of the others, to turn with."""
    gr = np.asarray(gr, dtype=float)
    idx = np.flatnonzero(np.asarray(allowed, dtype=bool))
    if not idx.size or count <= 0:
        return np.zeros(0, dtype=int)
    speed = np.hypot(gr[idx, 0], gr[idx, 1])
    sector = np.floor((np.arctan2(gr[idx, 1], gr[idx, 0]) + np.pi) / (2 * np.pi)
                      * headings).astype(int) % headings
    order = np.lexsort((-speed, sector))  # by sector, the farthest first in each
    idx, sector = idx[order], sector[order]
    rank = np.arange(idx.size) - np.searchsorted(sector, sector)  # the place in its sector
    return idx[np.lexsort((-speed[order], rank))][:int(count)]


def alternatives(damage) -> tuple:
    """The smaller damages to weigh against ``damage`` before simulating its table: each
    with one of its legs back (none for a single leg)."""
    legs = legs_of(damage)
    if len(legs) < 2:
        return ()
    return tuple(hypothesis(tuple(x for x in legs if x != leg)) for leg in legs)


def choose(feet: LostLegs, damage, simulate) -> str:
    """``damage``, or a smaller damage that explains the feet as well: one leg back whose
    missing contacts that damage's simulation reproduces (:data:`EXPLAINED`; of several, the
    one that reproduces them most), each simulated on the gaits the robot ran
    (``simulate(damage, gaits) -> (gr, fallen, duty)``). A leg whose foot misses the ground
    because the body tilts on the others is not lost."""
    gaits = np.array(sorted(feet.seen), dtype=int)
    best, best_share = damage, 1.0 - EXPLAINED
    for smaller in alternatives(damage) if gaits.size else ():
        back = (set(legs_of(damage)) - set(legs_of(smaller))).pop()
        share = feet.unexplained(back, gaits, simulate(smaller, gaits)[2])
        if share <= best_share:
            best, best_share = smaller, share
    return best


def from_archive(archive, legs, config=None, kinds=('remove',)) -> SelfModel:
    """The self-model of a robot with ``legs`` (names, in the order of its duty factors) over
    ``archive`` (:class:`~sela_ros.core.storage.Archive`); ``kinds``: the damage kinds its
    simulator takes. Raises ValueError for a robot whose simulator cannot remove a leg, or a
    map whose descriptor holds no duty factors for those legs (a 2-D map: no feet to read)."""
    from sela_ros.core.learning.damage_priors import params_checksum
    from sela_ros.core.storage.archive import DUTY_FACTOR_DESCRIPTOR

    if 'remove' not in kinds:
        raise ValueError("the self-model simulates legs removed, and this robot's simulator "
                         f"takes no damage kind 'remove' (it takes {', '.join(kinds)})")
    legs = tuple(legs)
    if archive.metadata.get('descriptor_name') != DUTY_FACTOR_DESCRIPTOR \
            or archive.descriptors.shape[1] != 2 + len(legs):
        raise ValueError(f'the self-model reads the feet through the map\'s duty factors: '
                         f'this map\'s descriptor is {archive.metadata.get("descriptor_name")!r} '
                         f'of {archive.descriptors.shape[1]} dimensions, not the final (x, y) '
                         f'and {len(legs)} duty factors')
    return SelfModel(archive.normalised_descriptors(), archive.generic_reward,
                     archive.descriptors[:, 2:], legs, params_checksum(archive.params),
                     archive.kernel_sigma, config)


def hypothesis(legs) -> str | None:
    """The damage spec of ``legs`` removed (None: none)."""
    return ','.join(f'remove:{leg}' for leg in legs) or None


def legs_of(damage) -> tuple:
    """The legs a :func:`hypothesis` removes."""
    return tuple(part.removeprefix('remove:') for part in (damage or '').split(',') if part)


def _parts(name) -> frozenset:
    return frozenset(p.strip() for p in str(name).removeprefix(PREFIX).split(',') if p.strip())


class SelfModel:
    """Reads each step's feet; when they show lost legs that no table holds, asks for that
    damage to be simulated (:meth:`request`: the caller runs the robot's simulator, beside the
    mission) and adds the outcomes' table to a SELA's damage priors (:meth:`install`).

    Args:
        descriptors: ``(M, d)`` the map's normalised descriptors; ``base_gr`` ``(M, k)`` its
            generic rewards; ``intact_duty`` ``(M, L)`` its duty factors; ``legs`` their names.
        archive_checksum: the map's (the table's ``DamagePriors.archive_checksum``).
        sigma: the length of the kernel that infers the gaits not simulated.
        config: :class:`SelfModelConfig`.
    """

    def __init__(self, descriptors, base_gr, intact_duty, legs, archive_checksum, sigma,
                 config: SelfModelConfig | None = None):
        self.descriptors = np.asarray(descriptors, dtype=float)
        self.base_gr = np.asarray(base_gr, dtype=float)
        self.feet = LostLegs(intact_duty, legs)
        self.archive_checksum = archive_checksum
        self.sigma = float(sigma)
        self.config = config or SelfModelConfig()
        speed = np.hypot(self.base_gr[:, 0], self.base_gr[:, 1])
        self.candidates = gait_subset(self.descriptors, self.config.gaits, speed,
                                      self.config.covering)
        self.run = []  # the gaits the robot ran (in order, once each)
        self.requested = None  # the damage being simulated
        self.installed = None  # the damage whose table is in the priors
        self.given_up = set()  # damages whose simulation failed
        self.answered = set()  # damages requested and answered (perhaps by a smaller one)
        self.simulated_gaits = 0  # gaits simulated so far (the cost)
        self.outcomes = None  # the installed damage's (gaits, gr, fallen) simulated
        self.table = None  # its (gr (M, k), fallen (M,)), the others inferred
        self.refined = set()  # damages whose refinement was asked
        self.refining = 0  # the gaits of the refinement under way

    def observe(self, index, duty_factors, fallen=False) -> None:
        """One step of the robot: its gait and feet."""
        if int(index) not in self.run:
            self.run.append(int(index))
        self.feet.observe(index, duty_factors, fallen)

    def request(self, priors: DamagePriors | None):
        """The simulation to start now, ``(damage, gaits (n,), feet)``, or None: once the feet
        show lost legs that no table of ``priors`` holds (the self-model's own aside), each
        hypothesis once. ``feet``: a copy of the evidence, for :func:`choose` (which may
        settle on a smaller damage). Its outcomes go to :meth:`install`."""
        damage = hypothesis(self.feet.lost())
        held = priors is not None and any(
            _parts(n) == _parts(damage) for n in priors.names if not n.startswith(PREFIX))
        if damage is None or held or damage in (self.requested, self.installed) \
                or damage in self.given_up or damage in self.answered:
            return self._refinement()
        self.requested = damage
        return (damage, np.unique(np.concatenate([self.candidates, np.asarray(self.run, int)])),
                copy.deepcopy(self.feet))

    def _refinement(self):
        """The installed table's gaits to simulate next (``config.refine`` of them, farthest
        by its inferred part, in every direction), once per damage, as a :meth:`request`;
        None if there is nothing to refine or a simulation is under way."""
        damage = self.installed
        if not self.config.refine or damage is None or self.requested is not None \
                or damage in self.refined or damage in self.given_up:
            return None
        self.refined.add(damage)
        simulated = np.zeros(len(self.base_gr), bool)
        simulated[self.outcomes[0]] = True
        gaits = farthest_by_heading(self.table[0], ~simulated & ~self.table[1],
                                    self.config.refine)
        if not gaits.size:
            return None
        self.requested, self.refining = damage, int(gaits.size)
        return damage, gaits, None

    def install(self, priors, damage, gaits, gr, fallen, asked=None) -> DamagePriors | None:
        """``priors`` with the table of ``damage`` simulated on ``gaits`` (``gr`` ``(n, k)``,
        ``fallen`` ``(n,)``), in place of an earlier table of the self-model's
        (:meth:`_with_table`); ``asked``: the damage requested, if :func:`choose` settled on
        ``damage`` instead. ``priors`` itself if the request is no longer the hypothesis
        (the feet have shown more since). Raises ValueError for outcomes that do not match
        ``gaits``."""
        gaits = np.asarray(gaits, dtype=int).reshape(-1)
        gr = np.asarray(gr, dtype=float)
        fallen = np.asarray(fallen, dtype=bool).reshape(-1)
        k = self.base_gr.shape[1]
        if gr.ndim != 2 or gr.shape[0] != gaits.size or gr.shape[1] < k \
                or fallen.size != gaits.size or not np.all(np.isfinite(gr[:, :k])) \
                or not gaits.size or gaits.min() < 0 or gaits.max() >= len(self.base_gr):
            raise ValueError(f'self-model: {gaits.size} gaits simulated but outcomes '
                             f'{gr.shape} and {fallen.size} falls, or gaits off the map')
        asked = damage if asked is None else asked
        if asked != self.requested:
            return priors
        self.answered.add(asked)
        self.simulated_gaits += gaits.size
        gr = gr[:, :k]
        if damage == self.installed and self.outcomes is not None:  # a refinement: more gaits
            known, mask = self.outcomes, ~np.isin(gaits, self.outcomes[0])
            gaits, gr, fallen = (np.concatenate([known[0], gaits[mask]]),
                                 np.concatenate([known[1], gr[mask]]),
                                 np.concatenate([known[2], fallen[mask]]))
        self.installed, self.requested = damage, None
        self.outcomes = (gaits, gr, fallen)
        self.table = infer(self.descriptors, self.base_gr, gaits, gr, fallen, self.sigma)
        return self._with_table(priors, damage, gaits, *self.table)

    def status(self) -> str:
        """Where it stands, in words: the damage being simulated, the one whose table is in
        the priors, or that the feet show no leg lost."""
        if self.requested is not None and self.requested == self.installed:
            return f'{self.installed} simulated, {self.refining} more gaits of it simulating'
        if self.requested is not None:
            return f'simulating {self.requested}'
        if self.installed is not None:
            return f'{self.installed} simulated'
        damage = hypothesis(self.feet.lost())
        if damage is None:
            return 'no leg lost'
        return f'{damage} not simulated' if damage in self.given_up \
            else f'{damage} held by a table'

    def failed(self, damage) -> None:
        """The simulation of ``damage`` gave nothing: it is not asked again."""
        self.given_up.add(damage)
        if damage == self.requested:
            self.requested = None

    def forget(self, priors):
        """Back to no evidence (the robot's learning forgotten): ``priors`` without the
        self-model's table."""
        self.feet = LostLegs(self.feet.intact_duty, self.feet.legs)
        self.run = []
        self.requested = self.installed = self.outcomes = self.table = None
        self.given_up, self.answered, self.refined = set(), set(), set()
        return self.forget_table(priors)

    @staticmethod
    def forget_table(priors):
        """``priors`` without the self-model's table (None if nothing else is left)."""
        if priors is None or not any(n.startswith(PREFIX) for n in priors.names):
            return priors
        for name in [n for n in priors.names if n.startswith(PREFIX)]:
            priors = priors.without(name)
        return priors if len(priors) else None

    def _with_table(self, priors, damage, gaits, table, table_fallen) -> DamagePriors:
        """``priors`` with the table of ``damage`` (``table`` ``(M, k)``, ``table_fallen``
        ``(M,)``, simulated on ``gaits``) in place of the self-model's earlier one: the last
        of the first tier (``config.first_tier``) or of the second."""
        k = self.base_gr.shape[1]
        simulated = np.zeros(len(self.base_gr), bool)
        simulated[gaits] = True
        second = not self.config.first_tier
        if priors is not None:
            priors = self.forget_table(priors)
        if priors is None:
            return DamagePriors((PREFIX + damage,), table[None], table_fallen[None],
                                self.archive_checksum, reproduce_only=np.array([second]),
                                simulated=simulated[None])
        at = len(priors) if second else len(priors.first_tier())
        rows = np.zeros((1, *priors.generic_reward.shape[1:]))
        rows[0, :, :k] = table
        shape = priors.fallen.shape[1:]

        def put(a, row):
            return np.concatenate([a[:at], row[None], a[at:]])

        none = np.zeros(shape, int)
        return DamagePriors(
            priors.names[:at] + (PREFIX + damage,) + priors.names[at:],
            put(priors.generic_reward, rows[0]), put(priors.fallen, table_fallen),
            priors.archive_checksum,
            None if priors.chained_runs is None else put(np.asarray(priors.chained_runs), none),
            None if priors.chained_falls is None else put(np.asarray(priors.chained_falls),
                                                          none),
            put(priors.second_tier, np.array(second)),
            put(np.ones((len(priors), *shape), bool) if priors.simulated is None
                else np.asarray(priors.simulated), simulated))
