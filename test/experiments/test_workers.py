"""A damage measured as if nobody foresaw it: which damage priors the experiments keep."""
import numpy as np
import pytest

from sela_ros.core.learning import DamagePriors, params_checksum, priors_path
from sela_ros.experiments import workers


class _Archive:
    def __init__(self, m=40, seed=0):
        self.params = np.random.default_rng(seed).random((m, 4))


def _priors(archive, names, second):
    rng = np.random.default_rng(3)
    m = len(archive.params)
    gr = rng.normal(0, 0.3, (len(names), m, 3))
    gr[2] = gr[0] + 0.01  # the second tier's shorten:front_left:0.3 is near remove:front_left
    gr[3] = gr[1] + 0.01  # and its block:rear_left.knee=0.4 near remove:rear_left
    return DamagePriors(names, gr, np.zeros((len(names), m), bool),
                        params_checksum(archive.params), reproduce_only=np.array(second))


def test_near_lists_the_table_and_those_within_the_threshold():
    archive = _Archive()
    names = ('remove:front_left', 'remove:rear_left', 'shorten:front_left:0.3',
             'block:rear_left.knee=0.4')
    priors = _priors(archive, names, [False, False, True, True])
    assert priors.near('remove:front_left') == ['remove:front_left', 'shorten:front_left:0.3']
    assert priors.near('remove:front_left', threshold=0.0) == ['remove:front_left']
    with pytest.raises(KeyError):
        priors.near('remove:middle_left')


def test_leaving_a_damage_out_drops_its_table_and_its_near_duplicates_of_the_second_tier(
        tmp_path):
    archive = _Archive()
    names = ('remove:front_left', 'remove:rear_left', 'shorten:front_left:0.3',
             'block:rear_left.knee=0.4')
    map_path = tmp_path / 'map.npz'
    _priors(archive, names, [False, False, True, True]).save(priors_path(map_path))

    def kept(damage):
        priors = workers.load_priors('auto', str(map_path), archive, damage, True)
        return priors.names, priors.second_tier.tolist()

    # A first-tier damage: its own table out, and the library's table near it.
    assert kept('remove:front_left') == (('remove:rear_left', 'block:rear_left.knee=0.4'),
                                         [False, True])
    # A second-tier damage (spelt otherwise): its table out; the first tier's near one stays.
    assert kept('block:rear_left.knee=0.40') == (
        ('remove:front_left', 'remove:rear_left', 'shorten:front_left:0.3'),
        [False, False, True])
    # A damage no table is: nothing out.
    assert kept('friction:0.5')[0] == names
    assert workers.load_priors('auto', str(map_path), archive, 'remove:front_left',
                               False).names == names
