"""The spin loops: one bounded spin under the stop, and spinning until the stop or the context ends."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

from fourbar_ros.runtime.stop import STOP, Stop

if TYPE_CHECKING:
    from rclpy.executors import Executor

#: Longest time (s) the node's spin loop waits for work before it looks at the stop flag again.
STOP_POLL_S = 0.1


def spin_once(executor: Executor, timeout_sec: float) -> None:
    """One bounded spin under ``STOP`` (a signal during it is raised after it, if the stop raises)."""
    STOP.spin_once(executor, timeout_sec)


def spin_until_stopped(executor: Executor, stop: Stop = STOP, poll_s: float = STOP_POLL_S) -> None:
    """Run callbacks until ``stop`` is requested or the context ends.

    Spins in slices of at most ``poll_s`` s (an EventsExecutor must never wait without a deadline, see
    fourbar_ros.runtime.executor); a stop also ends the running slice, after the callback in progress. A
    ``StallWatch`` restarts the timers that a backward step of the system clock stalled.
    """
    from fourbar_ros.runtime.executor import Spinner, StallWatch

    spinner = Spinner(executor, poll_s)
    stop.on_request(spinner.request_stop)
    context_ok: Callable[[], bool] = executor.context.ok
    try:
        with StallWatch(executor).running():  # timers stalled by a step of the system clock
            while not stop.requested and context_ok():
                spinner.spin_slice()
    finally:
        spinner.close()
