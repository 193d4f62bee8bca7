"""The one ``main()`` of every sela_ros node (Jazzy style: init, spin, clean shutdown)."""
import signal
import sys
import threading

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation
from rclpy.signals import SignalHandlerOptions

from sela_ros.nodes.guard import guard_clock, spin_guarded
from sela_ros.nodes.params import StartupParameterError, params_file_problems

#: Exit status of a node that refuses to start on a bad configuration (as argparse's).
EXIT_BAD_CONFIGURATION = 2

#: Longest wait (s) of the spin between two looks at a Ctrl-C: how long stopping can take.
SPIN_PERIOD = 0.1

_interrupted = threading.Event()


def _on_sigint(signum, frame):
    """Ctrl-C asks the spin to end at its next wake-up; the node then shuts down cleanly.

    Nothing is raised: a KeyboardInterrupt lands wherever the interpreter happens to be
    (inside rclpy's wait, its clean-up, a callback), and under `ros2 launch` Ctrl-C comes
    twice (the terminal's SIGINT to the process group, then launch's own), so a raised one
    could cut the clean-up short or leave it stuck. Later Ctrl-Cs are ignored from here on
    (not merely repeated: while the interpreter exits, a Python handler reverts to the
    default one, which would kill the process).
    SIGTERM keeps rclpy's handler (the context is shut down: the spin ends too).
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _interrupted.set()


def run_node(node_class, args=None, executor_factory=SingleThreadedExecutor):
    """Create ``node_class()`` and spin it until Ctrl-C or an external shutdown.

    A malformed ``--params-file`` stops the node before it starts, with the file, the line
    and the problem on stderr and exit status 2: running on defaults the user did not ask
    for would be worse than not running.
    """
    argv = sys.argv if args is None else args
    problems = params_file_problems(argv)
    if problems:
        for problem in problems:
            print(f'[ERROR] [{node_class.__name__}]: {problem}', file=sys.stderr)
        print(f'[ERROR] [{node_class.__name__}]: not started: fix the parameters file',
              file=sys.stderr)
        sys.exit(EXIT_BAD_CONFIGURATION)
    # Ctrl-C is ours (see _on_sigint); rclpy handles SIGTERM only.
    signal.signal(signal.SIGINT, _on_sigint)
    try:
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.SIGTERM)
    except rclpy_implementation.RCLError as exc:
        print(f'[ERROR] [{node_class.__name__}]: not started: {exc}', file=sys.stderr)
        sys.exit(EXIT_BAD_CONFIGURATION)
    status = _spin(node_class, executor_factory)
    if status:
        sys.exit(status)


def _spin(node_class, executor_factory):
    """Create the node and spin it; returns the exit status."""
    node = None
    status = 0
    try:
        node = node_class()
        guard_clock(node)
        executor = executor_factory()
        executor.add_node(node)
        spin_guarded(executor, node, stop=_interrupted.is_set, period=SPIN_PERIOD)
    except StartupParameterError as exc:
        # One line, as for a refused `ros2 param set`: the same check said it.
        name = exc.node_name or node_class.__name__
        print(f'[ERROR] [{name}]: {exc} (not started)', file=sys.stderr)
        status = EXIT_BAD_CONFIGURATION
    except ExternalShutdownException:
        pass
    finally:
        # Also after a SIGTERM or an external shutdown: a Ctrl-C while the interpreter exits
        # would otherwise meet the default handler and kill the process.
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return status
