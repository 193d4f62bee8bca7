"""Cully et al. (2015) open-loop hexapod controller: 36 parameters -> periodic joint targets.

For leg ``l`` (0..5, order of :data:`LEG_NAMES`) and joint group ``g`` (0: hip yaw,
1: hip pitch and knee) the triple (amplitude A, phase phi, duty d) is
``params[6 l + 3 g : 6 l + 3 g + 3]``. Each triple gives a 100-sample periodic signal:
a square wave (+A for the first ``floor(100 d)`` samples, -A after), smoothed with a
circular, normalised Gaussian kernel (half-width 10, sigma 3), then advanced by
``k = floor(100 phi)`` samples (``out[i] = smoothed[(i + k) mod 100]``, as in the
original sferes/resibots controller). At time ``t`` into a gait sample
``floor(100 t) mod 100`` is used (period 1 s). Joint targets:
``hip_yaw = (pi/8) s0``, ``hip_pitch = (pi/4) s1``, ``knee = -(pi/4) s1``.

The servo is a velocity command ``(q* - q) / (pi * 0.015)``; see :func:`servo_velocity`.
"""
from __future__ import annotations

import math

import numpy as np

#: Parameters of one gait: six legs, two joint groups, a triple each.
N_PARAMS = 36
N_LEGS = 6
N_SAMPLES = 100
PERIOD = 1.0
KERNEL_HALF_WIDTH = 10
KERNEL_SIGMA = 3.0
YAW_SCALE = math.pi / 8
PITCH_SCALE = math.pi / 4
SERVO_TIME_CONSTANT = math.pi * 0.015

CONTROLLER_VERSION = 'cully2015-v1'


def validate_params(params, n=N_PARAMS) -> np.ndarray:
    """Return ``params`` as a float64 array of shape ``(n,)`` in [0, 1], or raise ``ValueError``
    (``n``: the robot's number of gait parameters, the hexapod's 36 by default)."""
    try:
        p = np.asarray(params, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f'gait parameters must be {n} numbers in [0, 1]: {exc}') from None
    if p.shape != (n,):
        raise ValueError(f'gait parameters must have shape ({n},), got {p.shape}')
    if not np.all(np.isfinite(p)):
        bad = np.flatnonzero(~np.isfinite(p)).tolist()
        raise ValueError(f'gait parameters must be finite; non-finite at indices {bad}')
    if np.any((p < 0.0) | (p > 1.0)):
        bad = np.flatnonzero((p < 0.0) | (p > 1.0)).tolist()
        raise ValueError(f'gait parameters must lie in [0, 1]; out of range at indices {bad}')
    return p


def smoothing_kernel() -> np.ndarray:
    """The normalised Gaussian kernel (length 21, sums to 1)."""
    offsets = np.arange(-KERNEL_HALF_WIDTH, KERNEL_HALF_WIDTH + 1, dtype=np.float64)
    kernel = np.exp(-(offsets**2) / (2.0 * KERNEL_SIGMA**2))
    return kernel / kernel.sum()


_KERNEL = smoothing_kernel()
# Circulant matrix so that smoothing many signals is one matrix product:
# smoothed[i] = sum_j kernel[j] * square[(i + j - half) mod 100].
_SMOOTH = np.zeros((N_SAMPLES, N_SAMPLES))
for _i in range(N_SAMPLES):
    for _j, _w in enumerate(_KERNEL):
        _SMOOTH[_i, (_i + _j - KERNEL_HALF_WIDTH) % N_SAMPLES] += _w
del _i, _j, _w


def control_signals(amplitude, phase, duty) -> np.ndarray:
    """Vectorised periodic signals, one row of 100 samples per (A, phi, d) triple.

    Args:
        amplitude, phase, duty: arrays of the same shape (n,), values in [0, 1].

    Returns:
        Array (n, 100).
    """
    amplitude = np.atleast_1d(np.asarray(amplitude, dtype=np.float64))
    phase = np.atleast_1d(np.asarray(phase, dtype=np.float64))
    duty = np.atleast_1d(np.asarray(duty, dtype=np.float64))
    samples = np.arange(N_SAMPLES)
    up = np.floor(N_SAMPLES * duty).astype(np.int64)
    square = np.where(samples[None, :] < up[:, None], 1.0, -1.0) * amplitude[:, None]
    smoothed = square @ _SMOOTH.T
    shift = np.floor(N_SAMPLES * phase).astype(np.int64) % N_SAMPLES
    idx = (samples[None, :] + shift[:, None]) % N_SAMPLES
    return np.take_along_axis(smoothed, idx, axis=1)


def target_table(params) -> np.ndarray:
    """Joint-target table (100, 18) for one gait; column ``3 l + j`` is leg l, joint j.

    Joint j: 0 hip yaw, 1 hip pitch, 2 knee (radians).
    """
    p = validate_params(params).reshape(N_LEGS * 2, 3)
    sig = control_signals(p[:, 0], p[:, 1], p[:, 2]).reshape(N_LEGS, 2, N_SAMPLES)
    table = np.empty((N_SAMPLES, N_LEGS, 3))
    table[:, :, 0] = (YAW_SCALE * sig[:, 0, :]).T
    table[:, :, 1] = (PITCH_SCALE * sig[:, 1, :]).T
    table[:, :, 2] = (-PITCH_SCALE * sig[:, 1, :]).T
    return table.reshape(N_SAMPLES, N_LEGS * 3)


def sample_indices(n_steps: int, dt: float) -> np.ndarray:
    """Sample index ``floor(100 t) mod 100`` for each step ``k`` at ``t = k dt``."""
    t = np.arange(n_steps, dtype=np.float64) * dt
    # The small epsilon keeps t = k/100 exactly on its own sample despite rounding.
    return (np.floor(t * (N_SAMPLES / PERIOD) + 1e-9).astype(np.int64)) % N_SAMPLES


def servo_velocity(target, position):
    """Velocity command of the Cully et al. servo: ``(q* - q) / (pi * 0.015)``."""
    return (np.asarray(target) - np.asarray(position)) / SERVO_TIME_CONSTANT


def tripod_gait(amplitude_yaw: float = 1.0, amplitude_pitch: float = 0.5,
                turn: float = 0.0) -> np.ndarray:
    """A hand-made tripod gait (front_left, rear_left, middle_right swing together).

    ``turn`` = 0 walks forward; ``turn`` = +1 reverses the stroke of the left legs
    (turns left, counter-clockwise); -1 reverses the right legs (turns right).
    """
    p = np.zeros(N_PARAMS)
    group_a = {0, 2, 4}  # front_left, rear_left, middle_right
    for leg in range(N_LEGS):
        offset = 0.0 if leg in group_a else 0.5
        left = leg < 3
        yaw_phase = offset
        if (turn > 0 and left) or (turn < 0 and not left):
            yaw_phase += 0.5
        # The leg is lifted (s1 > 0) around yaw sample 0, where the foot swings forward.
        p[6 * leg:6 * leg + 3] = (amplitude_yaw, yaw_phase % 1.0, 0.5)
        p[6 * leg + 3:6 * leg + 6] = (amplitude_pitch, (offset + 0.25) % 1.0, 0.5)
    return p
