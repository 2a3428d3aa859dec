"""The one node of a test probe that runs as a process of its own (jtc_judge.py, goal_probe.py,
lifecycle_probe.py): spun in a background thread while the probe's main thread drives the steps."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import contextmanager

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node


@contextmanager
def probe_node(name: str, namespace: str) -> Iterator[Node]:
    """rclpy initialised and node ``name`` in ``namespace`` spinning (callbacks on the spinning thread); on leaving,
    the thread stopped and everything shut down."""
    rclpy.init()
    node = Node(name, namespace=namespace)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    stop = threading.Event()

    def spin() -> None:
        while not stop.is_set():
            executor.spin_once(timeout_sec=0.05)

    spinner = threading.Thread(target=spin)
    spinner.start()
    try:
        yield node
    finally:
        stop.set()
        spinner.join()
        executor.shutdown(timeout_sec=1.0)
        node.destroy_node()
        rclpy.try_shutdown()
