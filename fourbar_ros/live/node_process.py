"""``fourbar_node`` as a child process with a parameter file and domain id, stopped in escalating steps."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import IO

NODE_MAIN = 'import sys; from fourbar_ros.node import main; sys.exit(main())'


class NodeProcess:
    """``fourbar_node`` as a child process (own session) with a parameter file and domain id.

    ``stop()`` sends SIGINT and escalates to SIGTERM and SIGKILL; it is safe to call twice.
    """

    def __init__(self, params: Path | None, domain_id: int, log_path: Path | None = None,
                 ros_args: Sequence[str] = (), env: dict[str, str] | None = None) -> None:
        self.params = params
        self.domain_id = domain_id
        self.log_path = log_path
        self.ros_args = list(ros_args)
        self.env = dict(os.environ if env is None else env)
        self.env['ROS_DOMAIN_ID'] = str(domain_id)
        self.proc: subprocess.Popen[bytes] | None = None
        self._log: IO[bytes] | None = None

    def command(self) -> list[str]:
        """The argv that starts the node (the same interpreter as this process)."""
        args = [sys.executable, '-c', NODE_MAIN, '--ros-args']
        if self.params is not None:
            args += ['--params-file', str(self.params)]
        return args + self.ros_args

    def start(self) -> NodeProcess:
        """Start the node; its output goes to ``log_path`` (or is discarded)."""
        self._log = self.log_path.open('wb') if self.log_path else None
        self.proc = subprocess.Popen(
            self.command(), env=self.env, stdin=subprocess.DEVNULL,
            stdout=self._log or subprocess.DEVNULL, stderr=subprocess.STDOUT,
            start_new_session=True)
        return self

    def alive(self) -> bool:
        """True while the process runs."""
        return self.proc is not None and self.proc.poll() is None

    def last_log_line(self) -> str:
        """The last non-empty line the node wrote (for error messages)."""
        if self.log_path is None or not self.log_path.exists():
            return ''
        lines = [x for x in self.log_path.read_text(errors='replace').splitlines() if x.strip()]
        return lines[-1].strip() if lines else ''

    def stop(self, timeout_s: float = 10.0) -> int | None:
        """Stop the node (SIGINT, then SIGTERM, then SIGKILL); return its exit status."""
        proc = self.proc
        if proc is None:
            return None
        try:
            for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
                if proc.poll() is not None:
                    break
                with contextlib.suppress(ProcessLookupError):
                    proc.send_signal(sig)
                with contextlib.suppress(subprocess.TimeoutExpired):
                    proc.wait(timeout=timeout_s)
            return proc.wait()
        finally:
            if self._log is not None:
                self._log.close()
                self._log = None

    def __enter__(self) -> NodeProcess:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()
