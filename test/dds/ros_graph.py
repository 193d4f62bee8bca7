"""Test harness: start sela_ros node processes and a client node with its own context.

Every process runs in this test run's ROS_DOMAIN_ID on loopback; every wait has a timeout.
"""
import os
import signal
import subprocess
import tempfile
import time
from pathlib import Path

import rclpy
from rcl_interfaces.srv import (
    DescribeParameters,
    GetParameters,
    GetParameterTypes,
    ListParameters,
    SetParameters,
)
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from sela_ros.tools.ros_env import executable, package_prefix, ros_environment, wait_for_publishers

CONFIG = package_prefix() / 'share' / 'sela_ros' / 'config' / 'sela.yaml'

# Requests that may be sent twice with the same effect, and how long to wait for an answer
# before sending one again.
_REPEATABLE = (DescribeParameters, GetParameters, GetParameterTypes, ListParameters,
               SetParameters)
_RESEND_AFTER = 5.0


class NodeProcesses:
    """The package's nodes as separate processes, started like ``ros2 run sela_ros <n>``."""

    def __init__(self, overrides=None, names=('sim_bridge', 'planner', 'damage_detector',
                                               'sela_adapter'), namespace='',
                 params_files=(CONFIG,)):
        self.env = ros_environment(domain_id=int(os.environ['ROS_DOMAIN_ID']))
        # Under the test run's own temporary folder (conftest.py): pytest keeps the last few
        # runs' node logs to read after a failure and removes older ones.
        self.logdir = Path(tempfile.mkdtemp(prefix='sela_nodes_',
                                            dir=os.environ.get('SELA_TEST_NODE_LOGS')))
        self.procs = {}
        self.namespace = namespace
        self.params_files = tuple(params_files)
        self.overrides = {k: dict(v) for k, v in (overrides or {}).items()}
        # Each graph learns into its own state file: no test resumes another's learning.
        self.state_file = self.logdir / 'sela_adapter_state.json'
        self.overrides.setdefault('sela_adapter', {}).setdefault('state_file',
                                                                 str(self.state_file))
        for name in names:
            self.start(name)

    def start(self, name):
        cmd = [str(executable(name)), '--ros-args']
        for path in self.params_files:
            cmd += ['--params-file', str(path)]
        if self.namespace:  # as `ros2 launch ... namespace:=`: own names, own clock
            cmd += ['-r', f'__ns:={self.namespace}', '-r', '/clock:=clock']
        for key, value in self.overrides.get(name, {}).items():
            cmd += ['-p', f'{key}:={value}']
        log = open(self.logdir / f'{name}.log', 'a')  # noqa: SIM115
        self.procs[name] = (subprocess.Popen(cmd, env=self.env, stdout=log,
                                             stderr=subprocess.STDOUT), log)

    def kill(self, name, sig=signal.SIGKILL):
        proc, log = self.procs.pop(name)
        proc.send_signal(sig)
        proc.wait(timeout=20)
        log.close()

    def alive(self):
        return {n: p.poll() is None for n, (p, _) in self.procs.items()}

    def logs(self):
        return {p.name: p.read_text()[-3000:] for p in self.logdir.glob('*.log')}

    def stop(self):
        for proc, _ in self.procs.values():
            if proc.poll() is None:
                proc.send_signal(signal.SIGINT)
        deadline = time.monotonic() + 10
        for proc, log in self.procs.values():
            try:
                proc.wait(timeout=max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(timeout=10)
            log.close()
        self.procs.clear()


class Client:
    """A test node in its own rclpy context, spun on demand."""

    def __init__(self, name='sela_test_client'):
        self.context = Context()
        rclpy.init(context=self.context)
        self.node = Node(name, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)

    def spin_until(self, predicate, timeout, what='condition'):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if predicate():
                return
            self.executor.spin_once(timeout_sec=0.05)
        if predicate():
            return
        raise TimeoutError(f'timed out after {timeout} s waiting for {what}')

    def wait_for_publishers(self, topics, timeout=60.0, settle=0.5):
        """Wait until this node has discovered a publisher on each topic, then ``settle`` s:
        on volatile topics, what is published before discovery never arrives."""
        if not wait_for_publishers(self.node,
                                   lambda t: self.executor.spin_once(timeout_sec=t), topics,
                                   timeout, settle):
            raise TimeoutError(f'timed out after {timeout} s waiting for publishers on '
                               f'{", ".join(topics)}')

    def call(self, client, request, timeout=20.0):
        """The answer to ``request``, within ``timeout`` s from now.

        A service can take a request before the writer of its replies has matched this
        client, and the reply is then lost. A request that can be repeated (every parameter
        service's) is sent again every :data:`_RESEND_AFTER` s while no answer came."""
        deadline = time.monotonic() + timeout
        self.spin_until(client.service_is_ready, timeout, f'service {client.srv_name}')
        resend_after = _RESEND_AFTER if client.srv_type in _REPEATABLE else None
        while True:
            future = client.call_async(request)
            left = deadline - time.monotonic()
            wait = left if resend_after is None else min(resend_after, left)
            try:
                self.spin_until(future.done, max(wait, 0.0), f'answer of {client.srv_name}')
                return future.result()
            except TimeoutError:
                client.remove_pending_request(future)
                if time.monotonic() >= deadline:
                    raise TimeoutError(f'timed out after {timeout} s waiting for the answer '
                                       f'of {client.srv_name}') from None

    def close(self):
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
