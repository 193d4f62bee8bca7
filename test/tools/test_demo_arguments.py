"""sela-demo's options that reach the simulator: the pace of its gaits."""
import pytest

from sela_ros.tools import demo


@pytest.mark.parametrize('argv, factor', [([], 0.0), (['--gui'], 1.0),
                                          (['--gui', '--real-time-factor', '0'], 0.0),
                                          (['--real-time-factor', '2.5'], 2.5)])
def test_the_window_shows_the_robot_at_its_own_pace_unless_told(argv, factor):
    assert demo._pace(demo.build_parser().parse_args(argv)) == factor


@pytest.mark.parametrize('value', ['0.05', '-1', 'fast', '1e9'])
def test_a_factor_the_simulator_refuses_is_refused_with_the_range(value, capsys):
    with pytest.raises(SystemExit):
        demo.build_parser().parse_args(['--real-time-factor', value])
    assert '--real-time-factor' in capsys.readouterr().err
