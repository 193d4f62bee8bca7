"""The map's error against a damaged robot, by the displacement the map predicts."""
import numpy as np
from script_modules import load_script


def test_the_error_is_given_per_band_of_the_predicted_step():
    prior_error = load_script('prior_error')
    # Gaits the map says go 0.05 m and 0.35 m forward; the robot goes half as far.
    x = np.array([[0.05, 0.0, 0.0]] * 3 + [[0.35, 0.0, 0.0]] * 5)
    y = x * [0.5, 1.0, 1.0]
    table = prior_error.by_displacement([('shorten:front_left:0.5', x, y)])
    row = table.splitlines()[2].split(' | ')
    assert row[0] == '| shorten:front_left:0.5'
    assert row[1] == '0.025 / 0.025 (3)'  # 0-0.1 m: half of 0.05
    assert row[2] == row[3] == '-'  # no gait of the map goes 0.1-0.3 m
    assert row[4] == '0.175 / 0.175 (5)'  # 0.3-0.4 m: half of 0.35
