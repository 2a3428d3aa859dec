"""Why the controller manager deactivated the controller an actuator mode feeds, from its log (no ROS).

The manager deactivates a controller whose update fails (a joint read outside its robot-model limits with
``enforce_command_limits``, a forward command of the wrong size) and says so only in its log, at ERROR, naming the
controller: the lines it writes to /rosout under its own logger are the reason the node gives. A deactivation the
operator asks for (``ros2 control switch_controllers``) is logged at INFO and is not one."""

from __future__ import annotations

import re
from collections import deque

from fourbar_ros.interface.stamps import seconds_to_ns

#: rcl_interfaces/msg/Log's ERROR level: lines at it or above (FATAL) count.
LOG_ERROR = 40
#: A manager error line counts for a deactivation seen this long (s, steady clock) after it, or any time after the
#: deactivation: the line and the manager's activity reach the node on two topics, in either order.
AROUND_S = 2.0
#: The manager error lines kept (about one controller; the latest).
KEPT = 8


def manager_logger(manager: str) -> str:
    """The logger name under which the node ``manager`` (fully qualified, e.g. ``/tilt/controller_manager``) logs:
    rclcpp's, its namespace and name joined by dots, no leading one (``tilt.controller_manager``)."""
    return manager.strip('/').replace('/', '.')


class ManagerErrors:
    """The controller manager's ERROR lines naming ``controller`` (its logger ``logger``), and the deactivations of
    the controller the node saw, by steady-clock ns: ``reason`` is what the manager said about the latest one."""

    def __init__(self, logger: str, controller: str) -> None:
        self.logger = logger
        self._name = re.compile(rf'(?<![\w/]){re.escape(controller)}(?![\w/])')
        self._lines: deque[tuple[int, str]] = deque(maxlen=KEPT)
        self._left_ns: int | None = None  # when the controller last left active (None: active, or never seen so)

    def line(self, logger: str, level: int, text: str, now_ns: int) -> bool:
        """Take one /rosout line (its logger name, level and text) received at ``now_ns``; whether it was kept."""
        if logger != self.logger or level < LOG_ERROR or not self._name.search(text):
            return False
        self._lines.append((now_ns, text))
        return True

    def active(self, active: bool, now_ns: int) -> None:
        """The controller is (no longer) active as of ``now_ns``."""
        if active:
            self._left_ns = None
        elif self._left_ns is None:
            self._left_ns = now_ns

    def reason(self) -> str:
        """While the controller is not active: the manager's error lines around its latest leaving active, in order
        ('' for none: it was switched off on request, or the manager's log does not reach the node)."""
        if self._left_ns is None:
            return ''
        since = self._left_ns - seconds_to_ns(AROUND_S)
        return '; '.join(text for at, text in self._lines if at >= since)
