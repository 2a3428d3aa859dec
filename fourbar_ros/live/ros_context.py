"""rclpy contexts for the command-line tools: create, turn SIGTERM into Ctrl-C, close."""

from __future__ import annotations

import contextlib
import signal
from collections.abc import Callable, Iterator

import rclpy
import rclpy.utilities
from rclpy.context import Context
from rclpy.node import Node

from fourbar_ros.node.executor import INTERRUPT


def init_context(domain_id: int | None = None, handle_signals: bool = True) -> Context:
    """A fresh rclpy context (``domain_id`` None: from ROS_DOMAIN_ID, as rclpy does)."""
    from rclpy.signals import SignalHandlerOptions

    context = Context()
    rclpy.init(context=context, domain_id=domain_id,
               signal_handler_options=SignalHandlerOptions.ALL if handle_signals else SignalHandlerOptions.NO)
    return context


@contextlib.contextmanager
def interrupt_on_sigterm() -> Iterator[None]:
    """SIGTERM, like Ctrl-C, raises KeyboardInterrupt inside the block, so cleanup code runs.

    Use with ``init_context(handle_signals=False)``: rclpy's own handlers would invalidate the
    context under a running publisher instead of interrupting the program. A signal that lands while
    callbacks run (``graph.spin_until``, ``Replayer.run_timed``) is raised when that spin returns, not
    inside a callback (fourbar_ros.node.executor.DeferredInterrupt).
    """
    previous = {sig: signal.signal(sig, INTERRUPT) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def close_context(context: Context, *nodes: Node) -> None:
    """Destroy ``nodes`` and shut ``context`` down (idempotent)."""
    for node in nodes:
        destroy: Callable[[], object] = node.destroy_node
        destroy()
    rclpy.utilities.try_shutdown(context=context)
