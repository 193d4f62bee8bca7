"""A robot is a description: everything the stack knows of one robot, behind one interface.

A :class:`RobotDescription` gives the simulator (:class:`sim_bridge.simulator.Simulator`), the
map builder, the nodes and the experiments what they need of a robot: its URDF and how it is
loaded, its joints and legs, the open-loop gait controller that turns a parameter vector into
a table of joint targets over one period, its standing pose, its fall test, its damages (the
kinds and the leg and joint names they take), its behaviour descriptor (final x, y and one
duty factor per leg) and the settings stamped in its maps. Nothing outside a description
names a robot: sizes (parameters, descriptor dimensions) come from here or from an archive.

Descriptions are found by name (:data:`ROBOTS`) or as ``module:attribute``, imported when
asked for, so reading this module loads neither PyBullet nor any robot.

No PyBullet at import time here or in a description's module: a description imports the
simulator's handle inside the methods that load the robot.
"""
from __future__ import annotations

import importlib
import math

import numpy as np

from sim_bridge import controller
from sim_bridge.damage import DamageSpec, Vocabulary, parse_damage

#: The robots the stack knows by name (``robot`` parameter, ``--robot`` options).
ROBOTS = {
    'hexapod': 'sim_bridge.robots.hexapod:HEXAPOD',
    'a1': 'sim_bridge.robots.a1:A1',
    'toy': 'sim_bridge.robots.toy:TOY',
}
DEFAULT_ROBOT = 'hexapod'

#: Descriptions found as ``module:attribute`` in this process, by their name: a map stamps
#: its robot's name only, and whoever loads the map finds the description by that name.
_IMPORTED: dict[str, str] = {}


class RobotDescription:
    """One robot, as the simulator, the map builder and the nodes need it.

    A subclass sets the class attributes and implements :meth:`spawn` and
    :meth:`target_table` (and :meth:`urdf` for ``robot_description``); the rest has defaults
    that suit a legged robot on flat ground.

    Attributes:
        name: the robot's name (``robot`` parameter, archive metadata ``robot``).
        n_params: length of one gait's parameter vector, each in [0, 1].
        legs: leg names, in the order of the duty factors of an outcome.
        joint_names: the URDF names of the joints the gait controller drives, in the order of
            the columns of :meth:`target_table`.
        foot_links: the URDF link of each leg (same order as ``legs``) whose contacts with the
            ground count for its duty factor.
        vocabulary: the names of its damages (:class:`sim_bridge.damage.Vocabulary`).
        model_version, controller_version: stamped in every map built for it.
        n_samples, period: the controller's table holds ``n_samples`` targets over ``period``
            seconds, played in a loop.
        servo_time_constant: the velocity servo ``(q* - q) / servo_time_constant``.
        settle_time: seconds the robot settles in its standing pose when built.
        foot_friction, ground_friction: lateral friction coefficients.
        fall_tilt: a body tilted more than this (rad) has fallen.
        fall_height: a base lower than this (m) has fallen.
        reach: the final ``|x|`` and ``|y|`` (m) a gait can reach, for the map's descriptor
            bounds.
        gait_duration: the default length of one gait (s).
        default_damage: the ``damage`` parameter's default on this robot.
        archive: the short name of its shipped map (``sela_ros.core.storage``'s
            ``SHIPPED_ARCHIVES``), '' when none is shipped.
    """

    name = ''
    n_params = 0
    legs: tuple[str, ...] = ()
    joint_names: tuple[str, ...] = ()
    foot_links: tuple[str, ...] = ()
    vocabulary: Vocabulary
    model_version = ''
    controller_version = ''
    n_samples = 100
    period = 1.0
    servo_time_constant = math.pi * 0.015
    settle_time = 0.5
    foot_friction = 1.0
    ground_friction = 1.0
    fall_tilt = math.radians(60.0)
    fall_height = 0.03
    reach = 0.45
    gait_duration = 3.0
    default_damage = 'intact'
    archive = ''

    # -- damage

    def parse_damage(self, spec) -> DamageSpec:
        """``spec`` parsed over this robot's names (:func:`sim_bridge.damage.parse_damage`)."""
        return parse_damage(spec, self.vocabulary, self.name)

    def joint_key(self, joint_name: str) -> tuple[str, str]:
        """``(leg, joint)`` of a URDF joint name, as damages name it (default ``leg.joint``)."""
        leg, _, joint = joint_name.partition('.')
        return leg, joint

    def max_force(self, joint_name: str) -> float:
        """The intact motor's force limit (N m) of a driven joint."""
        raise NotImplementedError

    # -- model

    def urdf(self, damage='intact') -> str:
        """URDF text of the robot with ``damage`` (published as ``robot_description``)."""
        raise NotImplementedError

    def spawn(self, pybullet, client: int, spec: DamageSpec) -> int:
        """Load the robot with damage ``spec`` into physics client ``client``, standing above
        the origin with yaw 0; return its body id. Blocked joints are fixed joints in the
        loaded model; the rest of ``joint_names`` are revolute."""
        raise NotImplementedError

    def standing_targets(self) -> np.ndarray:
        """``(len(joint_names),)`` joint targets of the standing pose (default all 0)."""
        return np.zeros(len(self.joint_names))

    # -- controller

    def validate_params(self, params) -> np.ndarray:
        """``params`` as a float64 array of shape ``(n_params,)`` in [0, 1], or ValueError."""
        return controller.validate_params(params, self.n_params)

    def target_table(self, params) -> np.ndarray:
        """``(n_samples, len(joint_names))`` joint targets of one period of gait ``params``."""
        raise NotImplementedError

    def sample_indices(self, n_steps: int, dt: float) -> np.ndarray:
        """The table row played at each physics step ``k`` (time ``k dt``)."""
        t = np.arange(n_steps, dtype=np.float64) * dt
        # The small epsilon keeps t = k/100 exactly on its own sample despite rounding.
        return (np.floor(t * (self.n_samples / self.period) + 1e-9).astype(np.int64)
                % self.n_samples)

    # -- outcome

    def is_fallen(self, position, orientation) -> bool:
        """Body tilted more than ``fall_tilt`` (or upside down), or lower than
        ``fall_height``; ``orientation`` is the base quaternion (x, y, z, w)."""
        x, y, _, _ = orientation
        up_z = 1.0 - 2.0 * (x * x + y * y)  # z component of the body z axis
        return up_z < math.cos(self.fall_tilt) or position[2] < self.fall_height

    @property
    def descriptor_dims(self) -> dict[str, int]:
        """Descriptor name -> dimensions: final (x, y), and with one duty factor per leg."""
        return {'final_xy': 2, 'final_xy_duty_factors': 2 + len(self.legs)}

    def descriptor_bounds(self) -> tuple[tuple[float, float], ...]:
        """Ranges of the duty-factor descriptor: final x, y within ``reach``, duty in [0, 1]."""
        return ((-self.reach, self.reach),) * 2 + ((0.0, 1.0),) * len(self.legs)

    def stamp(self) -> dict:
        """What every map of this robot records besides the physics (its settings stamp)."""
        return {'controller_version': self.controller_version,
                'model_version': self.model_version, 'robot': self.name}

    def example_gait(self) -> np.ndarray:
        """A gait that moves the intact robot (tests, benchmarks, the docs)."""
        raise NotImplementedError

    def __repr__(self):
        return f'<robot {self.name}: {self.n_params} parameters, {len(self.joint_names)} ' \
               f'joints, legs {", ".join(self.legs)}>'


def get_robot(robot=None) -> RobotDescription:
    """The description of ``robot``: a name of :data:`ROBOTS`, ``module:attribute``, a
    description (returned as is) or None (the hexapod).

    Raises:
        ValueError: no such robot.
    """
    if robot is None:
        robot = DEFAULT_ROBOT
    if isinstance(robot, RobotDescription):
        return robot
    if not isinstance(robot, str):
        raise ValueError(f'robot must be a name such as {DEFAULT_ROBOT!r}, got '
                         f'{type(robot).__name__}')
    target = ROBOTS.get(robot) or _IMPORTED.get(robot, robot)
    module_name, colon, attribute = target.partition(':')
    if not colon:
        raise ValueError(f'unknown robot {robot!r}; known robots: {", ".join(ROBOTS)} (or '
                         "'package.module:DESCRIPTION')")
    try:
        found = getattr(importlib.import_module(module_name), attribute)
    except (ImportError, AttributeError) as exc:
        raise ValueError(f'robot {robot!r}: cannot import {target}: {exc}') from None
    if isinstance(found, type) and issubclass(found, RobotDescription):
        found = found()
    if not isinstance(found, RobotDescription):
        raise ValueError(f'robot {robot!r}: {target} is not a RobotDescription')
    if found.name not in ROBOTS:
        _IMPORTED.setdefault(found.name, target)
    return found


def robot_spec(robot) -> str:
    """What finds ``robot`` (as :func:`get_robot` takes it) in any process, a worker's too:
    a name of :data:`ROBOTS`, else the ``module:attribute`` its description was found as.

    Raises:
        ValueError: no such robot, or a description that no module attribute holds.
    """
    description = get_robot(robot)
    if description.name in ROBOTS:
        return description.name
    if description.name in _IMPORTED:
        return _IMPORTED[description.name]
    module = type(description).__module__
    for attribute, value in vars(importlib.import_module(module)).items():
        if value is description:
            return f'{module}:{attribute}'
    raise ValueError(f'robot {description.name!r}: no module attribute holds its description; '
                     "give it as 'package.module:DESCRIPTION'")


def robot_of(metadata: dict) -> str:
    """The robot an archive's metadata names (``robot``; a map without one is the
    hexapod's)."""
    return str(metadata.get('robot', DEFAULT_ROBOT))
