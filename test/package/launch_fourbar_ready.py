"""launch_testing test of the installed launch file: run with ``launch_test test/package/launch_fourbar_ready.py``
(test_launch.py does, over a colcon-built install). Not collected by pytest directly (no test_ prefix): it needs
the package in the ament index.

Active test: with fourbar.launch.py running in namespace /lt, a command on /lt/antenna_angle_cmd is answered on
/lt/joint_states with the core's rocker angles. Post-shutdown: every process exited with status 0.
"""

from __future__ import annotations

import sys
import threading
import time
import unittest
from pathlib import Path
from typing import Any

import launch_testing
import launch_testing.actions
import launch_testing.asserts
import rclpy
from ament_index_python.packages import get_package_share_directory
from diagnostic_msgs.msg import DiagnosticArray
from launch.actions import IncludeLaunchDescription
from launch.launch_description_sources import PythonLaunchDescriptionSource
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

from fourbar_ros.rules.diagnostics import status_name
from launch import LaunchDescription

NAMESPACE = 'lt'
TIMEOUT = 60.0


def generate_test_description() -> LaunchDescription:
    share = Path(get_package_share_directory('fourbar_ros'))
    return LaunchDescription([
        IncludeLaunchDescription(PythonLaunchDescriptionSource(str(share / 'launch' / 'fourbar.launch.py')),
                                 launch_arguments={'namespace': NAMESPACE}.items()),
        launch_testing.actions.ReadyToTest(),
    ])


class TestCommandIsAnswered(unittest.TestCase):
    """The launched node answers a command (real publisher and subscription in this process)."""

    def test_joint_states_answer_a_command(self) -> None:
        from fourbar_ros.config.antenna_config import load_config

        share = Path(get_package_share_directory('fourbar_ros'))
        cfg = load_config(share / 'config' / 'antenna.yaml')
        context = rclpy.Context()
        rclpy.init(context=context)
        node = Node('launch_test_client', context=context)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        got: list[Any] = []
        done = threading.Event()
        status: dict[str, str] = {}  # the node's latest diagnostics values: its side of a failure

        def on_joint_states(msg: Any) -> None:
            got.append(msg)
            done.set()

        def on_diagnostics(msg: Any) -> None:
            for entry in msg.status:
                if entry.name == status_name(f'/{NAMESPACE}/fourbar_node'):
                    status.clear()
                    status.update((kv.key, kv.value) for kv in entry.values)

        def graph(topic: str) -> str:
            def names(infos: Any) -> list[str]:
                return sorted(f'{i.node_namespace.rstrip("/")}/{i.node_name}' for i in infos)
            return (f'{topic}: publishers {names(node.get_publishers_info_by_topic(topic))}, subscriptions '
                    f'{names(node.get_subscriptions_info_by_topic(topic))}')

        try:
            sub = node.create_subscription(JointState, f'/{NAMESPACE}/joint_states', on_joint_states, 10)
            node.create_subscription(DiagnosticArray, '/diagnostics', on_diagnostics, 10)
            pub = node.create_publisher(Float64, f'/{NAMESPACE}/antenna_angle_cmd', 10)
            deadline = time.monotonic() + TIMEOUT
            published = 0
            # Publish until answered: the node skips outputs until it has discovered this subscription.
            while not done.is_set():
                if time.monotonic() >= deadline:
                    # This side: its own matches and graph; the node's side: its diagnostics (what it took and
                    # published, what it skipped for want of a subscriber); its log is in launch_test's output.
                    self.fail(f'no joint_states answer in {TIMEOUT} s: {published} commands published; this side: '
                              f'the command publisher matched {pub.get_subscription_count()} subscription(s), the '
                              f'joint_states subscription {sub.get_publisher_count()} publisher(s); graph of '
                              f'{graph(f"/{NAMESPACE}/antenna_angle_cmd")}; graph of '
                              f'{graph(f"/{NAMESPACE}/joint_states")}; the node\'s side (its diagnostics): '
                              f'{dict(status) if status else "none received"}')
                if pub.get_subscription_count() > 0:
                    pub.publish(Float64(data=0.05))
                    published += 1
                executor.spin_once(timeout_sec=0.2)
            gamma, delta = cfg.linkage.rocker_angles(0.05, cfg.branch)
            eps = sys.float_info.epsilon
            # Same core solve in node and test; 4 ulps for a different operation order (condition ~1.5 here).
            self.assertLessEqual(abs(got[0].position[0] - gamma), 4 * eps * abs(gamma))
            self.assertLessEqual(abs(got[0].position[1] - delta), 4 * eps * abs(delta))
        finally:
            executor.shutdown()
            node.destroy_node()
            context.try_shutdown()


@launch_testing.post_shutdown_test()
class TestShutdown(unittest.TestCase):
    """After the launch is shut down (SIGINT to every process), each exited with status 0."""

    def test_exit_codes(self, proc_info: Any) -> None:
        launch_testing.asserts.assertExitCodes(proc_info)
