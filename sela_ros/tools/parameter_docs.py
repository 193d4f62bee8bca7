"""``docs/parameters.md``, written from the nodes' own parameter specs (one source).

    .venv/bin/python -m sela_ros.tools.parameter_docs > docs/parameters.md

``test/nodes/test_parameter_docs.py`` checks that the file is what this writes, and that
``config/sela.yaml`` gives every parameter the default the code has.
"""
import sys


def node_parameters():
    """``{node name: (Spec, ...)}`` for the four nodes and the gait executor, as each
    declares them."""
    from sela_ros.core.detection import DetectorConfig
    from sela_ros.nodes import (
        adapter_params,
        damage_detector_node,
        gait_executor_node,
        planner_node,
    )
    from sela_ros.nodes import interface as ifc
    from sim_bridge import node as sim_node

    return {ifc.SIM_BRIDGE: sim_node.PARAMETERS, ifc.PLANNER: planner_node.PARAMETERS,
            ifc.DAMAGE_DETECTOR: damage_detector_node.parameters(DetectorConfig()),
            ifc.SELA_ADAPTER: adapter_params.PARAMETERS,
            ifc.GAIT_EXECUTOR: gait_executor_node.PARAMETERS}


def _default(spec):
    if spec.default is None:
        return 'not set'
    if isinstance(spec.default, bool):
        return str(spec.default).lower()
    if isinstance(spec.default, str):
        return f'`"{spec.default}"`'
    return f'`{spec.default}`'


def markdown():
    """The parameter reference, one table per node."""
    out = ['# Parameters', '',
           'Every parameter of the four nodes and of the gait executor (docs/hardware.md), with',
           'its default, the values it takes and whether it can change at run time',
           '(`ros2 param set`); written from the code by',
           '`python -m sela_ros.tools.parameter_docs`. `config/sela.yaml` sets each to the same',
           'default, keyed `/**/<node>` so that it applies in any namespace.', '']
    for node, specs in node_parameters().items():
        out += [f'## {node}', '', '| parameter | default | values | run time | what it does |',
                '| --- | --- | --- | --- | --- |']
        for spec in specs:
            description = spec.description.replace('|', '\\|')
            out.append(f'| `{spec.name}` | {_default(spec)} | {spec.constraints()} | '
                       f"{'no' if spec.read_only else 'yes'} | {description} |")
        out.append('')
    return '\n'.join(out)


def main():
    sys.stdout.write(markdown())
    return 0


if __name__ == '__main__':
    sys.exit(main())
