"""The rclpy node (fourbar_node) and the pure helpers it adapts: policy, cache, velocity, diagnostics, markers.

This package's face imports nothing (the bag tools use its pure helpers without rclpy); ``main`` is the
``fourbar_node`` console script.
"""

from __future__ import annotations

import signal
import sys


def _stop_while_starting(signum: int, frame: object) -> None:
    raise SystemExit(0)


def main(args: list[str] | None = None) -> int:
    """Console script ``fourbar_node``: the node's own ``main`` (fourbar_node.py), reached through a quiet start.

    Importing rclpy and the message packages takes a noticeable time; a SIGINT or SIGTERM in that window (a
    launch file or supervisor stopping right after starting the node) would otherwise end it with a
    KeyboardInterrupt traceback or status -15. Until the node installs its own handling, either signal exits 0.
    """
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, _stop_while_starting)
    from fourbar_ros.node.fourbar_node import main as node_main

    return node_main(args)


if __name__ == '__main__':
    sys.exit(main())
