"""The hexapod's body: geometry, masses, actuator and contact physics, and its URDF.

The URDF is generated as text for a damage (removed legs are absent, blocked joints are
welded); :class:`sim_bridge.hexapod.Hexapod` loads it into PyBullet, and sim_bridge's node
publishes it as ``robot_description``. This module imports PyBullet (quietly) for the whole
package: :mod:`sim_bridge.hexapod` uses the same handle.
"""
from __future__ import annotations

import math
import os


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

from sim_bridge.damage import JOINT_LIMITS, JOINT_NAMES, LEG_NAMES, parse_damage  # noqa: E402
from sim_bridge.settings import MODEL_VERSION  # noqa: E402

# The intact model as a file, for robot_state_publisher / RViz; regenerate with
# ``python -c "from sim_bridge.model import write_urdf; write_urdf()"`` when the model changes.
URDF_PATH = os.path.join(os.path.dirname(os.path.abspath(__file__)), 'urdf', 'hexapod.urdf')

ALL_JOINT_NAMES = tuple(f'{leg}.{joint}' for leg in LEG_NAMES for joint in JOINT_NAMES)

# Geometry and masses (resibots pexod reference: body 1.03 kg, total 2.5 kg).
BODY_SIZE = (0.24, 0.20, 0.04)
BODY_MASS = 1.03
COXA_LENGTH, FEMUR_LENGTH, TIBIA_LENGTH, FOOT_LENGTH = 0.06, 0.085, 0.14, 0.025
SEGMENT_RADIUS = 0.01
# A payload (damage ``payload:<kg>@<x>,<y>``) is a block of this size on top of the body.
PAYLOAD_SIZE = (0.06, 0.06, 0.03)
# Most leg mass sits in the servos near the hip (yaw + pitch) and at the knee.
COXA_MASS, FEMUR_MASS, TIBIA_MASS, FOOT_MASS = 0.12, 0.08, 0.03, 0.015
# Hip mounts (x, |y|) and mount angle away from the lateral direction (rad, + = forward)
# for front, middle, rear legs. Splaying front and rear legs by 45 deg lengthens the support
# polygon, as on pexod; without it the robot tips backwards when it accelerates.
HIP_MOUNTS = ((0.11, 0.09, math.pi / 4), (0.0, 0.10, 0.0), (-0.11, 0.09, -math.pi / 4))
STANDING_HEIGHT = TIBIA_LENGTH + FOOT_LENGTH

# Physics settings, fixed so that archives stay comparable (the solver's iterations and dt
# are settings stamped in archives instead: see sim_bridge.settings).
MAX_FORCE = 2.5  # N m, about a Dynamixel MX-28 stall torque
FOOT_FRICTION = 1.0
GROUND_FRICTION = 1.0
SETTLE_TIME = 0.5
FALL_TILT = math.radians(60.0)
FALL_HEIGHT = 0.03


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

    Links: ``base_link``, ``<leg>.coxa``, ``<leg>.femur``, ``<leg>.tibia``, ``<leg>.foot``,
    and ``payload`` when the damage fixes one on the body (the ground's friction is set by
    :class:`sim_bridge.hexapod.Hexapod`, not in the URDF).
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
    if spec.payload is not None:
        kg, x, y = spec.payload
        px, py, pz = PAYLOAD_SIZE
        parts.append(_link('payload', kg, (kg * (py**2 + pz**2) / 12, kg * (px**2 + pz**2) / 12,
                                           kg * (px**2 + py**2) / 12),
                           f'<box size="{px} {py} {pz}"/>'))
        parts.append(f'  <joint name="payload_joint" type="fixed"><parent link="base_link"/>'
                     f'<child link="payload"/><origin xyz="{x!r} {y!r} {(lz + pz) / 2!r}"/>'
                     f'</joint>\n')
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
