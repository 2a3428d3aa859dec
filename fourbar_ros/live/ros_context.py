"""rclpy contexts for the command-line tools: create, close (their signals: fourbar_ros.runtime.stop)."""

from __future__ import annotations

from collections.abc import Callable

import rclpy
import rclpy.utilities
from rclpy.context import Context
from rclpy.node import Node


def init_context(domain_id: int | None = None) -> Context:
    """A fresh rclpy context (``domain_id`` None: from ROS_DOMAIN_ID, as rclpy does), without rclpy's signal
    handlers: the tools stop by ``runtime.stop.stop_on_signals``."""
    from rclpy.signals import SignalHandlerOptions

    context = Context()
    rclpy.init(context=context, domain_id=domain_id, signal_handler_options=SignalHandlerOptions.NO)
    return context


def close_context(context: Context, *nodes: Node) -> None:
    """Destroy ``nodes`` and shut ``context`` down (idempotent)."""
    for node in nodes:
        destroy: Callable[[], object] = node.destroy_node
        destroy()
    rclpy.utilities.try_shutdown(context=context)
