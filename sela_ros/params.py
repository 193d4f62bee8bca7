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
