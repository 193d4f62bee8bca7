"""SELA and the paper's baselines as runners over a small environment protocol.

Every runner takes an environment (the toy world here; a hexapod environment later), a
:class:`Problem` (the archive, the motion model, the goal and the parameters) and a seeded
``numpy.random.Generator``, and returns a :class:`RunResult`.

Choices (documented because the paper leaves them open):

* Learning-phase trials move the robot in the world too: there is no reset between the
  learning phase and the task (a damaged robot in the field cannot be teleported back).
  The task phase starts from wherever learning left the robot.
* After a separate learning phase the learned model is frozen: the task phase exploits it
  (UCB with alpha 0, no more updates). SELA is the only method that keeps learning.
* The goal is judged on the TRUE pose (``env.true_pose()``); every decision uses the
  observed pose. The oracle uses the true pose and the damaged robot's true outcomes.
* A step cap (``Problem.max_steps``) on task steps, or a planning error (robot off the map
  or in an obstacle), ends the run as a failure.
* A mission of several goals (``Problem.via``, then ``Problem.goal``) visits them in order;
  the step cap is for the whole mission; whatever a method learns (SELA, or the model
  frozen after a learning phase) carries from one goal to the next.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from sela_ros.core.detection import DetectorConfig
from sela_ros.core.learning import (
    SELA,
    CandidateSetGP,
    SELAConfig,
    acquisition,
    observed_generic_reward,
)
from sela_ros.core.mission import StepperConfig, run_mission
from sela_ros.core.planning import PlanningError, next_waypoint, straight_line_planner


class Environment(Protocol):
    """What a runner needs from a world (toy or hexapod).

    ``observed_pose()`` returns the LATEST observation (drawn once per step, not re-sampled
    on each call), so that the pose a decision is made from is the pose the observed
    generic reward starts from.
    """

    def reset(self) -> None:
        """Put the robot back at the start (called once at the start of each run)."""

    def observed_pose(self) -> np.ndarray:
        """The latest (noisy) pose observation."""

    def true_pose(self) -> np.ndarray:
        """The true pose (used to judge the goal, and by the oracle)."""

    def execute(self, index: int) -> np.ndarray:
        """Execute behaviour ``index`` of the archive; returns the observed pose after."""


@dataclass
class Problem:
    """Everything a runner needs besides the environment.

    Attributes:
        candidates: ``(M, d)`` behaviour descriptors normalised to ``[0, 1]^d``.
        prior_gr: ``(M, k)`` generic rewards on the intact robot (prior mean).
        motion: ``PointMotion`` or ``SE2Motion``.
        goal: goal ``(x, y)`` (the last one of a mission).
        via: goals ``((x, y), ...)`` to reach, in order, before ``goal`` (default none).
        planner: ``(start_xy, goal_xy) -> path``; None for the straight line.
        config: SELA parameters (GP, UCB, lookahead, goal eps).
        max_steps: task-step cap (100 toy).
        true_gr: ``(M, k)`` outcomes on the damaged robot (needed by ``oracle`` only).
        ite_targets: ``(T, k)`` target generic rewards that ``ite_4dir`` learns one
            behaviour for (toy: a step up, down, left, right; hexapod: forward, backward,
            turn cw, turn ccw). None: unit directions of the GR's xy scaled to the prior's
            largest step.
        ite_max_iterations: M-BOA trials per target (10 toy, 15 hexapod).
        ite_tolerance: a target is learned when a trial lands within this fraction of
            the target's length from it.
        babbling_eps_model: random babbling stops once the model's error on the executed
            behaviour is below this (metres).
        babbling_max_iterations: random babbling trials at most (15).
        uncertainty_iterations: trials of ``ite_uncertainty`` (15).
        stability: ``(M,)`` the fall model's stability feature (SELA's ``stability``).
        priors: damage priors (:mod:`sela_ros.core.learning.damage_priors`) for ``sela`` only; the
            baselines are the paper's, over the intact map and one step ahead.
        stepper, detector, detect: for ``sela``, which runs the ``sela_adapter`` node's
            decision loop: its stepper's and damage detector's settings (the node's
            defaults), and whether the detector runs (False: adaptation from the first step
            only if ``stepper.adapt_on_start``). ``max_steps`` caps each goal of a mission.
        self_model: for ``sela``, ``(SelfModel, simulate)``: the self-model
            (:class:`~sela_ros.core.learning.self_model.SelfModel`) that reads each step's feet
            (the environment's ``last_execution``) and the robot's simulator that runs its
            hypotheses (:func:`~sela_ros.core.mission.run_mission`); None: none.
    """

    candidates: np.ndarray
    prior_gr: np.ndarray
    motion: object
    goal: np.ndarray
    via: tuple = ()
    planner: Callable | None = None
    config: SELAConfig = dataclasses.field(default_factory=SELAConfig)
    max_steps: int = 100
    true_gr: np.ndarray | None = None
    ite_targets: np.ndarray | None = None
    ite_max_iterations: int = 10
    ite_tolerance: float = 0.1
    babbling_eps_model: float = 0.01
    babbling_max_iterations: int = 15
    uncertainty_iterations: int = 15
    stability: np.ndarray | None = None
    priors: object = None
    stepper: StepperConfig = dataclasses.field(default_factory=StepperConfig)
    detector: DetectorConfig = dataclasses.field(default_factory=DetectorConfig)
    detect: bool = True
    self_model: object = None

    def make_sela(self, extensions=False) -> SELA:
        """A SELA over the problem; ``extensions``: with what this project adds to the
        paper's SELA (damage priors, two steps ahead), else as the paper's baselines use it
        (no priors, one step)."""
        config = self.config if extensions else \
            dataclasses.replace(self.config, planner_horizon=1.0)
        return SELA(self.candidates, self.prior_gr, self.motion, planner=self.planner,
                    goal=self.goal, config=config, stability=self.stability,
                    priors=self.priors if extensions else None)

    def targets(self) -> np.ndarray:
        if self.ite_targets is not None:
            return np.asarray(self.ite_targets, dtype=float)
        k = self.prior_gr.shape[1]
        reach = float(np.max(np.linalg.norm(self.prior_gr[:, :2], axis=1)))
        out = []
        for d in ((0, 1), (0, -1), (-1, 0), (1, 0)):  # up, down, left, right
            t = np.zeros(k)
            t[:2] = np.array(d) * reach
            out.append(t)
        return np.array(out)


@dataclass
class RunResult:
    success: bool
    steps: int
    learning_iterations: int
    goal_steps: list = dataclasses.field(default_factory=list)  # task steps when each goal
    # of the mission was reached
    behaviors: list = dataclasses.field(default_factory=list)  # archive index of each step
    # SELA: each step's record (sela_ros.core.mission.StepRecord), what a mission's summary
    # keeps (scripts/step_budget.py reads either)
    records: list = dataclasses.field(default_factory=list)


def _reached(env, problem) -> bool:
    pose = np.asarray(env.true_pose(), dtype=float)
    return bool(np.linalg.norm(pose[:2] - np.asarray(problem.goal)[:2])
                < problem.config.goal_eps)


def _waypoint(problem, pose):
    planner = problem.planner or straight_line_planner
    path = planner(np.asarray(pose)[:2], problem.goal)
    return next_waypoint(path, np.asarray(pose)[:2], problem.config.planner_lookahead)


def _task_phase(env, problem, choose, learn=None, learning_iterations=0) -> RunResult:
    """Step with ``choose(observed_pose) -> index`` to each goal in turn or the step cap.

    ``problem.goal`` is the goal being walked to while a leg of the mission runs (``choose``
    reads it there), and the last goal again at the end.
    """
    steps = 0
    reached = []
    last = problem.goal
    try:
        for goal in [*problem.via, last]:
            problem.goal = np.asarray(goal, dtype=float)
            while not _reached(env, problem):
                if steps >= problem.max_steps:
                    return RunResult(False, steps, learning_iterations, reached)
                before = np.asarray(env.observed_pose(), dtype=float).copy()
                index = choose(before)
                falls = getattr(env, 'falls', 0)
                standing = bool(getattr(env, 'standing', False))
                after = env.execute(index)
                steps += 1
                if learn is not None:
                    learn(index, observed_generic_reward(before, after, problem.motion),
                          getattr(env, 'falls', 0) > falls, standing)
            reached.append(steps)
    except PlanningError:
        return RunResult(False, steps, learning_iterations, reached)
    finally:
        problem.goal = last
    return RunResult(True, steps, learning_iterations, reached)


def _ask(sela, problem):
    """``choose`` for a SELA model: the index it picks toward the current goal."""
    def choose(pose):
        if sela.goal is None or not np.array_equal(sela.goal, np.asarray(problem.goal)[:2]):
            sela.set_goal(problem.goal)
        return sela.ask(pose).index
    return choose


def _exploit(env, problem, sela, learning_iterations):
    """Task phase with a frozen model: greedy (alpha 0) on its posterior mean."""
    sela.set_config(dataclasses.replace(sela.config, acquisition_ucb_alpha=0.0))
    return _task_phase(env, problem, _ask(sela, problem),
                       learning_iterations=learning_iterations)


def run_sela(env, problem: Problem, rng: np.random.Generator) -> RunResult:
    """SELA: learn while doing the task (no learning phase), through the decision loop the
    ``sela_adapter`` node runs (:func:`~sela_ros.core.mission.run_mission`: the stepper, the
    damage detector, the planner's whole path), with the node's defaults."""
    env.reset()
    model, simulate = problem.self_model or (None, None)
    run = run_mission(env, problem.make_sela(extensions=True), [*problem.via, problem.goal],
                      problem.planner or straight_line_planner,
                      detector_config=problem.detector, stepper_config=dataclasses.replace(
                          problem.stepper, max_steps=problem.max_steps),
                      detect=problem.detect, self_model=model, simulate=simulate)
    return RunResult(run.success, run.steps, 0, run.goal_steps,
                     [r.behavior_index for r in run.logic.records], list(run.logic.records))


def _learning_step(env, problem, sela, index):
    before = np.asarray(env.observed_pose(), dtype=float).copy()
    after = env.execute(index)
    gr = observed_generic_reward(before, after, problem.motion)
    sela.tell(index, gr)
    return gr


def run_random_babbling(env, problem: Problem, rng: np.random.Generator) -> RunResult:
    """Random babbling until the model's error < eps_model (or N trials), then the task."""
    env.reset()
    sela = problem.make_sela()
    iterations = 0
    while iterations < problem.babbling_max_iterations:
        index = int(rng.integers(sela.num_candidates))
        predicted = sela.predict()[0][index].copy()
        gr = _learning_step(env, problem, sela, index)
        iterations += 1
        if np.linalg.norm(gr - predicted) < problem.babbling_eps_model:
            break
    return _exploit(env, problem, sela, iterations)


def run_ite_uncertainty(env, problem: Problem, rng: np.random.Generator) -> RunResult:
    """IT&E variant 1: try the most uncertain behaviour N times, then the task."""
    env.reset()
    sela = problem.make_sela()
    for _ in range(problem.uncertainty_iterations):
        _, sigma = sela.predict()
        _learning_step(env, problem, sela, int(np.argmax(sigma)))
    return _exploit(env, problem, sela, problem.uncertainty_iterations)


def run_ite_4dir(env, problem: Problem, rng: np.random.Generator) -> RunResult:
    """IT&E (M-BOA) learns one behaviour per target GR, then reaches the goal with them.

    For each target, M-BOA models the performance ``-||GR - target||`` with a scalar GP
    whose prior mean is the intact robot's performance, tries UCB's choice, and stops when
    a trial lands within ``ite_tolerance * ||target||`` of the target or after
    ``ite_max_iterations`` trials. The best trial (and its observed GR) is kept.
    """
    env.reset()
    c = problem.config
    iterations = 0
    learned = []  # (index, observed GR)
    for target in problem.targets():
        prior_perf = -np.linalg.norm(problem.prior_gr - target, axis=1)
        model = CandidateSetGP(problem.candidates, prior_perf[:, None], sigma=c.gp_kernel_sigma,
                               variance=c.gp_kernel_variance, noise=c.gp_noise)
        best = None
        for _ in range(problem.ite_max_iterations):
            mu, var = model.query()
            index = acquisition.ucb(mu[:, 0], np.sqrt(var), c.acquisition_ucb_alpha)
            before = np.asarray(env.observed_pose(), dtype=float).copy()
            gr = observed_generic_reward(before, env.execute(index), problem.motion)
            iterations += 1
            perf = -float(np.linalg.norm(gr - target))
            model.add_sample(index, [perf])
            if best is None or perf > best[0]:
                best = (perf, index, gr)
            if perf >= -problem.ite_tolerance * float(np.linalg.norm(target)):
                break
        learned.append((best[1], best[2]))
    indices = np.array([i for i, _ in learned])
    grs = np.array([g for _, g in learned])

    def choose(pose):
        waypoint = _waypoint(problem, pose)
        predicted = problem.motion.predict(pose, grs)
        return int(indices[np.argmin(np.linalg.norm(predicted[:, :2] - waypoint, axis=1))])

    return _task_phase(env, problem, choose, learning_iterations=iterations)


def run_oracle(env, problem: Problem, rng: np.random.Generator) -> RunResult:
    """Knows the damaged robot's outcomes and its true pose: greedy toward the waypoint.

    Its step count is the lower bound the other methods are compared with.
    """
    if problem.true_gr is None:
        raise ValueError('oracle needs Problem.true_gr (the damaged robot\'s outcomes)')
    env.reset()
    true_gr = np.asarray(problem.true_gr, dtype=float)

    def choose(_observed):
        pose = np.asarray(env.true_pose(), dtype=float)
        waypoint = _waypoint(problem, pose)
        predicted = problem.motion.predict(pose, true_gr)
        return int(np.argmin(np.linalg.norm(predicted[:, :2] - waypoint, axis=1)))

    return _task_phase(env, problem, choose)


def run_oracle_2step(env, problem: Problem, rng: np.random.Generator) -> RunResult:
    """The oracle looking two steps ahead as SELA does (``planner.horizon`` 2): it knows the
    damaged robot's outcomes and its true pose, and of the best first gaits takes the one
    after which the best second gait lands nearest a second waypoint. SELA with two steps
    ahead can beat the greedy :func:`run_oracle`; this is the bound for it."""
    if problem.true_gr is None:
        raise ValueError('oracle_2step needs Problem.true_gr (the damaged robot\'s outcomes)')
    env.reset()
    config = dataclasses.replace(problem.config, acquisition_ucb_alpha=0.0,
                                 planner_horizon=2.0)
    knows = SELA(problem.candidates, np.asarray(problem.true_gr, dtype=float), problem.motion,
                 planner=problem.planner, goal=problem.goal, config=config)
    choose = _ask(knows, problem)
    return _task_phase(env, problem, lambda _observed: choose(env.true_pose()))


METHODS = {
    'sela': run_sela,
    'random_babbling': run_random_babbling,
    'ite_4dir': run_ite_4dir,
    'ite_uncertainty': run_ite_uncertainty,
    'oracle': run_oracle,
    'oracle_2step': run_oracle_2step,
}
