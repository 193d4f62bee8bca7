"""What ``ros2 topic pub -w N --once --keep-alive K <topic> geometry_msgs/msg/PoseStamped``
does (ros2cli's pub verb, Jazzy), for the tests of the README's goal command without a ROS
install: a new node with a publisher of the default QoS (reliable, volatile), wait until N
subscriptions match, publish once, stay alive K seconds, exit.

Usage: python topic_pub.py TOPIC X Y N KEEP_ALIVE [--ros-args ...]
"""
import sys
import time

import rclpy
from geometry_msgs.msg import PoseStamped
from rclpy.qos import QoSProfile


def main():
    topic, x, y, wanted, keep_alive = sys.argv[1:6]
    rclpy.init(args=sys.argv)
    node = rclpy.create_node('ros2cli_pub_emulation')
    pub = node.create_publisher(PoseStamped, topic, QoSProfile(depth=1))
    deadline = time.monotonic() + 60
    while pub.get_subscription_count() < int(wanted):
        if time.monotonic() > deadline:
            print(f'TIMEOUT waiting for {wanted} matching subscription(s)', flush=True)
            return 1
        time.sleep(0.1)
    msg = PoseStamped()
    msg.header.frame_id = 'odom'
    msg.pose.position.x, msg.pose.position.y = float(x), float(y)
    msg.pose.orientation.w = 1.0
    pub.publish(msg)
    time.sleep(float(keep_alive))
    node.destroy_node()
    rclpy.try_shutdown()
    print('PUBLISHED', flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
