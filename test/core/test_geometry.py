"""Planar geometry written once: one angle convention, SE(2), yaw <-> quaternion."""
import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from sela_ros.core import geometry as g

coord = st.floats(-10, 10)
angle = st.floats(-20, 20)


def test_angles_wrap_to_minus_pi_excluded_pi_included_for_scalars_and_arrays():
    assert g.wrap_angle(-math.pi) == math.pi and g.wrap_angle(math.pi) == math.pi
    assert g.wrap_angle(3 * math.pi) == math.pi
    arr = g.wrap_angle(np.array([-math.pi, math.pi, 0.5, 7.0]))
    assert arr[0] == math.pi and arr[1] == math.pi and arr[2] == 0.5
    assert abs(arr[3] - (7.0 - 2 * math.pi)) < 1e-12


@given(angle)
def test_scalar_and_array_wrapping_agree(a):
    w = g.wrap_angle(a)
    assert -math.pi < w <= math.pi and abs(math.remainder(w - a, 2 * math.pi)) < 1e-9
    assert abs(float(g.wrap_angle(np.array([a]))[0]) - w) < 1e-9 or abs(abs(w) - math.pi) < 1e-9


@given(coord, coord, angle, coord, coord, angle)
def test_relative_undoes_compose(x, y, yaw, dx, dy, dyaw):
    start = np.array([x, y, yaw])
    end = g.se2_compose(start, [dx, dy, dyaw])
    back = g.se2_relative(start, end)
    assert np.allclose(back[:2], [dx, dy], atol=1e-9)
    assert abs(math.remainder(back[2] - dyaw, 2 * math.pi)) < 1e-9
    assert np.allclose(g.generic_reward(start, end), back)


def test_compose_takes_many_deltas_at_once():
    out = g.se2_compose([1.0, 2.0, math.pi / 2], np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]))
    assert np.allclose(out, [[1.0, 3.0, math.pi / 2], [0.0, 2.0, math.pi / 2]])


@given(angle)
def test_yaw_quaternion_round_trip(yaw):
    back = g.quaternion_to_yaw(*g.yaw_to_quaternion(yaw))
    assert abs(math.remainder(back - yaw, 2 * math.pi)) < 1e-9
