"""Property-based tests of the parameter check used by every node's set-callback."""
import math
import sys

import pytest
from hypothesis import example, given
from hypothesis import strategies as st

from sela_ros.core.detection import DetectorConfig
from sela_ros.nodes.params import Spec, check, coerce
from sim_bridge.damage import LEG_NAMES
from sim_bridge.node import PARAMETERS, damage_rule

anything = st.one_of(st.none(), st.booleans(), st.integers(), st.floats(), st.text(),
                     st.lists(st.integers(), max_size=3))


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
    assert read_only == {'robot', 'sim.dt', 'sim.gait_duration', 'sim.solver_iterations',
                         'archive', 'sim.gui', 'seed', 'right_on_fall', 'righting_time',
                         'interface', 'map_frame'}


def test_the_simulators_map_frame_is_none_of_the_frames_it_parents():
    spec = next(s for s in PARAMETERS if s.name == 'map_frame')
    assert check(spec, 'map') is None and check(spec, '') is None and check(spec, 'world') is None
    for child in ('odom', 'base_link'):  # a transform to itself, or a loop in the tree
        assert 'another frame than odom and base_link' in check(spec, child)


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


@given(anything)
def test_a_parameter_with_a_word_takes_the_word_or_its_kind_of_value_and_nothing_else(value):
    spec = Spec('gp.kernel.sigma', 'auto', '', low=0.0, high=100.0, kind='double', word='auto')
    number = (isinstance(value, (int, float)) and not isinstance(value, bool)
              and math.isfinite(value) and 0 <= value <= 100)
    assert (check(spec, value) is None) == (number or value == 'auto')
    if isinstance(value, str) and value != 'auto':
        assert check(spec, value) == f'must be a number in [0, 100] or auto, got {value!r}'


def test_the_0_that_meant_a_word_is_read_as_the_word_and_nothing_else_is():
    from sela_ros.nodes.params import word_warning, zero_for_word

    rate = Spec('publish_max_rate', 5.0, '', low=0.0, high=1000.0, unit=' Hz', word='none')
    horizon = Spec('planner.horizon', 'auto', '', low=1, high=2, kind='integer', word='auto')
    assert rate.constraints() == 'a number in [0, 1000] Hz or none'
    assert horizon.constraints() == 'an integer in [1, 2] or auto'
    for spec, word in ((rate, 'none'), (horizon, 'auto')):
        for zero in (0, 0.0):
            assert zero_for_word(spec, zero) and coerce(spec, zero) == word
            assert check(spec, coerce(spec, zero)) is None
        assert not zero_for_word(spec, False) and coerce(spec, word) == word
        assert f'give {word} instead' in word_warning(spec)
    assert coerce(rate, 3) == 3.0 and coerce(horizon, 2) == 2
    assert check(horizon, 3) == 'must be an integer in [1, 2] or auto, got 3'
    assert check(horizon, 'none') == "must be an integer in [1, 2] or auto, got 'none'"
    assert coerce(Spec('x', 0.5, '', low=0.0), 0) == 0.0  # no word: 0 is a number


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
    # A list from a launch file, as launch_ros writes it: rcl reads it as a list.
    tagged = tmp_path / 'from_launch.yaml'
    tagged.write_text('/**/damage_detector:\n  ros__parameters:\n    heartbeat.nodes: '
                      '!!python/tuple\n    - planner\n    - sela_adapter\n')
    assert params_file_problems(['--params-file', str(tagged)]) == []


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


def test_yamls_null_for_a_parameter_not_set_by_default_is_not_set():
    """What ``ros2 param dump`` writes for ``map.obstacles`` left not set loads back."""
    unset = Spec('map.obstacles', None, 'rectangles', kind='double_array')
    for null in ('null', '~', 'NULL'):
        assert coerce(unset, null) is None and check(unset, coerce(unset, null)) is None
    assert coerce(unset, [1, 2, 3, 4]) == [1.0, 2.0, 3.0, 4.0]
    # Only there: a string parameter keeps the word, a set one refuses it.
    assert coerce(Spec('map.file', None, 'a file', kind='string'), 'null') == 'null'
    assert coerce(Spec('goal.eps', 0.1, 'm'), 'null') == 'null'
    assert check(Spec('goal.eps', 0.1, 'm'), 'null') is not None


@pytest.mark.parametrize('name', ['gp.kernel.sigma', 'fall.kernel.sigma'])
def test_a_kernel_length_too_short_for_the_gp_is_refused_with_its_range(name):
    from sela_ros.core.learning.gp import MIN_SIGMA
    from sela_ros.nodes.adapter_params import PARAMETERS as ADAPTER

    spec = next(s for s in ADAPTER if s.name == name)
    assert check(spec, MIN_SIGMA) is None and check(spec, 0.3) is None
    assert check(spec, 1e-300) == 'must be a number in [0.001, 100] or auto, got 1e-300'
