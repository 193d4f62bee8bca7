"""Node parameters: one declaration helper and one validator for start-up and run time.

Every node lists its parameters as :class:`Spec` (default, description, range, read-only)
and declares them with :func:`declare`. The same check (:func:`check`) judges a value given
at start-up (``-p``, a params file) and one set at run time (``ros2 param set``), with the
same message: a bad start-up value ends the node with that one line and exit status 2
(:class:`StartupParameterError`, caught by ``node_main.run_node``), a bad run-time value is
refused and nothing changes. ``ros2 param describe`` shows the description, the range and
the read-only flag. An integer is accepted where a double is expected (``ros2 param set
/planner planner.lookahead 1``) and stored as a double.

No name is a prefix of another one dot-segment-wise (``priors`` beside ``priors.max``): the
YAML that ``ros2 param dump`` writes nests the segments, and cannot hold both
(:func:`nesting_conflicts`). A parameter renamed for that keeps its earlier name readable from a
start-up file for one release (``Spec.renamed_from``).

A number that can also be "the archive's value" or "off" takes a word for that
(``Spec.word``: ``auto`` or ``none``), never a magic number: ``gp.kernel.sigma: auto``,
``publish_max_rate: none``. Such a parameter is a string while it holds the word and a number
otherwise (its descriptor allows both), so ``ros2 param dump`` writes either back as it was
given. A 0 given for it, the number that meant the word, is read as the word with a warning,
for one release.

The checks are ROS-free (property-tested); only :func:`declare` touches rclpy.
"""
import difflib
import math
import sys
from collections.abc import Callable
from dataclasses import dataclass


def _is_number(value):
    return isinstance(value, (int, float)) and not isinstance(value, bool)


class StartupParameterError(Exception):
    """A start-up parameter the node refuses: ``str()`` is the one line to print."""

    def __init__(self, message, node_name=None):
        super().__init__(message)
        self.node_name = node_name


@dataclass(frozen=True)
class Spec:
    """One parameter of a node.

    Attributes:
        name: the parameter's name (``planner.lookahead``).
        default: its value when none is given; ``None`` for "not set" (then ``kind``).
        description: what it does, for ``ros2 param describe``.
        low, high: inclusive bounds of a number (either may be None: unbounded).
        unit: appended to messages and the description (``' m'``).
        read_only: only given at start-up (``ros2 param set`` is refused).
        rule: an extra check ``value -> problem or None`` after type and range.
        kind: ``double``, ``integer``, ``bool``, ``string``, ``double_array``,
            ``integer_array`` or ``string_array``; inferred from ``default`` when None.
        renamed_from: an earlier name, still read from a parameter file or ``-p`` (with a
            warning) for one release.
        word: a word accepted beside the ``kind`` of value (``'auto'``, ``'none'``); a 0
            given is read as the word, with a warning.
    """
    name: str
    default: object
    description: str
    low: float | None = None
    high: float | None = None
    unit: str = ''
    read_only: bool = False
    rule: Callable | None = None
    kind: str | None = None
    renamed_from: str | None = None
    word: str | None = None

    @property
    def type(self):
        if self.kind:
            return self.kind
        value = self.default
        if isinstance(value, bool):
            return 'bool'
        if isinstance(value, int):
            return 'integer'
        if isinstance(value, float):
            return 'double'
        if isinstance(value, str):
            return 'string'
        if isinstance(value, (list, tuple)) and value:
            item = Spec(self.name, value[0], '').type
            return f'{item}_array'
        raise ValueError(f'parameter {self.name}: give kind= for default {value!r}')

    def constraints(self):
        """The accepted values in words (``a number in [0.05, 5] m``)."""
        base = {'double': 'a number', 'integer': 'an integer', 'bool': 'true or false',
                'string': 'a string', 'double_array': 'a list of numbers',
                'integer_array': 'a list of integers', 'string_array': 'a list of strings'}
        text = base[self.type]
        low, high = (f'{v:g}' if isinstance(v, float) else str(v) for v in (self.low, self.high))
        if self.low is not None and self.high is not None:
            text += f' in [{low}, {high}]'
        elif self.low is not None:
            text += f' >= {low}'
        elif self.high is not None:
            text += f' <= {high}'
        return text + self.unit + (f' or {self.word}' if self.word else '')


def _is_int(value):
    return isinstance(value, int) and not isinstance(value, bool)


def _is_sequence(value):
    return not isinstance(value, (str, bytes, dict)) and hasattr(value, '__len__')


def _fits(spec, value):
    kind = spec.type
    if kind == 'bool':
        return isinstance(value, bool)
    if kind == 'string':
        return isinstance(value, str)
    if kind.endswith('_array'):
        item = Spec(spec.name, None, '', kind=kind[:-len('_array')])
        return _is_sequence(value) and all(_fits(item, v) for v in value)
    if not (_is_int(value) if kind == 'integer' else _is_number(value)):
        return False
    if isinstance(value, float) and not math.isfinite(value):
        return False
    if kind == 'double' and abs(value) > sys.float_info.max:  # an integer no double holds
        return False
    return ((spec.low is None or value >= spec.low)
            and (spec.high is None or value <= spec.high))


def check(spec, value):
    """What is wrong with ``value`` for ``spec`` (``'must be ..., got ...'``), or None.

    ``None`` (not set) is accepted only for a parameter whose default is not set. An integer
    is a number; a bool is not.
    """
    if value is None and spec.default is None:
        return None
    if spec.word is not None and value == spec.word:
        return None
    if not _fits(spec, value):
        return f'must be {spec.constraints()}, got {value!r}'
    return spec.rule(value) if spec.rule is not None else None


#: How YAML says "no value": what ``ros2 param dump`` writes for a parameter not set, which
#: rcl's parameter file parser hands over as a string.
NULL_WORDS = ('null', 'Null', 'NULL', '~')


def coerce(spec, value):
    """``value`` in the spec's type where it is an integer given for a double, the spec's
    word where it is the 0 that stood for it (:func:`zero_for_word`), and not set where it is
    YAML's null for a parameter not set by default (a dump loads back)."""
    if spec.default is None and spec.type != 'string' and value in NULL_WORDS:
        return None
    if zero_for_word(spec, value):
        return spec.word
    if spec.type == 'double' and _as_double(value):
        return float(value)
    if spec.type == 'double_array' and _is_sequence(value) and all(map(_as_double, value)):
        return [float(v) for v in value]
    return value


def zero_for_word(spec, value):
    """Whether ``value`` is a 0 given for a parameter that spells it with a word."""
    return spec.word is not None and _is_number(value) and value == 0


def word_warning(spec):
    """What to tell a user who gave 0 for ``spec``'s word."""
    return (f'parameter {spec.name}: 0 is spelled {spec.word} now: read as {spec.name} = '
            f'{spec.word}; give {spec.word} instead (0 will stop meaning {spec.word})')


def _as_double(value):
    """An integer a double can hold (the nearest one; larger ones are left to be refused)."""
    return _is_int(value) and abs(value) <= sys.float_info.max


def unknown_parameter_message(node_name, name, known):
    """The reason ``ros2 param set`` prints for a name the node does not have: the closest
    names it has, and how to list them."""
    close = difflib.get_close_matches(name, sorted(known), n=3, cutoff=0.6)
    hint = f" (did you mean {' or '.join(repr(c) for c in close)}?)" if close else ''
    return (f'{node_name} has no parameter {name!r}{hint}; `ros2 param list {node_name}` '
            'lists its parameters')


def declare(node, specs, on_change=None):
    """Declare ``specs`` on ``node`` with descriptors; validate now and on every set.

    Args:
        node: an ``rclpy.node.Node`` (before anything else reads its parameters).
        specs: iterable of :class:`Spec`.
        on_change: ``callback(params) -> SetParametersResult or None``, called with a batch
            that passed :func:`check` (never during declaration): the node applies it, or
            refuses it for reasons that need its state.

    Returns:
        ``{name: value}``, the values in effect (integers given for doubles as floats).

    Raises:
        StartupParameterError: a value given at start-up fails :func:`check` (or a range).
    """
    from rcl_interfaces.msg import (
        FloatingPointRange,
        IntegerRange,
        ParameterDescriptor,
        SetParametersResult,
    )
    from rclpy.exceptions import ParameterException, ParameterNotDeclaredException
    from rclpy.parameter import Parameter

    class UnknownParameter(ParameterNotDeclaredException):
        """rclpy's refusal of an undeclared name, worded with the names the node has."""

        def __init__(self, name):
            Exception.__init__(self, unknown_parameter_message(
                node.get_fully_qualified_name(), name, node.list_parameters([], 0).names))

    specs = {spec.name: spec for spec in specs}
    declaring = [True]

    def coerce_batch(params):
        # rclpy's own refusal of an undeclared name comes after this callback and names
        # none of the parameters (its message lists an exhausted generator): said here.
        for p in params:
            if not declaring[0] and not node.has_parameter(p.name):
                raise UnknownParameter(p.name)
        for p in params:
            if p.name in specs and zero_for_word(specs[p.name], p.value):
                node.get_logger().warn(word_warning(specs[p.name]))
        return [Parameter(p.name, value=coerce(specs[p.name], p.value))
                if p.name in specs and coerce(specs[p.name], p.value) is not p.value else p
                for p in params]

    def refused(params, reason):
        # rclpy has already typed each dynamically typed parameter's descriptor after the
        # value it refuses: `ros2 param describe` would show the refused value's type.
        if not declaring[0]:
            for param in params:
                if node.has_parameter(param.name):
                    node.describe_parameter(param.name).type = \
                        node.get_parameter(param.name).type_.value
        return SetParametersResult(successful=False, reason=reason)

    def validate(params):
        for param in params:
            spec = specs.get(param.name)
            problem = check(spec, param.value) if spec is not None else None
            if problem:
                return refused(params, f'{param.name} {problem}')
        if on_change is not None and not declaring[0]:
            result = on_change(params)
            if result is not None and not result.successful:
                return refused(params, result.reason)
            if result is not None:
                return result
        return SetParametersResult(successful=True)

    # Values given at start-up are coerced the way a run-time set is (pre-set callback).
    overrides = getattr(node, '_parameter_overrides', None)
    if isinstance(overrides, dict):
        take_renamed(overrides, specs.values(), node.get_logger().warn)
        for name, param in list(overrides.items()):
            if name in specs:
                overrides[name] = coerce_batch([param])[0]
    node.add_pre_set_parameters_callback(coerce_batch)
    node.add_on_set_parameters_callback(validate)
    declared = []
    for spec in specs.values():
        descriptor = ParameterDescriptor(
            description=spec.description,
            additional_constraints=spec.constraints(), read_only=spec.read_only,
            dynamic_typing=True)
        if spec.type == 'double' and spec.low is not None and spec.high is not None:
            descriptor.floating_point_range = [FloatingPointRange(
                from_value=float(spec.low), to_value=float(spec.high), step=0.0)]
        if spec.type == 'integer' and spec.low is not None and spec.high is not None:
            descriptor.integer_range = [IntegerRange(
                from_value=int(spec.low), to_value=int(spec.high), step=1)]
        declared.append((spec.name, spec.default, descriptor))
    try:
        for name, default, descriptor in declared:
            try:
                node.declare_parameter(name, default, descriptor)
            except ParameterException as exc:
                # rclpy refused it through the same descriptor and callback as a run-time
                # set: the reason is the message `ros2 param set` would print.
                reason = str(exc).split('Reason: ', 1)[-1].removesuffix(f': {name}')
                raise StartupParameterError(reason, node.get_name()) from None
    finally:
        declaring[0] = False
    values = {name: node.get_parameter_or(name) for name in specs}
    return {name: None if param is None else param.value for name, param in values.items()}


def nesting_conflicts(names):
    """Pairs ``(a, b)`` of ``names`` where ``a`` is a dot-segment prefix of ``b``
    (``priors`` and ``priors.max``): ``ros2 param dump`` nests segments into YAML mappings,
    and a value cannot also be a mapping."""
    segments = {name: tuple(name.split('.')) for name in names}
    return sorted((a, b) for a, sa in segments.items() for b, sb in segments.items()
                  if a != b and sb[:len(sa)] == sa)


def take_renamed(overrides, specs, warn):
    """Move start-up values given under a spec's earlier name (``renamed_from``) to its
    name in ``overrides`` (``{name: Parameter}``), calling ``warn(message)`` for each.

    The earlier name wins over the new one: only a user's own file or ``-p`` still says it
    (layered over the shipped configuration, which has the new name).
    """
    for spec in specs:
        old = spec.renamed_from
        if not old or old not in overrides:
            continue
        param = overrides.pop(old)
        overrides[spec.name] = type(param)(spec.name, value=param.value)
        warn(f'parameter {old} is now {spec.name}: read as {spec.name} = {param.value!r}; '
             'rename it in the parameter file (the old name will stop working)')


def _tag_blind_loader():
    """A safe YAML loader that reads a node with an unknown tag as if it had none, as rcl's
    parser does: launch_ros writes a list given in a launch file as ``!!python/tuple``."""
    import yaml

    class Loader(yaml.SafeLoader):
        pass

    def untagged(loader, suffix, node):
        if isinstance(node, yaml.SequenceNode):
            return loader.construct_sequence(node, deep=True)
        if isinstance(node, yaml.MappingNode):
            return loader.construct_mapping(node, deep=True)
        return loader.construct_scalar(node)

    Loader.add_multi_constructor('', untagged)
    return Loader


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
                data = yaml.load(handle, Loader=_tag_blind_loader())  # noqa: S506 - safe
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
