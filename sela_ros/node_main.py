"""The one ``main()`` of every sela_ros node (Jazzy style: init, spin, clean shutdown)."""
import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor


def run_node(node_class, args=None, executor_factory=SingleThreadedExecutor):
    """Create ``node_class()`` and spin it until Ctrl-C or an external shutdown."""
    rclpy.init(args=args)
    node = None
    try:
        node = node_class()
        executor = executor_factory()
        executor.add_node(node)
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
