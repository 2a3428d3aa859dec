"""The process's one stop (SIGINT/SIGTERM), shared by fourbar_node and every ``fourbar`` command.

The handler notes the signal and wakes what waits; ``raises`` chooses what follows: None (loops read
``STOP.requested``), ``KeyboardInterrupt`` (commands: raised, but never inside an executor's callback) or a quiet
``SystemExit(0)`` while the node starts. Why: docs/explanation/node.md.
"""

from __future__ import annotations

import contextlib
import signal
import sys
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from rclpy.executors import Executor

#: The signals every fourbar process treats as "stop".
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class Stop:
    """The process's SIGINT/SIGTERM handler (see the module docstring)."""

    def __init__(self) -> None:
        self.signal: int | None = None
        self.raises: Callable[[], BaseException] | None = None
        self._wakers: list[Callable[[], None]] = []
        self._in_callbacks = False
        self._pending = False
        self._raised: BaseException | None = None  # the last exception the handler raised, until it is seen
        self._next_unraisable_hook: Callable[[Any], object] | None = None

    def reset(self, raises: Callable[[], BaseException] | None = None) -> None:
        """Forget earlier signals and wakers; raise ``raises()`` on the next one (None: only note it)."""
        self.signal = None
        self.raises = raises
        self._wakers.clear()
        self._in_callbacks = self._pending = False

    def __call__(self, signum: int, frame: object) -> None:
        self.signal = signum
        for wake in self._wakers:
            wake()
        if self.raises is not None:
            if self._in_callbacks:
                self._pending = True
            else:
                self._raised = exc = self.raises()
                raise exc

    def _unraisable(self, unraisable: Any) -> None:
        """``sys.unraisablehook`` while installed: an exception the handler raised that Python swallowed (it landed
        in a weakref callback or ``__del__``, e.g. importlib's module-lock cleanup) is raised again at the end of
        the next ``deferred`` block (each spin), so the stop is not lost."""
        if self._raised is not None and unraisable.exc_value is self._raised:
            self._raised = None
            self._pending = True
        if self._next_unraisable_hook is not None:
            self._next_unraisable_hook(unraisable)

    @property
    def requested(self) -> bool:
        """True once a stop signal arrived."""
        return self.signal is not None

    def on_request(self, wake: Callable[[], None]) -> None:
        """Call ``wake()`` from the handler when a stop arrives (e.g. to end a running spin slice). It runs in the
        main thread between any two bytecodes, so it must not wait for a lock that thread may hold."""
        self._wakers.append(wake)

    def install(self, raises: Callable[[], BaseException] | None = None) -> None:
        """Handle SIGINT and SIGTERM in this process from now on (main thread only); see ``reset``."""
        self.reset(raises)
        for signum in STOP_SIGNALS:
            signal.signal(signum, self)
        if sys.unraisablehook != self._unraisable:
            self._next_unraisable_hook = sys.unraisablehook
            sys.unraisablehook = self._unraisable

    @contextlib.contextmanager
    def deferred(self) -> Iterator[None]:
        """A stop that comes inside the block is raised after it, not inside (an executor's callbacks; starting a
        child process, whose handle would be lost with the child running)."""
        self._in_callbacks = True
        try:
            yield
        finally:
            self._in_callbacks = False
        if self._pending and self.raises is not None:
            self._pending = False
            raise self.raises()

    def spin_once(self, executor: Executor, timeout_sec: float) -> None:
        """``executor.spin_once(timeout_sec)``; a signal that came during it is raised after it, not inside."""
        with self.deferred():
            executor.spin_once(timeout_sec=timeout_sec)


#: The one stop of this process.
STOP = Stop()


@contextlib.contextmanager
def stop_on_signals(raises: Callable[[], BaseException] | None = KeyboardInterrupt) -> Iterator[Stop]:
    """``STOP`` handles SIGINT and SIGTERM inside the block (raising ``raises()``, see the module docstring);
    the previous handlers come back after it. For the ``fourbar`` commands, which may run in-process.

    Nested inside another (``commands.main`` holds one around every command), a stop that already came is kept:
    it is raised at once (or, with ``raises=None``, seen by ``STOP.requested``). A KeyboardInterrupt raised from
    the handler can be lost (Python only prints it when it lands in a weakref callback or ``__del__``, e.g.
    importlib's module-lock cleanup while rclpy imports), so what the signal asked is not lost with it."""
    previous = {signum: signal.getsignal(signum) for signum in STOP_SIGNALS}
    nested = previous[signal.SIGINT] is STOP
    outer_raises, earlier = (STOP.raises, STOP.signal) if nested else (None, None)
    STOP.install(raises)
    try:
        if earlier is not None:
            STOP.signal = earlier
            if raises is not None:
                raise raises()
        yield STOP
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        if nested:
            STOP.raises = outer_raises
        else:
            STOP.reset()
