"""The clock that periodic work runs on, and timers on it.

Periodic work (the simulated actuator's control loop, fourbar_node's joint_states republish, diagnostics, markers,
forward mode's setpoint stream) is meant to keep its rate, not to follow the calendar: with ``use_sim_time`` false
its timers run on the steady clock, so a step of the system clock (NTP, a virtual machine resumed, a user setting
the date) neither stalls them for the step (a backward step: a ROS-clock timer waits until the clock is back where
it was) nor fires them early. With ``use_sim_time`` true they run on the node's ROS clock and follow ``/clock``, as
sim time is meant to: they fire as sim time advances, and not while it stands still.

What is read from the clock for stamps (``joint_states``, ``/diagnostics``) stays ROS time either way. The choice is
made when a timer is created: ``use_sim_time`` given at start (as launch files do) is followed; changing it on a
running node does not move its timers to the other clock.
"""

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
