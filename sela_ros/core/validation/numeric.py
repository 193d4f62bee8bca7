"""Checks at the edge, written once: numbers and arrays of numbers. ROS-free.

Each says what was wrong and what was expected, in the words of the parameter or the field
(``goal.eps must be a number > 0, got -1.0``), so that a node can pass the message on as is.
"""
import math

import numpy as np


def number_problem(value, low=None, high=None, low_open=False, integer=False):
    """What is wrong with ``value`` as a finite number (an integer) in the range, or None."""
    kind = 'an integer' if integer else 'a number'
    ok_type = isinstance(value, int) if integer else isinstance(value, (int, float))
    if isinstance(value, bool) or not ok_type or not math.isfinite(value):
        return f'must be {kind}, got {value!r}'
    if low is not None and (value <= low if low_open else value < low):
        return f"must be {kind} {'>' if low_open else '>='} {low:g}, got {value!r}"
    if high is not None and value > high:
        return f'must be {kind} <= {high:g}, got {value!r}'
    return None


def check_number(name, value, **limits):
    """Raise ValueError (``'<name> must be ...'``) unless :func:`number_problem` is None."""
    problem = number_problem(value, **limits)
    if problem:
        raise ValueError(f'{name} {problem}')
    return value


def finite_array(values, name, length=None, error=ValueError, labels=None):
    """``values`` as a flat float array of finite numbers (``length`` of them if given);
    otherwise raise ``error`` saying which value is wrong (by its name in ``labels``, one per
    value, where given; else by its index)."""
    try:
        array = np.asarray(values, dtype=float).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise error(f'{name}: expected numbers, got {values!r}') from exc
    if length is not None and array.size != length:
        raise error(f'{name}: expected {length} values, got {array.size}')
    bad = ~np.isfinite(array)
    if bad.any():
        first = int(np.flatnonzero(bad)[0])
        which = labels[first] if labels is not None and first < len(labels) else \
            f'value {first}'
        raise error(f'{name}: {which} is {array[first]}; expected finite numbers')
    return array
