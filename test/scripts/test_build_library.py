"""The damage library's build plan: its conditions, its covering gaits, the gaits inferred."""
import importlib.util
from pathlib import Path

import numpy as np
import pytest

from sim_bridge.damage import parse_damage

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope='module')
def lib():
    spec = importlib.util.spec_from_file_location('build_library',
                                                  ROOT / 'scripts' / 'build_library.py')
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_plan_spans_the_kinds_parses_and_fits_the_budget(lib):
    names = lib.conditions()
    assert len(set(names)) == len(names)
    specs = [parse_damage(n) for n in names]  # every one a valid damage
    assert sum(len(s.removed) == 2 for s in specs) == 15  # every pair of legs removed
    assert {s.shortened[0][1] for s in specs if len(s.shortened) == 1} == \
        set(lib.SHORTEN_FACTORS)
    assert any(s.blocked for s in specs)
    _, evaluations, hours, _ = lib.plan(12442, lib.DEFAULT_GAITS)
    assert evaluations == len(names) * lib.DEFAULT_GAITS and hours <= lib.BUDGET_CORE_HOURS


def test_the_gaits_evaluated_cover_the_map(lib):
    rng = np.random.default_rng(0)
    descriptors = rng.random((2000, 3))
    subset = lib.gait_subset(descriptors, 200)
    assert len(set(subset.tolist())) == 200
    np.testing.assert_array_equal(subset, lib.gait_subset(descriptors, 200))  # resumable
    gap = np.min(np.linalg.norm(descriptors[:, None] - descriptors[subset][None], axis=2),
                 axis=1)
    random = rng.choice(2000, 200, replace=False)
    gap_random = np.min(np.linalg.norm(descriptors[:, None] - descriptors[random][None],
                                       axis=2), axis=1)
    assert gap.max() < gap_random.max()


def test_the_gaits_not_evaluated_are_inferred_from_their_neighbours(lib):
    rng = np.random.default_rng(1)
    descriptors = rng.random((1500, 2))
    base = np.column_stack([descriptors, np.zeros(1500)])
    # A damage that takes a smooth share of every gait's displacement, and tips over the
    # gaits of one corner.
    truth = base * (0.3 + 0.4 * descriptors[:, :1])
    falls = (descriptors[:, 0] > 0.8) & (descriptors[:, 1] > 0.8)
    subset = lib.gait_subset(descriptors, 300)
    gr, fallen = lib.infer(descriptors, base, subset, truth[subset], falls[subset], 0.1)
    np.testing.assert_array_equal(gr[subset], truth[subset])
    assert np.abs(gr - truth).max() < 0.05
    assert np.mean(fallen == falls) > 0.97
