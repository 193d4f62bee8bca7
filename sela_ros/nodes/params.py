"""Validation of node parameters set at run time (ROS-free, property-tested).

A node lists a rule per parameter; :func:`first_problem` checks a whole batch before any of
it is applied, so a rejected ``ros2 param set`` changes nothing and says why.
"""
import math

STARTUP_ONLY = 'can only be set at start-up (restart the node with the new value)'


def _is_number(value):
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def positive_number(unit=''):
    def rule(value):
        if not (_is_number(value) and math.isfinite(value) and value > 0):
            return f'must be a finite number > 0{unit}, got {value!r}'
        return None
    return rule


def non_negative_number(unit=''):
    def rule(value):
        if not (_is_number(value) and math.isfinite(value) and value >= 0):
            return f'must be a finite number >= 0{unit}, got {value!r}'
        return None
    return rule


def positive_int(value):
    if not (isinstance(value, int) and not isinstance(value, bool) and value > 0):
        return f'must be an integer > 0, got {value!r}'
    return None


def non_negative_int(value):
    if not (isinstance(value, int) and not isinstance(value, bool) and value >= 0):
        return f'must be an integer >= 0, got {value!r}'
    return None


def string(value):
    return None if isinstance(value, str) else f'must be a string, got {value!r}'


def startup_only(value):
    return STARTUP_ONLY


def first_problem(changes, rules):
    """Return ``'<name> <problem>'`` for the first change a rule refuses, else None.

    Args:
        changes: iterable of ``(name, value)``.
        rules: ``{name: rule}``; a rule returns None or what is wrong. Names without a rule
            are accepted (ROS itself checks their declared types).
    """
    for name, value in changes:
        rule = rules.get(name)
        problem = rule(value) if rule is not None else None
        if problem:
            return f'{name} {problem}'
    return None


def params_file_problems(args):
    """Problems with the ``--params-file`` files named in ``args`` (a node's command line).

    rcl refuses a file it cannot parse with a terse message; this says which file, where and
    what, before rcl sees it. Returns a list of messages (empty: all files look right).
    """
    import yaml

    problems = []
    args = list(args or [])
    for i, arg in enumerate(args):
        if arg != '--params-file':
            continue
        if i + 1 >= len(args):
            problems.append('--params-file needs a file name')
            continue
        path = args[i + 1]
        try:
            with open(path) as handle:
                data = yaml.safe_load(handle)
        except OSError as exc:
            problems.append(f'params file {path}: {exc.strerror}')
            continue
        except yaml.YAMLError as exc:
            mark = getattr(exc, 'problem_mark', None)
            where = f':{mark.line + 1}:{mark.column + 1}' if mark is not None else ''
            what = getattr(exc, 'problem', None) or str(exc)
            problems.append(f'params file {path}{where}: not valid YAML: {what}')
            continue
        if not isinstance(data, dict):
            problems.append(f'params file {path}: expected a mapping of node names, each with '
                            'a ros__parameters mapping')
            continue
        for node, section in data.items():
            if not (isinstance(section, dict)
                    and isinstance(section.get('ros__parameters'), dict)):
                problems.append(f'params file {path}: node {node!r} needs a '
                                'ros__parameters mapping')
    return problems
