"""A minimal publisher or subscriber process, for the first DDS integration test."""
import sys
import time

import rclpy
from rclpy.executors import ExternalShutdownException
from std_msgs.msg import String


def main():
    role, topic, payload, timeout = sys.argv[1], sys.argv[2], sys.argv[3], float(sys.argv[4])
    rclpy.init()
    node = rclpy.create_node(f'dds_probe_{role}')
    received = []
    try:
        if role == 'pub':
            pub = node.create_publisher(String, topic, 10)
            deadline = time.monotonic() + timeout
            while time.monotonic() < deadline:
                pub.publish(String(data=payload))
                rclpy.spin_once(node, timeout_sec=0.1)
            return 0
        node.create_subscription(String, topic, lambda m: received.append(m.data), 10)
        deadline = time.monotonic() + timeout
        while not received and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.1)
        if received:
            print(f'RECEIVED {received[0]}', flush=True)
            return 0
        print('TIMEOUT', flush=True)
        return 1
    except (KeyboardInterrupt, ExternalShutdownException):
        return 2
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
