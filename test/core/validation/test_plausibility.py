"""Plausibility limits on outcomes: a gait cannot move the robot a kilometre."""
import math

import pytest

from sela_ros.core.validation import ImplausibleOutcome, OutcomeLimits, check_outcome


def test_ordinary_outcomes_pass():
    # (0.2, 0.3) in odom from a heading of 0.5 rad is (0.319, 0.167) in the start frame.
    check_outcome([0.319, 0.167, 1.0], [1.0, 1.0, 0.5], [1.2, 1.3, 1.5],
                  expected_start=[1.01, 0.99, 0.5])
    check_outcome([0.0, 0.0, 0.0])


@pytest.mark.parametrize('gr, start, end, expected, match', [
    ([1e9, 0, 0], None, None, None, 'moves the robot 1e\\+09 m'),
    ([3.0, 0, 0], None, None, None, 'more than outcome.max_displacement 2 m'),
    ([0.1, 0, 0], [0, 0, 0], [1e9, 0, 0], None, 'from its start pose to its end pose'),
    ([0.1, 0, 0], [1e308, 0, 0], [-1e308, 0, 0], None, 'inf m'),
    ([0.1, 0, 0], [50, 0, 0], [50.1, 0, 0], [0, 0, 0], 'planned from'),
    ([math.nan, 0, 0], None, None, None, 'non-finite'),
    ([0.1, 0, 0], [0, math.inf, 0], None, None, 'start pose has a non-finite'),
])
def test_implausible_outcomes_are_refused_with_the_reason(gr, start, end, expected, match):
    with pytest.raises(ImplausibleOutcome, match=match):
        check_outcome(gr, start, end, expected_start=expected)


def test_the_limit_is_a_parameter():
    check_outcome([5.0, 0, 0], limits=OutcomeLimits(max_displacement=10.0))
    with pytest.raises(ImplausibleOutcome, match='max_displacement 0.5 m'):
        check_outcome([0.6, 0, 0], limits=OutcomeLimits(max_displacement=0.5))


@pytest.mark.parametrize('bad', [0, -1.0, math.inf, math.nan, True, '2'])
def test_a_bad_limit_is_a_clear_error(bad):
    with pytest.raises(ValueError, match='outcome.max_displacement must be'):
        OutcomeLimits(max_displacement=bad)
