"""The bridge on the real ros2_control stack: a controller manager with the topic-based hardware plugin
(``joint_state_topic_hardware_interface/JointStateTopicSystem``) and the joint_state_broadcaster, the bridge's
simulated drive away from the model's initial value. Before anything commands, the broadcaster publishes the drive's
position (not ``initial_value``), the plugin's NaN commands are held and nothing is written to the drive.

Skipped, with the reason, where ros2_control or the plugin is not installed.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

pytest.importorskip('rclpy')

from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from support.isolation import kill_group
from support.ros2_control_support import ros2_control_missing, with_ros2_control
from support.ros_support import RosSession

from fourbar_ros.config.antenna_config import config_from_values
from fourbar_ros.config.robot_model import driven_angle, robot_description
from fourbar_ros.drive.backend import SimulatedBackend
from fourbar_ros.drive.bridge_node import DriveBridge
from fourbar_ros.motion.limits import JointLimits

pytestmark = [pytest.mark.ros, pytest.mark.slow]

PLUGIN = 'joint_state_topic_hardware_interface/JointStateTopicSystem'
NAMESPACE = '/drive_real'
MANAGER = f'{NAMESPACE}/controller_manager'
COMMANDS, STATES = f'{NAMESPACE}/drive_commands', f'{NAMESPACE}/drive_states'
START = 0.95  # rad: the drive's position, away from the model's initial value
TIMEOUT = 60.0
#: Broadcaster messages after the first with the drive's position that must all carry it too.
AFTER = 20


def _missing(env: dict[str, str]) -> str | None:
    why = ros2_control_missing(env)
    if why is not None:
        return why
    roots = [Path(p) for p in env.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    index = Path('share') / 'ament_index' / 'resource_index' / 'packages' / 'joint_state_topic_hardware_interface'
    if not any((root / index).exists() for root in roots):
        return f'the topic-based hardware plugin ({PLUGIN}) is not installed with ros2_control'
    return None


def _executable(env: dict[str, str], name: str) -> str:
    for root in env['AMENT_PREFIX_PATH'].split(os.pathsep):
        path = Path(root) / 'lib' / 'controller_manager' / name
        if path.exists():
            return str(path)
    raise AssertionError(f'controller_manager/{name} not found')


class Processes:
    """Child processes in groups of their own, each ended (SIGINT, then SIGKILL) on leaving."""

    def __init__(self, tmp: Path) -> None:
        self.tmp = tmp
        self.procs: list[tuple[subprocess.Popen[bytes], Path]] = []

    def start(self, name: str, args: list[str], env: dict[str, str]) -> subprocess.Popen[bytes]:
        log = self.tmp / f'{name}.log'
        with open(log, 'wb') as out:
            proc = subprocess.Popen(args, env=env, stdout=out, stderr=subprocess.STDOUT, start_new_session=True)
        self.procs.append((proc, log))
        return proc

    def logs(self) -> str:
        return '\n'.join(f'--- {log.name}\n{log.read_text(errors="replace")[-3000:]}' for _, log in self.procs)

    def close(self) -> None:
        for proc, _ in reversed(self.procs):
            if proc.poll() is None:
                proc.send_signal(signal.SIGINT)
                try:
                    proc.wait(timeout=20)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait()
            kill_group(proc.pid)


@pytest.fixture
def processes(tmp_path: Path) -> Iterator[Processes]:
    procs = Processes(tmp_path)
    try:
        yield procs
    finally:
        procs.close()


def test_the_broadcaster_publishes_the_drives_position_before_anything_commands(
        ros: RosSession, processes: Processes, tmp_path: Path) -> None:
    env = with_ros2_control(ros.env(PYTHON=sys.executable))
    if (why := _missing(env)) is not None:
        pytest.skip(why)
    cfg = config_from_values({'hardware_parameters': [f'joint_commands_topic={COMMANDS}',
                                                      f'joint_states_topic={STATES}']})
    joint = cfg.driven_joint
    assert abs(driven_angle(cfg) - START) > 0.05  # the model's initial value is elsewhere
    backend = SimulatedBackend(START, JointLimits.from_config(cfg).at_rocker(1))
    bridge = DriveBridge(backend=backend, context=ros.context, parameter_overrides=[
        Parameter('joint_commands_topic', value=COMMANDS), Parameter('joint_states_topic', value=STATES)])
    ros.add_node(bridge)
    description = ros.publisher(String, f'{NAMESPACE}/robot_description',
                                QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    description.publish(String(data=robot_description(cfg, hardware_plugin=PLUGIN)))
    measured = ros.collect(JointState, f'{NAMESPACE}/joint_states')
    params = tmp_path / 'controllers.yaml'
    params.write_text(f'{MANAGER}:\n  ros__parameters:\n    update_rate: 100\n    joint_state_broadcaster:\n'
                      '      type: joint_state_broadcaster/JointStateBroadcaster\n', encoding='utf-8')
    try:
        processes.start('controller_manager', [_executable(env, 'ros2_control_node'), '--ros-args',
                                               '-r', f'__ns:={NAMESPACE}', '--params-file', str(params)], env)
        spawner = processes.start('spawner', [sys.executable, _executable(env, 'spawner'),
                                              'joint_state_broadcaster', '-c', MANAGER], env)
        first = measured.wait_match(lambda m: joint in m.name and m.position[list(m.name).index(joint)] == START,
                                    TIMEOUT)
        index = measured.messages.index(first)
        after = measured.wait_count(index + 1 + AFTER, TIMEOUT)[index + 1:]
        assert all(m.position[list(m.name).index(joint)] == START for m in after)
        counters = bridge.rules.counters
        ros.wait_for(lambda: counters.held_not_finite > 0, TIMEOUT, "the plugin's NaN commands held")
        assert backend.writes == [] and counters.written == 0
        assert spawner.wait(timeout=TIMEOUT) == 0
    except AssertionError as exc:
        raise AssertionError(f'{exc}\n{processes.logs()}') from None
    finally:
        ros.remove_node(bridge)
        ros.destroy(description)
