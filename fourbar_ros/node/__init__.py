"""The rclpy nodes (fourbar_node, sim_actuator) and what runs them: the nodes (fourbar_node.py, sim_actuator.py),
how they start, spin and stop (run.py, also the stop of every ``fourbar`` command), the executor choice, markers.

This package's face imports no rclpy; ``main`` and ``sim_actuator_main`` (run.py) are the ``fourbar_node`` and
``fourbar_sim_actuator`` console scripts.
"""

from __future__ import annotations

from fourbar_ros.node.run import main, sim_actuator_main

__all__ = ['main', 'sim_actuator_main']
