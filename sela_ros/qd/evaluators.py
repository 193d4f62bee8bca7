"""Evaluation functions of map building: one gait's descriptor, fitness and generic reward.

An *evaluation function* is any picklable callable ``params (n,) -> EvaluationResult``:
:class:`RobotEvaluator` (PyBullet, through ``sim_bridge.evaluation.evaluate_gait``, for any
robot description of ``sim_bridge.robots``; :class:`HexapodEvaluator` is the hexapod's) or
the cheap :class:`SyntheticEvaluator` used by tests and benchmarks.

Descriptor and fitness (see docs/archive.md): the descriptor is the final ``(x, y)`` of one
gait in the start frame, the fitness is minus the angle between the final yaw and the
heading of the circular arc that joins the start to that point (Cully et al. 2015;
Chatzilygeroudis et al. 2018, reset-free trial and error).
"""
from __future__ import annotations

import time
from typing import NamedTuple

import numpy as np

from sela_ros.core.geometry import wrap_angle

#: Behaviour descriptors, with their dimensions on the hexapod: the final (x, y) in the start
#: frame (2-D), and the paper's 8-D one that adds the duty factors, one per leg in the
#: description's leg order (2 + legs dimensions on another robot).
DESCRIPTORS = {'final_xy': 2, 'final_xy_duty_factors': 8}


class EvaluationResult(NamedTuple):
    """What one evaluation tells MAP-Elites.

    Attributes:
        valid: False for a gait to discard (the robot fell).
        fitness: quality, higher is better.
        descriptor: ``(d,)`` raw behaviour descriptor.
        generic_reward: ``(3,)`` ``(dx, dy, dyaw)`` in the start frame.
    """

    valid: bool
    fitness: float
    descriptor: np.ndarray
    generic_reward: np.ndarray


def arc_fitness(generic_reward) -> np.ndarray:
    """Minus the angle between the final yaw and the yaw of the joining circular arc.

    A circular arc that leaves the origin heading along +x and ends at ``(x, y)`` arrives
    with heading ``2 atan2(y, x)``; a gait that follows such an arc is easy to chain and to
    predict. The fitness is ``-|wrap(dyaw - 2 atan2(dy, dx))|`` in ``[-pi, 0]``, 0 is best.
    Walking straight backwards without turning is an arc too (``2 atan2(0, -1) = 2 pi``).

    Args:
        generic_reward: ``(..., 3)`` array of ``(dx, dy, dyaw)``.
    """
    gr = np.asarray(generic_reward, dtype=np.float64)
    arc_yaw = 2.0 * np.arctan2(gr[..., 1], gr[..., 0])
    return -np.abs(wrap_angle(gr[..., 2] - arc_yaw))


class SyntheticEvaluator:
    """A cheap, deterministic stand-in for the hexapod (tests, benchmarks, dry runs).

    Maps 36 parameters to a smooth, non-linear ``(dx, dy, dyaw)`` that covers roughly
    ``[-1, 1]^2 x [-1.5, 1.5]``; parameters 0 and 1 both above 0.95 count as a fall. The
    8-D descriptor adds six "duty factors" in ``[0, 1]`` (the amplitudes' mean per leg).

    Args:
        delay: seconds to sleep per evaluation, to emulate a simulator's cost.
        descriptor: a key of :data:`DESCRIPTORS`.
    """

    #: Its gaits have as many parameters as the hexapod's.
    n_params = 36

    def __init__(self, delay: float = 0.0, descriptor: str = 'final_xy'):
        if descriptor not in DESCRIPTORS:
            raise ValueError(f'descriptor must be one of {sorted(DESCRIPTORS)}, got '
                             f'{descriptor!r}')
        self.delay = float(delay)
        self.descriptor = descriptor
        weights = np.random.default_rng(20180219).normal(size=(3, self.n_params))
        self.weights = weights

    def __call__(self, params) -> EvaluationResult:
        if self.delay:
            time.sleep(self.delay)
        p = np.asarray(params, dtype=np.float64) - 0.5
        z = 3.0 * (self.weights @ p)
        gr = np.array([np.tanh(z[0]) + 0.1 * np.sin(12.0 * p[3]),
                       np.tanh(z[1]) + 0.1 * np.cos(9.0 * p[7]),
                       1.5 * np.tanh(z[2])])
        fallen = params[0] > 0.95 and params[1] > 0.95
        desc = gr[:2].copy()
        if self.descriptor == 'final_xy_duty_factors':
            duty = (np.asarray(params, dtype=np.float64).reshape(6, -1)[:, ::3]).mean(axis=1)
            desc = np.concatenate([desc, duty])
        return EvaluationResult(not fallen, float(arc_fitness(gr)), desc, gr)

    def settings(self, dt: float = 1.0 / 240.0, gait_duration: float = 3.0) -> dict:
        """Settings recorded in an archive built with this function."""
        return {'dt': dt, 'gait_duration': gait_duration,
                'controller_version': 'synthetic', 'model_version': 'synthetic'}


class RobotEvaluator:
    """One gait on a simulated robot: descriptor final ``(x, y)`` (+ duty factors), arc.

    Picklable: each worker process imports PyBullet and builds its own simulator.

    Args:
        dt: physics time step (s); fix it before building an archive.
        gait_duration: how long one gait runs (s).
        damage: damage spec understood by ``sim_bridge`` (``'intact'`` for an archive).
        solver_iterations: PyBullet constraint-solver iterations per step.
        descriptor: a key of :data:`DESCRIPTORS`.
        robot: a robot's name (or ``module:attribute``) for ``sim_bridge.robots.get_robot``;
            it travels to worker processes by name.
    """

    def __init__(self, dt: float = 1.0 / 240.0, gait_duration: float = 3.0,
                 damage: str = 'intact', solver_iterations: int = 50,
                 descriptor: str = 'final_xy', robot: str = 'hexapod'):
        if dt <= 0 or gait_duration <= 0:
            raise ValueError(f'dt and gait_duration must be > 0, got {dt}, {gait_duration}')
        if descriptor not in DESCRIPTORS:
            raise ValueError(f'descriptor must be one of {sorted(DESCRIPTORS)}, got '
                             f'{descriptor!r}')
        self.dt = float(dt)
        self.gait_duration = float(gait_duration)
        self.damage = damage
        self.solver_iterations = int(solver_iterations)
        self.descriptor = descriptor
        self.robot = str(robot)

    def description(self):
        """The robot's description (imports it, and the simulator's package)."""
        from sim_bridge.robots import get_robot

        return get_robot(self.robot)

    @property
    def n_params(self) -> int:
        """Gait parameters of the robot (the map's solution dimension)."""
        return self.description().n_params

    @property
    def dims(self) -> int:
        """Dimensions of this evaluator's descriptor on its robot."""
        return self.description().descriptor_dims[self.descriptor]

    def __call__(self, params) -> EvaluationResult:
        from sim_bridge.evaluation import evaluate_gait

        outcome = evaluate_gait(np.asarray(params, dtype=np.float64), damage=self.damage,
                                dt=self.dt, gait_duration=self.gait_duration,
                                solver_iterations=self.solver_iterations, robot=self.robot)
        gr = np.asarray(outcome.generic_reward, dtype=np.float64)
        valid = not bool(outcome.fallen) and bool(np.all(np.isfinite(gr)))
        desc = gr[:2].copy()
        if self.descriptor == 'final_xy_duty_factors':
            desc = np.concatenate([desc, np.asarray(outcome.duty_factors, dtype=np.float64)])
        return EvaluationResult(valid, float(arc_fitness(gr)) if valid else -np.inf, desc, gr)

    def settings(self) -> dict:
        """The simulator settings an archive built with this evaluator must record."""
        from sim_bridge.settings import simulator_settings

        return dict(simulator_settings(self.dt, self.gait_duration, self.solver_iterations,
                                       robot=self.description()))


class HexapodEvaluator(RobotEvaluator):
    """:class:`RobotEvaluator` of the hexapod."""

    def __init__(self, dt: float = 1.0 / 240.0, gait_duration: float = 3.0,
                 damage: str = 'intact', solver_iterations: int = 50,
                 descriptor: str = 'final_xy'):
        super().__init__(dt, gait_duration, damage, solver_iterations, descriptor, 'hexapod')
