"""The simulated hexapod (18 DOF) with damage, executing Cully et al. gaits; no ROS.

Legs, in index order 0..5: ``front_left, middle_left, rear_left, front_right, middle_right,
rear_right``; joints ``<leg>.hip_yaw``, ``<leg>.hip_pitch``, ``<leg>.knee``. Sign conventions
are the same on both sides: positive hip_yaw swings the foot forward, positive hip_pitch
raises the femur, positive knee swings the foot outwards. See ``docs/hexapod.md``; its
description is :data:`sim_bridge.robots.hexapod.HEXAPOD`.
"""
from __future__ import annotations

from sela_ros.core.geometry import generic_reward
from sim_bridge.robots.hexapod import HEXAPOD
from sim_bridge.settings import SIM_DEFAULTS
from sim_bridge.simulator import GaitOutcome, Simulator, StepCallback

__all__ = ['GaitOutcome', 'Hexapod', 'StepCallback', 'generic_reward']


class Hexapod(Simulator):
    """The simulated hexapod (:class:`Simulator` with the hexapod's description)."""

    def __init__(self, dt: float = SIM_DEFAULTS['dt'],
                 gait_duration: float = SIM_DEFAULTS['gait_duration'],
                 damage='intact', gui: bool = False,
                 solver_iterations: int = SIM_DEFAULTS['solver_iterations']):
        super().__init__(dt=dt, gait_duration=gait_duration, damage=damage, gui=gui,
                         solver_iterations=solver_iterations, robot=HEXAPOD)
