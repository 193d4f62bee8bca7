"""The Unitree A1 quadruped, from the URDF that ships in the installed ``pybullet_data``.

The model is read from ``pybullet_data.getDataPath()/a1/a1.urdf`` (never copied into this
repository); a damage edits the text before it is loaded: a blocked joint becomes a fixed
joint at its angle, a shortened lower leg has its calf and foot moved up. Legs, in order:
``front_left, front_right, rear_left, rear_right`` (URDF prefixes FL, FR, RL, RR); joints of
a leg: ``hip`` (abduction, about x), ``thigh`` and ``calf`` (about y; the calf bends backwards
with negative angles).

The gait controller is the hexapod's kind: open-loop and periodic, every joint following a
smoothed square wave (:func:`sim_bridge.controller.control_signals`) of its own amplitude,
phase and duty cycle, around the standing pose. 36 parameters: for leg ``l`` and joint ``j``
the triple ``params[9 l + 3 j : 9 l + 3 j + 3]``; targets ``stand[j] + scale[j] * s``.
"""
from __future__ import annotations

import os
import tempfile
import xml.etree.ElementTree as ET

import numpy as np

from sim_bridge import controller
from sim_bridge.damage import Vocabulary
from sim_bridge.robots import RobotDescription

LEGS = ('front_left', 'front_right', 'rear_left', 'rear_right')
PREFIX = {'front_left': 'FL', 'front_right': 'FR', 'rear_left': 'RL', 'rear_right': 'RR'}
JOINTS = ('hip', 'thigh', 'calf')
URDF_JOINT = {'hip': 'hip_joint', 'thigh': 'upper_joint', 'calf': 'lower_joint'}
#: Joint limits of the URDF (rad).
LIMITS = {'hip': (-0.802851455917, 0.802851455917), 'thigh': (-1.0471975512, 4.18879020479),
          'calf': (-2.69653369433, -0.916297857297)}
#: Standing pose and the swing of the controller's signal around it (rad).
STAND = {'hip': 0.0, 'thigh': 0.8, 'calf': -1.6}
SCALE = {'hip': 0.1, 'thigh': 0.3, 'calf': 0.3}
LOWER_LEG = 0.2  # m, knee to foot centre
STANDING_HEIGHT = 0.30  # m, the base above the ground, standing (it settles a few mm lower)


def urdf_directory() -> str:
    """The folder of the A1's URDF in the installed ``pybullet_data``."""
    import pybullet_data

    return os.path.join(pybullet_data.getDataPath(), 'a1')


class A1Description(RobotDescription):
    """The Unitree A1 (12 joints, four legs) with the open-loop periodic gait family."""

    name = 'a1'
    n_params = 36
    legs = LEGS
    joint_names = tuple(f'{PREFIX[leg]}_{URDF_JOINT[joint]}' for leg in LEGS
                        for joint in JOINTS)
    foot_links = tuple(f'{PREFIX[leg]}_toe' for leg in LEGS)
    vocabulary = Vocabulary(LEGS, JOINTS, LIMITS, block_default=dict(STAND),
                            kinds=('intact', 'shorten', 'block', 'weaken', 'friction'))
    model_version = 'a1-pybullet-data-v1'
    controller_version = 'a1-periodic-v1'
    n_samples = controller.N_SAMPLES
    period = 1.0
    fall_height = 0.12
    reach = 0.6
    default_damage = 'block:rear_right.calf'
    archive = 'a1'

    def joint_key(self, joint_name: str) -> tuple[str, str]:
        prefix, _, rest = joint_name.partition('_')
        leg = next(leg for leg, p in PREFIX.items() if p == prefix)
        joint = next(j for j, u in URDF_JOINT.items() if u == rest)
        return leg, joint

    def max_force(self, joint_name: str) -> float:
        return self._efforts()[joint_name]

    def _efforts(self) -> dict:
        if not hasattr(self, '_effort_cache'):
            root = ET.parse(os.path.join(urdf_directory(), 'a1.urdf')).getroot()
            self._effort_cache = {j.get('name'): float(j.find('limit').get('effort'))
                                  for j in root.findall('joint') if j.get('type') == 'revolute'}
        return self._effort_cache

    def urdf(self, damage='intact') -> str:
        spec = self.parse_damage(damage)
        folder = urdf_directory()
        root = ET.parse(os.path.join(folder, 'a1.urdf')).getroot()
        for mesh in root.iter('mesh'):  # absolute, so that the edited text loads from anywhere
            mesh.set('filename', os.path.join(folder, mesh.get('filename')))
        joints = {j.get('name'): j for j in root.findall('joint')}  # not transmissions'
        links = {link.get('name'): link for link in root.findall('link')}
        for leg, factor in spec.shortened:
            _shorten(links[f'{PREFIX[leg]}_lower'], joints[f'{PREFIX[leg]}_toe_fixed'], factor)
        for leg, joint, angle in spec.blocked:
            _weld(joints[f'{PREFIX[leg]}_{URDF_JOINT[joint]}'], angle)
        comment = ET.Comment(f' the Unitree A1 of pybullet_data, damage: {spec.canonical()} ')
        root.insert(0, comment)
        return ET.tostring(root, encoding='unicode')

    def spawn(self, pybullet, client: int, spec) -> int:
        with tempfile.NamedTemporaryFile('w', suffix='.urdf', delete=False) as handle:
            handle.write(self.urdf(spec))
            path = handle.name
        try:
            body = pybullet.loadURDF(path, [0, 0, STANDING_HEIGHT],
                                     flags=pybullet.URDF_USE_INERTIA_FROM_FILE,
                                     physicsClientId=client)
        finally:
            os.unlink(path)
        # Legs folded into the standing pose before the robot settles on them.
        for j in range(pybullet.getNumJoints(body, physicsClientId=client)):
            info = pybullet.getJointInfo(body, j, physicsClientId=client)
            if info[2] == pybullet.JOINT_REVOLUTE:
                _, joint = self.joint_key(info[1].decode())
                pybullet.resetJointState(body, j, STAND[joint], physicsClientId=client)
        return body

    def standing_targets(self) -> np.ndarray:
        return np.array([STAND[joint] for _ in LEGS for joint in JOINTS])

    def target_table(self, params) -> np.ndarray:
        p = self.validate_params(params).reshape(len(LEGS) * len(JOINTS), 3)
        signals = controller.control_signals(p[:, 0], p[:, 1], p[:, 2])
        stand = self.standing_targets()
        scale = np.array([SCALE[joint] for _ in LEGS for joint in JOINTS])
        return (stand[:, None] + scale[:, None] * signals).T

    def example_gait(self) -> np.ndarray:
        """A trot: diagonal pairs (front_left with rear_right) half a period apart, each foot
        lifted (calf bent) while its thigh swings forward."""
        p = np.zeros(self.n_params)
        for index, leg in enumerate(LEGS):
            offset = 0.0 if leg in ('front_left', 'rear_right') else 0.5
            base = 9 * index
            p[base:base + 3] = (0.0, 0.0, 0.5)  # hip: still
            p[base + 3:base + 6] = (0.35, offset, 0.5)  # thigh: forward while up
            p[base + 6:base + 9] = (0.35, (offset + 0.25) % 1.0, 0.5)  # calf: bent mid-swing
        return p


def _shorten(lower_link, toe_joint, factor: float) -> None:
    """The calf's length times ``factor``: its collision box, its visual and its foot."""
    for element in lower_link.iter('collision'):
        origin, box = element.find('origin'), element.find('geometry/box')
        origin.set('xyz', f'0 0 {-LOWER_LEG / 2 * factor!r}')
        sizes = box.get('size').split()
        box.set('size', ' '.join([repr(float(sizes[0]) * factor), *sizes[1:]]))
    for mesh in lower_link.iter('mesh'):
        mesh.set('scale', f'1 1 {factor!r}')
    inertial = lower_link.find('inertial/origin')
    x, y, z = (float(v) for v in inertial.get('xyz').split())
    inertial.set('xyz', f'{x!r} {y!r} {z * factor!r}')
    toe_joint.find('origin').set('xyz', f'0 0 {-LOWER_LEG * factor!r}')


def _weld(joint, angle: float) -> None:
    """A revolute joint about a coordinate axis becomes a fixed one at ``angle``."""
    axis = [float(v) for v in joint.find('axis').get('xyz').split()]
    origin = joint.find('origin')
    rpy = [float(v) for v in origin.get('rpy').split()]
    if any(rpy) or sorted(map(abs, axis)) != [0.0, 0.0, 1.0]:
        raise ValueError(f'joint {joint.get("name")}: only a joint about a coordinate axis of '
                         'an unrotated frame can be blocked')
    origin.set('rpy', ' '.join(repr(a * angle) for a in axis))
    joint.set('type', 'fixed')
    for tag in ('axis', 'limit', 'dynamics'):
        for child in joint.findall(tag):
            joint.remove(child)


A1 = A1Description()

__all__ = ['A1', 'A1Description', 'urdf_directory']
