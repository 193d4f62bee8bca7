"""Checks at the edge, written once: what was wrong and what was expected."""
import math

import numpy as np
import pytest

from sela_ros.core.validation.numeric import check_number, finite_array, number_problem


@pytest.mark.parametrize('value, limits, problem', [
    (0.5, {'low': 0.0}, None),
    (0.0, {'low': 0.0, 'low_open': True}, 'must be a number > 0, got 0.0'),
    (-1, {'low': 0.0}, 'must be a number >= 0, got -1'),
    (2.0, {'high': 1.0}, 'must be a number <= 1, got 2.0'),
    (math.nan, {}, 'must be a number, got nan'),
    (True, {}, 'must be a number, got True'),
    ('1', {}, "must be a number, got '1'"),
    (1.5, {'integer': True}, 'must be an integer, got 1.5'),
    (0, {'integer': True, 'low': 1}, 'must be an integer >= 1, got 0'),
])
def test_number_problems_say_what_was_expected(value, limits, problem):
    assert number_problem(value, **limits) == problem


def test_check_number_names_the_parameter():
    assert check_number('goal.eps', 0.1, low=0.0) == 0.1
    with pytest.raises(ValueError, match=r'^goal.eps must be a number > 0, got -1.0$'):
        check_number('goal.eps', -1.0, low=0.0, low_open=True)


def test_finite_array_says_which_value_and_raises_the_callers_error():
    class Bad(ValueError):
        pass

    assert np.array_equal(finite_array([[1, 2]], 'x'), [1.0, 2.0])
    with pytest.raises(Bad, match=r'x: value 1 is inf; expected finite numbers'):
        finite_array([0.0, math.inf], 'x', error=Bad)
    with pytest.raises(ValueError, match=r'goal: position.y is nan; expected finite numbers'):
        finite_array([0.0, math.nan], 'goal', labels=('position.x', 'position.y'))
    with pytest.raises(ValueError, match='expected 3 values, got 2'):
        finite_array([0.0, 1.0], 'x', length=3)
    with pytest.raises(ValueError, match='expected numbers'):
        finite_array(['a'], 'x')
