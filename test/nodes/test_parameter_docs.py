"""One source for every default: the node specs, the core's config classes, the shipped YAML
and docs/parameters.md agree."""
from pathlib import Path

import pytest
import yaml

from sela_ros.tools.parameter_docs import markdown, node_parameters

ROOT = Path(__file__).resolve().parents[2]


def _yaml():
    raw = yaml.safe_load((ROOT / 'config' / 'sela.yaml').read_text())
    return {k.removeprefix('/**/'): v['ros__parameters'] for k, v in raw.items()}


def test_docs_parameters_is_written_from_the_specs():
    text = (ROOT / 'docs' / 'parameters.md').read_text()
    assert text == markdown(), ('docs/parameters.md is out of date: run '
                                '.venv/bin/python -m sela_ros.tools.parameter_docs > '
                                'docs/parameters.md')


@pytest.mark.parametrize('node', sorted(node_parameters()))
def test_the_shipped_yaml_gives_every_parameter_the_codes_default(node):
    shipped = _yaml()[node]
    specs = {s.name: s for s in node_parameters()[node]}
    unknown = sorted(set(shipped) - set(specs) - {'use_sim_time'})
    assert not unknown, f'config/sela.yaml sets {unknown} that {node} does not declare'
    for name, spec in specs.items():
        if spec.default is None:  # not set by default (an empty typed array): absent
            assert name not in shipped, name
            continue
        assert name in shipped, f'config/sela.yaml leaves out {node} {name}'
        value = shipped[name]
        if isinstance(spec.default, float):
            assert float(value) == spec.default, name
        else:
            assert value == spec.default, name


def test_the_adapters_defaults_are_the_cores():
    from sela_ros.core.learning import SELAConfig
    from sela_ros.core.mission import StepperConfig
    from sela_ros.nodes import adapter_params

    specs = {s.name: s.default for s in adapter_params.PARAMETERS}
    config = SELAConfig().to_dict()
    for name in adapter_params.SELA_KEYS:
        # The archive's own value where the spec says auto: checked against the shipped
        # archive in test_launch_and_config.
        if specs[name] != 'auto':
            assert specs[name] == config[adapter_params.SELA_NAMES.get(name, name)], name
    stepper = StepperConfig()
    for name, field in adapter_params.stepper_fields().items():
        if specs[name] != 'auto':  # the archive's: test_adapter_support
            assert specs[name] == getattr(stepper, field), name


def test_auto_and_none_are_spelled_as_words_everywhere():
    """Where a parameter's number can also mean "the archive's" or "off", the YAML, the docs
    and the spec say it with the word; a 0 there is read as the word, with a warning."""
    words = {(node, spec.name): spec.word for node, specs in node_parameters().items()
             for spec in specs if spec.word}
    assert words == {('sim_bridge', 'publish_max_rate'): 'none',
                     ('sela_adapter', 'gp.kernel.sigma'): 'auto',
                     ('sela_adapter', 'fall.kernel.sigma'): 'auto',
                     ('sela_adapter', 'planner.horizon'): 'auto',
                     ('sela_adapter', 'outcome.max_displacement'): 'auto',
                     ('sela_adapter', 'acquisition.caution'): 'none',
                     ('sela_adapter', 'acquisition.progress'): 'none',
                     ('sela_adapter', 'acquisition.reach'): 'none',
                     ('sela_adapter', 'gp.mean.affine'): 'none',
                     ('sela_adapter', 'gp.mean.descriptor'): 'none',
                     ('sela_adapter', 'planner.reach'): 'none',
                     ('sela_adapter', 'gp.hyper.sd'): 'none',
                     ('sela_adapter', 'priors.max_misfit'): 'none',
                     ('sela_adapter', 'priors.weights.sd'): 'none',
                     ('gait_executor', 'fall.min_height'): 'none',
                     ('gait_executor', 'trajectory_rate'): 'auto'}
    shipped = _yaml()
    docs = (ROOT / 'docs' / 'parameters.md').read_text()
    for (node, name), word in words.items():
        spec = next(s for s in node_parameters()[node] if s.name == name)
        assert f'{word} =' in spec.description or f'{word}:' in spec.description, name
        assert '0 =' not in spec.description and '(0:' not in spec.description, name
        if spec.default == word:
            assert shipped[node][name] == word, name
        section = docs.split(f'## {node}\n', 1)[1]  # a name may be another node's too
        assert f'or {word} |' in section.split(f'| `{name}` |', 1)[1].split('\n', 1)[0], name
