"""Environment for processes that touch DDS, and lookup of the package's executables.

ROS-free: used by the demo launcher, the experiments and the tests to start node processes
the way `ros2 run sela_ros <node>` would, with DDS kept on loopback.
"""
import os
import sys
from pathlib import Path

PACKAGE = 'sela_ros'
LOOPBACK_PROFILE = 'fastdds_loopback.xml'


def ros_environment(domain_id=None, base=None):
    """Return a copy of ``base`` (default ``os.environ``) fit for a DDS process here.

    DDS stays on loopback: the RMW is Fast DDS with the package's loopback profile
    (``config/fastdds_loopback.xml``: discovery and data on 127.0.0.1 and shared memory only)
    and ``ROS_AUTOMATIC_DISCOVERY_RANGE=SYSTEM_DEFAULT``, the range in which the rmw applies
    the profile as it is. (``LOCALHOST`` alone keeps discovery local but makes Fast DDS bind
    send sockets on every interface.) Without the profile file, ``LOCALHOST`` is the fallback.
    When no ament prefix is set the running interpreter's prefix is used (the project's
    .venv, where the package is installed with its ament index entry).

    Args:
        domain_id: ``ROS_DOMAIN_ID`` to use; ``None`` keeps the inherited one.
        base: mapping to start from.
    """
    env = dict(os.environ if base is None else base)
    env['RMW_IMPLEMENTATION'] = 'rmw_fastrtps_cpp'  # the profile below is Fast DDS's
    if not env.get('AMENT_PREFIX_PATH'):
        env['AMENT_PREFIX_PATH'] = sys.prefix
    profile = loopback_profile(env['AMENT_PREFIX_PATH'])
    if profile is None:
        env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    else:
        # Fast DDS 2.x reads the first name, 3.x the second.
        env['FASTRTPS_DEFAULT_PROFILES_FILE'] = env['FASTDDS_DEFAULT_PROFILES_FILE'] = \
            str(profile)
        env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'SYSTEM_DEFAULT'
    if domain_id is not None:
        domain_id = int(domain_id)
        if not 0 <= domain_id <= 101:
            raise ValueError(f'ROS_DOMAIN_ID must be in [0, 101], got {domain_id}')
        env['ROS_DOMAIN_ID'] = str(domain_id)
    env.setdefault('PYTHONUNBUFFERED', '1')
    return env


def loopback_profile(ament_prefix_path=None):
    """Path of ``fastdds_loopback.xml``: installed (``<prefix>/share/sela_ros/config`` of an
    ament prefix, then of the prefix this module is installed in) or in the source tree;
    None when none has it."""
    prefixes = (ament_prefix_path or os.environ.get('AMENT_PREFIX_PATH') or sys.prefix)
    here = Path(__file__).resolve()
    candidates = [Path(p) / 'share' / PACKAGE / 'config' for p in prefixes.split(os.pathsep)
                  if p]
    candidates += [p / 'share' / PACKAGE / 'config' for p in here.parents]
    candidates.append(here.parents[2] / 'config')
    for folder in candidates:
        if (folder / LOOPBACK_PROFILE).is_file():
            return folder / LOOPBACK_PROFILE
    return None


def ensure_ros_environment():
    """Apply :func:`ros_environment` to this process (before ``rclpy.init``)."""
    os.environ.update(ros_environment())


def package_prefix():
    """The install prefix of sela_ros according to the ament index."""
    ensure_ros_environment()
    from ament_index_python.packages import get_package_prefix

    return Path(get_package_prefix(PACKAGE))


def executable(name):
    """Path of ``name`` under ``<prefix>/lib/sela_ros/``, as ``ros2 run sela_ros name`` finds it.

    Raises:
        FileNotFoundError: when the package is installed without that executable.
    """
    path = package_prefix() / 'lib' / PACKAGE / name
    if not (path.exists() and os.access(path, os.X_OK)):
        raise FileNotFoundError(
            f'no executable {name!r} in {path.parent}: run `make venv` (or colcon build) first')
    return path


def wait_for_publishers(node, spin_once, topics, timeout=60.0, settle=0.5):
    """Spin until ``node`` has discovered a publisher on each of ``topics`` and each of its
    own subscriptions to them has matched every one, then ``settle`` s.

    On volatile topics what is published before discovery never arrives, so a client that
    listens to a mission calls this before sending the goal. A reader only sees its own side
    of a match: ``settle`` leaves the writers' side the time to match it too.
    ``spin_once(timeout_sec)`` spins the node's executor. Returns whether every publisher
    was found (and matched) within ``timeout`` s.
    """
    import time

    def matched(topic):
        publishers = node.count_publishers(topic)
        return publishers > 0 and all(
            s.get_publisher_count() >= publishers for s in node.subscriptions
            if s.topic_name == topic)

    deadline = time.monotonic() + timeout
    found = False
    while time.monotonic() < deadline:
        found = all(matched(t) for t in topics)
        if found:
            break
        spin_once(0.05)
    end = time.monotonic() + settle
    while time.monotonic() < end:
        spin_once(0.05)
    return found
