"""The rclpy node (fourbar_node) and what runs it: the node (fourbar_node.py), how it starts, spins and stops
(run.py, also the stop of every ``fourbar`` command), the executor choice, markers.

This package's face imports no rclpy; ``main`` (run.py) is the ``fourbar_node`` console script.
"""

from __future__ import annotations

from fourbar_ros.node.run import main

__all__ = ['main']
