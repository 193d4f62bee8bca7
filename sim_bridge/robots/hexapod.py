"""The hexapod (Cully et al. 2015): 18 joints, six legs, 36 gait parameters.

Its body is :mod:`sim_bridge.model`, its controller :mod:`sim_bridge.controller`, its damage
names :data:`sim_bridge.damage.HEXAPOD`; see docs/hexapod.md.
"""
from __future__ import annotations

import os
import tempfile

import numpy as np

from sim_bridge import controller
from sim_bridge.damage import HEXAPOD as HEXAPOD_DAMAGES
from sim_bridge.damage import JOINT_NAMES, LEG_NAMES
from sim_bridge.robots import RobotDescription
from sim_bridge.settings import CONTROLLER_VERSION, MODEL_VERSION


def _model():
    # The body's module loads PyBullet: only when the robot is built or measured.
    from sim_bridge import model

    return model


class HexapodDescription(RobotDescription):
    """The hexapod of docs/hexapod.md."""

    name = 'hexapod'
    n_params = controller.N_PARAMS
    legs = LEG_NAMES
    joint_names = tuple(f'{leg}.{joint}' for leg in LEG_NAMES for joint in JOINT_NAMES)
    foot_links = tuple(f'{leg}.foot' for leg in LEG_NAMES)
    vocabulary = HEXAPOD_DAMAGES
    model_version = MODEL_VERSION
    controller_version = CONTROLLER_VERSION
    n_samples = controller.N_SAMPLES
    period = controller.PERIOD
    servo_time_constant = controller.SERVO_TIME_CONSTANT
    default_damage = 'remove:middle_right'
    archive = '8d'

    @property
    def settle_time(self):
        return _model().SETTLE_TIME

    @property
    def foot_friction(self):
        return _model().FOOT_FRICTION

    @property
    def ground_friction(self):
        return _model().GROUND_FRICTION

    @property
    def fall_tilt(self):
        return _model().FALL_TILT

    @property
    def fall_height(self):
        return _model().FALL_HEIGHT

    def max_force(self, joint_name: str) -> float:
        return _model().MAX_FORCE

    def urdf(self, damage='intact') -> str:
        return _model().hexapod_urdf(self.parse_damage(damage))

    def spawn(self, pybullet, client: int, spec) -> int:
        with tempfile.NamedTemporaryFile('w', suffix='.urdf', delete=False) as handle:
            handle.write(self.urdf(spec))
            path = handle.name
        try:
            return pybullet.loadURDF(path, [0, 0, _model().STANDING_HEIGHT + 0.002],
                                     flags=pybullet.URDF_USE_INERTIA_FROM_FILE,
                                     physicsClientId=client)
        finally:
            os.unlink(path)

    def target_table(self, params) -> np.ndarray:
        return controller.target_table(params)

    def sample_indices(self, n_steps: int, dt: float) -> np.ndarray:
        return controller.sample_indices(n_steps, dt)

    def stamp(self) -> dict:
        # The hexapod's maps predate the ``robot`` key: a map without one is the hexapod's.
        return {'controller_version': self.controller_version,
                'model_version': self.model_version}

    def example_gait(self) -> np.ndarray:
        return controller.tripod_gait()


HEXAPOD = HexapodDescription()
