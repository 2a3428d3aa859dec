"""``fourbar_node`` as a child process on a ROS_DOMAIN_ID nobody else on this host uses. No rclpy.

The demo, the benchmarks and the tests lease domain ids through this one module (docs/explanation/testing.md)."""

from __future__ import annotations

import contextlib
import fcntl
import os
import signal
import socket
import subprocess
import sys
import tempfile
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import IO

from fourbar_ros.core.errors import FourBarError
from fourbar_ros.interface.topics import NODE_EXECUTABLE, SIM_EXECUTABLE
from fourbar_ros.runtime.stop import STOP

#: The console scripts ``fourbar_node`` and ``fourbar_sim_actuator`` (setup.py) as ``python -c`` programs, for an
#: uninstalled tree.
NODE_MAIN = 'import sys; from fourbar_ros.node import main; sys.exit(main())'
SIM_ACTUATOR_MAIN = ('import sys; from fourbar_ros.plant.sim_drive import sim_actuator_main; '
                     'sys.exit(sim_actuator_main())')
#: Domain ids a fourbar run may take: safe on Linux (discovery ports outside the ephemeral range) and
#: clear of the ranges developers use by hand (10-89).
FREE_DOMAIN_IDS: tuple[int, ...] = (*range(90, 102), *range(215, 233))
DOMAIN_LOCK_DIR = Path(tempfile.gettempdir()) / 'fourbar_ros_domain_locks'


class DomainError(FourBarError):
    """No ROS_DOMAIN_ID is free on this host."""


class NodeStopError(FourBarError):
    """The node process did not exit within its deadline after a signal (it was killed)."""


# --------------------------------------------------------------------------- domain ids

#: The ros2 command line's daemon serves on 127.0.0.1 at this TCP port plus the domain id.
ROS2_DAEMON_BASE_PORT = 11511


def _port_free(port: int, kind: socket.SocketKind = socket.SOCK_DGRAM, host: str = '') -> bool:
    """Whether ``port`` can be bound (without SO_REUSEADDR) on ``host`` for a socket of ``kind``."""
    with socket.socket(socket.AF_INET, kind) as s:
        try:
            s.bind((host, port))
        except OSError:
            return False
    return True


def domain_in_use(domain_id: int, participants: int = 8) -> bool:
    """True if a DDS participant of ``domain_id`` runs on this host, or its ros2 daemon's port is taken.

    Checks the first ``participants`` unicast discovery ports of the RTPS port mapping
    (7400 + 250 d + 10 + 2 i), which a running participant holds exclusively, and the ros2 daemon's TCP port
    (11511 + d on 127.0.0.1), bound as ``ros2 daemon start`` binds it. A running daemon holds that port; so does,
    for 60 s after a daemon stopped, a connection it closed first (TIME_WAIT), and ``ros2 daemon start`` then says
    the daemon is "already running" and starts none.
    """
    base = 7400 + 250 * domain_id + 10
    return (not all(_port_free(base + 2 * i) for i in range(participants))
            or not _port_free(ROS2_DAEMON_BASE_PORT + domain_id, socket.SOCK_STREAM, '127.0.0.1'))


class DomainLease:
    """A held ROS_DOMAIN_ID: an flock on ``<lock_dir>/<id>.lock``; ``release()`` gives it back (idempotent).

    A crashed run's lock disappears with its process.
    """

    def __init__(self, domain_id: int, fd: int) -> None:
        self.domain_id = domain_id
        self._fd: int | None = fd

    def release(self) -> None:
        """Give the id back."""
        fd, self._fd = self._fd, None
        if fd is not None:
            os.close(fd)  # drops the flock


def lease_domain_id(candidates: Sequence[int] = FREE_DOMAIN_IDS,
                    lock_dir: Path = DOMAIN_LOCK_DIR) -> DomainLease:
    """Reserve a ROS_DOMAIN_ID nobody on this host uses until ``release()``.

    A domain is free when no other fourbar run holds its lock file and no DDS participant holds its
    discovery ports. The search starts at an offset from the pid, so concurrent runs rarely contend.
    """
    lock_dir.mkdir(parents=True, exist_ok=True)
    start = os.getpid() % len(candidates)
    for domain in list(candidates[start:]) + list(candidates[:start]):
        try:
            fd = os.open(lock_dir / f'{domain}.lock', os.O_CREAT | os.O_RDWR, 0o666)
        except OSError:
            continue
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            continue
        if domain_in_use(domain):
            os.close(fd)
            continue
        return DomainLease(domain, fd)
    raise DomainError(f'no free ROS_DOMAIN_ID among {candidates[0]}..{candidates[-1]}')


@contextlib.contextmanager
def free_domain_id(candidates: Sequence[int] = FREE_DOMAIN_IDS,
                   lock_dir: Path = DOMAIN_LOCK_DIR) -> Iterator[int]:
    """``lease_domain_id`` for the duration of a ``with`` block."""
    lease = lease_domain_id(candidates, lock_dir)
    try:
        yield lease.domain_id
    finally:
        lease.release()


# --------------------------------------------------------------------------- the node as a process

def _console_command(script: str, program: str) -> list[str]:
    """The console script ``script`` next to this Python, else ``program`` (its entry point) through this
    interpreter."""
    path = Path(sys.executable).parent / script
    if path.exists():
        return [str(path)]
    return [sys.executable, '-c', program]


def node_command() -> list[str]:
    """How to start ``fourbar_node`` (the default command of ``NodeProcess``)."""
    return _console_command(NODE_EXECUTABLE, NODE_MAIN)


def sim_actuator_command() -> list[str]:
    """How to start the simulated actuator, ``fourbar_sim_actuator`` (``NodeProcess(command=...)``)."""
    return _console_command(SIM_EXECUTABLE, SIM_ACTUATOR_MAIN)


def node_args(params: Path | None, *ros_args: str) -> list[str]:
    """``--ros-args [--params-file PARAMS] ROS_ARGS...``: the node's arguments."""
    return ['--ros-args', *(['--params-file', str(params)] if params is not None else []), *ros_args]


def _read_all(f: IO[bytes]) -> str:
    """The whole file, read without moving the offset the child process shares (pread)."""
    fd = f.fileno()
    return os.pread(fd, os.fstat(fd).st_size, 0).decode('utf-8', 'replace')


class NodeProcess:
    """``fourbar_node ARGS`` as a child process in its own session (signals reach only it).

    ``env`` must carry the ROS_DOMAIN_ID to use. Output goes to files, never pipes, so a chatty node can
    never block: stdout and stderr to ``log_path`` together if given, else each to a temporary file,
    whose text is in ``stdout`` and ``stderr`` once the process has exited. ``stop(sig)`` sends one
    signal and waits for the exit; ``kill()`` (also on leaving a ``with`` block) ends it on every path.
    """

    def __init__(self, args: Sequence[str], env: Mapping[str, str], *, command: Sequence[str] | None = None,
                 cwd: Path | None = None, log_path: Path | None = None) -> None:
        self.args = list(args)
        self.env = dict(env)
        self.command = list(command) if command is not None else node_command()
        self.cwd = cwd
        self.log_path = log_path
        self.proc: subprocess.Popen[bytes] | None = None
        self.stdout = ''
        self.stderr = ''
        self._out: IO[bytes] | None = None
        self._err: IO[bytes] | None = None

    def start(self) -> NodeProcess:
        """Start the process."""
        if self.log_path is not None:
            self._out = self._err = self.log_path.open('w+b')
        else:
            self._out = tempfile.TemporaryFile()  # noqa: SIM115 - closed in _collect_output
            self._err = tempfile.TemporaryFile()  # noqa: SIM115
        with STOP.deferred():  # a Ctrl-C while Popen waits for the exec would lose the running child's handle
            self.proc = subprocess.Popen([*self.command, *self.args], env=self.env, cwd=self.cwd,
                                         stdin=subprocess.DEVNULL, stdout=self._out, stderr=self._err,
                                         start_new_session=True)
        return self

    def __enter__(self) -> NodeProcess:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.kill()

    def running(self) -> bool:
        """True while the process has not exited."""
        return self.proc is not None and self.proc.poll() is None

    def stderr_now(self) -> str:
        """What the process wrote to stderr so far (with ``log_path``: all its output)."""
        return _read_all(self._err) if self._err is not None else self.stderr

    def last_log_line(self) -> str:
        """The last non-empty line the node wrote to stderr (for error messages)."""
        lines = [x.strip() for x in self.stderr_now().splitlines() if x.strip()]
        return lines[-1] if lines else ''

    def _collect_output(self) -> None:
        out, err, self._out, self._err = self._out, self._err, None, None
        if err is not None:
            self.stderr = _read_all(err)
            err.close()
        if out is not None and out is not err:
            self.stdout = _read_all(out)
            out.close()

    def wait_exit(self, timeout_s: float = 30.0) -> int:
        """Wait for the process to exit by itself; return its status (NodeStopError, killed, at the deadline)."""
        assert self.proc is not None, 'not started'
        try:
            self.proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            self.kill()
            raise NodeStopError(f'{" ".join(self.command)} did not exit within {timeout_s:g} s') from None
        self._collect_output()
        return self.proc.returncode

    def stop(self, sig: int = signal.SIGINT, timeout_s: float = 30.0) -> int:
        """Send ``sig`` (unless it has exited already) and wait for the exit status, as ``wait_exit``."""
        assert self.proc is not None, 'not started'
        if self.proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                self.proc.send_signal(sig)
        return self.wait_exit(timeout_s)

    def kill(self) -> None:
        """SIGTERM, then SIGKILL; always reaps the process and keeps its output (safe to call repeatedly)."""
        proc = self.proc
        if proc is None:
            return
        for sig, wait_s in ((signal.SIGTERM, 5.0), (signal.SIGKILL, 10.0)):
            if proc.poll() is not None:
                break
            with contextlib.suppress(ProcessLookupError):
                proc.send_signal(sig)
            with contextlib.suppress(subprocess.TimeoutExpired):
                proc.wait(timeout=wait_s)
        proc.wait()
        self._collect_output()
