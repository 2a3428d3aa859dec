"""Helpers for the bag tests: the committed bags, the expected node outputs from the core, the `fourbar`
CLI as a child process whose stderr lines a test can wait for (or in this process), and independent bag readers.
"""

from __future__ import annotations

import contextlib
import math
import os
import signal
import sqlite3
import subprocess
import sys
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fourbar_ros.config.antenna_config import AntennaConfig
from support.cli_support import fourbar
from support.paths import REPO, TEST_DATA
from support.ros_support import TIMEOUT, Collector

BAG_DIR = TEST_DATA / 'bags'
DEMO_BAG = REPO / 'fourbar_ros' / 'data' / 'demo_sweep'
CONFIG = REPO / 'config' / 'antenna.yaml'


def committed_bags() -> list[Path]:
    """Every committed command bag, the bundled demo sweep included."""
    return [*sorted(p for p in BAG_DIR.iterdir() if p.is_dir()), DEMO_BAG]


# --------------------------------------------------------------------------- expected outputs

def served(values: Sequence[float], cfg: AntennaConfig, policy: str | None = None) -> list[float]:
    """The angles (rad) the node must serve, by the interface contract (written here independently of
    the node's code): NaN/inf never; inside [theta_min, theta_max] (limits included) as commanded;
    finite outside: nothing (reject) or the nearer limit (clamp)."""
    policy = policy or cfg.out_of_limits
    out = []
    for theta in values:
        if not math.isfinite(theta):
            continue
        if cfg.theta_min <= theta <= cfg.theta_max:
            out.append(theta)
        elif policy == 'clamp':
            out.append(cfg.theta_min if theta < cfg.theta_min else cfg.theta_max)
    return out


@dataclass(frozen=True)
class Expected:
    """Core values for one served angle: rocker angles (rad) and driven-rocker torque (N m)."""

    theta: float
    gamma: float
    delta: float
    torque: float


def expected_outputs(thetas: Sequence[float], cfg: AntennaConfig) -> list[Expected]:
    """The core's values for each served angle under the configured constant load."""
    assert not cfg.has_gravity_load, 'the bag tests expect the shipped constant-load configuration'
    out = []
    for theta in thetas:
        s = cfg.linkage.state(theta, cfg.load_torque, cfg.driven, cfg.branch)
        out.append(Expected(theta, float(s.gamma), float(s.delta), float(s.input_torque)))
    return out


def diag_values(msg: Any) -> dict[str, str]:
    """Key/value pairs of the first status of a DiagnosticArray."""
    return {kv.key: kv.value for kv in msg.status[0].values} if msg.status else {}


def what_the_node_took(diagnostics: Collector[Any], commands: int, answers: int) -> str:
    """Where messages went missing, from the node's latest diagnostics status: the commands it took of
    ``commands`` published (those lost in a gap of publication sequence numbers counted apart; the last ones
    leave no gap), the answers it published of ``answers`` expected."""
    values = diag_values(diagnostics.messages[-1]) if len(diagnostics) else {}
    if not values:
        return 'no diagnostics from the node'
    return (f'latest status: the node took {values.get("commands_received")} of {commands} commands '
            f'(commands_lost by sequence gaps: {values.get("commands_lost")}) and published '
            f'{values.get("joint_states_published")} joint_states and {values.get("input_torque_published")} '
            f'input_torque of {answers}')


# --------------------------------------------------------------------------- the CLI as a process

def fourbar_command() -> list[str]:
    """The `fourbar` console script next to this Python (else ``python -m fourbar_ros.commands``)."""
    script = Path(sys.executable).parent / 'fourbar'
    return [str(script)] if script.exists() else [sys.executable, '-m', 'fourbar_ros.commands']


class Tool:
    """``fourbar ARGS`` (or ``COMMAND ARGS``, e.g. the node's console script) as a child process in its own session
    (so its process group is its own), in ``cwd``, with ``pass_fds`` kept open in it; its output lines can be waited
    for. Leaving the ``with`` block kills what is still running of the process group and reaps the process."""

    def __init__(self, args: Sequence[str | os.PathLike[str]], env: dict[str, str],
                 command: Sequence[str] | None = None, cwd: Path = REPO, pass_fds: Sequence[int] = ()) -> None:
        self.args = [str(a) for a in args]
        self.cmd = [*(command or fourbar_command()), *self.args]
        self.proc = subprocess.Popen(self.cmd, env=env, cwd=cwd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                     stderr=subprocess.PIPE, text=True, start_new_session=True,
                                     pass_fds=tuple(pass_fds))
        self.lines: list[str] = []  # stderr
        self.out_lines: list[str] = []  # stdout
        self._cond = threading.Condition()
        self._readers = [threading.Thread(target=self._read, args=(self.proc.stderr, self.lines), daemon=True),
                         threading.Thread(target=self._read, args=(self.proc.stdout, self.out_lines), daemon=True)]
        for reader in self._readers:
            reader.start()

    def _read(self, stream: Any, lines: list[str]) -> None:
        for line in stream:
            with self._cond:
                lines.append(line.rstrip('\n'))
                self._cond.notify_all()

    @property
    def stdout(self) -> str:
        """Everything written to stdout so far."""
        with self._cond:
            return ''.join(f'{line}\n' for line in self.out_lines)

    @property
    def stderr(self) -> str:
        """Everything written to stderr so far."""
        with self._cond:
            return ''.join(f'{line}\n' for line in self.lines)

    def wait_line(self, text: str, timeout: float = TIMEOUT, stdout: bool = False) -> str:
        """Block until a stderr (or stdout) line contains ``text``; fail if the process exits first."""
        lines = self.out_lines if stdout else self.lines
        deadline = time.monotonic() + timeout
        with self._cond:
            while True:
                for line in lines:
                    if text in line:
                        return line
                if self.proc.poll() is not None and not any(r.is_alive() for r in self._readers):
                    raise AssertionError(f'{" ".join(self.cmd)} exited {self.proc.returncode} '
                                         f'without {text!r}: {self.lines}')
                left = deadline - time.monotonic()
                if left <= 0:
                    raise AssertionError(f'timed out waiting for {text!r} from {self.cmd}: {self.lines}')
                self._cond.wait(min(left, 0.2))

    def wait(self, timeout: float = TIMEOUT) -> int:
        """Wait for the exit status (the process is killed at the deadline)."""
        try:
            rc = self.proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.kill()
            raise AssertionError(f'{self.cmd} did not finish within {timeout} s: {self.lines}') from None
        for reader in self._readers:
            reader.join(timeout=5)
        return rc

    def signal(self, sig: int, group: bool = False) -> None:
        """Send ``sig`` to the process (``group``: to its whole process group, as a terminal's Ctrl-C does)."""
        if group:
            os.killpg(self.proc.pid, sig)
        else:
            self.proc.send_signal(sig)

    def kill(self) -> None:
        """Kill the process and its process group (every child it started there) if still running, and reap it
        (safe to repeat)."""
        if self.proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.proc.pid, signal.SIGKILL)
        self.proc.wait()

    def __enter__(self) -> Tool:
        return self

    def __exit__(self, *exc: object) -> None:
        self.kill()


def run_tool(args: Sequence[str | os.PathLike[str]], env: dict[str, str],
             timeout: float = TIMEOUT) -> tuple[int, list[str], str]:
    """Run ``fourbar ARGS`` to completion: (status, stderr lines, stdout)."""
    with Tool(args, env) as tool:
        rc = tool.wait(timeout)
        return rc, tool.lines, tool.stdout


def run_main(args: Sequence[str | os.PathLike[str]]) -> tuple[int, list[str], str]:
    """``run_tool`` in this process (``commands.main``), for a command that needs no ROS graph and no signal:
    (status, stderr lines, stdout)."""
    done = fourbar(*args)
    return done.returncode, done.stderr.splitlines(), done.stdout


# --------------------------------------------------------------------------- independent readers

def storage_file(bag: Path) -> Path:
    """The single storage file (.mcap or .db3) of a bag directory."""
    files = [p for p in bag.iterdir() if p.suffix in ('.mcap', '.db3')]
    assert len(files) == 1, files
    return files[0]


def read_with_mcap(bag: Path) -> dict[str, list[tuple[int, Any]]]:
    """Decode every message with the `mcap` + `mcap-ros2-support` packages (not rosbags)."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    out: dict[str, list[tuple[int, Any]]] = {}
    with storage_file(bag).open('rb') as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        assert reader.get_header().profile == 'ros2'
        for _schema, channel, message, decoded in reader.iter_decoded_messages(log_time_order=True):
            out.setdefault(channel.topic, []).append((message.log_time, decoded))
    return out


def read_with_sqlite(bag: Path) -> dict[str, list[tuple[int, Any]]]:
    """Decode every message with Python's sqlite3 and rclpy's own deserializer (not rosbags)."""
    import importlib

    from rclpy.serialization import deserialize_message

    def get_message(msgtype: str) -> Any:
        pkg, kind, name = msgtype.split('/')
        return getattr(importlib.import_module(f'{pkg}.{kind}'), name)

    out: dict[str, list[tuple[int, Any]]] = {}
    con = sqlite3.connect(f'file:{storage_file(bag)}?mode=ro', uri=True)
    try:
        topics = {tid: (name, get_message(typ)) for tid, name, typ in
                  con.execute('SELECT id, name, type FROM topics')}
        for tid, stamp, data in con.execute('SELECT topic_id, timestamp, data FROM messages ORDER BY timestamp, id'):
            name, cls = topics[tid]
            out.setdefault(name, []).append((stamp, deserialize_message(bytes(data), cls)))
    finally:
        con.close()
    return out
