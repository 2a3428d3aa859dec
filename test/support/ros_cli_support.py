"""Running the real ``ros2`` command line in tests: long-lived commands (``ros2 run``, ``ros2 launch``,
``ros2 topic echo``) in their own process group, one-shot commands with a deadline, and cleanup of every process
a command started (its whole process group, then any descendant still alive).
"""

from __future__ import annotations

import contextlib
import os
import pty
import re
import signal
import subprocess
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import psutil

from fourbar_ros.live.node_process import ROS2_DAEMON_BASE_PORT
from support.isolation import kill_group

#: Deadline (s) for a one-shot command and for waits; generous because the machine is shared.
TIMEOUT = 60.0


def run(cmd: Sequence[str], env: dict[str, str], timeout: float = TIMEOUT, cwd: Path | None = None
        ) -> subprocess.CompletedProcess[str]:
    """A one-shot command in a process group of its own; its output, never raising on a non-zero status. Whatever
    is left of the group when the command has exited (or at the deadline: TimeoutExpired, with the output so far)
    is killed, so nothing it started outlives it (a ros2 daemon it spawned by itself too, which stays in its group
    on Linux: ``cli_env`` starts the daemon apart, before the commands)."""
    with subprocess.Popen(list(cmd), env=env, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                          stdin=subprocess.DEVNULL, start_new_session=True) as proc:
        try:
            out, err = proc.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            kill_group(proc.pid)
            out, err = proc.communicate()
            raise subprocess.TimeoutExpired(proc.args, timeout, out, err) from None
        finally:
            kill_group(proc.pid)
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, err)


def _signal_masks(pid: int) -> dict[str, str]:
    """Each thread's pending, blocked, ignored and caught signal masks (hex, bit n-1 for signal n) from /proc."""
    masks = {}
    for status in sorted(Path(f'/proc/{pid}/task').glob('*/status')):
        with contextlib.suppress(OSError):
            fields = dict(line.split(':\t', 1) for line in status.read_text().splitlines() if ':\t' in line)
            masks[f'{fields.get("Name", "?").strip()}/{status.parent.name}'] = ' '.join(
                f'{k}={fields.get(k, "?").strip()}' for k in ('SigPnd', 'ShdPnd', 'SigBlk', 'SigIgn', 'SigCgt'))
    return masks


class Background:
    """A long-lived command in a new session (so a signal can go to it alone, or to its group as Ctrl-C
    does); output goes to files, so it can never block on a full pipe.

    ``terminal`` (default: for ``ros2 launch``) gives the command a terminal (a pseudo-terminal) as its standard
    input, as typed in one. Without one launch is non-interactive: on SIGINT it sends SIGINT to every process itself,
    as it must when signalled alone (by a script or a service manager); on top of the group's SIGINT that is a second
    one, which can end a C++ node mid-shutdown by the signal (status -2)."""

    def __init__(self, cmd: Sequence[str], env: dict[str, str], cwd: Path | None = None,
                 terminal: bool | None = None) -> None:
        self.cmd = list(cmd)
        self._out = tempfile.TemporaryFile()  # noqa: SIM115 - closed in _collect
        self._err = tempfile.TemporaryFile()  # noqa: SIM115
        self._terminal: int | None = None  # the pseudo-terminal's controller side, closed in _collect
        stdin: int = subprocess.DEVNULL
        if terminal or (terminal is None and self.cmd[1:2] == ['launch']):
            self._terminal, stdin = pty.openpty()
        # faulthandler: a command that hangs is sent SIGABRT before it is killed, and prints every thread's stack
        try:
            self.proc = subprocess.Popen(self.cmd, env={**env, 'PYTHONFAULTHANDLER': '1'}, cwd=cwd,
                                         stdout=self._out, stderr=self._err, stdin=stdin, start_new_session=True)
        finally:
            if self._terminal is not None:
                os.close(stdin)
        self.stdout = ''
        self.stderr = ''
        self._seen: dict[int, Any] = {}

    def output(self) -> str:
        """Everything printed so far (stdout then stderr), without consuming it."""
        parts = []
        for f in (self._out, self._err):
            if f.closed:
                continue
            fd = f.fileno()
            parts.append(os.pread(fd, os.fstat(fd).st_size, 0).decode('utf-8', 'replace'))
        return ''.join(parts) if parts else self.stdout + self.stderr

    def descendants(self) -> list[Any]:
        """The command's live descendants (remembered, so they can be checked after the command exits)."""
        try:
            for child in psutil.Process(self.proc.pid).children(recursive=True):
                self._seen.setdefault(child.pid, child)
        except psutil.NoSuchProcess:
            pass
        return [p for p in self._seen.values() if _alive(p)]

    def wait_output(self, predicate: Callable[[str], bool], what: str, timeout: float = TIMEOUT) -> str:
        """Poll the output until ``predicate`` holds; AssertionError (with the output) at the deadline."""
        deadline = time.monotonic() + timeout
        while True:
            self.descendants()
            text = self.output()
            if predicate(text):
                return text
            if self.proc.poll() is not None:
                raise AssertionError(f'{self.cmd[:4]} exited ({self.proc.returncode}) before {what}:\n{text[-3000:]}')
            if time.monotonic() > deadline:
                raise AssertionError(f'timed out after {timeout} s waiting for {what}:\n{text[-3000:]}')
            time.sleep(0.05)

    def wait_exit(self, timeout: float = TIMEOUT) -> int:
        """Wait for the command to exit by itself; return its status."""
        try:
            self.proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            alive = [' '.join(p.cmdline()[:3]) for p in self.descendants()]
            masks = _signal_masks(self.proc.pid)
            self.proc.send_signal(signal.SIGABRT)  # the Python stacks of the hung command, on its stderr
            with contextlib.suppress(subprocess.TimeoutExpired):
                self.proc.wait(timeout=10.0)
            self.kill()
            raise AssertionError(f'{self.cmd[:4]} did not exit within {timeout} s (descendants alive: {alive}; '
                                 f'signal masks per thread: {masks}):\n{(self.stdout + self.stderr)[-6000:]}') from None
        self._collect()
        return self.proc.returncode

    def interrupt(self, group: bool = False, timeout: float = TIMEOUT) -> int:
        """SIGINT to the command (``group``: to its whole process group, as Ctrl-C in a terminal); its status."""
        self.descendants()
        if self.proc.poll() is None:
            if group:
                os.killpg(self.proc.pid, signal.SIGINT)
            else:
                self.proc.send_signal(signal.SIGINT)
        return self.wait_exit(timeout)

    def kill(self) -> None:
        """End the command, its process group and every descendant seen (SIGTERM, then SIGKILL); reap it."""
        self.descendants()
        for sig, wait in ((signal.SIGTERM, 5.0), (signal.SIGKILL, 10.0)):
            targets = [p for p in self._seen.values() if _alive(p)]
            if self.proc.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(self.proc.pid, sig)
            for p in targets:
                with contextlib.suppress(psutil.NoSuchProcess):
                    p.send_signal(sig)
            _, still = psutil.wait_procs(targets, timeout=wait)
            try:
                self.proc.wait(timeout=wait)
            except subprocess.TimeoutExpired:
                continue
            if not still:
                break
        if self.proc.returncode is None:
            self.proc.kill()
            self.proc.wait()
        self._collect()

    def _collect(self) -> None:
        if self._terminal is not None:
            os.close(self._terminal)
            self._terminal = None
        for name in ('_out', '_err'):
            f = getattr(self, name)
            if f.closed:
                continue
            f.seek(0)
            setattr(self, 'stdout' if name == '_out' else 'stderr', f.read().decode('utf-8', 'replace'))
            f.close()


def _alive(p: Any) -> bool:
    try:
        return bool(p.is_running()) and p.status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False


def echo_once(env: dict[str, str], topic: str, msg_type: str) -> Background:
    """``ros2 topic echo --once TOPIC TYPE`` in the background (the type given: no discovery of it needed)."""
    from support.colcon_support import ros2

    return Background([ros2(), 'topic', 'echo', '--once', topic, msg_type], env)


#: A line of a message as ``ros2 topic echo`` prints it (YAML block style): ``key:``, ``key: value``, ``- item``,
#: indented by spaces. Anything else on its stdout is a note of the CLI ("A message was lost") or the middleware's
#: log: Fast DDS writes its log to stdout, e.g. "[RTPS_TRANSPORT_SHM Error] Failed init_port ..." with colour codes.
_MESSAGE_LINE = re.compile(r' *(?:[A-Za-z_]\w*:(?: .*)?|-(?: .*)?)')


def echoed_messages(stdout: str) -> list[dict[str, Any]]:
    """The messages ``ros2 topic echo`` printed on ``stdout``, in order, without the other lines between them."""
    import yaml

    messages = []
    for chunk in stdout.split('\n---'):
        lines = [line for line in chunk.splitlines() if _MESSAGE_LINE.fullmatch(line)]
        doc = yaml.safe_load('\n'.join(lines)) if lines else None
        if isinstance(doc, dict):
            messages.append(doc)
    return messages


#: ``ros2 topic pub`` of one message that must arrive: ``-w 1`` waits until the publisher matches a subscription,
#: not until the subscription matches the publisher. Under load the subscriber's side lagged, and the one message was
#: lost when the publisher exited 0.1 s after it (its default keep-alive); alive 5 s, the reliable writer resends it
#: once both sides have matched.
PUB_ONCE = ('topic', 'pub', '--once', '-w', '1', '--keep-alive', '5')


def publish_until_echoed(env: dict[str, str], echo: Background, topic: str, value: float,
                         timeout: float = TIMEOUT) -> dict[str, Any]:
    """``ros2 topic pub --once`` (which waits for a matching subscription) until the echo has a message.

    Repeated because discovery is not symmetric: the node may not yet see the echo's subscription when the
    first command arrives (it skips outputs nobody subscribes to); one answer ends the echo.
    """
    from support.colcon_support import ros2

    deadline = time.monotonic() + timeout
    while echo.proc.poll() is None:
        if time.monotonic() > deadline:
            raise AssertionError(f'no message on the echo after {timeout} s:\n{echo.output()[-2000:]}')
        out = run([ros2(), 'topic', 'pub', '--once', '-w', '1', topic, 'std_msgs/msg/Float64',
                   f'{{data: {value!r}}}'], env, timeout=max(5.0, deadline - time.monotonic()))
        assert out.returncode == 0, out.stdout + out.stderr
    assert echo.wait_exit() == 0, echo.stderr
    messages = echoed_messages(echo.stdout)
    assert messages, f'no message in the echo\'s output:\n{echo.stdout}'
    return messages[0]


def start_daemon(env: dict[str, str], log: Path, timeout: float = TIMEOUT) -> str:
    """``ros2 daemon start --debug`` (its code, waiting up to ``timeout``) for ``env``'s domain (a leased one: no
    daemon there, its port free), in this process's group (not ``run``'s, which is killed when the command exits):
    the daemon lives until ``ros2 daemon stop``. Debug output is the one way to keep what the daemon prints (it goes
    to /dev/null otherwise): the command's and the daemon's output are appended to ``log``, unbuffered
    (``daemon_log`` reads it back). AssertionError, with that output, if no daemon runs then: the command says
    "already running" and starts none when it cannot bind the daemon's port.

    Returns ``daemon_state`` right after the command, for failure reports."""
    from support.colcon_support import ros2

    # What `ros2 daemon start --debug` runs, with this deadline instead of its fixed 10 s: the daemon must import
    # rclpy and join the graph before it answers, which took longer than 10 s on a loaded 2-core machine, and the
    # command then terminates it ("Timed out waiting for daemon to become ready").
    with open(ros2(), encoding='utf-8') as script:
        python = script.readline().removeprefix('#!').strip().split()
    start = ('import argparse, sys; from ros2cli.node.daemon import spawn_daemon; '
             f'print("The daemon has been started" if spawn_daemon(argparse.Namespace(), timeout={timeout!r}, '
             'debug=True) else "The daemon is already running")')
    with log.open('ab') as out:
        started = subprocess.run([*python, '-c', start], env={**env, 'PYTHONUNBUFFERED': '1'},
                                 stdout=out, stderr=subprocess.STDOUT, timeout=timeout + 5.0, check=False,
                                 stdin=subprocess.DEVNULL)
    assert started.returncode == 0, f'ros2 daemon start failed:\n{daemon_log(log)}'
    assert _daemons(env), (f'ros2 daemon start started no daemon on domain {env.get("ROS_DOMAIN_ID")} '
                           f'({daemon_state(env)}); its output:\n{daemon_log(log)}')
    return daemon_state(env)


def daemon_log(log: Path, lines: int = 20) -> str:
    """The last ``lines`` lines of ``start_daemon``'s log (the command's and the daemon's output), each cut to 300
    characters (the daemon prints every network address it sees on each request)."""
    try:
        text = log.read_text(errors='replace')
    except OSError as exc:
        return f'(no daemon log: {exc})'
    return '\n'.join(line[:300] for line in text.splitlines()[-lines:])


def _port_holders(env: dict[str, str]) -> str:
    """The TCP sockets on the daemon's port of ``env``'s domain: 'port P: pid N (STATUS), ...'."""
    port = ROS2_DAEMON_BASE_PORT + int(env.get('ROS_DOMAIN_ID', '0'))
    try:
        held = [f'pid {c.pid} ({c.status})' for c in psutil.net_connections(kind='tcp')
                if c.laddr and c.laddr.port == port]
    except psutil.Error as exc:
        return f'port {port}: unknown ({exc})'
    return f'port {port}: {", ".join(held) or "free"}'


def _daemons(env: dict[str, str]) -> list[Any]:
    """The ros2 daemon processes of ``env``'s domain now."""
    domain = env.get('ROS_DOMAIN_ID', '0')
    found = []
    for proc in psutil.process_iter(['cmdline', 'status']):
        cmd = proc.info['cmdline'] or []
        if 'ros2-daemon' in cmd and '--ros-domain-id' in cmd and cmd[cmd.index('--ros-domain-id') + 1] == domain:
            found.append(proc)
    return found


def daemon_state(env: dict[str, str]) -> str:
    """The ros2 daemons of ``env``'s domain now, as 'pid N (status, process group G)', and the processes holding the
    daemon's TCP port, for failure reports (``ros2 daemon start`` logs "already running" when it cannot bind that
    port; a command finds no daemon when nothing listens there)."""
    found = []
    for proc in _daemons(env):
        with contextlib.suppress(psutil.NoSuchProcess, ProcessLookupError):
            found.append(f'pid {proc.pid} ({proc.info["status"]}, process group {os.getpgid(proc.pid)})')
    return f'daemons {found}; {_port_holders(env)}'


def stop_daemon(env: dict[str, str], timeout: float = TIMEOUT) -> None:
    """``ros2 daemon stop`` for ``env``'s domain, then wait until its process has exited (the command returns once
    the daemon stops answering, about 2 s before). Its port may stay taken for 60 s more (``domain_in_use``)."""
    from support.colcon_support import ros2

    run([ros2(), 'daemon', 'stop'], env, timeout=timeout)
    _, alive = psutil.wait_procs(_daemons(env), timeout=timeout)
    assert not alive, f'ros2 daemon still running {timeout} s after ros2 daemon stop: {[p.pid for p in alive]}'


def wait_node(env: dict[str, str], node: str, timeout: float = TIMEOUT) -> list[str]:
    """Poll ``ros2 node list`` (the daemon's graph) until ``node`` is listed; return the list.

    The daemon must be running (``start_daemon``; ``cli_env`` starts one). Without one, ``ros2 node list`` spawns
    one and answers from a direct node of its own, and ``run`` then kills the daemon with the command's group: the
    node is listed, and the next command's new daemon may not have discovered it yet."""
    from support.colcon_support import ros2

    deadline = time.monotonic() + timeout
    while True:
        nodes = run([ros2(), 'node', 'list'], env).stdout.split()
        if node in nodes:
            return nodes
        if time.monotonic() > deadline:
            raise AssertionError(f'{node} not listed after {timeout} s: {nodes}')


@contextlib.contextmanager
def fourbar_launch(env: Any, namespace: str, arguments: Sequence[str],
                   ready: str | None = None) -> Iterator[Background]:
    """``ros2 launch fourbar_ros fourbar.launch.py namespace:=NAMESPACE ARGUMENTS rviz:=false`` from ``env`` (a
    colcon_support.CliEnv), once ``/NAMESPACE/fourbar_node`` is up and, if given, the line ``ready`` is in its
    output; on leaving, Ctrl-C to its group ends it all with status 0 and no traceback (the output shows otherwise),
    and whatever is left is killed."""
    from support.colcon_support import ros2

    launch = Background([ros2(), 'launch', 'fourbar_ros', 'fourbar.launch.py', f'namespace:={namespace}',
                         *arguments, 'rviz:=false'], env.env, cwd=env.cwd)
    try:
        try:
            wait_node(env.env, f'/{namespace}/fourbar_node')
        except AssertionError as exc:  # what the launch said (a node that refused to start says why)
            raise AssertionError(f'{exc}\nthe launch printed:\n{launch.output()[-3000:]}') from None
        if ready is not None:
            launch.wait_output(lambda t: ready in t, repr(ready))
        yield launch
        assert launch.interrupt(group=True) == 0, launch.stdout[-2000:] + launch.stderr[-2000:]
        assert 'Traceback' not in launch.stdout + launch.stderr, launch.stdout[-3000:] + launch.stderr[-3000:]
    finally:
        launch.kill()
