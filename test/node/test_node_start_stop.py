"""A stop that arrives while fourbar_node is still starting also ends it with status 0 and no traceback.

Launch files and supervisors may stop a node right after starting it, while Python is still importing rclpy and
the message packages (a noticeable time). The test makes that moment deterministic: a ``sitecustomize`` on
PYTHONPATH holds the node's first ``import rclpy`` on a pipe nobody writes to and says so on stderr; the signal
is sent then, so it lands inside the import. Without the quiet start (``fourbar_ros.node.main``) SIGINT there
gives a KeyboardInterrupt traceback and SIGTERM status -15.
"""

from __future__ import annotations

import os
import signal
import sys
from pathlib import Path

import pytest
from support.bag_support import Tool
from support.ros_support import lease_domain_id, node_command

pytestmark = pytest.mark.ros

GATE = '''
import importlib.abc, os, sys

class _Gate(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name == 'rclpy':
            sys.meta_path.remove(self)
            sys.stderr.write('GATE: importing rclpy\\n')
            sys.stderr.flush()
            os.read(int(os.environ['FOURBAR_TEST_GATE_FD']), 1)  # never written: the signal ends the wait
        return None

sys.meta_path.insert(0, _Gate())
'''
DEADLINE_S = 60.0


def start_gated(tmp_path: Path, domain_id: int) -> tuple[Tool, int]:
    """The node started with the gate; the pipe's write end (closing it lets the held import go on)."""
    (tmp_path / 'sitecustomize.py').write_text(GATE, encoding='utf-8')
    read_fd, write_fd = os.pipe()
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path), os.environ.get('PYTHONPATH', '')]),
               FOURBAR_TEST_GATE_FD=str(read_fd), ROS_DOMAIN_ID=str(domain_id))
    try:
        node = Tool(['--ros-args', '-p', 'frame_id:=gated'], env, command=node_command(), pass_fds=(read_fd,))
    except BaseException:
        os.close(write_fd)
        raise
    finally:
        os.close(read_fd)
    return node, write_fd


@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM], ids=['SIGINT', 'SIGTERM'])
def test_a_stop_while_importing_rclpy_exits_0_without_a_traceback(tmp_path: Path, sig: signal.Signals) -> None:
    if not node_command()[0].endswith('fourbar_node'):
        pytest.skip('needs the fourbar_node console script (the quiet start is its entry point)')
    lease = lease_domain_id()
    try:
        node, write_fd = start_gated(tmp_path, lease.domain_id)
        with node:  # killed and reaped on leaving, whatever happens
            try:
                node.wait_line('GATE: importing rclpy', DEADLINE_S)  # fails if the node ends first
                node.signal(sig)
                status = node.wait(DEADLINE_S)
            finally:
                os.close(write_fd)
    finally:
        lease.release()
    stderr = node.stderr
    assert status == 0, f'{sig.name} while importing: status {status}\n{stderr}'
    assert 'Traceback' not in stderr, stderr
    assert node.stdout == ''
    assert sys.executable  # the same interpreter's console script (node_command)
