"""The self-model in the decision loop the nodes run: the stepper asks for the damage the feet
show to be simulated, takes the answer later, and chooses on the table."""
from types import SimpleNamespace

import numpy as np
import pytest

from sela_ros.core.geometry import se2_compose
from sela_ros.core.learning import DamagePriors
from sela_ros.core.learning.self_model import PREFIX, SelfModel, SelfModelConfig
from sela_ros.core.mission import StepperConfig, make_sela, run_mission
from sela_ros.core.mission import stepper_io as io
from sela_ros.core.planning import straight_line_planner

LEGS = ('a', 'b', 'c', 'd')


def _world(m=300, seed=0):
    """A map of gaits; the robot lost leg 'a': each gait goes where the map says times 0.4 if
    it leans on 'a' (its intact duty factor over 0.5), as the map says if not."""
    rng = np.random.default_rng(seed)
    duty = rng.uniform(0, 1, (m, len(LEGS)))
    descriptors = np.column_stack([rng.uniform(0, 1, (m, 2)), duty])
    heading = rng.uniform(-np.pi, np.pi, m)
    speed = rng.uniform(0.05, 0.3, m)
    gr = np.column_stack([speed * np.cos(heading), speed * np.sin(heading),
                          rng.normal(0, 0.2, m)])
    damaged = gr * np.where(duty[:, :1] > 0.5, 0.4, 1.0)
    return descriptors, gr, duty, damaged


class _Robot:
    """Walks the damaged map; its feet: the intact duty factors, leg 'a' never touching."""

    def __init__(self, damaged, duty):
        self.damaged, self.duty, self.pose, self.falls = damaged, duty, np.zeros(3), 0
        self.last_execution = None

    def true_pose(self):
        return self.pose.copy()

    observed_pose = true_pose

    def execute(self, index):
        self.pose = se2_compose(self.pose, self.damaged[index])
        feet = self.duty[index].copy()
        feet[0] = 0.0
        self.last_execution = SimpleNamespace(duty_factors=feet, fallen=False)
        return self.pose.copy()


def _mission(delay, simulate, gaits=120, goal=(1.5, 0.5)):
    descriptors, gr, duty, damaged = _world()
    archive = SimpleNamespace(params=np.zeros((len(gr), 36)), generic_reward=gr,
                              kernel_sigma=0.3, normalised_descriptors=lambda: descriptors)
    # A table of another damage, so that the priors are there as the node's are.
    other = DamagePriors(('remove:d',), (gr * 0.5)[None], np.zeros((1, len(gr)), bool), 'sum')
    sela = make_sela(archive, {'planner.lookahead': 0.3}, priors=other)
    model = SelfModel(descriptors, gr, duty, LEGS, 'sum', 0.3,
                      SelfModelConfig(gaits=gaits, covering=gaits // 2, delay_steps=delay))
    calls = []

    def counted(damage, indices):
        calls.append((damage, np.asarray(indices).copy()))
        return simulate(damaged, damage, indices)

    robot = _Robot(damaged, duty)
    said = []
    run = run_mission(robot, sela, [goal], straight_line_planner,
                      stepper_config=StepperConfig(max_steps=60, adapt_on_start=True),
                      on_step=lambda record: said.append(model.status()),
                      self_model=model, simulate=counted)
    return run, sela, model, calls, said


def _simulator(damaged, damage, indices):
    descriptors, _, duty, _ = _world()
    feet = duty[indices].copy()
    feet[:, 0] = 0.0
    return damaged[indices], np.zeros(len(indices), bool), feet


@pytest.mark.parametrize('delay', [0, 2])
def test_the_feet_are_simulated_and_the_table_used_from_the_delay_on(delay):
    run, sela, model, calls, said = _mission(delay, _simulator)
    assert run.success
    (damage, gaits), *more = calls
    assert damage == 'remove:a' and len(gaits) >= 120
    # Asked once the feet showed it (two steps leaning on leg 'a' at least), answered
    # ``delay`` gaits later: the step after that is the first chosen with the table in.
    asked = said.index('simulating remove:a')
    assert asked >= 1 and said[:asked] == ['no leg lost'] * asked
    in_use = [i for i, s in enumerate(said) if s.startswith('remove:a simulated')]
    assert in_use and in_use[0] == asked + delay + 1
    # Then the gaits the table infers go farthest, once, while the table is in use.
    (again, extra), = more
    assert again == 'remove:a' and not set(extra) & set(gaits)
    assert said[in_use[0]] == f'remove:a simulated, {len(extra)} more gaits of it simulating'
    # Counted once answered (at once with no delay; the mission may end before).
    assert model.simulated_gaits == len(gaits) + len(extra) if delay == 0 \
        else model.simulated_gaits in (len(gaits), len(gaits) + len(extra))
    assert PREFIX + 'remove:a' in sela.priors.names
    assert sela.select_prior().name == PREFIX + 'remove:a'  # it explains the steps


def test_without_a_simulator_the_mission_goes_on_and_the_damage_is_not_asked_again():
    descriptors, gr, duty, damaged = _world()
    archive = SimpleNamespace(params=np.zeros((len(gr), 36)), generic_reward=gr,
                              kernel_sigma=0.3, normalised_descriptors=lambda: descriptors)
    model = SelfModel(descriptors, gr, duty, LEGS, 'sum', 0.3,
                      SelfModelConfig(gaits=50, delay_steps=0))
    run = run_mission(_Robot(damaged, duty), make_sela(archive, {'planner.lookahead': 0.3}),
                      [(1.0, 0.0)], straight_line_planner,
                      stepper_config=StepperConfig(max_steps=60, adapt_on_start=True),
                      self_model=model)
    assert run.end is not None
    assert model.installed is None and model.status() == 'remove:a not simulated'


def test_the_stepper_reports_a_failed_or_malformed_answer_and_keeps_its_priors():
    from stepper_driver import Driver, only

    descriptors, gr, duty, _ = _world(m=50)
    driver = Driver(adapt_on_start=True)
    stepper = driver.stepper
    stepper.self_model = SelfModel(stepper.sela._candidates, stepper.sela._prior,
                                   duty, LEGS, 'sum', 0.3, SelfModelConfig(gaits=10))
    priors = stepper.sela.priors
    out = driver(io.DamageSimulated('remove:a', (1, 2), error='worker died'))
    assert [r.level for r in out if isinstance(r, io.Report)] == [io.Level.WARN]
    assert 'worker died' in out[0].message and stepper.sela.priors is priors
    stepper.self_model.requested = 'remove:b'
    out = driver(io.DamageSimulated('remove:b', (1, 2), ((0.1, 0.0, 0.0),), (False,)))
    assert 'outcomes' in only(out, io.Report).message and stepper.sela.priors is priors
    assert 'remove:b' in stepper.self_model.given_up


@pytest.mark.parametrize('legs', [('a',), ()])
def test_clear_forgets_the_feet_and_the_table(legs):
    from stepper_driver import Driver

    descriptors, gr, duty, damaged = _world(m=50)
    driver = Driver(adapt_on_start=True)
    stepper = driver.stepper
    model = SelfModel(stepper.sela._candidates, stepper.sela._prior[:, :3] if
                      stepper.sela._prior.shape[1] >= 3 else np.column_stack(
                          [stepper.sela._prior, np.zeros(50)]), duty, LEGS, 'sum', 0.3,
                      SelfModelConfig(gaits=10))
    stepper.self_model = model
    for g in np.flatnonzero(duty[:, 0] > 0.5)[:2]:
        feet = duty[g].copy()
        feet[[LEGS.index(leg) for leg in legs]] = 0.0
        model.observe(g, feet)
    driver(io.ClearRequested())
    assert model.feet.lost() == () and model.installed is None
