"""A publisher's calls on a callback's good path without rclpy's per-call handle guard.

rclpy's ``Publisher.publish`` and ``get_subscription_count`` enter ``with self.handle`` on every call (about 4 of the
5 us of a count) so that no other thread destroys the publisher meanwhile; the handle's own methods hold the GIL for
the whole call, so none can, and one of a destroyed publisher raises RCLError. See docs/explanation/node.md.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from rclpy.publisher import Publisher


def subscription_count(publisher: Publisher) -> Callable[[], int]:
    """``publisher.get_subscription_count`` as one C call."""
    count: Callable[[], int] = publisher.handle.get_subscription_count
    return count


def publish(publisher: Publisher) -> Callable[[Any], None]:
    """``publisher.publish`` for a message of the publisher's type, as one C call."""
    send: Callable[[Any], None] = publisher.handle.publish
    return send
