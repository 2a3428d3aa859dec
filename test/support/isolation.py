"""Each test process on a ROS domain of its own, limited to this host; and no process a test module started left
behind when the module ends. No rclpy here (conftest.py uses it for every run, ROS or not).

- ``isolate_process()``: lease a ROS_DOMAIN_ID for this process (one per pytest-xdist worker, or the lone pytest
  process) and write it, with ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``, into ``os.environ`` before any rclpy
  context exists: the session's rclpy context and every child started from ``os.environ`` use that domain and
  discover only on this host. ``release_process()`` gives the id back.
- ``isolated_env(base, domain_id)``: an environment for a child process on ``domain_id``, limited to this host
  (all processes that must see each other need the same range: the harness sets it everywhere).
- ``default_stop_signals()``: SIGINT and SIGQUIT as a terminal's foreground process has them, even when the run
  inherited them ignored (a shell's background job, ``make test &``, ignores both; children inherit that across
  exec, and ``ros2 launch`` started with SIGINT ignored never stops on it).
- ``kill_group(pid)``: SIGKILL to what is left of a process group (a child started with ``start_new_session``).
- ``leave_time_wait(port)``: a connection in TIME_WAIT on a port of 127.0.0.1, as a server that closes first leaves
  one (the ros2 daemon does).
- ``Leftovers``: the descendants of this process a module started and left running, ended and named.
"""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from fourbar_ros.live.node_process import DomainLease, lease_domain_id

#: What limits discovery to this host (Jazzy; the older ROS_LOCALHOST_ONLY would override it with a warning).
DISCOVERY_RANGE = {'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST'}
#: Variables that would widen or redirect discovery, dropped from every test environment.
DROPPED = ('ROS_LOCALHOST_ONLY', 'ROS_STATIC_PEERS', 'ROS_DISCOVERY_SERVER', 'FASTRTPS_DEFAULT_PROFILES_FILE',
           'FASTDDS_DEFAULT_PROFILES_FILE')

_LEASE: list[DomainLease] = []  # this process's lease, once taken


def isolated_env(base: Mapping[str, str], domain_id: int, **extra: str) -> dict[str, str]:
    """``base`` on ``domain_id``, discovery limited to this host, plus ``extra``."""
    env = {k: v for k, v in base.items() if k not in DROPPED}
    env['ROS_DOMAIN_ID'] = str(domain_id)
    env.update(DISCOVERY_RANGE)
    env.update(extra)
    return env


def default_stop_signals() -> None:
    """SIGINT back to Python's KeyboardInterrupt and SIGQUIT to its default action where they are ignored."""
    if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    if signal.getsignal(signal.SIGQUIT) == signal.SIG_IGN:
        signal.signal(signal.SIGQUIT, signal.SIG_DFL)


def isolate_process() -> DomainLease:
    """Lease this process's domain id and put it (and the discovery range) in ``os.environ``; idempotent."""
    if not _LEASE:
        _LEASE.append(lease_domain_id())
        for name in DROPPED:
            os.environ.pop(name, None)
        os.environ['ROS_DOMAIN_ID'] = str(_LEASE[0].domain_id)
        os.environ.update(DISCOVERY_RANGE)
    return _LEASE[0]


def process_lease() -> DomainLease | None:
    """This process's lease (``isolate_process``), or None when it has none."""
    return _LEASE[0] if _LEASE else None


def release_process() -> None:
    """Give this process's domain id back (at the end of the run)."""
    while _LEASE:
        _LEASE.pop().release()


def kill_group(pid: int) -> None:
    """SIGKILL whatever still runs in the process group led by ``pid`` (nothing if the group is gone)."""
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(pid, signal.SIGKILL)


def leave_time_wait(port: int, timeout: float = 10.0) -> None:
    """Leave a connection in TIME_WAIT on 127.0.0.1:``port``, which holds the port for 60 s (Linux): its server
    side closes first, then the client. Returns once /proc/net/tcp lists it."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as server:
        server.bind(('127.0.0.1', port))
        server.listen()
        client = socket.create_connection(('127.0.0.1', port), timeout=timeout)
        conn, _ = server.accept()
    conn.close()
    client.close()
    deadline = time.monotonic() + timeout
    while not _in_time_wait(port):
        assert time.monotonic() < deadline, f'no TIME_WAIT on 127.0.0.1:{port} after {timeout} s'
        time.sleep(0.01)


def _in_time_wait(port: int) -> bool:
    """Whether /proc/net/tcp lists a socket of 127.0.0.1:``port`` in TIME_WAIT (state 06)."""
    local = f'0100007F:{port:04X}'
    rows = (line.split() for line in Path('/proc/net/tcp').read_text().splitlines()[1:])
    return any(row[1] == local and row[3] == '06' for row in rows)


class Leftovers:
    """The descendants of this process at ``__init__`` are known; ``end()`` kills every later one still running
    (its process group first) and returns their descriptions (empty: nothing was left behind). Without psutil
    (installed with the ros2 command line) it sees nothing."""

    def __init__(self) -> None:
        try:
            import psutil
        except ImportError:
            self._psutil: Any = None
        else:
            self._psutil = psutil
        self._before = {p.pid for p in self._children()}

    def _children(self) -> list[Any]:
        if self._psutil is None:
            return []
        try:
            return list(self._psutil.Process().children(recursive=True))
        except self._psutil.Error:
            return []

    def end(self) -> list[str]:
        psutil = self._psutil
        left: list[tuple[Any, str]] = []
        for proc in self._children():
            if proc.pid in self._before:
                continue
            try:
                if proc.status() != psutil.STATUS_ZOMBIE:
                    left.append((proc, f'pid {proc.pid}: {" ".join(proc.cmdline()[:4])}'))
            except psutil.Error:
                continue
        own_group = os.getpgid(0)
        for proc, _ in left:
            with contextlib.suppress(psutil.Error, ProcessLookupError):
                pgid = os.getpgid(proc.pid)
                if pgid != own_group:
                    kill_group(pgid)
                proc.kill()
        if left:
            psutil.wait_procs([p for p, _ in left], timeout=10)
        return [what for _, what in left]
