"""Property-based tests of the parameter validators used by every node's set-callback."""
import math
import sys

from hypothesis import example, given
from hypothesis import strategies as st

from sela_ros.core.detection import DetectorConfig
from sela_ros.nodes.params import (
    STARTUP_ONLY,
    Spec,
    check,
    coerce,
    first_problem,
    non_negative_int,
    non_negative_number,
    positive_int,
    positive_number,
    startup_only,
    string,
)
from sim_bridge.damage import LEG_NAMES
from sim_bridge.node import PARAMETERS, damage_rule

anything = st.one_of(st.none(), st.booleans(), st.integers(), st.floats(), st.text(),
                     st.lists(st.integers(), max_size=3))


@given(anything)
def test_positive_number_accepts_exactly_finite_positive_numbers(value):
    ok = (isinstance(value, (int, float)) and not isinstance(value, bool)
          and math.isfinite(value) and value > 0)
    assert (positive_number(' (m)')(value) is None) == ok


@given(anything)
def test_non_negative_number(value):
    ok = (isinstance(value, (int, float)) and not isinstance(value, bool)
          and math.isfinite(value) and value >= 0)
    assert (non_negative_number()(value) is None) == ok


@given(anything)
def test_integer_rules(value):
    is_int = isinstance(value, int) and not isinstance(value, bool)
    assert (positive_int(value) is None) == (is_int and value > 0)
    assert (non_negative_int(value) is None) == (is_int and value >= 0)


@given(anything)
def test_string_and_startup_only(value):
    assert (string(value) is None) == isinstance(value, str)
    assert startup_only(value) == STARTUP_ONLY


@given(st.lists(st.tuples(st.sampled_from(['a', 'b', 'c']), anything), max_size=6))
def test_first_problem_names_the_first_refused_parameter(changes):
    rules = {'a': positive_int, 'b': string}
    problem = first_problem(changes, rules)
    refused = [n for n, v in changes if n in rules and rules[n](v)]
    if refused:
        assert problem.startswith(refused[0] + ' ')
    else:
        assert problem is None


@given(st.sampled_from(LEG_NAMES), st.text(max_size=12))
def test_damage_rule(leg, junk):
    assert damage_rule(f'remove:{leg}') is None
    assert damage_rule('intact') is None
    assert damage_rule(3) is not None
    problem = damage_rule(f'remove:{junk}x')
    if problem is not None:
        assert 'middle_right' in problem  # the valid names are listed


def test_sim_bridge_start_up_parameters_are_read_only():
    read_only = {spec.name for spec in PARAMETERS if spec.read_only}
    assert read_only == {'sim.dt', 'sim.gait_duration', 'sim.solver_iterations', 'archive',
                         'sim.gui', 'seed', 'right_on_fall', 'righting_time'}


@given(anything, st.one_of(st.none(), st.floats(-10, 10)),
       st.one_of(st.none(), st.floats(-10, 10)))
@example(2 ** 53 + 1, None, None)  # an integer no double holds: the nearest one is taken
@example(10 ** 400, None, None)    # beyond every double: refused, not an OverflowError
def test_check_of_a_double_accepts_numbers_in_range_and_integers(value, low, high):
    spec = Spec('x', 0.5, 'a number', low=low, high=high, unit=' m')
    ok = (isinstance(value, (int, float)) and not isinstance(value, bool)
          and (math.isfinite(value) if isinstance(value, float)
               else abs(value) <= sys.float_info.max)
          and (low is None or value >= low) and (high is None or value <= high))
    problem = check(spec, value)
    assert (problem is None) == ok
    if not ok:
        assert problem.startswith('must be a number') and problem.endswith(f'got {value!r}')
    coerced = coerce(spec, value)
    if ok:
        assert isinstance(coerced, float) and coerced == float(value)


@given(anything)
def test_check_of_an_integer_bool_string_and_array(value):
    is_int = isinstance(value, int) and not isinstance(value, bool)
    assert (check(Spec('n', 1, '', low=1, high=9), value) is None) == (is_int and 1 <= value <= 9)
    assert (check(Spec('b', False, ''), value) is None) == isinstance(value, bool)
    assert (check(Spec('s', 'odom', ''), value) is None) == isinstance(value, str)
    is_list = isinstance(value, list) and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
        for v in value)
    assert (check(Spec('a', [1.0], ''), value) is None) == is_list


def test_check_runs_the_extra_rule_and_allows_not_set_only_without_default():
    spec = Spec('obstacles', None, '', kind='double_array',
                rule=lambda v: None if len(v) % 4 == 0 else 'must hold rectangles')
    assert check(spec, None) is None
    assert check(spec, [1, 2, 3]) == 'must hold rectangles'
    assert coerce(spec, [1, 2, 3, 4]) == [1.0, 2.0, 3.0, 4.0]
    assert check(Spec('x', 1.0, ''), None) == 'must be a number, got None'
    assert Spec('seed', 0, '', low=0, high=2**31 - 1).constraints() == (
        'an integer in [0, 2147483647]')


@given(st.floats(allow_nan=True), st.integers(-3, 3), st.integers(-3, 3),
       st.floats(allow_nan=True))
def test_detector_config_validation(threshold, window, cooldown, max_sigma):
    ok = (math.isfinite(threshold) and threshold >= 0 and window >= 1 and cooldown >= 0
          and math.isfinite(max_sigma) and max_sigma >= 0)
    try:
        DetectorConfig(threshold=threshold, window=window, cooldown=cooldown,
                       max_sigma=max_sigma)
        assert ok
    except ValueError as exc:
        assert not ok and 'detection.' in str(exc)


def test_params_file_problems_say_which_file_where_and_what(tmp_path):
    from sela_ros.nodes.params import params_file_problems

    good = tmp_path / 'good.yaml'
    good.write_text('planner:\n  ros__parameters:\n    planner.lookahead: 0.6\n')
    broken = tmp_path / 'broken.yaml'
    broken.write_text('planner:\n  ros__parameters:\n    planner.lookahead: [0.6\n')
    flat = tmp_path / 'flat.yaml'
    flat.write_text('planner:\n  planner.lookahead: 0.6\n')
    assert params_file_problems(['planner', '--ros-args', '--params-file', str(good)]) == []
    (problem,) = params_file_problems(['--ros-args', '--params-file', str(broken)])
    assert f'{broken}:4:1' in problem and 'not valid YAML' in problem
    (problem,) = params_file_problems(['--params-file', str(flat)])
    assert "node 'planner' needs a ros__parameters mapping" in problem
    (problem,) = params_file_problems(['--params-file', str(tmp_path / 'missing.yaml')])
    assert 'missing.yaml' in problem and 'No such file' in problem


def test_a_node_given_a_malformed_params_file_says_where_and_does_not_start(tmp_path):
    import os
    import subprocess

    from sela_ros.tools.ros_env import executable, ros_environment

    broken = tmp_path / 'broken.yaml'
    broken.write_text('planner:\n  ros__parameters:\n    planner.lookahead: [0.6\n')
    env = ros_environment(domain_id=int(os.environ.get('ROS_DOMAIN_ID', '0')))
    proc = subprocess.run([str(executable('planner')), '--ros-args', '--params-file',
                           str(broken)], env=env, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2, proc.stderr
    assert f'{broken}:4:1: not valid YAML' in proc.stderr
    assert 'Traceback' not in proc.stderr
