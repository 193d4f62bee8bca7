"""Shared fixtures: every test run gets its own ROS_DOMAIN_ID and stays on loopback; the tests
over DDS are the ones in test/dds/."""
import fcntl
import os
import random
import tempfile
from pathlib import Path

import pytest
from hypothesis import settings

# Property tests draw the same examples on every run: a failure is met again by the next run,
# not once by chance in CI. No deadline: a loaded machine must not fail a slow example.
settings.register_profile('sela_ros', derandomize=True, deadline=None, database=None)
settings.load_profile('sela_ros')

_DOMAIN_LOCK = None


def _claim_domain_id():
    """Claim a ROS_DOMAIN_ID that no other test run on this machine holds.

    An exclusive flock on one file per id, held for the whole session, makes concurrent
    runs pick different ids; the lock dies with the process, so a killed run frees its id.
    """
    global _DOMAIN_LOCK
    ids = list(range(10, 100))
    random.Random(os.getpid()).shuffle(ids)
    lock_dir = os.path.join(tempfile.gettempdir(), 'sela_ros_domain_ids')
    os.makedirs(lock_dir, exist_ok=True)
    for domain_id in ids:
        handle = open(os.path.join(lock_dir, f'{domain_id}.lock'), 'w')  # noqa: SIM115
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            handle.close()
            continue
        _DOMAIN_LOCK = handle
        return domain_id
    raise RuntimeError('no free ROS_DOMAIN_ID in 10..99: too many concurrent test runs')


def pytest_configure(config):
    if 'SELA_TEST_DOMAIN_ID' not in os.environ:
        os.environ['SELA_TEST_DOMAIN_ID'] = str(_claim_domain_id())
    # This process (the tests' own client nodes) and every node it starts: this run's domain,
    # DDS on loopback only (sela_ros.tools.ros_env; dds/test_loopback_sockets.py checks the
    # sockets).
    from sela_ros.tools.ros_env import ros_environment

    os.environ.update(ros_environment(domain_id=int(os.environ['SELA_TEST_DOMAIN_ID'])))
    os.environ.setdefault('ROS_LOG_DIR', os.path.join(tempfile.gettempdir(), 'sela_ros_test_logs'))


#: Where the tests that start processes over DDS live (marked ``dds``); every other folder
#: holds tests that never touch DDS (``make test TEST_ARGS='-m "not dds"'`` runs those).
DDS_TESTS = Path(__file__).resolve().parent / 'dds'


def pytest_collection_modifyitems(config, items):
    """A test in test/dds/ is marked ``dds``, and no test outside it is."""
    wrong = []
    for item in items:
        inside = DDS_TESTS in Path(str(item.path)).resolve().parents
        marked = item.get_closest_marker('dds') is not None
        if inside != marked:
            wrong.append(f'{item.nodeid}: ' + ('in test/dds/ but not marked dds' if inside
                                                else 'marked dds outside test/dds/'))
    if wrong:
        raise pytest.UsageError('DDS tests are the ones in test/dds/, marked dds:\n'
                                + '\n'.join(wrong))


#: What pip adds beside rosdep (requirements-qd.txt): the offline map builder's extras. The
#: tests of the map builder need them and fail without them (they never skip).
QD_EXTRAS = {'ribs': 'pyribs', 'distributed': 'Dask'}


def missing_qd_extras():
    import importlib.util

    return [name for module, name in QD_EXTRAS.items()
            if importlib.util.find_spec(module) is None]


def pytest_report_header(config):
    lines = [f"ROS_DOMAIN_ID={os.environ.get('ROS_DOMAIN_ID')}, DDS on loopback "
             f"({os.environ.get('FASTDDS_DEFAULT_PROFILES_FILE', 'no profile')})"]
    missing = missing_qd_extras()
    if missing:
        lines.append(f"{' and '.join(missing)} not installed: test_cvt.py and "
                     'test_map_elites.py will fail; pip install -r requirements-qd.txt '
                     '(rosdep does not install them)')
    return lines


@pytest.fixture(scope='session', autouse=True)
def node_log_root(tmp_path_factory):
    """The node processes' logs and state files go under this run's pytest temporary folder,
    which pytest removes after a few more runs (test/dds/ros_graph.py reads the variable)."""
    root = tmp_path_factory.mktemp('nodes')
    os.environ['SELA_TEST_NODE_LOGS'] = str(root)
    return root


@pytest.fixture
def ros_env():
    """Environment for a child process that talks DDS in this test run's domain."""
    from sela_ros.tools.ros_env import ros_environment

    return ros_environment(domain_id=int(os.environ['ROS_DOMAIN_ID']))
