"""The paper's toy world: a damaged point robot that must reach a goal.

A point robot takes a 0.1 m step in direction theta; the damage adds 0.5 rad to every
direction theta > 0. Position observations carry Gaussian noise. The intact robot's exact
model is the prior mean (no behaviour-performance map); the behaviours are a dense grid of
theta normalised to [0, 1].
"""
from __future__ import annotations

import math

import numpy as np

from sela_ros.core.learning import PointMotion, SELAConfig
from sela_ros.core.mission import StepperConfig
from sela_ros.core.planning import GridPlanner, OccupancyGrid
from sela_ros.experiments.baselines import Problem

PAPER_NOISE_STD = 0.1  # the paper's sigma^2 = 0.01


class ToyWorld:
    """The toy environment (implements ``baselines.Environment``).

    Args:
        num_behaviours: number of theta values, evenly spaced in [-pi, pi).
        noise_std: standard deviation of the noise on each observed coordinate.
        damage_offset: radians added to theta when theta > 0.
        step: step length (metres).
        start: start position.
        rng: generator for the observation noise.
    """

    def __init__(self, num_behaviours: int = 1000, noise_std: float = PAPER_NOISE_STD,
                 damage_offset: float = 0.5, step: float = 0.1, start=(0.0, 0.0),
                 rng: np.random.Generator | None = None):
        if int(num_behaviours) < 2:
            raise ValueError(f'num_behaviours must be >= 2, got {num_behaviours}')
        if not math.isfinite(noise_std) or noise_std < 0:
            raise ValueError(f'noise_std must be a finite number >= 0, got {noise_std!r}')
        if not math.isfinite(step) or step <= 0:
            raise ValueError(f'step must be > 0, got {step!r}')
        self.thetas = np.linspace(-math.pi, math.pi, int(num_behaviours), endpoint=False)
        self.noise_std = float(noise_std)
        self.damage_offset = float(damage_offset)
        self.step = float(step)
        self.start = np.asarray(start, dtype=float).reshape(2)
        self.rng = rng if rng is not None else np.random.default_rng()
        self.reset()

    @property
    def candidates(self) -> np.ndarray:
        """``(M, 1)`` behaviour descriptors: theta mapped to [0, 1)."""
        return ((self.thetas + math.pi) / (2.0 * math.pi))[:, None]

    def _outcome(self, thetas):
        return self.step * np.stack([np.cos(thetas), np.sin(thetas)], axis=-1)

    def intact_generic_reward(self) -> np.ndarray:
        """``(M, 2)`` step of each behaviour on the intact robot (the prior mean)."""
        return self._outcome(self.thetas)

    def damaged_thetas(self) -> np.ndarray:
        return np.where(self.thetas > 0, self.thetas + self.damage_offset, self.thetas)

    def damaged_generic_reward(self) -> np.ndarray:
        """``(M, 2)`` true step of each behaviour on the damaged robot (oracle only)."""
        return self._outcome(self.damaged_thetas())

    def _observe(self):
        self._observed = self._true + self.rng.normal(0.0, self.noise_std, 2)

    def reset(self) -> None:
        self._true = self.start.copy()
        self._observe()

    def true_pose(self) -> np.ndarray:
        return self._true.copy()

    def observed_pose(self) -> np.ndarray:
        return self._observed.copy()

    def execute(self, index: int) -> np.ndarray:
        index = int(index)
        if not 0 <= index < len(self.thetas):
            raise ValueError(f'behaviour index must be in [0, {len(self.thetas)}), got {index}')
        theta = self.thetas[index]
        if theta > 0:
            theta += self.damage_offset
        self._true = self._true + self.step * np.array([math.cos(theta), math.sin(theta)])
        self._observe()
        return self._observed.copy()


def toy_problem(world: ToyWorld, goal=(2.0, 2.0), max_steps: int = 100,
                config: SELAConfig | None = None, grid_resolution: float = 0.05,
                grid_bounds=(-12.0, 14.0, -12.0, 14.0)) -> Problem:
    """The paper's toy task for ``world``: the A* reward selection layer on an empty map.

    The default map is large enough (26 m square) that no run can leave it within its
    learning phase and step cap, so failures are step-cap failures.
    """
    grid = OccupancyGrid.empty(*grid_bounds, grid_resolution)
    step = world.step
    return Problem(
        candidates=world.candidates, prior_gr=world.intact_generic_reward(),
        motion=PointMotion(), goal=np.asarray(goal, dtype=float), planner=GridPlanner(grid),
        # The paper's rules: each gait by its predicted distance (no caution).
        config=config or SELAConfig(planner_lookahead=step, acquisition_caution=None,
                                     gp_mean_affine=None),
        max_steps=max_steps,
        true_gr=world.damaged_generic_reward(),
        ite_targets=np.array([[0.0, step], [0.0, -step], [-step, 0.0], [step, 0.0]]),
        ite_max_iterations=10,
        # The paper's toy SELA learns from the first step: its 0.1 m steps are below any
        # detection threshold set for the hexapod.
        stepper=StepperConfig(adapt_on_start=True), detect=False)
