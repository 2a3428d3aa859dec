"""The readiness of the controller an actuator mode feeds, from its controller manager's ``~/activity``.

The rclpy side of ``fourbar_ros.rules.command_fate.readiness``: the manager publishes its controllers' and hardware
components' lifecycle states there (reliable, transient local: the latest on connecting); a manager whose
publisher has gone, or has a successor, is gone; its ERROR lines on /rosout say why it deactivated the controller
(``rules.manager_errors``). Needs controller_manager_msgs; without it the controller is not followed."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from rcl_interfaces.msg import Log
from rclpy.clock import Clock
from rclpy.clock_type import ClockType
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from fourbar_ros.core.errors import one_line
from fourbar_ros.interface.topics import ROSOUT, activity_topic
from fourbar_ros.node.qos import qos
from fourbar_ros.rules.command_fate import Readiness, readiness
from fourbar_ros.rules.manager_errors import ManagerErrors, manager_logger
from fourbar_ros.runtime.problem_log import ProblemLog

#: Steady-clock period (s) of the check for a manager that has gone (its activity publisher unmatched).
GONE_CHECK_S = 0.2
_qos_profile: Callable[..., QoSProfile] = QoSProfile  # rclpy's constructor is unannotated
#: The manager's activity QoS (controller_manager: depth 1, reliable, transient local): a late joiner gets the
#: latest state.
ACTIVITY_QOS = _qos_profile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                            durability=DurabilityPolicy.TRANSIENT_LOCAL)


def activity_type() -> tuple[Any, str]:
    """(controller_manager_msgs' ControllerManagerActivity, '') or (None, why it cannot be imported)."""
    try:
        from controller_manager_msgs.msg import (  # type: ignore[import-not-found,unused-ignore]
            ControllerManagerActivity,
        )
    except Exception as exc:  # ImportError, or a message library that does not load
        return None, f'controller_manager_msgs cannot be imported ({type(exc).__name__}: {one_line(exc)})'
    return ControllerManagerActivity, ''


class ControllerWatch:
    """Follows controller ``controller`` of manager ``manager`` (a node name, relative to the node's namespace);
    ``on_change`` gets each new readiness. ``readiness`` stays NOT_FOLLOWED until a manager is heard from, or for
    good where ``manager`` is empty or controller_manager_msgs is missing (``why_not_followed`` says which)."""

    def __init__(self, node: Node, manager: str, controller: str, problems: ProblemLog,
                 on_change: Callable[[Readiness], None]) -> None:
        self.controller = controller
        self.readiness = Readiness.NOT_FOLLOWED
        self._on_change = on_change
        self._seen = False
        msg_type, why = activity_type() if manager else (None, 'the controller_manager parameter is empty')
        self.why_not_followed = why
        self.topic = ''
        self.errors: ManagerErrors | None = None
        if self.why_not_followed:
            return
        self._node, self._gids = node, frozenset[bytes]()

        def subscribe() -> Any:
            topic = activity_topic(manager)  # kept deeper than the manager's (ACTIVITY_DEPTH says why)
            return node.create_subscription(msg_type, topic.name,
                                            problems.guard.wrap('sub_controller_activity', self._on_activity),
                                            qos(topic))
        self._subscribe = subscribe
        self._sub = subscribe()
        self.topic = self._sub.topic_name
        self.errors = ManagerErrors(manager_logger(self.topic.removesuffix('/activity')), controller)
        node.create_subscription(Log, ROSOUT.name, problems.guard.wrap('sub_rosout', self._on_log), qos(ROSOUT))
        node.create_timer(GONE_CHECK_S, problems.guard.wrap('controller_manager_check', self._check_manager),
                          clock=Clock(clock_type=ClockType.STEADY_TIME))

    def _set(self, new: Readiness) -> None:
        if new is not self.readiness:
            self.readiness = new
            if self.errors is not None:
                self.errors.active(new in (Readiness.ACTIVE, Readiness.HARDWARE_INACTIVE), time.monotonic_ns())
            self._on_change(new)

    def _on_log(self, msg: Log) -> None:
        assert self.errors is not None
        self.errors.line(msg.name, msg.level, msg.msg, time.monotonic_ns())

    def deactivation(self) -> str:
        """While the controller is not active: what its manager logged as the reason it deactivated it ('' for
        nothing: switched off on request, or not followed)."""
        return self.errors.reason() if self.errors is not None else ''

    def _on_activity(self, msg: Any) -> None:
        self._seen = True
        self._set(readiness(((c.name, c.state.label) for c in msg.controllers),
                            ((h.name, h.state.label) for h in msg.hardware_components), self.controller))

    def check(self) -> None:
        """Look at the graph now, as the periodic check does: after a silence of the measurements, a respawned
        manager is told apart before its measurements resume a command its predecessor was running."""
        if self.topic:
            self._check_manager()

    def _check_manager(self) -> None:
        """A manager whose activity publisher left the graph is gone; one that appears beside it is its successor
        (a manager killed stays in the graph until its lease ends): gone too, and subscribing afresh takes the
        successor's latest activity, which may have come before the old one left."""
        gids = frozenset(bytes(i.endpoint_gid) for i in self._node.get_publishers_info_by_topic(self.topic))
        if self._gids and gids - self._gids:
            self._set(Readiness.GONE)
            self._node.destroy_subscription(self._sub)
            self._sub = self._subscribe()
        elif self._seen and not gids:
            self._set(Readiness.GONE)
        self._gids = gids
