"""When the sela_adapter's archive may change (no DDS: the checks over a stand-in node)."""
from types import SimpleNamespace

import numpy as np

from sela_ros.core.mission import stepper_io as io
from sela_ros.core.storage import default_archive_path
from sela_ros.nodes import adapter_support


def _change(value, state, learned=0):
    stepper = SimpleNamespace(state=state,
                              sela=SimpleNamespace(observations=(np.zeros(learned),)))
    return adapter_support.archive_change(value, '/nowhere/in_use.npz', stepper,
                                          'sela_adapter')


def test_a_file_that_cannot_be_loaded_is_refused_for_its_problem_even_mid_step(tmp_path):
    broken = tmp_path / 'broken.npz'
    broken.write_bytes(b'PK\x03\x04 truncated')
    for state in io.State:
        reason, _, archive = _change(str(broken), state, learned=3)
        assert archive is None
        assert reason is not None and 'broken.npz' in reason, (state, reason)
        assert 'mid-step' not in reason and 'learned' not in reason


def test_a_good_file_is_refused_mid_step_and_while_something_is_learned():
    good = str(default_archive_path())
    for state in (io.State.PLANNING, io.State.EXECUTING, io.State.VERDICT,
                  io.State.RESETTING):
        reason, _, archive = _change(good, state)
        assert archive is None
        assert 'mid-step' in reason and 'between steps' in reason, (state, reason)
    reason, _, _ = _change(good, io.State.IDLE, learned=2)
    assert '2 observation(s)' in reason and 'sela_adapter/clear' in reason
    reason, path, archive = _change(good, io.State.IDLE)  # nothing learned, between steps
    assert reason is None and len(archive) > 0 and str(path) == good


def test_a_file_built_for_other_physics_than_the_simulators_is_refused_first():
    good = str(default_archive_path())
    stepper = SimpleNamespace(state=io.State.EXECUTING,
                              sela=SimpleNamespace(observations=(np.zeros(2),)))
    reason, _, archive = adapter_support.archive_change(
        good, '/nowhere/in_use.npz', stepper, 'sela_adapter',
        lambda archive, path: f'{path} was built with other simulator settings')
    assert archive is None and 'other simulator settings' in reason
    assert 'archive:=' in reason and 'mid-step' not in reason
    reason, _, archive = adapter_support.archive_change(
        good, '/nowhere/in_use.npz', None, 'sela_adapter', lambda archive, path: None)
    assert reason is None and len(archive) > 0


def test_the_file_in_use_is_kept_and_not_loaded_again(tmp_path):
    in_use = tmp_path / 'in_use.npz'
    in_use.write_bytes(b'not even an archive')  # never read: it is the file in use
    reason, path, archive = adapter_support.archive_change(str(in_use), str(in_use), None,
                                                           'sela_adapter')
    assert reason is None and archive is None


def test_an_empty_plan_says_why_from_the_planners_map_when_the_adapter_has_it():
    from sela_ros.core.planning.maps import default_grid

    command = io.RequestPlan(step=3, start=np.zeros(3), goal=np.array([40.0, 0.0]))
    empty = SimpleNamespace(plan=SimpleNamespace(poses=[]))
    assert 'off the map' in adapter_support.plan_event(empty, command, default_grid()).reason
    assert 'diagnostics' in adapter_support.plan_event(empty, command).reason
    assert 'did not answer' in adapter_support.plan_event(None, command, default_grid()).reason


def _defaults(**changes):
    from sela_ros.nodes import adapter_params
    values = {spec.name: spec.default for spec in adapter_params.PARAMETERS}
    values.update({'priors.tables': 'none'}, **changes)
    return values


def test_the_outcome_limit_follows_the_archive_and_a_spoofed_long_outcome_is_refused():
    from sela_ros.core.storage import load_archive
    from sela_ros.nodes import adapter_params
    archive = load_archive(default_archive_path())
    fastest = float(np.max(np.hypot(*archive.generic_reward[:, :2].T)))
    stepper = adapter_support.new_stepper(_defaults(), archive, None)
    assert stepper.config.max_displacement == np.float64(2 * fastest)
    assert 1.2 < stepper.config.max_displacement < 1.3  # the 8-D map's: 0.63 m
    stepper.handle(io.PoseObserved((0.0, 0.0, 0.0), stamp=0.0), 0.0)
    request = next(c for c in stepper.handle(io.GoalReceived((3.0, 0.0)), 0.0)
                   if isinstance(c, io.RequestPlan))
    gait = next(c for c in stepper.handle(io.PlanReceived(
        request.step, tuple(request.start), (0.6, 0.0)), 0.0) if isinstance(c, io.SendGait))
    # 1.5 m, consistent with its own poses: no gait of the map goes that far.
    out = stepper.handle(io.OutcomeReceived(gait.behavior_id, (1.5, 0.0, 0.0),
                                            (1.5, 0.0, 0.0), start_pose=(0.0, 0.0, 0.0)), 3.0)
    refused = [c.message for c in out if isinstance(c, io.Report) and 'refused' in c.message]
    assert refused and 'moves the robot 1.5 m' in refused[0], out
    assert 'outcome.max_displacement 1.25' in refused[0], out
    assert len(stepper.sela.observations[0]) == 0 and stepper.state is io.State.EXECUTING
    # An explicit value is still taken, and auto again follows the archive.
    assert adapter_support.new_stepper(_defaults(**{'outcome.max_displacement': 3.0}), archive,
                                       None).config.max_displacement == 3.0
    assert adapter_params.stepper_change('outcome.max_displacement', 'auto', archive) == {
        'max_displacement': 2 * fastest}


def test_the_shipped_priors_are_logged_with_their_tiers_and_what_was_inferred():
    from sela_ros.core.storage import load_archive

    lines = []
    logger = SimpleNamespace(info=lines.append, error=lines.append)
    path = default_archive_path()
    priors = adapter_support.load_priors('auto', load_archive(path), path, logger)
    assert priors is not None and len(priors.first_tier()) == 6
    assert '6 foreseen damages (remove:front_left' in lines[0]
    # The library's 84 other conditions, counted by kind.
    assert ('84 more, each used once it reproduces the robot\'s standing starts (18 shorten, '
            '30 block, 6 weaken, 15 remove+remove, 15 shorten+shorten)') in lines[0]
    assert lines[1].startswith('damage priors: 84 tables partly inferred (each simulated '
                               '4000 of 12442 gaits)')
    lines.clear()
    assert adapter_support.load_priors('/nowhere.npz', load_archive(path), path, logger) is None
    assert len(lines) == 1 and 'no such file' in lines[0] and 'intact map alone' in lines[0]
