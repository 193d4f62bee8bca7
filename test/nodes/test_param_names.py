"""Every node's parameter names nest in the YAML of ``ros2 param dump``: none is a prefix of
another, and an earlier name is read as the new one."""
import pytest

from sela_ros.nodes.params import Spec, nesting_conflicts, take_renamed
from sela_ros.tools.parameter_docs import node_parameters

SPECS = node_parameters()  # every node's specs, as docs/parameters.md lists them


@pytest.mark.parametrize('node', sorted(SPECS))
def test_no_parameter_name_is_a_prefix_of_another(node):
    names = [spec.name for spec in SPECS[node]] + ['use_sim_time']
    assert len(set(names)) == len(names)
    assert nesting_conflicts(names) == []


def test_nesting_conflicts_are_found_segment_by_segment():
    assert nesting_conflicts(['priors', 'priors.max.misfit', 'priors.max.misfit.reproduced',
                              'priors_x', 'gp.noise']) == [
        ('priors', 'priors.max.misfit'), ('priors', 'priors.max.misfit.reproduced'),
        ('priors.max.misfit', 'priors.max.misfit.reproduced')]
    assert nesting_conflicts(['map.file', 'map.file_x', 'map']) == [
        ('map', 'map.file'), ('map', 'map.file_x')]


def test_an_earlier_name_is_read_as_the_new_one_with_a_warning():
    from rclpy.parameter import Parameter

    specs = [Spec('priors.tables', 'auto', '', renamed_from='priors'),
             Spec('priors.max_misfit', 0.6, '', renamed_from='priors.max.misfit')]
    overrides = {'priors': Parameter('priors', value='none'),
                 'priors.max.misfit': Parameter('priors.max.misfit', value=0.4),
                 'priors.max_misfit': Parameter('priors.max_misfit', value=0.5)}
    said = []
    take_renamed(overrides, specs, said.append)
    assert set(overrides) == {'priors.tables', 'priors.max_misfit'}
    assert overrides['priors.tables'].value == 'none'
    # The earlier name wins: only a user's own file still says it, over the shipped one.
    assert overrides['priors.max_misfit'].value == 0.4
    assert len(said) == 2 and all('is now' in s for s in said)
