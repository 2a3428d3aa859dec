"""The ROS graph as the bag tools need it: spin until a condition, which nodes publish or subscribe a topic."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any, cast

from rclpy.executors import Executor
from rclpy.node import Node
from rclpy.qos import QoSProfile

from fourbar_ros.core.errors import FourBarError
from fourbar_ros.runtime.spin import spin_once

#: rclpy's QoSProfile constructor is unannotated; a typed alias keeps mypy strict about the rest.
make_qos = cast('Callable[..., QoSProfile]', QoSProfile)


class ReplayError(FourBarError):
    """The node is absent, did not answer a command in time, or its parameters are unusable."""


def spin_until(executor: Executor, done: Callable[[], bool], timeout_s: float) -> bool:
    """Run callbacks until ``done()`` or ``timeout_s`` seconds pass; return ``done()``."""
    end = time.monotonic() + timeout_s
    while not done():
        remaining = end - time.monotonic()
        if remaining <= 0.0:
            return done()
        spin_once(executor, min(remaining, 0.1))  # a signal during it is raised after it (runtime.stop)
    return True


def _node_names(node: Node, infos: Sequence[Any]) -> list[str]:
    me = node.get_fully_qualified_name()
    names: list[str] = []
    for info in infos:
        if info.node_name == '_NODE_NAME_UNKNOWN_':  # rmw placeholder until discovery completes
            continue
        fqn = f'{info.node_namespace.rstrip("/")}/{info.node_name}'
        if fqn != me and fqn not in names:
            names.append(fqn)
    return names


def subscriber_nodes(node: Node, topic: str) -> list[str]:
    """Fully qualified names of the other nodes subscribed to ``topic``."""
    return _node_names(node, node.get_subscriptions_info_by_topic(topic))


def publisher_nodes(node: Node, topic: str) -> list[str]:
    """Fully qualified names of the other nodes publishing ``topic``."""
    return _node_names(node, node.get_publishers_info_by_topic(topic))


def wait_for_node_names(node: Node, executor: Executor, lookup: Callable[[], list[str]],
                        timeout_s: float, what: str) -> list[str]:
    """Wait until the graph names the nodes behind ``what`` (names arrive after the endpoints)."""
    if not spin_until(executor, lambda: bool(lookup()), timeout_s):
        raise ReplayError(f'no named node {what} within {timeout_s:g} s')
    return lookup()
