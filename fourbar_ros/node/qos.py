"""The rclpy QoS profile of one of the package's topics (``fourbar_ros.interface.topics.Topic``)."""

from __future__ import annotations

from collections.abc import Callable

from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from fourbar_ros.interface.topics import Topic

_qos_profile: Callable[..., QoSProfile] = QoSProfile  # rclpy's constructor is unannotated


def qos(topic: Topic) -> QoSProfile:
    """Keep-last ``topic.depth``, ``topic.reliability``, transient local or volatile as ``topic`` says."""
    durability = DurabilityPolicy.TRANSIENT_LOCAL if topic.transient_local else DurabilityPolicy.VOLATILE
    return _qos_profile(depth=topic.depth, reliability=ReliabilityPolicy[topic.reliability.name],
                        durability=durability)
