"""The rclpy QoS profile of one of the package's topics (``fourbar_ros.interface.topics.Topic``)."""

from __future__ import annotations

from collections.abc import Callable

from rclpy.qos import QoSProfile, ReliabilityPolicy

from fourbar_ros.interface.topics import Topic

_qos_profile: Callable[..., QoSProfile] = QoSProfile  # rclpy's constructor is unannotated


def qos(topic: Topic) -> QoSProfile:
    """Keep-last ``topic.depth``, ``topic.reliability``, volatile."""
    return _qos_profile(depth=topic.depth, reliability=ReliabilityPolicy[topic.reliability.name])
