"""The layers of the package: imports only go down, and nothing imports in a circle.

Every import counts, at module level or inside a function. Ranks, bottom up: the learning
core (numpy/scipy only, no ROS); the robot (sim_bridge's simulator modules, which may use the
core's geometry); map building (qd); experiments and the ROS nodes; the simulator's node;
the tools (demo, archive builder, mission client). Inside the core, the same rule between its
subpackages (CORE_RANKS).
"""
import ast
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
RANKS = {'sela_ros.core': 0, 'sim_bridge.robot': 1, 'sela_ros.qd': 2,
         'sela_ros.experiments': 3, 'sela_ros.nodes': 3, 'sim_bridge.node': 4,
         'sela_ros.tools': 5, 'sela_ros': 6}
# Besides numpy/scipy, two file-format readers for the map loader (core/planning/maps.py): pyyaml
# for map YAML files and Pillow (which matplotlib brings) for PNG maps. Never ROS.
CORE_MAY_IMPORT = {'numpy', 'scipy', 'sela_ros', 'yaml', 'PIL'}
# The core's subpackages, bottom up; its root (geometry) is under them all.
CORE_RANKS = {'sela_ros.core': 0, 'sela_ros.core.validation': 1, 'sela_ros.core.storage': 2,
              'sela_ros.core.planning': 2, 'sela_ros.core.detection': 2,
              'sela_ros.core.learning': 3, 'sela_ros.core.mission': 4}


def _modules():
    found = {}
    for package in ('sela_ros', 'sim_bridge'):
        for path in sorted((ROOT / package).rglob('*.py')):
            parts = list(path.relative_to(ROOT).with_suffix('').parts)
            if parts[-1] == '__init__':
                parts.pop()
            found['.'.join(parts)] = path
    return found


MODULES = _modules()


def _imports(name, path):
    """Every module ``name`` imports (absolute names, relative ones resolved)."""
    out = set()
    package = name if path.name == '__init__.py' else name.rsplit('.', 1)[0]
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ''
            if node.level:
                base = '.'.join(package.split('.')[:len(package.split('.')) - node.level + 1]
                                + ([base] if base else []))
            submodules = {f'{base}.{alias.name}' for alias in node.names
                          if f'{base}.{alias.name}' in MODULES}
            # Submodules of the package this module is in: its __init__ is not imported again.
            if not (name.startswith(f'{base}.') and len(submodules) == len(node.names)):
                out.add(base)
            out.update(submodules)
    return out


IMPORTS = {name: _imports(name, path) for name, path in MODULES.items()}


def _layer(module):
    if module.startswith('sim_bridge'):
        return 'sim_bridge.node' if module == 'sim_bridge.node' else 'sim_bridge.robot'
    parts = module.split('.')
    return '.'.join(parts[:2]) if len(parts) > 1 else parts[0]


def _core_part(module):
    """The core subpackage ``module`` is in (the core's root for its own modules)."""
    parts = module.split('.')
    package = '.'.join(parts[:3])
    return package if package in CORE_RANKS else 'sela_ros.core'


def _internal(module):
    return module in MODULES


def test_every_module_is_in_a_layer():
    assert {_layer(m) for m in MODULES} <= set(RANKS)


@pytest.mark.parametrize('module', sorted(MODULES))
def test_imports_only_go_down(module):
    here = RANKS[_layer(module)]
    for target in sorted(filter(_internal, IMPORTS[module])):
        if target in ('sela_ros', 'sim_bridge'):
            continue  # the packages themselves: version strings only
        there = RANKS[_layer(target)]
        assert there <= here, f'{module} (layer {_layer(module)}) imports {target} ' \
            f'(layer {_layer(target)}, above it)'


CORE_MODULES = sorted(m for m in MODULES if _layer(m) == 'sela_ros.core')


def test_every_core_package_has_a_rank():
    packages = {m for m in CORE_MODULES if (ROOT / m.replace('.', '/') / '__init__.py').exists()}
    assert packages == set(CORE_RANKS)


@pytest.mark.parametrize('module', CORE_MODULES)
def test_inside_the_core_imports_only_go_down(module):
    here = CORE_RANKS[_core_part(module)]
    inside = (t for t in IMPORTS[module] if _internal(t) and _layer(t) == 'sela_ros.core')
    for target in sorted(inside):
        there = CORE_RANKS[_core_part(target)]
        assert there < here or _core_part(target) == _core_part(module), \
            f'{module} ({_core_part(module)}) imports {target} ({_core_part(target)}, ' \
            'not below it)'


@pytest.mark.parametrize('module', CORE_MODULES)
def test_the_core_imports_numpy_and_scipy_only(module):
    stdlib = sys.stdlib_module_names
    for target in IMPORTS[module]:
        top = target.split('.')[0]
        assert top in stdlib or top in CORE_MAY_IMPORT or top == '__future__', \
            f'{module} imports {target}: the core is numpy/scipy only (no ROS)'
        if top == 'sela_ros' and target != 'sela_ros':  # the package root: its version
            assert target.startswith('sela_ros.core'), f'{module} imports {target}'


def _cycle(graph):
    """A cycle of ``graph`` ({node: set of nodes}) as a list, or None."""
    state = {}

    def visit(node, trail):
        state[node] = 'open'
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 'open':
                return trail[trail.index(nxt):] + [nxt]
            if nxt not in state:
                found = visit(nxt, trail + [nxt])
                if found:
                    return found
        state[node] = 'done'
        return None

    for start in sorted(graph):
        if start not in state:
            found = visit(start, [start])
            if found:
                return found
    return None


def test_no_import_cycle_between_modules():
    graph = {m: {t for t in IMPORTS[m] if _internal(t) and t != m
                 and t not in ('sela_ros', 'sim_bridge')} for m in MODULES}
    assert _cycle(graph) is None, ' -> '.join(_cycle(graph))


def test_no_import_cycle_between_layers():
    graph = {}
    for module, targets in IMPORTS.items():
        for target in filter(_internal, targets):
            if _layer(target) != _layer(module) and target not in ('sela_ros', 'sim_bridge'):
                graph.setdefault(_layer(module), set()).add(_layer(target))
    assert _cycle(graph) is None, ' -> '.join(_cycle(graph))


def test_no_import_cycle_between_core_packages():
    graph = {}
    for module in CORE_MODULES:
        for target in filter(_internal, IMPORTS[module]):
            if _layer(target) == 'sela_ros.core' and _core_part(target) != _core_part(module):
                graph.setdefault(_core_part(module), set()).add(_core_part(target))
    assert _cycle(graph) is None, ' -> '.join(_cycle(graph))


def test_the_cycle_finder_finds_cycles():
    assert _cycle({'a': {'b'}, 'b': {'c'}, 'c': {'a'}}) == ['a', 'b', 'c', 'a']
    assert _cycle({'a': {'b'}, 'b': set()}) is None
