"""The drive bridge's real-stack tests' shared parts: what the topic-based plugin needs, the controller manager's
executables, and child processes with their logs in files."""

from __future__ import annotations

import os
import signal
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest

from support.isolation import kill_group
from support.ros2_control_support import ros2_control_missing

PLUGIN = 'joint_state_topic_hardware_interface/JointStateTopicSystem'


def topic_plugin_missing(env: dict[str, str]) -> str | None:
    """Why ros2_control with the topic-based hardware plugin cannot be started with ``env`` (None when it can)."""
    why = ros2_control_missing(env)
    if why is not None:
        return why
    roots = [Path(p) for p in env.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    index = Path('share') / 'ament_index' / 'resource_index' / 'packages' / 'joint_state_topic_hardware_interface'
    if not any((root / index).exists() for root in roots):
        return f'the topic-based hardware plugin ({PLUGIN}) is not installed with ros2_control'
    return None


def manager_executable(env: dict[str, str], name: str) -> str:
    """The path of controller_manager's executable ``name`` (ros2_control_node, spawner) on ``env``'s ament paths."""
    for root in env['AMENT_PREFIX_PATH'].split(os.pathsep):
        path = Path(root) / 'lib' / 'controller_manager' / name
        if path.exists():
            return str(path)
    raise AssertionError(f'controller_manager/{name} not found')


class Processes:
    """Child processes in groups of their own, each ended (SIGINT, then SIGKILL) on leaving; logs in files."""

    def __init__(self, tmp: Path) -> None:
        self.tmp = tmp
        self.procs: list[tuple[subprocess.Popen[bytes], Path]] = []

    def start(self, name: str, args: list[str], env: dict[str, str]) -> subprocess.Popen[bytes]:
        log = self.tmp / f'{name}.log'
        with open(log, 'wb') as out:
            proc = subprocess.Popen(args, env=env, stdout=out, stderr=subprocess.STDOUT, start_new_session=True)
        self.procs.append((proc, log))
        return proc

    def log(self, name: str) -> str:
        path = self.tmp / f'{name}.log'
        return path.read_text(errors='replace') if path.exists() else ''

    def logs(self) -> str:
        return '\n'.join(f'--- {log.name}\n{log.read_text(errors="replace")[-3000:]}' for _, log in self.procs)

    @staticmethod
    def stop(proc: subprocess.Popen[bytes]) -> int:
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        kill_group(proc.pid)
        return proc.returncode

    def close(self) -> None:
        for proc, _ in reversed(self.procs):
            self.stop(proc)


@pytest.fixture
def processes(tmp_path: Path) -> Iterator[Processes]:
    """A test's child processes, all ended when it ends."""
    procs = Processes(tmp_path)
    try:
        yield procs
    finally:
        procs.close()
