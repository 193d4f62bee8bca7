"""The adapter's self-model plumbing: the feet of an outcome message reach the stepper, and
the simulations run in worker processes and come back as stepper events."""
import time

import numpy as np

from sela_ros.core.mission import stepper_io as io
from sela_ros.core.storage import default_archive_path, load_archive
from sela_ros.nodes import conversions as conv
from sela_ros.nodes.self_model_runner import SelfModelSimulations


def test_an_outcome_message_gives_the_stepper_its_feet():
    duty = np.array([0.0, 0.5, 0.25, 1.0, 0.75, 0.125])
    outcome = conv.BehaviorOutcome(behavior_id=7, generic_reward=np.array([0.1, 0.0, 0.2]),
                           start_pose=np.zeros(3), end_pose=np.array([0.1, 0.0, 0.2]),
                           fallen=False, sim_time=3.0, duty_factors=duty, standing_start=True)
    event = conv.outcome_event(conv.outcome_to_msg(outcome))
    assert isinstance(event, io.OutcomeReceived) and event.duty_factors == tuple(duty)


def _wait(simulations, timeout=120.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        answers = simulations.poll()
        if answers:
            return answers
        time.sleep(0.05)
    raise TimeoutError('no answer from the workers')


def test_the_workers_simulate_as_the_map_builder_and_say_why_when_they_cannot():
    from sim_bridge.evaluation import evaluate_gait

    archive = load_archive(default_archive_path())
    settings = archive.simulator_settings
    simulations = SelfModelSimulations(archive.params, settings, 'hexapod', workers=2)
    try:
        gaits = (3, 11, 42)
        simulations.submit(io.SimulateDamage('remove:front_left', gaits))
        assert simulations.busy == 1
        (answer,) = _wait(simulations)
        assert simulations.busy == 0 and answer.error == '' and answer.gaits == gaits
        for g, gr, fell in zip(gaits, answer.generic_reward, answer.fallen):
            outcome = evaluate_gait(archive.params[g], 'remove:front_left', settings['dt'],
                                    settings['gait_duration'], settings['solver_iterations'])
            np.testing.assert_allclose(gr, outcome.generic_reward)
            assert fell == outcome.fallen
        simulations.submit(io.SimulateDamage('remove:middle_centre', gaits))
        (answer,) = _wait(simulations)
        assert answer.error and 'middle_centre' in answer.error and not answer.generic_reward
        simulations.submit(io.SimulateDamage('remove:front_left', gaits))
        simulations.cancel()
        assert simulations.busy == 0 and simulations.poll() == []
    finally:
        simulations.close()
