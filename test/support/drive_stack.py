"""The drive bridge's real-stack tests' shared parts: what the topic-based plugin needs, the configuration its
topics are set in, the controller manager's executables, and child processes with their logs in files."""

from __future__ import annotations

import os
import signal
import subprocess
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

from fourbar_ros.config.antenna_config import AntennaConfig, config_from_values
from fourbar_ros.config.robot_model import driven_angle, robot_description
from fourbar_ros.drive.rules import DriveLimits
from support.isolation import kill_group
from support.ros2_control_support import ros2_control_missing

if TYPE_CHECKING:  # the message packages come with ROS: the pure drive tests share this module's fixture
    from sensor_msgs.msg import JointState

    from support.ros_support import RosSession

PLUGIN = 'joint_state_topic_hardware_interface/JointStateTopicSystem'
COMMANDS, STATES = 'drive_joint_commands', 'drive_joint_states'  # relative: in the manager's namespace
#: The shipped configuration with the plugin's topics as hardware parameters.
CFG = config_from_values({'hardware_parameters': [f'joint_commands_topic={COMMANDS}',
                                                  f'joint_states_topic={STATES}']})
JOINT, COMPONENT = CFG.driven_joint, CFG.hardware_id
LIMITS = DriveLimits.from_config(CFG)
INITIAL = driven_angle(CFG)  # the URDF's initial_value: the plugin's position state before its first reading
#: The commanded move (rad) and its duration (s): 0.005 rad/s, within the speed limit at the rocker.
STEP, STEP_S = 0.005, 1
TIMEOUT = 60.0
RESEND_S = 0.5  # s between two sends of the command until the drive moves


def publish_description(ros: RosSession, namespace: str, cfg: AntennaConfig = CFG) -> Any:
    """``cfg``'s URDF with the topic plugin on ``namespace``/robot_description, transient local as
    robot_state_publisher publishes it (a manager started later gets it); the publisher."""
    from rclpy.qos import DurabilityPolicy, QoSProfile
    from std_msgs.msg import String

    publisher = ros.publisher(String, f'{namespace}/robot_description',
                              QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    publisher.publish(String(data=robot_description(cfg, hardware_plugin=PLUGIN)))
    return publisher


def joint_position(msg: JointState) -> float | None:
    """The driven joint's position (rad) in ``msg``, None where it has none."""
    names = list(msg.name)
    return float(msg.position[names.index(JOINT)]) if JOINT in names and msg.position else None


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
