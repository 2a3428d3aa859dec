"""The rclpy nodes (fourbar_node, sim_actuator) and what runs them: the nodes (fourbar_node.py, sim_actuator.py),
how they start, spin and stop (run.py, also the stop of every ``fourbar`` command), the executor choice, markers.

This package's face imports no rclpy; ``main`` (run.py) is the ``fourbar_node`` console script,
``sim_actuator_main`` the ``fourbar_sim_actuator`` one.
"""

from __future__ import annotations

from fourbar_ros.node.run import STOP, main


def sim_actuator_main(args: list[str] | None = None) -> int:
    """Console script ``fourbar_sim_actuator``: sim_actuator.py's ``main``, exiting 0 on a stop that arrives while
    rclpy and the message packages import (see run.py)."""
    STOP.install(raises=lambda: SystemExit(0))
    from fourbar_ros.node.sim_actuator import main as sim_main

    return sim_main(args)


__all__ = ['main', 'sim_actuator_main']
