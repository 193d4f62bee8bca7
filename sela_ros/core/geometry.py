"""Planar geometry, written once: angles, yaw <-> quaternion, SE(2), the generic reward.

ROS-free. Poses are ``(x, y, yaw)`` in the odom frame; angles are wrapped to ``(-pi, pi]``
everywhere (the simulator's, the learner's and the map builder's convention alike).
"""
import math

import numpy as np

TWO_PI = 2.0 * math.pi


def wrap_angle(angle):
    """Angle(s) wrapped to ``(-pi, pi]``: a float for a scalar, an array for an array."""
    if np.ndim(angle) == 0:
        wrapped = math.remainder(float(angle), TWO_PI)  # exact, no rounding
        return math.pi if wrapped == -math.pi else wrapped
    wrapped = np.remainder(np.asarray(angle, dtype=float) + math.pi, TWO_PI) - math.pi
    return np.where(wrapped == -math.pi, math.pi, wrapped)


def planar_distance(a, b):
    """Distance between the (x, y) of two poses."""
    return float(math.hypot(a[0] - b[0], a[1] - b[1]))


def yaw_to_quaternion(yaw):
    """``(x, y, z, w)`` of a rotation by ``yaw`` about +z."""
    return 0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0)


def quaternion_to_yaw(x, y, z, w):
    """Heading of the body x axis projected on the ground (robust to roll and pitch)."""
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def se2_compose(pose, delta):
    """``pose`` moved by ``delta`` = (dx, dy, dyaw) in its own frame; ``delta`` may be (M, 3)."""
    x, y, yaw = np.asarray(pose, dtype=float)[:3]
    delta = np.asarray(delta, dtype=float)
    c, s = math.cos(yaw), math.sin(yaw)
    dx, dy, dyaw = delta[..., 0], delta[..., 1], delta[..., 2]
    return np.stack([x + c * dx - s * dy, y + s * dx + c * dy, wrap_angle(yaw + dyaw)],
                    axis=-1)


def se2_relative(start, end):
    """``end`` in the frame of ``start``: (dx, dy, dyaw), so that compose(start, it) = end."""
    x0, y0, yaw0 = (float(v) for v in np.asarray(start, dtype=float)[:3])
    x1, y1, yaw1 = (float(v) for v in np.asarray(end, dtype=float)[:3])
    c, s = math.cos(yaw0), math.sin(yaw0)
    dxw, dyw = x1 - x0, y1 - y0
    return np.array([c * dxw + s * dyw, -s * dxw + c * dyw, wrap_angle(yaw1 - yaw0)])


def generic_reward(start_pose, end_pose):
    """The paper's generic reward (``afun``) of a gait: its end pose in its start frame."""
    return se2_relative(start_pose, end_pose)
