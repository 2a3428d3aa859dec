"""The rclpy nodes, fourbar_node and sim_actuator; this face, their console scripts' mains, imports no rclpy."""

from __future__ import annotations

from fourbar_ros.node.run import main, sim_actuator_main

__all__ = ['main', 'sim_actuator_main']
