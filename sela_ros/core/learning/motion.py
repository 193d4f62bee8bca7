"""Motion models of SELA: how a pose and a generic reward (GR) give the next pose.

:class:`PointMotion` (the toy world's point robot) and :class:`SE2Motion` (the hexapod: the GR
in the robot's frame at the start of the behaviour); each also says where many behaviours land
from many poses at once (the two-step choice of :class:`~sela_ros.core.learning.sela.SELA`).
"""
from __future__ import annotations

import math

import numpy as np

from sela_ros.core.geometry import se2_compose, se2_relative


class PointMotion:
    """Point robot: pose ``(x, y)``, generic reward ``(dx, dy)`` in the world frame."""

    pose_dim = 2
    gr_dim = 2

    def predict(self, pose, gr):
        """Poses after behaviours with generic rewards ``gr`` ((k,) or (M, k))."""
        return np.asarray(pose, dtype=float)[:2] + np.asarray(gr, dtype=float)

    def predict_xy_columns(self, pose, gr_t):
        """Predicted ``(x (M,), y (M,))`` from GRs given as rows ``gr_t`` (k, M)."""
        return pose[0] + gr_t[0], pose[1] + gr_t[1]

    def landing_sq_distances(self, poses, gr_t, target):
        """``(K, M)`` squared distances from ``target`` of where each of the M behaviours
        (GRs as rows ``gr_t``) lands from each of the K ``poses`` (rows)."""
        a = np.asarray(poses, dtype=float)[:, :2] - np.asarray(target, dtype=float)[:2]
        out = (2.0 * a) @ gr_t[:2]
        out += np.sum(a * a, axis=1)[:, None]
        out += np.sum(gr_t[:2] ** 2, axis=0)[None, :]
        return out

    def generic_reward(self, pose_before, pose_after):
        """``afun``: the displacement between two poses."""
        return np.asarray(pose_after, dtype=float)[:2] - np.asarray(pose_before, dtype=float)[:2]


class SE2Motion:
    """Planar robot: pose ``(x, y, yaw)``; GR ``(dx, dy, dyaw)`` in the robot's frame at
    the start of the behaviour. The predicted pose is the pose composed with the GR."""

    pose_dim = 3
    gr_dim = 3

    def predict(self, pose, gr):
        return se2_compose(pose, gr)

    def predict_xy_columns(self, pose, gr_t):
        """Predicted ``(x (M,), y (M,))`` from GRs given as rows ``gr_t`` (k, M)."""
        c, s = math.cos(pose[2]), math.sin(pose[2])
        return pose[0] + c * gr_t[0] - s * gr_t[1], pose[1] + s * gr_t[0] + c * gr_t[1]

    def landing_sq_distances(self, poses, gr_t, target):
        """``(K, M)`` squared distances from ``target`` of where each of the M behaviours
        (GRs as rows ``gr_t``) lands from each of the K ``poses`` (rows): the rotation
        keeps lengths, so it is ``|a|^2 + |g|^2 + 2 (a . R g)``, a rank-2 product."""
        poses = np.asarray(poses, dtype=float)
        a = poses[:, :2] - np.asarray(target, dtype=float)[:2]
        c, s = np.cos(poses[:, 2]), np.sin(poses[:, 2])
        # a . R g = g0 (a0 c + a1 s) + g1 (a1 c - a0 s)
        rotated = np.column_stack([a[:, 0] * c + a[:, 1] * s, a[:, 1] * c - a[:, 0] * s])
        out = (2.0 * rotated) @ gr_t[:2]
        out += np.sum(a * a, axis=1)[:, None]
        out += np.sum(gr_t[:2] ** 2, axis=0)[None, :]
        return out

    def generic_reward(self, pose_before, pose_after):
        """``afun``: world displacement rotated into the start frame, yaw change wrapped."""
        return se2_relative(pose_before, pose_after)
