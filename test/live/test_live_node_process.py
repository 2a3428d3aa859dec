"""The node process and domain lease helper (fourbar_ros.live.node_process) on stand-in child processes: no ROS."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from support.isolation import leave_time_wait
from support.ros_support import wait_for

from fourbar_ros.live import node_process
from fourbar_ros.live.node_process import (
    ROS2_DAEMON_BASE_PORT,
    DomainError,
    NodeProcess,
    NodeStopError,
    domain_in_use,
    lease_domain_id,
)

#: A child that says 'first' once its SIGINT handler is in place, then on SIGINT says 'second' and exits 0.
ANSWERS_SIGINT = """
import signal, sys, time
def stop(*_):
    sys.stderr.write('second\\n'); sys.stderr.flush(); sys.exit(0)
signal.signal(signal.SIGINT, stop)
sys.stdout.write('out\\n'); sys.stdout.flush()
sys.stderr.write('first\\n'); sys.stderr.flush()
while True:
    time.sleep(1)
"""
#: A child that ignores SIGINT and SIGTERM and says so.
IGNORES_SIGNALS = """
import signal, sys, time
signal.signal(signal.SIGINT, signal.SIG_IGN)
signal.signal(signal.SIGTERM, signal.SIG_IGN)
sys.stderr.write('ready\\n'); sys.stderr.flush()
while True:
    time.sleep(1)
"""


def child(program: str, log_path: Path | None = None) -> NodeProcess:
    return NodeProcess([], dict(os.environ), command=[sys.executable, '-c', program], log_path=log_path)


def test_stop_returns_the_status_and_keeps_each_stream() -> None:
    with child(ANSWERS_SIGINT) as proc:
        wait_for(lambda: 'first' in proc.stderr_now(), what='the child to start')
        assert proc.stderr_now() == 'first\n'  # reading does not disturb what the child writes next
        assert proc.stop(signal.SIGINT) == 0
    assert (proc.stdout, proc.stderr) == ('out\n', 'first\nsecond\n')
    assert not proc.running()


def test_a_log_path_holds_both_streams_and_names_the_last_line(tmp_path: Path) -> None:
    log = tmp_path / 'node.log'
    with child(ANSWERS_SIGINT, log) as proc:
        wait_for(lambda: proc.last_log_line() == 'first', what='the child to start')
        assert proc.stop() == 0
    assert log.read_text().splitlines() == ['out', 'first', 'second']


def test_a_process_that_ignores_the_signal_is_killed_and_reported() -> None:
    proc = child(IGNORES_SIGNALS).start()
    try:
        wait_for(lambda: 'ready' in proc.stderr_now(), what='the child to start')
        with pytest.raises(NodeStopError, match=r'did not exit within 0\.5 s'):
            proc.stop(signal.SIGINT, timeout_s=0.5)
        assert proc.proc is not None and proc.proc.returncode == -signal.SIGKILL
    finally:
        proc.kill()
    assert proc.stderr == 'ready\n'


def test_leases_are_distinct_until_released(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # The lock files alone (in a private directory): whether other DDS participants on this shared host
    # hold these ids' ports is not this test's question.
    monkeypatch.setattr(node_process, 'domain_in_use', lambda domain_id, participants=8: False)
    ids = (230, 231)
    first = lease_domain_id(ids, tmp_path)
    second = lease_domain_id(ids, tmp_path)
    assert {first.domain_id, second.domain_id} == set(ids)
    first.release()
    first.release()  # idempotent
    third = lease_domain_id(ids, tmp_path)
    assert third.domain_id == first.domain_id
    second.release()
    third.release()


def test_a_domain_whose_ros2_daemon_port_is_in_time_wait_is_in_use(tmp_path: Path) -> None:
    """A stopped ros2 daemon can leave its port in TIME_WAIT for 60 s, and ``ros2 daemon start`` there then starts
    none (test/package/test_ros2_daemon.py): no lease takes that domain meanwhile."""
    held = lease_domain_id()
    try:
        assert not domain_in_use(held.domain_id)
        leave_time_wait(ROS2_DAEMON_BASE_PORT + held.domain_id)
        assert domain_in_use(held.domain_id)
        with pytest.raises(DomainError):
            lease_domain_id((held.domain_id,), tmp_path)  # a lock directory of its own: only the port decides
    finally:
        held.release()


def test_commands_a_run_started_as_a_background_job_starts_are_interruptible() -> None:
    """A shell's background job (``make test &``) ignores SIGINT and SIGQUIT, and its children inherit that: a
    Python child then never raises KeyboardInterrupt (``ros2 launch`` cannot be stopped by SIGINT). The session
    restores both (``isolation.default_stop_signals``, from conftest) before it starts anything."""
    from support.isolation import default_stop_signals

    probe = [sys.executable, '-c', 'import signal; print(signal.getsignal(signal.SIGINT) is signal.default_int_handler,'
             ' signal.getsignal(signal.SIGQUIT) == signal.SIG_DFL)']
    previous = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGQUIT)}
    try:
        for s in previous:
            signal.signal(s, signal.SIG_IGN)
        inherited = subprocess.run(probe, capture_output=True, text=True, check=True).stdout.split()
        default_stop_signals()
        restored = subprocess.run(probe, capture_output=True, text=True, check=True).stdout.split()
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
    assert inherited == ['False', 'False']  # what a background job's children get
    assert restored == ['True', 'True']
