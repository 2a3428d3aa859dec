"""The clock that periodic work runs on, and timers on it.

The steady clock without ``use_sim_time`` (a step of the system clock neither stalls nor hurries them), the node's
ROS clock with it; stamps stay ROS time either way. Why: docs/explanation/node.md."""

from __future__ import annotations

import weakref
from collections.abc import Callable
from typing import Any

from rclpy.clock import Clock, ROSClock
from rclpy.clock_type import ClockType
from rclpy.node import Node
from rclpy.timer import Timer

#: One steady clock per node: the EventsExecutor runs a thread per clock that has timers.
_STEADY: weakref.WeakKeyDictionary[Node, Clock] = weakref.WeakKeyDictionary()


def work_clock(node: Node) -> Clock:
    """The node's ROS clock while it runs on sim time, else the node's steady clock (one per node)."""
    get_clock: Callable[[], Clock] = node.get_clock  # rclpy's accessor is unannotated
    clock = get_clock()
    if isinstance(clock, ROSClock) and clock.ros_time_is_active:
        return clock
    steady = _STEADY.get(node)
    if steady is None:
        steady = _STEADY[node] = Clock(clock_type=ClockType.STEADY_TIME)
    return steady


def periodic_timer(node: Node, period_s: float, callback: Callable[[], Any]) -> Timer:
    """``node.create_timer(period_s, callback)`` on ``work_clock(node)``: steady unless on sim time."""
    create_timer: Callable[..., Timer] = node.create_timer
    return create_timer(period_s, callback, clock=work_clock(node))
