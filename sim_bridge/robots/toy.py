"""A toy robot: a box on four stiff legs, one hip joint each (4 joints, 12 gait parameters).

It exists to show what a description is, and that a robot the stack did not know needs
nothing but its description and its map: its URDF is written here as text, its controller is
the hexapod's signal generator (one smoothed square wave per joint), its damages are the
grammar's kinds over its own leg names. It shuffles more than it walks.
"""
from __future__ import annotations

import os
import tempfile

import numpy as np

from sim_bridge import controller
from sim_bridge.damage import Vocabulary
from sim_bridge.robots import RobotDescription

LEGS = ('front_left', 'front_right', 'rear_left', 'rear_right')
HIP_LIMIT = 0.6  # rad
SWING = 0.4  # rad, the signal's full scale
BODY = (0.20, 0.12, 0.04)  # m
BODY_MASS, LEG_MASS = 0.6, 0.05  # kg
LEG_LENGTH, FOOT_RADIUS = 0.08, 0.012  # m
MAX_FORCE = 1.5  # N m


def _inertia(mass, x, y, z):
    return (mass * (y * y + z * z) / 12, mass * (x * x + z * z) / 12,
            mass * (x * x + y * y) / 12)


def _link(name, mass, geometry, inertia, xyz='0 0 0'):
    ixx, iyy, izz = inertia
    return (f'  <link name="{name}"><inertial><origin xyz="{xyz}"/><mass value="{mass!r}"/>'
            f'<inertia ixx="{ixx!r}" ixy="0" ixz="0" iyy="{iyy!r}" iyz="0" izz="{izz!r}"/>'
            f'</inertial><visual><origin xyz="{xyz}"/><geometry>{geometry}</geometry></visual>'
            f'<collision><origin xyz="{xyz}"/><geometry>{geometry}</geometry></collision>'
            f'</link>\n')


class ToyDescription(RobotDescription):
    """Four legs, four hip joints about y (positive swings the foot backwards)."""

    name = 'toy'
    n_params = 12
    legs = LEGS
    joint_names = tuple(f'{leg}.hip' for leg in LEGS)
    foot_links = tuple(f'{leg}.foot' for leg in LEGS)
    vocabulary = Vocabulary(LEGS, ('hip',), {'hip': (-HIP_LIMIT, HIP_LIMIT)},
                            kinds=('intact', 'shorten', 'block', 'weaken', 'friction'))
    model_version = 'toy-v1'
    controller_version = 'toy-square-v1'
    n_samples = controller.N_SAMPLES
    period = 0.5
    fall_height = 0.01
    reach = 0.3
    default_damage = 'intact'

    def max_force(self, joint_name: str) -> float:
        return MAX_FORCE

    def urdf(self, damage='intact') -> str:
        spec = self.parse_damage(damage)
        lx, ly, lz = BODY
        parts = ['<?xml version="1.0"?>\n',
                 f'<!-- the toy robot of sim_bridge.robots.toy, damage: {spec.canonical()} -->\n',
                 '<robot name="sela_toy">\n',
                 _link('base_link', BODY_MASS, f'<box size="{lx} {ly} {lz}"/>',
                       _inertia(BODY_MASS, lx, ly, lz))]
        for leg in LEGS:
            x = lx / 2 if leg.startswith('front') else -lx / 2
            y = ly / 2 if leg.endswith('left') else -ly / 2
            length = LEG_LENGTH * spec.shorten_factor(leg)
            parts.append(_link(f'{leg}.leg', LEG_MASS,
                               f'<box size="0.015 0.015 {length!r}"/>',
                               _inertia(LEG_MASS, 0.015, 0.015, length),
                               xyz=f'0 0 {-length / 2!r}'))
            parts.append(_link(f'{leg}.foot', 0.01, f'<sphere radius="{FOOT_RADIUS}"/>',
                               (1e-6, 1e-6, 1e-6)))
            angle = spec.blocked_angle(leg, 'hip')
            hip = f'<origin xyz="{x!r} {y!r} {-lz / 2!r}"'
            if angle is None:
                parts.append(f'  <joint name="{leg}.hip" type="revolute"><parent link='
                             f'"base_link"/><child link="{leg}.leg"/>{hip}/><axis xyz="0 1 0"/>'
                             f'<limit lower="{-HIP_LIMIT}" upper="{HIP_LIMIT}" '
                             f'effort="{MAX_FORCE}" velocity="20"/></joint>\n')
            else:  # blocked: welded at its angle
                parts.append(f'  <joint name="{leg}.hip" type="fixed"><parent link='
                             f'"base_link"/><child link="{leg}.leg"/>{hip} '
                             f'rpy="0 {angle!r} 0"/></joint>\n')
            parts.append(f'  <joint name="{leg}.ankle" type="fixed"><parent link="{leg}.leg"/>'
                         f'<child link="{leg}.foot"/><origin xyz="0 0 {-length!r}"/>'
                         f'</joint>\n')
        parts.append('</robot>\n')
        return ''.join(parts)

    def spawn(self, pybullet, client: int, spec) -> int:
        with tempfile.NamedTemporaryFile('w', suffix='.urdf', delete=False) as handle:
            handle.write(self.urdf(spec))
            path = handle.name
        try:
            height = BODY[2] / 2 + LEG_LENGTH + FOOT_RADIUS + 0.002
            return pybullet.loadURDF(path, [0, 0, height],
                                     flags=pybullet.URDF_USE_INERTIA_FROM_FILE,
                                     physicsClientId=client)
        finally:
            os.unlink(path)

    def target_table(self, params) -> np.ndarray:
        p = self.validate_params(params).reshape(len(LEGS), 3)
        return (SWING * controller.control_signals(p[:, 0], p[:, 1], p[:, 2])).T

    def example_gait(self) -> np.ndarray:
        """Diagonal pairs half a period apart."""
        return np.array([1.0, 0.0, 0.5, 1.0, 0.5, 0.5, 1.0, 0.5, 0.5, 1.0, 0.0, 0.5])


TOY = ToyDescription()

__all__ = ['TOY', 'ToyDescription']
