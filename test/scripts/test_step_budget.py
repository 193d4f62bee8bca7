"""Where a mission's steps go: each step classed from its record, runs and DDS summaries."""
import json
import math

import numpy as np
import pytest
from script_modules import load_script


@pytest.fixture(scope='module')
def budget():
    return load_script('step_budget')


def _step(index, pose, predicted, observed, fallen=False):
    return {'behavior_index': index, 'pose': list(pose), 'predicted_gr': list(predicted),
            'observed_gr': list(observed), 'fallen': fallen}


def test_each_kind_of_step_is_told_apart(budget):
    goal = (2.0, 0.0)
    steps = [
        _step(1, (0, 0, 0), (0.4, 0, 0), (0.38, 0, 0)),                # as predicted, nearer
        _step(2, (0.38, 0, 0), (0.4, 0, 0), (0.05, 0, 0)),             # new gait, 0.35 m short
        _step(1, (0.43, 0, 0), (0.4, 0, 0), (0.1, 0.1, 0)),            # proven gait, short
        _step(3, (0.53, 0.1, 0), (0.0, 0, 1.0), (0.0, 0.0, 0.9)),      # turns on the spot
        _step(4, (0.53, 0.1, 0.9), (0.0, 0.05, 0), (0.0, 0.04, 0.0)),  # as predicted, no gain
        _step(5, (0.53, 0.1, 0.9), (0.3, 0, 0), (0.1, 0, 0), fallen=True),
    ]
    assert budget.classify(steps, goal) == [
        'progress', 'untried, disappointed', 'proven, disappointed', 'turning',
        'out of reach', 'fell']


def test_the_table_counts_a_traced_run_and_a_dds_summary_alike(budget, tmp_path):
    """A real run of the loop the nodes run, kept with its steps' records, and the same steps
    as a DDS mission's summary.json: each step in one class, the oracle's steps beside."""
    from sela_ros.core.storage import default_archive_path
    from sela_ros.experiments.hexapod import Job, run_method

    job = Job('sela', np.random.SeedSequence(0), str(default_archive_path()),
              'remove:middle_right', (1.0, 0.5), noise_std=0.01, max_steps=12, noise_seed=0,
              trace=True)
    out = run_method(job)
    assert len(out['steps_detail']) == out['steps'] > 0
    run = {'case': 'c', 'damage': 'remove:middle_right', 'goal': [1.0, 0.5],
           'method': 'sela', 'seed': 0, 'success': out['success'], 'steps': out['steps'],
           'falls': out['falls'], 'steps_detail': out['steps_detail']}
    oracle = dict(run, method='oracle', steps=2)
    oracle.pop('steps_detail')
    runs = tmp_path / 'runs.jsonl'
    runs.write_text(json.dumps(run) + '\n' + json.dumps(oracle) + '\n')
    # A DDS mission's summary keeps each step's status as sent: text.
    as_text = [{k: ' '.join(map(str, v)) if isinstance(v, list) else str(v)
                for k, v in step.items()} for step in out['steps_detail']]
    summary = tmp_path / 'summary.json'
    summary.write_text(json.dumps({'damage': 'remove:middle_right', 'goal': [1.0, 0.5],
                                   'steps': out['steps'], 'success': out['success'],
                                   'steps_detail': as_text}))
    missions = budget.load([str(runs), str(summary)])
    assert [m[0] for m in missions] == ['sela', 'DDS mission']
    text = budget.budget_table(missions, {('remove:middle_right', (1.0, 0.5)): 2.0},
                               lambda damage: 'remove')
    rows = [line for line in text.splitlines()[2:]]
    assert len(rows) == 2
    for row in rows:
        cells = [c.strip() for c in row.strip('|').split('|')]
        assert cells[4] == str(out['steps'])
        assert cells[5] == '2 (1)' and cells[6] == str(out['steps'] - 2)
        assert sum(int(c) for c in cells[7:]) == out['steps']


def test_a_step_brings_the_robot_where_its_generic_reward_says(budget):
    end = budget._after((1.0, 1.0, math.pi / 2), (0.5, 0.0, 0.1))
    np.testing.assert_allclose(end, (1.0, 1.5, math.pi / 2 + 0.1), atol=1e-12)
