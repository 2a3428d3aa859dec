"""The executor a process spins, chosen by the user, and how it is spun (rclpy 7.1.6 wheels).

- ``events``: ``rclpy.experimental.EventsExecutor``. The middleware's new-data callbacks feed a queue in
  C++; a wake-up runs the ready callback and nothing else. The default.
- ``single``: ``rclpy.executors.SingleThreadedExecutor``. Every wake-up rebuilds, in Python, a wait set
  over every entity of its nodes (subscriptions, timers, parameter services, guard conditions).

Never call ``EventsExecutor.spin()``, or ``spin_once()`` without a timeout, with these wheels: an
unbounded wait is a deadline of ``steady_clock::time_point::max()``, which the wheel's condition variable
(built without ``pthread_cond_clockwait``) converts to the system clock; the sum overflows to a negative
time, ``pthread_cond_timedwait`` fails at once (EINVAL) without releasing the queue's mutex, and the wait
loop retries forever. One core stays busy, the middleware threads that enqueue new messages and rclpy's
signal thread block on that mutex: no callback runs and SIGINT/SIGTERM are never seen. Any finite timeout
(below about 7.4e9 s) waits correctly, so everything here spins in bounded slices.
"""

from __future__ import annotations

import inspect
import os
from collections.abc import Callable
from typing import Any

from rclpy.context import Context
from rclpy.executors import Executor, SingleThreadedExecutor
from rclpy.task import Future

#: The choices, the default first.
EXECUTORS = ('events', 'single')
DEFAULT_EXECUTOR = EXECUTORS[0]
#: Environment variable naming the executor when no command-line option does.
EXECUTOR_ENV = 'FOURBAR_EXECUTOR'
#: Longest single wait (s): how late a stop request or a ``done()`` condition may be noticed when idle.
SLICE_S = 0.1


class ExecutorChoiceError(ValueError):
    """An executor name that is not one of EXECUTORS."""


def executor_kind(name: str | None = None) -> str:
    """``name``, else $FOURBAR_EXECUTOR, else the default; one-line ExecutorChoiceError if unknown."""
    source = 'executor'
    if name is None:
        name, source = os.environ.get(EXECUTOR_ENV) or DEFAULT_EXECUTOR, EXECUTOR_ENV
    if name not in EXECUTORS:
        raise ExecutorChoiceError(f'{source}: unknown executor {name!r} (choose from {", ".join(EXECUTORS)})')
    return name


def create_executor(kind: str | None = None, context: Context | None = None) -> Executor:
    """A new executor of ``kind`` (see executor_kind) on ``context`` (default: rclpy's)."""
    kind = executor_kind(kind)
    if kind == 'events':
        from rclpy.experimental.events_executor import EventsExecutor

        return EventsExecutor(context=context)
    return SingleThreadedExecutor(context=context)


def is_events(executor: Executor) -> bool:
    """True for an EventsExecutor (a C++ class that only looks like an rclpy Executor)."""
    from rclpy.impl.implementation_singleton import rclpy_implementation

    return isinstance(executor, rclpy_implementation.EventsExecutor)


class Spinner:
    """Runs an executor's callbacks in bounded slices until told to stop.

    ``request_stop()`` may be called from a signal handler or a callback: an EventsExecutor slice then ends
    after the running callback (its queue is stopped), a SingleThreadedExecutor's after the current wait.
    """

    def __init__(self, executor: Executor, slice_s: float = SLICE_S) -> None:
        self.executor = executor
        self.slice_s = slice_s
        self.stopped = False
        self._events = is_events(executor)
        new_future: Callable[[], Future] = Future  # rclpy's Future is unannotated: typed names for its calls
        self._wake = new_future()
        self._wake_done: Callable[[], bool] = self._wake.done
        self._wake_set: Callable[[object], None] = self._wake.set_result

    def request_stop(self) -> None:
        """End the running slice (after the callback in progress) and every later one."""
        self.stopped = True
        if not self._wake_done():
            self._wake_set(None)  # its done-callback (added by the running slice) stops the events queue

    def spin_slice(self, timeout_s: float | None = None) -> None:
        """Run ready callbacks for at most ``timeout_s`` (default slice_s) seconds."""
        timeout = self.slice_s if timeout_s is None else timeout_s
        if self._events:
            # Many callbacks per call (spin_once returns after each); ends at the deadline or request_stop.
            self.executor.spin_until_future_complete(self._wake, timeout_sec=timeout)
        else:
            self.executor.spin_once(timeout_sec=timeout)

    def spin(self) -> None:
        """Until request_stop() or the context shuts down."""
        context_ok: Callable[[], bool] = self.executor.context.ok
        while not self.stopped and context_ok():
            self.spin_slice()


class MessageInfoCallback:
    """A subscription callback taking ``(msg, info)`` that both executors call correctly.

    rclpy picks the message-info form when the callback's signature binds two arguments; the
    SingleThreadedExecutor then calls ``callback(msg, info)``, but rclpy 7.1.6's EventsExecutor calls
    ``callback((msg, info))`` with one tuple (a two-parameter function then fails with a TypeError).
    """

    __signature__ = inspect.Signature([
        inspect.Parameter('msg', inspect.Parameter.POSITIONAL_ONLY),
        inspect.Parameter('info', inspect.Parameter.POSITIONAL_ONLY)])

    def __init__(self, callback: Callable[[Any, dict[str, Any]], None]) -> None:
        self.callback = callback

    def __call__(self, *args: Any) -> None:
        if len(args) == 1:  # EventsExecutor: one (msg, info) tuple
            args = args[0]
        msg, info = args
        self.callback(msg, info)
