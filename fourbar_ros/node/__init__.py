"""The rclpy nodes (fourbar_node, sim_actuator) and the pure helpers they adapt: policy, cache, velocity,
diagnostics, markers, the simulated drive.

This package's face imports nothing (the bag tools use its pure helpers without rclpy); ``main`` is the
``fourbar_node`` console script, ``sim_actuator_main`` the ``fourbar_sim_actuator`` one.
"""

from __future__ import annotations

import signal
import sys


def _stop_while_starting(signum: int, frame: object) -> None:
    raise SystemExit(0)


def _quiet_start() -> None:
    """Importing rclpy and the message packages takes a noticeable time; a SIGINT or SIGTERM in that window (a
    launch file or supervisor stopping right after starting the node) would otherwise end it with a
    KeyboardInterrupt traceback or status -15. Until the node installs its own handling, either signal exits 0."""
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, _stop_while_starting)


def main(args: list[str] | None = None) -> int:
    """Console script ``fourbar_node``: the node's own ``main`` (fourbar_node.py), reached through a quiet start."""
    _quiet_start()
    from fourbar_ros.node.fourbar_node import main as node_main

    return node_main(args)


def sim_actuator_main(args: list[str] | None = None) -> int:
    """Console script ``fourbar_sim_actuator``: the simulated drive's ``main`` (sim_actuator.py), quietly started."""
    _quiet_start()
    from fourbar_ros.node.sim_actuator import main as sim_main

    return sim_main(args)


if __name__ == '__main__':
    sys.exit(main())
