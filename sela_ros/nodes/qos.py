"""Named QoS profiles of the sela_ros graph, one place for every node and tool."""
from rclpy.qos import QoSDurabilityPolicy, QoSHistoryPolicy, QoSProfile, QoSReliabilityPolicy

# Streams where only the latest sample matters (clock, odometry, joint states, diagnostics).
STATE_QOS = QoSProfile(depth=10, history=QoSHistoryPolicy.KEEP_LAST,
                       reliability=QoSReliabilityPolicy.RELIABLE)
# A goal, a map, a path, a target: a node that starts late must still get the last one.
LATCHED_QOS = QoSProfile(depth=1, history=QoSHistoryPolicy.KEEP_LAST,
                         reliability=QoSReliabilityPolicy.RELIABLE,
                         durability=QoSDurabilityPolicy.TRANSIENT_LOCAL)
# Commands and their outcomes: none may be lost, each is paired one to one.
COMMAND_QOS = QoSProfile(depth=50, history=QoSHistoryPolicy.KEEP_LAST,
                         reliability=QoSReliabilityPolicy.RELIABLE)
# Outcomes are also kept for a late joiner (a restarted adapter or detector).
OUTCOME_QOS = QoSProfile(depth=50, history=QoSHistoryPolicy.KEEP_LAST,
                         reliability=QoSReliabilityPolicy.RELIABLE,
                         durability=QoSDurabilityPolicy.TRANSIENT_LOCAL)
