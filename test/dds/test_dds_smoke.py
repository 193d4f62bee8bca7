"""First integration test over DDS: two separate processes, one publishes, one receives."""
import os
import subprocess
import sys
import uuid
from pathlib import Path

import pytest

PROBE = Path(__file__).with_name('dds_probe.py')


@pytest.mark.dds
def test_message_crosses_between_two_processes(ros_env):
    payload = f'hello-{uuid.uuid4().hex[:8]}'
    topic = f'/sela_smoke_{uuid.uuid4().hex[:6]}'
    sub = subprocess.Popen([sys.executable, str(PROBE), 'sub', topic, payload, '20'],
                           env=ros_env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                           text=True)
    pub = subprocess.Popen([sys.executable, str(PROBE), 'pub', topic, payload, '20'],
                           env=ros_env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        out, _ = sub.communicate(timeout=40)
    finally:
        pub.kill()
        pub.wait(timeout=10)
        if sub.poll() is None:
            sub.kill()
    assert sub.returncode == 0, out
    assert f'RECEIVED {payload}' in out


@pytest.mark.dds
def test_other_domain_does_not_hear(ros_env):
    """Runs in different ROS_DOMAIN_IDs are isolated: the premise of per-run domain ids."""
    payload = 'should-not-arrive'
    topic = f'/sela_smoke_{uuid.uuid4().hex[:6]}'
    other = dict(ros_env, ROS_DOMAIN_ID=str((int(os.environ['ROS_DOMAIN_ID']) + 1) % 100 or 1))
    sub = subprocess.Popen([sys.executable, str(PROBE), 'sub', topic, payload, '4'],
                           env=ros_env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                           text=True)
    pub = subprocess.Popen([sys.executable, str(PROBE), 'pub', topic, payload, '5'],
                           env=other, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        out, _ = sub.communicate(timeout=30)
    finally:
        pub.kill()
        pub.wait(timeout=10)
    assert sub.returncode == 1 and 'TIMEOUT' in out, out
