"""The bridge on the real ros2_control stack: a controller manager with the topic-based hardware plugin
(``joint_state_topic_hardware_interface/JointStateTopicSystem``) and the joint_state_broadcaster, the bridge's
simulated drive away from the model's initial value. Before anything commands, the broadcaster publishes the drive's
position (not ``initial_value``), the plugin's NaN commands are held and nothing is written to the drive.

Skipped, with the reason, where ros2_control or the plugin is not installed.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

pytest.importorskip('rclpy')

from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from support.drive_stack import Processes, manager_executable, publish_description, topic_plugin_missing
from support.ros2_control_support import with_ros2_control
from support.ros_support import RosSession

from fourbar_ros.config.antenna_config import config_from_values
from fourbar_ros.config.robot_model import driven_angle
from fourbar_ros.drive.backend import SimulatedBackend
from fourbar_ros.drive.bridge_node import DriveBridge
from fourbar_ros.motion.limits import JointLimits

pytestmark = [pytest.mark.ros, pytest.mark.slow]

NAMESPACE = '/drive_real'
MANAGER = f'{NAMESPACE}/controller_manager'
COMMANDS, STATES = f'{NAMESPACE}/drive_commands', f'{NAMESPACE}/drive_states'
START = 0.95  # rad: the drive's position, away from the model's initial value
TIMEOUT = 60.0
#: Broadcaster messages after the first with the drive's position that must all carry it too.
AFTER = 20


def test_the_broadcaster_publishes_the_drives_position_before_anything_commands(
        ros: RosSession, processes: Processes, tmp_path: Path) -> None:
    env = with_ros2_control(ros.env(PYTHON=sys.executable))
    if (why := topic_plugin_missing(env)) is not None:
        pytest.skip(why)
    cfg = config_from_values({'hardware_parameters': [f'joint_commands_topic={COMMANDS}',
                                                      f'joint_states_topic={STATES}']})
    joint = cfg.driven_joint
    assert abs(driven_angle(cfg) - START) > 0.05  # the model's initial value is elsewhere
    backend = SimulatedBackend(START, JointLimits.from_config(cfg).at_rocker(1))
    bridge = DriveBridge(backend=backend, context=ros.context, parameter_overrides=[
        Parameter('joint_commands_topic', value=COMMANDS), Parameter('joint_states_topic', value=STATES)])
    ros.add_node(bridge)
    description = publish_description(ros, NAMESPACE, cfg)
    measured = ros.collect(JointState, f'{NAMESPACE}/joint_states')
    params = tmp_path / 'controllers.yaml'
    params.write_text(f'{MANAGER}:\n  ros__parameters:\n    update_rate: 100\n    joint_state_broadcaster:\n'
                      '      type: joint_state_broadcaster/JointStateBroadcaster\n', encoding='utf-8')
    try:
        processes.start('controller_manager', [manager_executable(env, 'ros2_control_node'), '--ros-args',
                                               '-r', f'__ns:={NAMESPACE}', '--params-file', str(params)], env)
        spawner = processes.start('spawner', [sys.executable, manager_executable(env, 'spawner'),
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
