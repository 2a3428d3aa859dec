"""The ros2 daemon as the tests start it (support.ros_cli_support.start_daemon), with the real ``ros2`` command line:
``ros2 daemon start`` binds the daemon's TCP port (11511 + ROS_DOMAIN_ID on 127.0.0.1) without SO_REUSEADDR. A
connection that a stopped daemon closed first stays in TIME_WAIT on that port for 60 s; meanwhile the command says
the daemon is "already running", starts none, and every later command finds no daemon (``ros2 param set``: "Node
not found" when its own graph has not yet seen the node). A domain lease skips such a domain (``domain_in_use``).
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from support.colcon_support import ros2, ros2_cli_missing
from support.isolation import isolated_env, leave_time_wait

from fourbar_ros.live.node_process import ROS2_DAEMON_BASE_PORT, DomainLease

if (_why := ros2_cli_missing()) is not None:
    pytest.skip(_why, allow_module_level=True)
from support.ros_cli_support import daemon_state, run, start_daemon, stop_daemon  # psutil: with ros2cli

pytestmark = [pytest.mark.ros]


def test_a_daemon_starts_on_a_leased_domain_and_stops(lease: DomainLease, tmp_path: Path) -> None:
    env = isolated_env(os.environ, lease.domain_id)
    log = tmp_path / 'ros2_daemon.log'
    started = start_daemon(env, log)
    try:
        status = run([ros2(), 'daemon', 'status'], env)
        assert status.stdout.strip() == 'The daemon is running', f'{status}; at start: {started}'
    finally:
        stop_daemon(env)
    assert daemon_state(env).startswith('daemons []'), daemon_state(env)
    assert 'The daemon has been started' in log.read_text(), log.read_text()


def test_ros2_daemon_start_starts_none_while_its_port_is_in_time_wait(lease: DomainLease, tmp_path: Path) -> None:
    env = isolated_env(os.environ, lease.domain_id)
    leave_time_wait(ROS2_DAEMON_BASE_PORT + lease.domain_id)
    with pytest.raises(AssertionError, match='started no daemon') as failed:
        start_daemon(env, tmp_path / 'ros2_daemon.log')
    assert 'The daemon is already running' in str(failed.value), failed.value
    status = run([ros2(), 'daemon', 'status'], env)
    assert status.stdout.strip() == 'The daemon is not running', status
