"""A module's state is changed by its owner: no module reaches into another's private names.

``obj._name`` is allowed on ``self`` and ``cls``, and on any object in the module that
defines ``_name`` (a class working on another instance of itself). Anywhere else it is an
object's insides used from outside, which this test refuses, with the place.
"""
import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# Private names of other libraries that have no public equivalent, and why.
THIRD_PARTY = {
    '_negative_number_matcher': 'argparse before Python 3.13 has no public way to take '
                                '"-2,1.5" as a value',
}


def _modules():
    for package in ('sela_ros', 'sim_bridge'):
        yield from sorted((ROOT / package).rglob('*.py'))


def _defined_private_names(tree):
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif (isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store)
              and isinstance(node.value, ast.Name) and node.value.id in ('self', 'cls')):
            names.add(node.attr)
        elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
            names.add(node.id)
    return {n for n in names if n.startswith('_') and not n.startswith('__')}


def _private_uses(path):
    tree = ast.parse(path.read_text())
    own = _defined_private_names(tree)
    for node in ast.walk(tree):
        if not isinstance(node, ast.Attribute):
            continue
        name = node.attr
        if not name.startswith('_') or name.startswith('__') or name in THIRD_PARTY:
            continue
        if isinstance(node.value, ast.Name) and node.value.id in ('self', 'cls'):
            continue
        if name in own:
            continue
        yield f'{path.relative_to(ROOT)}:{node.lineno}: {ast.unparse(node)}'


def test_no_module_uses_another_modules_private_names():
    found = [use for path in _modules() for use in _private_uses(path)]
    assert not found, 'private names used from outside their module:\n' + '\n'.join(found)


def test_the_rule_sees_a_use_from_outside(tmp_path):
    sample = tmp_path / 'sample.py'
    sample.write_text('def f(stepper):\n    stepper._plan = None\n    return stepper._x\n')
    global ROOT
    saved, ROOT = ROOT, tmp_path
    try:
        found = list(_private_uses(sample))
    finally:
        ROOT = saved
    # Assigning another object's private name does not make it this module's own.
    assert found == ['sample.py:2: stepper._plan', 'sample.py:3: stepper._x']
