"""Start-up of the adapter on a long life's state file: how long taking it back takes.

Builds a state file of ``--observations`` steps on the shipped archive (gaits drawn at
random, each landing where the archive says, a few centimetres off, 2 % of them fallen), then
takes it back as the ``sela_adapter`` node does at start-up (its parameters from
config/sela.yaml, the damage priors, :func:`persistence.resume_state` into a fresh stepper),
and prints the time and the observations kept (``max_observations``)::

    nice -n 10 .venv/bin/python benchmarks/bench_state_file.py --observations 3000
"""
import argparse
import logging
import os
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

from sela_ros.core.storage import load_archive, persistence, resolve_archive_path
from sela_ros.core.validation import OutcomeLimits
from sela_ros.nodes import adapter_params, adapter_support

CONFIG = Path(__file__).resolve().parents[1] / 'config' / 'sela.yaml'


def adapter_values():
    """The adapter's parameters: their defaults, with config/sela.yaml's over them."""
    values = {spec.name: spec.default for spec in adapter_params.PARAMETERS}
    with open(CONFIG) as handle:
        config = yaml.safe_load(handle)
    for key, section in config.items():
        if key.removeprefix('/**/') == 'sela_adapter':
            values.update(section['ros__parameters'])
    return values


def state_file(path, archive, values, priors, count, seed):
    """Write a state file of ``count`` observations; returns its size in bytes."""
    rng = np.random.default_rng(seed)
    stepper = adapter_support.new_stepper(values, archive, priors)
    document = persistence.state_document(len(archive), stepper.snapshot())
    indices = rng.integers(0, len(archive), count)
    rewards = archive.generic_reward[indices] + rng.normal(0.0, 0.03, (count, 3))
    sela = document['sela']
    sela.update(indices=indices.tolist(), generic_rewards=rewards.tolist(),
                standing_starts=[False] * count, fall_indices=indices.tolist(),
                fallen=(rng.random(count) < 0.02).tolist())
    persistence.atomic_write_json(path, document)
    return os.path.getsize(path)


def take_back(path, archive, values, priors):
    """As the node's start-up: the state file into a fresh stepper; returns the stepper."""
    restored = {}

    def restore(state):
        stepper = adapter_support.new_stepper(values, archive, priors)
        stepper.restore(state, 0.0)
        restored['stepper'] = stepper

    limit = adapter_params.stepper_config(values, archive).max_displacement
    _, problem = persistence.resume_state(path, len(archive), restore,
                                          limits=OutcomeLimits(limit))
    if problem:
        raise SystemExit(problem)
    return restored['stepper']


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--observations', type=int, nargs='+', default=[300, 1000, 3000])
    parser.add_argument('--seed', type=int, default=0)
    args = parser.parse_args(argv)
    values = adapter_values()
    path = resolve_archive_path(values['archive'])
    archive = load_archive(path)
    priors = adapter_support.load_priors(values['priors.tables'], archive, path,
                                         logging.getLogger('bench_state_file'))
    print(f'archive {Path(path).name}: {len(archive)} gaits; damage priors: '
          f'{0 if priors is None else len(priors)}')
    with tempfile.TemporaryDirectory() as tmp:
        for count in args.observations:
            file = Path(tmp) / f'state_{count}.json'
            size = state_file(file, archive, values, priors, count, args.seed)
            start = time.perf_counter()
            stepper = take_back(file, archive, values, priors)
            seconds = time.perf_counter() - start
            kept = len(stepper.sela.observations[0])
            print(f'{count:6d} observations ({size / 1e6:.2f} MB): taken back in '
                  f'{seconds:7.2f} s, {kept} kept', flush=True)


if __name__ == '__main__':
    main()
