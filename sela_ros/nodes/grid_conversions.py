"""Occupancy grids (``nav_msgs/OccupancyGrid``) to and from numpy arrays, validated at the
edge as every message of :mod:`sela_ros.nodes.conversions`."""
import math

import numpy as np
from builtin_interfaces.msg import Time
from nav_msgs.msg import OccupancyGrid as OccupancyGridMsg

from sela_ros.core.planning import MapError, check_geometry
from sela_ros.core.validation import finite_array
from sela_ros.nodes.conversions import MessageError, quaternion_to_yaw, time_to_msg


def occupancy_grid_to_msg(occupancy, resolution, origin_xy, stamp=0.0, frame_id='odom'):
    """``occupancy``: (height, width) array, row 0 at ``origin_xy`` (REP-103 map layout)."""
    occupancy = np.asarray(occupancy)
    msg = OccupancyGridMsg()
    msg.header.stamp = time_to_msg(stamp) if not isinstance(stamp, Time) else stamp
    msg.header.frame_id = frame_id
    msg.info.resolution = float(resolution)
    msg.info.height, msg.info.width = (int(v) for v in occupancy.shape)
    msg.info.origin.position.x = float(origin_xy[0])
    msg.info.origin.position.y = float(origin_xy[1])
    msg.info.origin.orientation.w = 1.0
    msg.data = np.where(occupancy > 0, 100, 0).astype(np.int8).reshape(-1).tolist()
    return msg


def occupancy_values_from_msg(msg):
    """Return ``(values (height, width) int16, resolution, origin_xy)`` of a map message.

    ``values`` keep ROS's convention (-1 unknown, 0..100); row 0 is at the origin. A map
    rotated in its frame (origin yaw not 0) is refused: the planner plans without rotation.
    """
    h, w = msg.info.height, msg.info.width
    data = np.asarray(msg.data, dtype=np.int16)
    if h < 1 or w < 1 or data.size != h * w:
        raise MessageError(f'occupancy grid: {data.size} cells for {w} x {h} (width x height)')
    if not (msg.info.resolution > 0 and math.isfinite(msg.info.resolution)):
        raise MessageError(f'occupancy grid: resolution {msg.info.resolution} must be > 0')
    origin = finite_array([msg.info.origin.position.x, msg.info.origin.position.y],
                          'occupancy grid origin', 2, error=MessageError)
    try:  # the limits of the map.* parameters and of map files
        check_geometry(msg.info.resolution, origin, w * msg.info.resolution,
                       h * msg.info.resolution, 'occupancy grid:')
    except MapError as exc:
        raise MessageError(str(exc)) from None
    yaw = quaternion_to_yaw(msg.info.origin.orientation)
    if not abs(yaw) < 1e-6:
        raise MessageError(f'occupancy grid: origin yaw {yaw:.4f} rad is not supported '
                           '(expected an unrotated map, yaw 0)')
    return data.reshape(h, w), float(msg.info.resolution), origin


def occupancy_grid_from_msg(msg):
    """Return ``(occupied (height, width) bool, resolution, origin_xy)``; unknown is occupied."""
    values, resolution, origin = occupancy_values_from_msg(msg)
    return (values >= 50) | (values < 0), resolution, origin
