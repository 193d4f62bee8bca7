"""A guard at every edge: an exception in a callback is reported, never the end of the node.

rclpy lets an exception raised by a subscription, timer, service or parameter callback
escape ``spin()``, and the node process dies: one malformed message, one unforeseen value,
and the robot loses a node (and, before it is restarted, whatever it was doing). Each
callback of a node is decorated with one of these; an exception becomes an ERROR on
``diagnostics`` (name ``<node>: <what>``, the exception type and message) and in the log
(with the traceback), and the node goes on with the next message:

* :func:`guard` for subscriptions, timers and future done-callbacks (nothing to return);
* :func:`guard_service` for services: the response is returned, with ``success`` false and
  the error in ``message`` when the type has those fields;
* :func:`guard_parameters` for on-set-parameters callbacks: the change is refused with the
  error as the reason (nothing is applied: a callback validates before it applies).
"""
import functools
import time
import traceback
import weakref

from diagnostic_msgs.msg import DiagnosticStatus
from rcl_interfaces.msg import SetParametersResult
from rosgraph_msgs.msg import Clock as ClockMsg

from sela_ros.nodes import interface as ifc
from sela_ros.nodes.conversions import diagnostic_array, diagnostic_status

MAX_TEXT = 400  # characters of an exception message kept (a fuzzed message can be huge)
# Each node's diagnostics publisher for reports of failed callbacks, made on the first one.
_PUBLISHERS = weakref.WeakKeyDictionary()


def _short(text):
    text = str(text)
    return text if len(text) <= MAX_TEXT else text[:MAX_TEXT] + f'... ({len(text)} chars)'


def report_exception(node, what, exc):
    """Log ``exc`` with its traceback and publish it as an ERROR on ``/diagnostics``.

    Never raises: a report that cannot be published (the node is shutting down) is only
    logged. Returns the one-line description.
    """
    line = f'{what} failed: {type(exc).__name__}: {_short(exc)} (the node keeps running)'
    try:
        node.get_logger().error(line + '\n' + _short(''.join(
            traceback.format_exception(type(exc), exc, exc.__traceback__)[-6:])))
    except Exception:  # noqa: BLE001 - the logger itself failing must not end the node
        pass
    try:
        pub = _PUBLISHERS.get(node)
        if pub is None:
            pub = _PUBLISHERS[node] = ifc.publisher(node, ifc.DIAGNOSTICS)
        pub.publish(diagnostic_array(
            diagnostic_status(DiagnosticStatus.ERROR, f'{node.get_name()}: {what}', line,
                              {'exception': type(exc).__name__}),
            node.get_clock().now().to_msg()))
    except Exception:  # noqa: BLE001 - e.g. the context is already shut down
        pass
    return line


def _wrap(method, what, fallback):
    name = what or method.__name__.removesuffix('_callback').replace('_', ' ')

    @functools.wraps(method)
    def guarded(self, *args):
        try:
            return method(self, *args)
        except Exception as exc:  # noqa: BLE001 - that is the point: report, keep running
            return fallback(args, report_exception(self, name, exc))
    return guarded


def _failed_response(args, line):
    response = args[-1] if args else None
    for field, value in (('success', False), ('message', line)):
        if response is not None and hasattr(response, field):
            setattr(response, field, value)
    return response


def _refused(args, line):
    return SetParametersResult(successful=False, reason=line)


def _decorator(fallback, doc):
    def decorate(method=None, *, what=None):
        if method is None:
            return lambda m: _wrap(m, what, fallback)
        return _wrap(method, what, fallback)
    decorate.__doc__ = doc
    return decorate


guard = _decorator(lambda args, line: None, 'Decorate a subscription, timer or done callback '
                   '(``@guard`` or ``@guard(what=...)``).')
guard_service = _decorator(_failed_response, 'Decorate a service callback '
                           '``(self, request, response)``.')
guard_parameters = _decorator(_refused, 'Decorate an on-set-parameters callback '
                              '``(self, params)``.')


#: s (wall): how often refused ``/clock`` messages are said again, with their count.
CLOCK_REFUSAL_PERIOD = 60.0


def clock_problem(msg):
    """What makes a ``rosgraph_msgs/Clock`` unusable as sim time, or None."""
    sec, nanosec = msg.clock.sec, msg.clock.nanosec
    if sec < 0:
        return f'negative seconds ({sec})'
    if nanosec >= 1_000_000_000:
        return f'nanoseconds {nanosec} >= 1e9'
    return None


def guard_clock(node):
    """Refuse ``/clock`` messages rclpy's time source cannot take (``use_sim_time``).

    rclpy's own ``/clock`` subscription raises on a negative time, once per message, out of
    reach of the decorators above. Its callback is wrapped here (now, and whenever
    ``use_sim_time`` turns it on): a bad message is dropped (sim time keeps its last value)
    with one log line, and further ones are counted and said at most every
    :data:`CLOCK_REFUSAL_PERIOD` s."""
    said = {'at': -float('inf'), 'count': 0}

    def refuse(problem):
        said['count'] += 1
        now = time.monotonic()
        if now - said['at'] < CLOCK_REFUSAL_PERIOD:
            return
        node.get_logger().error(
            f'/clock refused: {problem}; sim time keeps its last value ({said["count"]} '
            f'refused so far, said at most every {CLOCK_REFUSAL_PERIOD:g} s)')
        said['at'] = now

    def wrap(*_):
        for sub in node.subscriptions:
            if sub.msg_type is not ClockMsg or getattr(sub.callback, 'clock_guarded', False):
                continue

            def guarded(msg, inner=sub.callback):
                problem = clock_problem(msg)
                if problem:
                    refuse(problem)
                else:
                    inner(msg)
            guarded.clock_guarded = True
            sub.callback = guarded

    wrap()
    node.add_post_set_parameters_callback(wrap)


def spin_guarded(executor, node, stop=None, period=None):
    """``executor.spin()``, except that an exception a callback raises is reported and the
    spin goes on: the outer guard, for what no decorator covers (a lambda, a done callback,
    rclpy's own callbacks such as the sim-time ``/clock`` subscription).

    With ``stop`` (a callable), the spin also ends once ``stop()`` is true, looked at after
    every callback and at least every ``period`` seconds."""
    from rclpy.executors import ExternalShutdownException, ShutdownException

    while executor.context.ok() and not (stop is not None and stop()):
        try:
            executor.spin_once(timeout_sec=period)
        except (ExternalShutdownException, ShutdownException):
            raise
        except Exception as exc:  # noqa: BLE001 - reported; the node keeps running
            report_exception(node, 'callback', exc)
