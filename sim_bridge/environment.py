"""The hexapod as the learner sees it: noisy position observations and observed outcomes.

ROS-free. The sim_bridge node and the in-process experiments both drive the robot through
:class:`ObservedHexapod`, so that the same seed gives the same observations, and therefore
the same decisions, over DDS and in process.

Observation model (the paper's): the robot's (x, y) is observed with Gaussian noise of
standard deviation ``noise_std`` once after every gait (and once after a reset); the heading
is observed exactly. The observed generic reward of a gait is computed (``afun``) from the
observations before and after it: the displacement rotated into the frame of the observed
start pose, and the heading change wrapped to (-pi, pi].
"""
import math
from dataclasses import dataclass

import numpy as np

from sim_bridge.simulator import generic_reward  # afun, the same as the simulator's

#: Sim seconds a fallen robot takes to get up where it lies (one gait's time).
RIGHTING_TIME = 3.0


@dataclass
class Execution:
    """One executed gait: what was observed and what really happened."""

    observed_generic_reward: np.ndarray
    observed_start: np.ndarray
    observed_end: np.ndarray
    true_start: np.ndarray
    true_end: np.ndarray
    fallen: bool
    sim_time: float
    duty_factors: np.ndarray
    standing_start: bool = False  # GaitOutcome.standing_start


class ObservedHexapod:
    """A :class:`sim_bridge.hexapod.Hexapod` behind the paper's noisy observation model.

    Args:
        robot: the simulated hexapod (owns physics, damage and sim time).
        noise_std: standard deviation (m) of the Gaussian noise on observed positions.
        seed: seed of the observation noise generator.
        right_on_fall: after a gait that ends fallen or flipped, the robot gets up where it
            lies (the step still counts, and is reported as fallen); False: it stays down.
        righting_time: sim seconds that getting up takes.
    """

    def __init__(self, robot, noise_std=0.0, seed=0, right_on_fall=True,
                 righting_time=RIGHTING_TIME):
        self.robot = robot
        self.set_noise_std(noise_std)
        self.rng = np.random.default_rng(seed)
        self.right_on_fall = bool(right_on_fall)
        self.righting_time = float(righting_time)
        self.falls = 0
        self._observed = self._observe(self.robot.pose())

    def set_noise_std(self, noise_std) -> None:
        """The standard deviation (m) of the noise on observed positions from now on."""
        noise_std = float(noise_std)
        if not (math.isfinite(noise_std) and noise_std >= 0.0):
            raise ValueError(f'noise_std must be a finite number >= 0, got {noise_std}')
        self.noise_std = noise_std

    def _observe(self, true_pose):
        pose = np.array(true_pose, dtype=float)
        if self.noise_std > 0.0:
            pose[:2] += self.rng.normal(0.0, self.noise_std, size=2)
        return pose

    def reset(self):
        self.robot.reset()
        self._observed = self._observe(self.robot.pose())

    def observed_pose(self):
        return self._observed.copy()

    def true_pose(self):
        return np.asarray(self.robot.pose(), dtype=float)

    def execute(self, params, callback=None, callback_period=None):
        """One gait of the controller's parameters: the robot's outcome, observed."""
        return self._run_observed(self.robot.execute, np.asarray(params, dtype=float), callback,
                              callback_period)

    def execute_targets(self, targets, callback=None, callback_period=None):
        """The joint targets of one physics step after another
        (:meth:`~sim_bridge.hexapod.Hexapod.execute_targets`), observed as a gait."""
        return self._run_observed(self.robot.execute_targets, targets, callback, callback_period)

    def _run_observed(self, run, command, callback, callback_period):
        kwargs = {}
        if callback is not None:
            kwargs = {'callback': callback}
            if callback_period is not None:
                kwargs['callback_period'] = callback_period
        outcome = run(command, **kwargs)
        if outcome.fallen:
            self.falls += 1
            if self.right_on_fall:
                self.robot.right(self.righting_time)
        observed_start = self._observed
        observed_end = self._observe(outcome.end_pose)
        self._observed = observed_end
        return Execution(
            observed_generic_reward=generic_reward(observed_start, observed_end),
            observed_start=observed_start.copy(), observed_end=observed_end.copy(),
            true_start=np.asarray(outcome.start_pose, float),
            true_end=np.asarray(outcome.end_pose, float), fallen=bool(outcome.fallen),
            sim_time=float(outcome.sim_time),
            duty_factors=np.asarray(outcome.duty_factors, float),
            standing_start=bool(outcome.standing_start))
