"""The one ``main()`` of every sela_ros node (Jazzy style: init, spin, clean shutdown)."""
import signal
import sys

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation

from sela_ros.nodes.guard import spin_guarded
from sela_ros.nodes.params import StartupParameterError, params_file_problems

#: Exit status of a node that refuses to start on a bad configuration (as argparse's).
EXIT_BAD_CONFIGURATION = 2


def _first_interrupt_only(signum, frame):
    """Ctrl-C in a terminal under `ros2 launch` reaches every node twice (the terminal's
    SIGINT to the process group, then launch's own): the second must not interrupt the
    clean shutdown with a KeyboardInterrupt traceback. SIGTERM still ends a stuck node."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    raise KeyboardInterrupt


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
    # Installed before rclpy.init so that rclpy's handler (which wakes the executor) chains
    # to it: the first Ctrl-C ends the spin, any later one is ignored at once.
    signal.signal(signal.SIGINT, _first_interrupt_only)
    try:
        rclpy.init(args=args)
    except rclpy_implementation.RCLError as exc:
        print(f'[ERROR] [{node_class.__name__}]: not started: {exc}', file=sys.stderr)
        sys.exit(EXIT_BAD_CONFIGURATION)
    try:
        status = _spin(node_class, executor_factory)
    except KeyboardInterrupt:
        # The one Ctrl-C our handler turns into KeyboardInterrupt can land after rclpy's own
        # handler already ended the spin, inside the clean-up (seen under load): the clean-up
        # was cut short, so finish it here; later Ctrl-Cs are ignored already.
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        rclpy.try_shutdown()
        status = 0
    if status:
        sys.exit(status)


def _spin(node_class, executor_factory):
    """Create the node and spin it; returns the exit status."""
    node = None
    status = 0
    try:
        node = node_class()
        executor = executor_factory()
        executor.add_node(node)
        spin_guarded(executor, node)
    except StartupParameterError as exc:
        # One line, as for a refused `ros2 param set`: the same check said it.
        name = exc.node_name or node_class.__name__
        print(f'[ERROR] [{name}]: {exc} (not started)', file=sys.stderr)
        status = EXIT_BAD_CONFIGURATION
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # also after an external shutdown
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return status
