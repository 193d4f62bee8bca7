"""Unit tests of the Cully et al. (2015) open-loop controller."""
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sim_bridge import controller


def test_kernel_is_normalised_and_symmetric():
    kernel = controller.smoothing_kernel()
    assert kernel.shape == (21,)
    assert math.isclose(kernel.sum(), 1.0, rel_tol=0, abs_tol=1e-15)
    np.testing.assert_array_equal(kernel, kernel[::-1])
    assert kernel.argmax() == 10


def test_square_wave_duty_half_phase_zero():
    sig = controller.control_signals([1.0], [0.0], [0.5])[0]
    kernel = controller.smoothing_kernel()
    # Far from the edges (samples 10..39 and 60..89) the smoothing changes nothing.
    np.testing.assert_allclose(sig[10:40], 1.0, atol=1e-12)
    np.testing.assert_allclose(sig[60:90], -1.0, atol=1e-12)
    # At the rising edge (sample 0): 10 samples at -1 before, 11 at +1 from it on.
    expected0 = kernel[10:].sum() - kernel[:10].sum()
    assert math.isclose(sig[0], expected0, abs_tol=1e-12)
    # At sample 50 (first -1 sample): mirror image.
    assert math.isclose(sig[50], -expected0, abs_tol=1e-12)
    # Hand-computed at the last +1 sample (49): 11 at +1 (39..49), 10 at -1 (50..59).
    assert math.isclose(sig[49], -sig[50], abs_tol=1e-12)


def test_phase_advances_the_wave():
    base = controller.control_signals([0.7], [0.0], [0.3])[0]
    shifted = controller.control_signals([0.7], [0.25], [0.3])[0]
    np.testing.assert_array_equal(shifted, np.roll(base, -25))
    # floor(100 phi): 0.259 is still a shift of 25 samples.
    np.testing.assert_array_equal(controller.control_signals([0.7], [0.259], [0.3])[0], shifted)


def test_duty_extremes_and_amplitude():
    np.testing.assert_allclose(controller.control_signals([0.4], [0.3], [1.0])[0], 0.4)
    np.testing.assert_allclose(controller.control_signals([0.4], [0.3], [0.0])[0], -0.4)
    np.testing.assert_allclose(controller.control_signals([0.0], [0.3], [0.6])[0], 0.0)


def test_target_table_layout_and_scales():
    params = np.zeros(36)
    leg = 4
    params[6 * leg:6 * leg + 6] = (1.0, 0.0, 1.0, 0.5, 0.0, 1.0)  # constant +1 and +0.5
    table = controller.target_table(params)
    assert table.shape == (100, 18)
    np.testing.assert_allclose(table[:, 3 * leg], math.pi / 8)
    np.testing.assert_allclose(table[:, 3 * leg + 1], 0.5 * math.pi / 4)
    np.testing.assert_allclose(table[:, 3 * leg + 2], -0.5 * math.pi / 4)
    others = np.delete(table, [3 * leg, 3 * leg + 1, 3 * leg + 2], axis=1)
    # Amplitude 0 everywhere else.
    np.testing.assert_array_equal(others, 0.0)


def test_target_table_matches_per_signal_computation():
    rng = np.random.default_rng(3)
    params = rng.random(36)
    table = controller.target_table(params)
    for leg in range(6):
        a, ph, d = params[6 * leg:6 * leg + 3]
        s0 = controller.control_signals([a], [ph], [d])[0]
        a, ph, d = params[6 * leg + 3:6 * leg + 6]
        s1 = controller.control_signals([a], [ph], [d])[0]
        np.testing.assert_allclose(table[:, 3 * leg], math.pi / 8 * s0, atol=1e-15)
        np.testing.assert_allclose(table[:, 3 * leg + 1], math.pi / 4 * s1, atol=1e-15)
        np.testing.assert_allclose(table[:, 3 * leg + 2], -math.pi / 4 * s1, atol=1e-15)


def test_sample_indices_one_second_period():
    idx = controller.sample_indices(720, 1.0 / 240.0)
    assert idx[0] == 0
    assert idx[240] == 0 and idx[239] == 99
    assert idx[12] == 5  # t = 0.05 s exactly
    assert idx[11] == 4
    np.testing.assert_array_equal(idx[:240], idx[240:480])
    idx1k = controller.sample_indices(3000, 1e-3)
    assert idx1k[10] == 1 and idx1k[9] == 0 and idx1k[2990] == 99


def test_servo_velocity():
    assert math.isclose(controller.servo_velocity(0.3, 0.1), 0.2 / (math.pi * 0.015))


@pytest.mark.parametrize('bad, match', [
    (np.zeros(35), 'shape'),
    (np.zeros((6, 6)), 'shape'),
    (np.r_[np.zeros(35), np.nan], 'finite'),
    (np.r_[np.zeros(35), 1.5], r'\[0, 1\]'),
    (np.r_[-0.1, np.zeros(35)], 'indices \\[0\\]'),
    ('abc', '36 numbers'),
])
def test_invalid_params_raise(bad, match):
    with pytest.raises(ValueError, match=match):
        controller.target_table(bad)


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(0.0, 1.0), min_size=36, max_size=36))
def test_targets_stay_within_joint_limits(params):
    table = controller.target_table(params)
    assert np.all(np.abs(table[:, 0::3]) <= math.pi / 8 + 1e-12)
    assert np.all(np.abs(table[:, 1::3]) <= math.pi / 4 + 1e-12)
    np.testing.assert_array_equal(table[:, 2::3], -table[:, 1::3])
