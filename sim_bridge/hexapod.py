"""PyBullet hexapod (18 DOF) with damage, executing Cully et al. gaits; no ROS.

Frames follow REP-103: +x forward, +y left, +z up. Legs, in index order 0..5:
``front_left, middle_left, rear_left, front_right, middle_right, rear_right``; joints
``<leg>.hip_yaw``, ``<leg>.hip_pitch``, ``<leg>.knee``. Sign conventions are the same on
both sides: positive hip_yaw swings the foot forward, positive hip_pitch raises the
femur, positive knee swings the foot outwards. See ``docs/hexapod.md``.

Each :class:`Hexapod` owns a private DIRECT physics client, so several coexist in one
process. Outcomes are bitwise deterministic for a fixed ``dt``: every gait evaluation
from a standing start begins with ``restoreState`` of the same settled state.
"""
from __future__ import annotations

import json
import math
import os
import tempfile
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np


def _import_pybullet_quietly():
    """Import pybullet without its C-level "pybullet build time: ..." banner.

    A node's output is the user's terminal (and the demo's): the banner is noise. It is
    written at import time (on stderr with this build); file descriptors 1 and 2 point at
    /dev/null during the import, and libc's buffers are flushed before they are put back,
    so it cannot come out later either. A failed import still raises, after the restore.
    """
    import ctypes
    import sys

    sys.stdout.flush()
    sys.stderr.flush()
    saved = {fd: os.dup(fd) for fd in (1, 2)}
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        for fd in saved:
            os.dup2(devnull, fd)
        import pybullet
        ctypes.CDLL(None).fflush(None)
    finally:
        for fd, copy in saved.items():
            os.dup2(copy, fd)
            os.close(copy)
        os.close(devnull)
    return pybullet


p = _import_pybullet_quietly()

from sela_ros.core.geometry import generic_reward, quaternion_to_yaw  # noqa: E402
from sim_bridge import controller  # noqa: E402 - after the quiet import, on purpose
from sim_bridge.damage import (  # noqa: E402
    JOINT_LIMITS,
    JOINT_NAMES,
    LEG_NAMES,
    DamageSpec,
    parse_damage,
)

MODEL_VERSION = 'sela-hexapod-v1'
CONTROLLER_VERSION = controller.CONTROLLER_VERSION

# What an archive that predates a key was built with: a missing key means this value.
SIM_DEFAULTS = {
    'dt': 1.0 / 240.0,
    'gait_duration': 3.0,
    'controller_version': CONTROLLER_VERSION,
    'model_version': MODEL_VERSION,
    'solver_iterations': 50,
}

#: Physics of the 8-D map, chosen with benchmarks/bench_physics.py: over twice the
#: evaluations/s of the defaults, gaits ending a few cm from where the defaults put them.
FAST_SETTINGS = {'dt': 1.0 / 120.0, 'solver_iterations': 30}

# The intact model as a file, for robot_state_publisher / RViz; regenerate with
# ``python -c "from sim_bridge.hexapod import write_urdf; write_urdf()"`` when the model changes.
URDF_PATH = os.path.join(os.path.dirname(os.path.abspath(__file__)), 'urdf', 'hexapod.urdf')

ALL_JOINT_NAMES = tuple(f'{leg}.{joint}' for leg in LEG_NAMES for joint in JOINT_NAMES)

# Geometry and masses (resibots pexod reference: body 1.03 kg, total 2.5 kg).
BODY_SIZE = (0.24, 0.20, 0.04)
BODY_MASS = 1.03
COXA_LENGTH, FEMUR_LENGTH, TIBIA_LENGTH, FOOT_LENGTH = 0.06, 0.085, 0.14, 0.025
SEGMENT_RADIUS = 0.01
# Most leg mass sits in the servos near the hip (yaw + pitch) and at the knee.
COXA_MASS, FEMUR_MASS, TIBIA_MASS, FOOT_MASS = 0.12, 0.08, 0.03, 0.015
# Hip mounts (x, |y|) and mount angle away from the lateral direction (rad, + = forward)
# for front, middle, rear legs. Splaying front and rear legs by 45 deg lengthens the support
# polygon, as on pexod; without it the robot tips backwards when it accelerates.
HIP_MOUNTS = ((0.11, 0.09, math.pi / 4), (0.0, 0.10, 0.0), (-0.11, 0.09, -math.pi / 4))
STANDING_HEIGHT = TIBIA_LENGTH + FOOT_LENGTH

# Physics settings, fixed so that archives stay comparable (the solver's iterations and dt
# are settings stamped in archives instead: see simulator_settings).
MAX_FORCE = 2.5  # N m, about a Dynamixel MX-28 stall torque
FOOT_FRICTION = 1.0
GROUND_FRICTION = 1.0
SETTLE_TIME = 0.5
FALL_TILT = math.radians(60.0)
FALL_HEIGHT = 0.03


def simulator_settings(dt: float = SIM_DEFAULTS['dt'],
                       gait_duration: float = SIM_DEFAULTS['gait_duration'],
                       solver_iterations: int = SIM_DEFAULTS['solver_iterations']) -> dict:
    """Settings that make gait outcomes comparable; stamp archives with them.

    A longer dt and fewer solver iterations make evaluations cheaper but move where gaits
    end by centimetres, so an archive is only valid in a simulator with its own settings.
    """
    dt = float(dt)
    gait_duration = float(gait_duration)
    if not (math.isfinite(dt) and 0.0 < dt <= 0.01):
        raise ValueError(f'dt must be in (0, 0.01] s, got {dt}')
    if not (math.isfinite(gait_duration) and gait_duration > 0.0):
        raise ValueError(f'gait_duration must be > 0 s, got {gait_duration}')
    if isinstance(solver_iterations, bool) or not float(solver_iterations).is_integer() \
            or not 1 <= solver_iterations <= 1000:
        raise ValueError(f'solver_iterations must be an integer in [1, 1000], got '
                         f'{solver_iterations!r}')
    return {'dt': dt, 'gait_duration': gait_duration,
            'controller_version': CONTROLLER_VERSION, 'model_version': MODEL_VERSION,
            'solver_iterations': int(solver_iterations)}


def physics_settings(metadata: dict) -> dict:
    """Keyword arguments of :class:`Hexapod` for an archive's metadata (or settings dict).

    A key the archive predates takes the value it was built with (:data:`SIM_DEFAULTS`),
    so the shipped 2-D archive keeps running with 50 solver iterations.
    """
    return {key: metadata.get(key, SIM_DEFAULTS[key])
            for key in ('dt', 'gait_duration', 'solver_iterations')}


def read_archive_settings(path: str | os.PathLike) -> dict:
    """:func:`physics_settings` of the archive file at ``path`` (from its JSON metadata).

    sim_bridge reads the stamp itself rather than through sela_ros, which sits above it.

    Raises:
        ValueError: no such file, or no readable metadata in it.
    """
    try:
        with np.load(path, allow_pickle=False) as npz:
            metadata = json.loads(str(npz['metadata']))
    except Exception as exc:
        raise ValueError(f'cannot read the simulator settings of archive {path}: '
                         f'{type(exc).__name__}: {exc}') from None
    if not isinstance(metadata, dict):
        raise ValueError(f'archive {path}: metadata is not a JSON object')
    return physics_settings(metadata)


# --------------------------------------------------------------------------- URDF


def _cylinder_inertia(mass, radius, length):
    axial = 0.5 * mass * radius**2
    transverse = mass * (3 * radius**2 + length**2) / 12.0
    return axial, transverse


def _link(name, mass, inertia, visual_collision, origin='0 0 0', rpy='0 0 0'):
    ixx, iyy, izz = inertia
    return (f'  <link name="{name}">\n'
            f'    <inertial><origin xyz="{origin}" rpy="0 0 0"/><mass value="{mass!r}"/>'
            f'<inertia ixx="{ixx!r}" ixy="0" ixz="0" iyy="{iyy!r}" iyz="0" izz="{izz!r}"/>'
            f'</inertial>\n'
            f'    <visual><origin xyz="{origin}" rpy="{rpy}"/>'
            f'<geometry>{visual_collision}</geometry></visual>\n'
            f'    <collision><origin xyz="{origin}" rpy="{rpy}"/>'
            f'<geometry>{visual_collision}</geometry></collision>\n'
            f'  </link>\n')


def _joint(name, parent, child, xyz, axis, limit, rpy='0 0 0', fixed_angle=None):
    if fixed_angle is not None:
        # A blocked joint is welded at its angle: exact, and nothing to servo.
        ax = [float(v) for v in axis.split()]
        base = p.getQuaternionFromEuler([float(v) for v in rpy.split()])
        lock = p.getQuaternionFromAxisAngle(ax, fixed_angle)
        _, orn = p.multiplyTransforms([0, 0, 0], base, [0, 0, 0], lock)
        rpy = ' '.join(repr(float(v)) for v in p.getEulerFromQuaternion(orn))
        return (f'  <joint name="{name}" type="fixed"><parent link="{parent}"/>'
                f'<child link="{child}"/><origin xyz="{xyz}" rpy="{rpy}"/></joint>\n')
    return (f'  <joint name="{name}" type="revolute"><parent link="{parent}"/>'
            f'<child link="{child}"/><origin xyz="{xyz}" rpy="{rpy}"/><axis xyz="{axis}"/>'
            f'<limit lower="{-limit!r}" upper="{limit!r}" effort="{MAX_FORCE!r}" '
            f'velocity="100.0"/></joint>\n')


def hexapod_urdf(damage='intact') -> str:
    """URDF text of the hexapod with ``damage`` applied (removed legs are absent).

    Links: ``base_link``, ``<leg>.coxa``, ``<leg>.femur``, ``<leg>.tibia``, ``<leg>.foot``.
    Each hip_yaw joint frame is turned so that its +x points away from the body along the
    leg, so the same axes serve both sides.
    """
    spec = parse_damage(damage)
    lx, ly, lz = BODY_SIZE
    body_inertia = (BODY_MASS * (ly**2 + lz**2) / 12, BODY_MASS * (lx**2 + lz**2) / 12,
                    BODY_MASS * (lx**2 + ly**2) / 12)
    parts = ['<?xml version="1.0"?>\n',
             f'<!-- generated by sim_bridge.hexapod ({MODEL_VERSION}), '
             f'damage: {spec.canonical()} -->\n',
             '<robot name="sela_hexapod">\n',
             _link('base_link', BODY_MASS, body_inertia, f'<box size="{lx} {ly} {lz}"/>')]
    r = SEGMENT_RADIUS
    for index, leg in enumerate(LEG_NAMES):
        if leg in spec.removed:
            continue
        left = index < 3
        hip_x, hip_y, splay = HIP_MOUNTS[index % 3]
        mount_yaw = math.pi / 2 - splay if left else -math.pi / 2 + splay
        yaw_axis = '0 0 -1' if left else '0 0 1'
        factor = spec.shorten_factor(leg)
        tibia = TIBIA_LENGTH * factor
        foot = FOOT_LENGTH * factor
        hip_xyz = f'{hip_x!r} {(hip_y if left else -hip_y)!r} 0'
        a, t = _cylinder_inertia(COXA_MASS, r, COXA_LENGTH)
        parts.append(_link(f'{leg}.coxa', COXA_MASS, (a, t, t),
                           f'<cylinder radius="{r}" length="{COXA_LENGTH}"/>',
                           origin=f'{COXA_LENGTH / 2!r} 0 0', rpy=f'0 {math.pi / 2!r} 0'))
        a, t = _cylinder_inertia(FEMUR_MASS, r, FEMUR_LENGTH)
        parts.append(_link(f'{leg}.femur', FEMUR_MASS, (a, t, t),
                           f'<cylinder radius="{r}" length="{FEMUR_LENGTH}"/>',
                           origin=f'{FEMUR_LENGTH / 2!r} 0 0', rpy=f'0 {math.pi / 2!r} 0'))
        a, t = _cylinder_inertia(TIBIA_MASS, r, tibia)
        parts.append(_link(f'{leg}.tibia', TIBIA_MASS, (t, t, a),
                           f'<cylinder radius="{r}" length="{tibia!r}"/>',
                           origin=f'0 0 {-tibia / 2!r}'))
        foot_radius = foot / 2
        i_foot = 0.4 * FOOT_MASS * foot_radius**2
        parts.append(_link(f'{leg}.foot', FOOT_MASS, (i_foot, i_foot, i_foot),
                           f'<sphere radius="{foot_radius!r}"/>'))
        parts.append(_joint(f'{leg}.hip_yaw', 'base_link', f'{leg}.coxa', hip_xyz,
                            yaw_axis, JOINT_LIMITS['hip_yaw'], rpy=f'0 0 {mount_yaw!r}',
                            fixed_angle=spec.blocked_angle(leg, 'hip_yaw')))
        parts.append(_joint(f'{leg}.hip_pitch', f'{leg}.coxa', f'{leg}.femur',
                            f'{COXA_LENGTH!r} 0 0', '0 -1 0', JOINT_LIMITS['hip_pitch'],
                            fixed_angle=spec.blocked_angle(leg, 'hip_pitch')))
        parts.append(_joint(f'{leg}.knee', f'{leg}.femur', f'{leg}.tibia',
                            f'{FEMUR_LENGTH!r} 0 0', '0 -1 0', JOINT_LIMITS['knee'],
                            fixed_angle=spec.blocked_angle(leg, 'knee')))
        parts.append(f'  <joint name="{leg}.foot_joint" type="fixed"><parent link="{leg}.tibia"/>'
                     f'<child link="{leg}.foot"/><origin xyz="0 0 {-(tibia + foot_radius)!r}"/>'
                     f'</joint>\n')
    parts.append('</robot>\n')
    return ''.join(parts)


def write_urdf(path: str = URDF_PATH, damage='intact') -> str:
    """Write :func:`hexapod_urdf` to ``path``; return the path."""
    with open(path, 'w', encoding='utf-8') as handle:
        handle.write(hexapod_urdf(damage))
    return path


# --------------------------------------------------------------------------- outcomes


@dataclass
class GaitOutcome:
    """What one gait did.

    Attributes:
        generic_reward: (dx, dy, dyaw) in the robot frame at the start of the gait,
            dyaw wrapped to (-pi, pi].
        start_pose, end_pose: (x, y, yaw) in the world (odom) frame.
        duty_factors: (6,) fraction of steps each foot touched the ground (0 if removed).
        fallen: the robot had fallen (see :meth:`Hexapod.is_fallen`) at the end.
        sim_time: total simulated time of the simulator at the end of the gait (s).
    """

    generic_reward: np.ndarray
    start_pose: np.ndarray
    end_pose: np.ndarray
    duty_factors: np.ndarray
    fallen: bool
    sim_time: float


# --------------------------------------------------------------------------- simulator

StepCallback = Callable[[float, np.ndarray, np.ndarray, np.ndarray], None]


class Hexapod:
    """The simulated hexapod, with damage that can change at run time.

    Args:
        dt: physics time step (s); fixed for the life of the instance.
        gait_duration: length of one gait (s).
        damage: damage spec string or :class:`DamageSpec` (see ``sim_bridge.damage``).
        gui: open the PyBullet GUI (needs a display) instead of headless DIRECT mode.
        solver_iterations: constraint-solver iterations per step (an archive's setting:
            see :func:`physics_settings`).
    """

    def __init__(self, dt: float = SIM_DEFAULTS['dt'],
                 gait_duration: float = SIM_DEFAULTS['gait_duration'],
                 damage='intact', gui: bool = False,
                 solver_iterations: int = SIM_DEFAULTS['solver_iterations']):
        self.settings = simulator_settings(dt, gait_duration, solver_iterations)
        self.dt = self.settings['dt']
        self.gait_duration = self.settings['gait_duration']
        self.n_steps = int(round(self.gait_duration / self.dt))
        self._sample_index = controller.sample_indices(self.n_steps, self.dt)
        spec = parse_damage(damage)
        if gui and not os.environ.get('DISPLAY') and not os.environ.get('WAYLAND_DISPLAY'):
            raise RuntimeError('gui=True needs a display (DISPLAY is not set); '
                               'use gui=False for headless DIRECT mode')
        self._client = p.connect(p.GUI if gui else p.DIRECT)
        if self._client < 0:
            raise RuntimeError('could not connect to a PyBullet physics server')
        self._sim_time = 0.0
        self._robot = None
        self._standing_state = None
        try:
            self._setup_world()
            self._build(spec)
        except BaseException:
            self.close()
            raise

    # -- life cycle

    def close(self) -> None:
        """Disconnect the private physics client (idempotent)."""
        if getattr(self, '_client', -1) >= 0:
            try:
                p.disconnect(physicsClientId=self._client)
            except p.error:
                pass
            self._client = -1

    def __del__(self):
        self.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def _setup_world(self) -> None:
        cid = self._client
        p.resetSimulation(physicsClientId=cid)
        p.setGravity(0, 0, -9.81, physicsClientId=cid)
        p.setPhysicsEngineParameter(fixedTimeStep=self.dt, numSubSteps=0,
                                    numSolverIterations=self.settings['solver_iterations'],
                                    deterministicOverlappingPairs=1, physicsClientId=cid)
        plane = p.createCollisionShape(p.GEOM_PLANE, physicsClientId=cid)
        self._ground = p.createMultiBody(0, plane, physicsClientId=cid)
        p.changeDynamics(self._ground, -1, lateralFriction=GROUND_FRICTION,
                         physicsClientId=cid)

    def _build(self, spec: DamageSpec, pose=(0.0, 0.0, 0.0)) -> None:
        """(Re)build the robot for ``spec``, settle it at the origin, then place it at pose."""
        cid = self._client
        if self._standing_state is not None:
            p.removeState(self._standing_state, physicsClientId=cid)
            self._standing_state = None
        if self._robot is not None:
            p.removeBody(self._robot, physicsClientId=cid)
            self._robot = None
        with tempfile.NamedTemporaryFile('w', suffix='.urdf', delete=False) as handle:
            handle.write(hexapod_urdf(spec))
            path = handle.name
        try:
            self._robot = p.loadURDF(path, [0, 0, STANDING_HEIGHT + 0.002],
                                     flags=p.URDF_USE_INERTIA_FROM_FILE, physicsClientId=cid)
        finally:
            os.unlink(path)
        self.damage = spec
        self._index_joints()
        for link in self._foot_links:
            if link >= 0:
                p.changeDynamics(self._robot, link, lateralFriction=FOOT_FRICTION,
                                 physicsClientId=cid)
        # Disable the default motors of every joint; ours are set explicitly each step.
        n = p.getNumJoints(self._robot, physicsClientId=cid)
        p.setJointMotorControlArray(self._robot, list(range(n)), p.VELOCITY_CONTROL,
                                    targetVelocities=[0.0] * n, forces=[0.0] * n,
                                    physicsClientId=cid)
        zero = np.zeros(len(self._active_columns))
        for _ in range(int(round(SETTLE_TIME / self.dt))):
            self._servo(zero)
            p.stepSimulation(physicsClientId=cid)
        self._standing_state = p.saveState(physicsClientId=cid)
        if any(pose):
            self._place(pose)

    def _index_joints(self) -> None:
        cid = self._client
        by_name = {}
        link_by_name = {}
        for j in range(p.getNumJoints(self._robot, physicsClientId=cid)):
            info = p.getJointInfo(self._robot, j, physicsClientId=cid)
            by_name[info[1].decode()] = (j, info[2])
            link_by_name[info[12].decode()] = j
        self._active_joints = []  # PyBullet joint indices we servo
        self._active_columns = []  # their columns in the (100, 18) target table
        self._joint_names = []
        self._joint_sources = []  # per reported joint: ('active', k) or ('blocked', angle)
        for col, name in enumerate(ALL_JOINT_NAMES):
            if name not in by_name:
                continue
            j, jtype = by_name[name]
            self._joint_names.append(name)
            if jtype == p.JOINT_REVOLUTE:
                self._joint_sources.append(('active', len(self._active_joints)))
                self._active_joints.append(j)
                self._active_columns.append(col)
            else:
                leg, joint = name.split('.')
                self._joint_sources.append(('blocked', self.damage.blocked_angle(leg, joint)))
        self._foot_links = [link_by_name.get(f'{leg}.foot', -1) for leg in LEG_NAMES]
        self._link_to_leg = {link: i for i, link in enumerate(self._foot_links) if link >= 0}
        self._forces = [MAX_FORCE] * len(self._active_joints)
        self._max_link = max(link_by_name.values()) if link_by_name else -1

    def _servo(self, targets: np.ndarray) -> np.ndarray:
        cid = self._client
        states = p.getJointStates(self._robot, self._active_joints, physicsClientId=cid)
        q = np.fromiter((s[0] for s in states), dtype=np.float64, count=len(states))
        velocity = (targets - q) * (1.0 / controller.SERVO_TIME_CONSTANT)
        p.setJointMotorControlArray(self._robot, self._active_joints, p.VELOCITY_CONTROL,
                                    targetVelocities=velocity.tolist(), forces=self._forces,
                                    physicsClientId=cid)
        return q

    def _place(self, pose) -> None:
        """Move the (standing) robot rigidly to world pose (x, y, yaw)."""
        cid = self._client
        x, y, yaw = (float(v) for v in pose)
        pos, orn = p.getBasePositionAndOrientation(self._robot, physicsClientId=cid)
        cur_yaw = self._yaw(orn)
        turn = p.getQuaternionFromEuler([0, 0, yaw - cur_yaw])
        _, new_orn = p.multiplyTransforms([0, 0, 0], turn, [0, 0, 0], orn)
        p.resetBasePositionAndOrientation(self._robot, [x, y, pos[2]], new_orn,
                                          physicsClientId=cid)
        p.resetBaseVelocity(self._robot, [0, 0, 0], [0, 0, 0], physicsClientId=cid)

    # -- public API

    @property
    def client_id(self) -> int:
        return self._client

    @property
    def robot_id(self) -> int:
        return self._robot

    @property
    def sim_time(self) -> float:
        """Total simulated time spent executing gaits (s); settling is not counted."""
        return self._sim_time

    @property
    def joint_names(self) -> list[str]:
        """Joints of the current body (removed legs' joints are absent; blocked ones stay)."""
        return list(self._joint_names)

    def total_mass(self) -> float:
        """Mass of the current body (kg)."""
        cid = self._client
        return sum(p.getDynamicsInfo(self._robot, link, physicsClientId=cid)[0]
                   for link in range(-1, self._max_link + 1))

    def reset(self) -> None:
        """Put the robot back standing at the origin with yaw 0 (sim_time keeps running)."""
        p.restoreState(self._standing_state, physicsClientId=self._client)

    def set_damage(self, damage) -> DamageSpec:
        """Apply ``damage`` now: rebuild the body, standing, at the current x, y and yaw."""
        spec = parse_damage(damage)
        pose = self.pose()
        self._build(spec, pose=tuple(pose))
        return spec

    @staticmethod
    def _yaw(orn) -> float:
        return quaternion_to_yaw(*orn)

    def pose(self) -> np.ndarray:
        """(x, y, yaw) of base_link in the world frame."""
        pos, orn = p.getBasePositionAndOrientation(self._robot, physicsClientId=self._client)
        return np.array([pos[0], pos[1], self._yaw(orn)])

    def base_pose_3d(self) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """Full base position (x, y, z) and quaternion (x, y, z, w)."""
        return p.getBasePositionAndOrientation(self._robot, physicsClientId=self._client)

    def base_velocity(self) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """Base linear and angular velocity in the world frame."""
        return p.getBaseVelocity(self._robot, physicsClientId=self._client)

    def joint_states(self) -> tuple[np.ndarray, np.ndarray]:
        """Positions and velocities in :attr:`joint_names` order."""
        states = p.getJointStates(self._robot, self._active_joints,
                                  physicsClientId=self._client)
        pos = np.empty(len(self._joint_names))
        vel = np.zeros(len(self._joint_names))
        for i, (kind, value) in enumerate(self._joint_sources):
            if kind == 'active':
                pos[i] = states[value][0]
                vel[i] = states[value][1]
            else:
                pos[i] = value
        return pos, vel

    def is_fallen(self) -> bool:
        """Body tilted more than 60 deg (or upside down), or lying on the ground."""
        pos, orn = self.base_pose_3d()
        x, y, _, _ = orn
        up_z = 1.0 - 2.0 * (x * x + y * y)  # z component of the body z axis
        return up_z < math.cos(FALL_TILT) or pos[2] < FALL_HEIGHT

    def execute(self, params, callback: StepCallback | None = None,
                callback_period: float = 0.02) -> GaitOutcome:
        """Run one gait from wherever the robot stands (no reset).

        Args:
            params: 36 controller parameters in [0, 1].
            callback: called as ``callback(sim_time, pose, joint_positions,
                joint_velocities)`` every ``callback_period`` simulated seconds (and at the
                end of the gait); joint arrays follow :attr:`joint_names`.
            callback_period: seconds of simulated time between callbacks.

        Returns:
            The gait's :class:`GaitOutcome`.
        """
        table = controller.target_table(params)[:, self._active_columns]
        if callback is not None and not (callback_period > 0 and math.isfinite(callback_period)):
            raise ValueError(f'callback_period must be > 0 s, got {callback_period}')
        cid = self._client
        robot = self._robot
        joints = self._active_joints
        forces = self._forces
        gain = 1.0 / controller.SERVO_TIME_CONSTANT
        sample_index = self._sample_index
        link_to_leg = self._link_to_leg
        ground = self._ground
        callback_every = (max(1, int(round(callback_period / self.dt)))
                          if callback is not None else 0)
        start_pose = self.pose()
        start_time = self._sim_time
        n_joints = len(joints)
        # Plain Python lists in the loop: for 18 numbers they beat numpy's call overhead,
        # and this loop runs 720 times per gait.
        rows = table.tolist()
        row_of_step = [rows[i] for i in sample_index.tolist()]
        get_states = p.getJointStates
        set_motors = p.setJointMotorControlArray
        step = p.stepSimulation
        get_contacts = p.getContactPoints
        vel_mode = p.VELOCITY_CONTROL
        n_legs = len(LEG_NAMES)
        contact_steps = [0] * n_legs
        for k in range(self.n_steps):
            if n_joints:
                states = get_states(robot, joints, physicsClientId=cid)
                velocity = [(t - s[0]) * gain for t, s in zip(row_of_step[k], states)]
                set_motors(robot, joints, vel_mode, targetVelocities=velocity,
                           forces=forces, physicsClientId=cid)
            step(physicsClientId=cid)
            touching = 0
            for contact in get_contacts(robot, ground, physicsClientId=cid):
                leg = link_to_leg.get(contact[3])
                if leg is not None:
                    touching |= 1 << leg
            if touching:
                for leg in range(n_legs):
                    if touching >> leg & 1:
                        contact_steps[leg] += 1
            if callback_every and (k + 1) % callback_every == 0:
                self._sim_time = start_time + (k + 1) * self.dt
                pos, vel = self.joint_states()
                callback(self._sim_time, self.pose(), pos, vel)
        self._sim_time = start_time + self.n_steps * self.dt
        end_pose = self.pose()
        if callback_every and self.n_steps % callback_every:
            pos, vel = self.joint_states()
            callback(self._sim_time, end_pose, pos, vel)
        return GaitOutcome(
            generic_reward=generic_reward(start_pose, end_pose),
            start_pose=start_pose,
            end_pose=end_pose,
            duty_factors=np.array(contact_steps, dtype=np.float64) / self.n_steps,
            fallen=self.is_fallen(),
            sim_time=self._sim_time,
        )


# --------------------------------------------------------------------------- evaluate_gait

_CACHE: OrderedDict = OrderedDict()
_CACHE_SIZE = 4


def _cached_hexapod(damage, dt, gait_duration, solver_iterations) -> Hexapod:
    spec = parse_damage(damage)
    settings = simulator_settings(dt, gait_duration, solver_iterations)
    key = (spec, settings['dt'], settings['gait_duration'], settings['solver_iterations'])
    sim = _CACHE.get(key)
    if sim is None:
        sim = Hexapod(dt=settings['dt'], gait_duration=settings['gait_duration'], damage=spec,
                      solver_iterations=settings['solver_iterations'])
        _CACHE[key] = sim
        while len(_CACHE) > _CACHE_SIZE:
            _, old = _CACHE.popitem(last=False)
            old.close()
    else:
        _CACHE.move_to_end(key)
    return sim


def evaluate_gait(params, damage='intact', dt: float = SIM_DEFAULTS['dt'],
                  gait_duration: float = SIM_DEFAULTS['gait_duration'],
                  solver_iterations: int = SIM_DEFAULTS['solver_iterations']) -> GaitOutcome:
    """One gait from a fresh standing start at the origin (deterministic, picklable).

    Uses a per-process cache of simulators (one per damage/dt/duration, reset with
    ``restoreState``), so it is cheap to call many times in a worker process.
    ``sim_time`` of the outcome is the gait duration.
    """
    sim = _cached_hexapod(damage, dt, gait_duration, solver_iterations)
    sim.reset()
    sim._sim_time = 0.0
    return sim.execute(params)
