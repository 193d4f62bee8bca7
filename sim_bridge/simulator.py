"""A legged robot in PyBullet with damage, executing open-loop periodic gaits; no ROS.

The robot is a description (:class:`sim_bridge.robots.RobotDescription`: the hexapod by
default): it loads the body, names the joints the controller drives and the feet whose
contacts make the duty factors, turns a parameter vector into a table of joint targets and
says when the robot has fallen. Frames follow REP-103: +x forward, +y left, +z up.

Each :class:`Simulator` owns a private DIRECT physics client, so several coexist in one
process. Outcomes are bitwise deterministic for a fixed ``dt``: every gait evaluation
from a standing start begins with ``restoreState`` of the same settled state.
"""
from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from sela_ros.core.geometry import generic_reward, quaternion_to_yaw
from sim_bridge.damage import DamageSpec
from sim_bridge.model import p
from sim_bridge.robots import RobotDescription, get_robot
from sim_bridge.settings import SIM_DEFAULTS, simulator_settings

# --------------------------------------------------------------------------- outcomes


@dataclass
class GaitOutcome:
    """What one gait did.

    Attributes:
        generic_reward: (dx, dy, dyaw) in the robot frame at the start of the gait,
            dyaw wrapped to (-pi, pi].
        start_pose, end_pose: (x, y, yaw) in the world (odom) frame.
        duty_factors: (legs,) fraction of steps each foot touched the ground (0 if removed).
        fallen: the robot had fallen (see :meth:`Simulator.is_fallen`) at the end.
        sim_time: total simulated time of the simulator at the end of the gait (s).
        standing_start: the gait started from the settled standing state (the robot built,
            reset or righted, no gait since): the start every archive gait was evaluated
            from; False: chained from where the last gait left the legs.
    """

    generic_reward: np.ndarray
    start_pose: np.ndarray
    end_pose: np.ndarray
    duty_factors: np.ndarray
    fallen: bool
    sim_time: float
    standing_start: bool = False


# --------------------------------------------------------------------------- simulator

StepCallback = Callable[[float, np.ndarray, np.ndarray, np.ndarray], None]


class Simulator:
    """A simulated robot, with damage that can change at run time.

    Args:
        dt: physics time step (s); fixed for the life of the instance.
        gait_duration: length of one gait (s).
        damage: damage spec string or :class:`DamageSpec` (the robot's damage names).
        gui: open the PyBullet GUI (needs a display) instead of headless DIRECT mode.
        solver_iterations: constraint-solver iterations per step (an archive's setting:
            see :func:`physics_settings`).
        robot: its description, or a name for :func:`sim_bridge.robots.get_robot` (default
            the hexapod).
    """

    def __init__(self, dt: float = SIM_DEFAULTS['dt'],
                 gait_duration: float = SIM_DEFAULTS['gait_duration'],
                 damage='intact', gui: bool = False,
                 solver_iterations: int = SIM_DEFAULTS['solver_iterations'],
                 robot: RobotDescription | str | None = None):
        self.description = get_robot(robot)
        self.settings = simulator_settings(dt, gait_duration, solver_iterations,
                                           robot=self.description)
        self.dt = self.settings['dt']
        self.gait_duration = self.settings['gait_duration']
        self.n_steps = int(round(self.gait_duration / self.dt))
        self._sample_index = self.description.sample_indices(self.n_steps, self.dt)
        spec = self.description.parse_damage(damage)
        if gui and not os.environ.get('DISPLAY') and not os.environ.get('WAYLAND_DISPLAY'):
            raise RuntimeError('gui=True needs a display (DISPLAY is not set); '
                               'use gui=False for headless DIRECT mode')
        self._client = p.connect(p.GUI if gui else p.DIRECT)
        self._owner = os.getpid()
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
        """Disconnect the private physics client (idempotent). Only the process that
        connected it does: a forked child holds a copy of the client, gone with the child."""
        if getattr(self, '_client', -1) >= 0:
            if getattr(self, '_owner', None) == os.getpid():
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
        p.changeDynamics(self._ground, -1, lateralFriction=self.description.ground_friction,
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
        description = self.description
        self._robot = description.spawn(p, cid, spec)
        self.damage = spec
        # The ground's friction is part of the damage (``friction:<coefficient>``).
        p.changeDynamics(self._ground, -1, physicsClientId=cid,
                         lateralFriction=description.ground_friction if spec.friction is None
                         else spec.friction)
        self._index_joints()
        for link in self._foot_links:
            if link >= 0:
                p.changeDynamics(self._robot, link, lateralFriction=description.foot_friction,
                                 physicsClientId=cid)
        # Disable the default motors of every joint; ours are set explicitly each step.
        n = p.getNumJoints(self._robot, physicsClientId=cid)
        p.setJointMotorControlArray(self._robot, list(range(n)), p.VELOCITY_CONTROL,
                                    targetVelocities=[0.0] * n, forces=[0.0] * n,
                                    physicsClientId=cid)
        standing = description.standing_targets()[self._active_columns]
        for _ in range(int(round(description.settle_time / self.dt))):
            self._servo(standing)
            p.stepSimulation(physicsClientId=cid)
        self._standing_state = p.saveState(physicsClientId=cid)
        self.standing = True  # settled, no gait run since (GaitOutcome.standing_start)
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
        description = self.description
        self._active_joints = []  # PyBullet joint indices we servo
        self._active_columns = []  # their columns in the description's target table
        self._joint_names = []
        self._joint_sources = []  # per reported joint: ('active', k) or ('blocked', angle)
        for col, name in enumerate(description.joint_names):
            if name not in by_name:
                continue
            j, jtype = by_name[name]
            self._joint_names.append(name)
            if jtype == p.JOINT_REVOLUTE:
                self._joint_sources.append(('active', len(self._active_joints)))
                self._active_joints.append(j)
                self._active_columns.append(col)
            else:
                self._joint_sources.append(
                    ('blocked', self.damage.blocked_angle(*description.joint_key(name))))
        self._foot_links = [link_by_name.get(link, -1) for link in description.foot_links]
        self._link_to_leg = {link: i for i, link in enumerate(self._foot_links) if link >= 0}
        self._forces = []
        for col in self._active_columns:
            name = description.joint_names[col]
            self._forces.append(description.max_force(name)
                                * self.damage.torque_share(*description.joint_key(name)))
        self._max_link = max(link_by_name.values()) if link_by_name else -1

    def _servo(self, targets: np.ndarray) -> np.ndarray:
        cid = self._client
        states = p.getJointStates(self._robot, self._active_joints, physicsClientId=cid)
        q = np.fromiter((s[0] for s in states), dtype=np.float64, count=len(states))
        velocity = (targets - q) * (1.0 / self.description.servo_time_constant)
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

    def reset(self, clock=False) -> None:
        """Put the robot back standing at the origin with yaw 0; sim_time keeps running
        (``clock``: it starts again at 0, as for a fresh robot)."""
        p.restoreState(self._standing_state, physicsClientId=self._client)
        self.standing = True
        if clock:
            self._sim_time = 0.0

    def right(self, duration: float = 0.0) -> None:
        """Get up where it lies: rebuilt standing at the current x, y and yaw (the damage
        kept); getting up takes ``duration`` seconds of sim time."""
        self.set_damage(self.damage)
        self._sim_time += max(0.0, float(duration))

    def set_damage(self, damage) -> DamageSpec:
        """Apply ``damage`` now: rebuild the body, standing, at the current x, y and yaw."""
        spec = self.description.parse_damage(damage)
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
        """The description's fall test (body tilted too far, or lying on the ground)."""
        pos, orn = self.base_pose_3d()
        return self.description.is_fallen(pos, orn)

    def execute(self, params, callback: StepCallback | None = None,
                callback_period: float = 0.02) -> GaitOutcome:
        """Run one gait from wherever the robot stands (no reset).

        Args:
            params: the description's gait parameters (``n_params`` numbers in [0, 1]).
            callback: called as ``callback(sim_time, pose, joint_positions,
                joint_velocities)`` every ``callback_period`` simulated seconds (and at the
                end of the gait); joint arrays follow :attr:`joint_names`.
            callback_period: seconds of simulated time between callbacks.

        Returns:
            The gait's :class:`GaitOutcome`.
        """
        table = self.description.target_table(params)
        return self.execute_targets(table[self._sample_index], callback, callback_period)

    def execute_targets(self, targets, callback: StepCallback | None = None,
                        callback_period: float = 0.02) -> GaitOutcome:
        """Run the joint targets of one physics step after another, as :meth:`execute`.

        Args:
            targets: (n_steps, len(description.joint_names)) targets in rad, one row per
                physics step, columns in the description's ``joint_names`` order (the joints
                the damage removed or blocked are not driven); the gait lasts
                ``n_steps * dt``.
            callback, callback_period: as :meth:`execute`.
        """
        targets = np.asarray(targets, dtype=np.float64)
        n_columns = len(self.description.joint_names)
        if targets.ndim != 2 or targets.shape[1] != n_columns or not len(targets):
            raise ValueError(f'targets must have shape (n_steps >= 1, {n_columns}), '
                             f'got {targets.shape}')
        if callback is not None and not (callback_period > 0 and math.isfinite(callback_period)):
            raise ValueError(f'callback_period must be > 0 s, got {callback_period}')
        cid = self._client
        robot = self._robot
        joints = self._active_joints
        forces = self._forces
        gain = 1.0 / self.description.servo_time_constant
        link_to_leg = self._link_to_leg
        ground = self._ground
        callback_every = (max(1, int(round(callback_period / self.dt)))
                          if callback is not None else 0)
        start_pose = self.pose()
        start_time = self._sim_time
        standing_start, self.standing = self.standing, False
        n_joints = len(joints)
        # Plain Python lists in the loop: for tens of numbers they beat numpy's call
        # overhead, and this loop runs hundreds of times per gait.
        row_of_step = targets[:, self._active_columns].tolist()
        n_steps = len(row_of_step)
        get_states = p.getJointStates
        set_motors = p.setJointMotorControlArray
        step = p.stepSimulation
        get_contacts = p.getContactPoints
        vel_mode = p.VELOCITY_CONTROL
        n_legs = len(self.description.legs)
        contact_steps = [0] * n_legs
        for k in range(n_steps):
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
        self._sim_time = start_time + n_steps * self.dt
        end_pose = self.pose()
        if callback_every and n_steps % callback_every:
            pos, vel = self.joint_states()
            callback(self._sim_time, end_pose, pos, vel)
        return GaitOutcome(
            generic_reward=generic_reward(start_pose, end_pose),
            start_pose=start_pose,
            end_pose=end_pose,
            duty_factors=np.array(contact_steps, dtype=np.float64) / n_steps,
            fallen=self.is_fallen(),
            sim_time=self._sim_time,
            standing_start=standing_start,
        )
