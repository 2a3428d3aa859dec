"""The executor a process spins, chosen by the user, and how it is spun (rclpy 7.1.6 wheels).

``events`` (``rclpy.experimental.EventsExecutor``, the default) or ``single`` (``SingleThreadedExecutor``), always
in bounded slices, with ``StallWatch`` restarting timers a backward step of the system clock stalled: both work
around the wheels' condition variable built without ``pthread_cond_clockwait``. Why: docs/explanation/node.md."""

from __future__ import annotations

import contextlib
import inspect
import os
import threading
from collections.abc import Callable, Iterator
from typing import Any

from rclpy.clock import ROSClock
from rclpy.clock_type import ClockType
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
#: How often (s, steady) ``StallWatch`` looks for stalled timers; also how overdue a call must be to count as stalled.
STALL_CHECK_S = 0.5


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

    ``request_stop()`` may be called from a signal handler, a callback or another thread: an EventsExecutor slice
    then ends after the running callback (its queue is stopped), a SingleThreadedExecutor's after the current wait.

    An EventsExecutor slice ends early only when its future completes, and completing the future takes the
    future's lock, which this thread holds for a moment in every slice (the executor adds and removes its
    done-callback under it). A signal handler runs in this thread, possibly right there, and would wait for
    itself forever; so a helper thread completes the future, and ``request_stop`` only releases that thread
    (a lock release, which never waits).
    """

    def __init__(self, executor: Executor, slice_s: float = SLICE_S) -> None:
        self.executor = executor
        self.slice_s = slice_s
        self.stopped = False
        self._events = is_events(executor)
        new_future: Callable[[], Future] = Future  # rclpy's Future is unannotated: typed names for its calls
        self._wake = new_future()
        self._requested = threading.Lock()  # held until request_stop()
        self._requested.acquire()
        self._waker: threading.Thread | None = None
        if self._events:
            self._waker = threading.Thread(target=self._complete_on_request, name='stop-waker', daemon=True)
            self._waker.start()

    def _complete_on_request(self) -> None:
        self._requested.acquire()
        complete: Callable[[object], None] = self._wake.set_result
        complete(None)  # its done-callback (added by the running slice) stops the events queue

    def request_stop(self) -> None:
        """End the running slice (after the callback in progress) and every later one. Never waits."""
        self.stopped = True
        with contextlib.suppress(RuntimeError):  # released by an earlier request
            self._requested.release()

    def close(self) -> None:
        """Stop, and wait for the helper thread to end (call when no slice runs any more)."""
        self.request_stop()
        if self._waker is not None:
            self._waker.join()

    def spin_slice(self, timeout_s: float | None = None) -> None:
        """Run ready callbacks for at most ``timeout_s`` (default slice_s) seconds."""
        timeout = self.slice_s if timeout_s is None else timeout_s
        if self._events:
            # Many callbacks per call (spin_once returns after each); ends at the deadline or request_stop.
            self.executor.spin_until_future_complete(self._wake, timeout_sec=timeout)
        else:
            self.executor.spin_once(timeout_sec=timeout)


class StallWatch:
    """Restarts the executor's waits that a backward step of the system clock stalled (see the module docstring).

    Every ``STALL_CHECK_S`` s of a steady wait (Python's own waits use the monotonic clock), a thread looks at the
    steady-clock timers of the executor's nodes. One whose call is overdue by more than ``STALL_CHECK_S`` is
    stalled, not merely late behind other callbacks (those take milliseconds): the SingleThreadedExecutor is woken (its
    next wait is computed anew), the EventsExecutor's timer is reset (its timer thread then computes its wait anew;
    the timer's next call is one period after the reset). A stall thus lasts one to two checks (plus a period on the
    EventsExecutor) instead of the step. ROS-clock timers are left alone: under sim time they follow /clock by design.
    """

    def __init__(self, executor: Executor, check_s: float = STALL_CHECK_S) -> None:
        self.executor = executor
        self.check_s = check_s
        self.restarts = 0  # timers found stalled
        self._events = is_events(executor)
        self._done = threading.Event()

    def check(self) -> int:
        """Restart the stalled timers' waits now; the number of stalled timers."""
        stalled = 0
        slack_ns = round(self.check_s * 1e9)
        for node in self.executor.get_nodes():
            for timer in list(node.timers):
                if timer.clock.clock_type != ClockType.STEADY_TIME:
                    continue
                until_next: Callable[[], int | None] = timer.time_until_next_call  # rclpy's are unannotated
                left = until_next()
                if left is None or -left <= slack_ns:
                    continue
                stalled += 1
                if self._events:
                    reset: Callable[[], None] = timer.reset
                    reset()
        if stalled and not self._events:
            self.executor.wake()
        self.restarts += stalled
        return stalled

    def _run(self) -> None:
        while not self._done.wait(self.check_s):
            with contextlib.suppress(Exception):  # a node or timer destroyed meanwhile: the next check sees it
                self.check()

    @contextlib.contextmanager
    def running(self) -> Iterator[StallWatch]:
        """Watch in a thread while the block runs (the thread has ended when it returns)."""
        thread = threading.Thread(target=self._run, name='stall-watch', daemon=True)
        thread.start()
        try:
            yield self
        finally:
            self._done.set()
            thread.join()


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


def arrival_ns(clock: Any, info: dict[str, Any]) -> int:
    """When a message reached this process (ns, ``clock``'s time): the middleware's reception time
    (``received_timestamp``, system clock), which a late callback of a busy executor does not move; ``clock``'s now
    under simulated time or where the middleware gives none."""
    received = int(info.get('received_timestamp') or 0)
    if received > 0 and not (isinstance(clock, ROSClock) and clock.ros_time_is_active):
        return received
    return int(clock.now().nanoseconds)
