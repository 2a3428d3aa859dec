"""Logging by problem kind, and the callback boundary no exception crosses.

``ProblemLog`` logs one line per kind per period (not rclpy's one per call site); ``CallbackGuard.wrap``, applied
where each callback is handed to rclpy, counts, logs once and swallows an exception. See docs/explanation/node.md."""

from __future__ import annotations

import contextlib
import functools
import inspect
import time
from collections.abc import Callable
from typing import Any, TypeVar

from fourbar_ros.core.errors import one_line

__all__ = ['CallbackGuard', 'ProblemLog']

F = TypeVar('F', bound=Callable[..., Any])

#: Most problem kinds remembered (memory stays bounded; the oldest is forgotten first).
MAX_KINDS = 256


class ProblemLog:
    """``warn(kind, message)`` / ``error(kind, message)``: one line per kind per ``period`` s (module docstring).
    ``log`` takes (level, line) and writes it (a node's logger)."""

    def __init__(self, log: Callable[[str, str], object], period: float = 1.0,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self._log = log
        self._period = period
        self._clock = clock
        self._kinds: dict[str, tuple[float, int]] = {}  # kind -> (time last logged, held back since)
        #: the callback boundary of the node this log belongs to (its exceptions are logged here)
        self.guard = CallbackGuard(self)

    def warn(self, kind: str, message: str) -> bool:
        """Log ``message`` as a warning unless ``kind`` was logged less than a period ago; True if logged."""
        return self._emit('warn', kind, message)

    def error(self, kind: str, message: str) -> bool:
        """As ``warn``, at error level."""
        return self._emit('error', kind, message)

    def _emit(self, level: str, kind: str, message: str) -> bool:
        now = self._clock()
        last = self._kinds.get(kind)
        if last is not None and now - last[0] < self._period:
            self._kinds[kind] = (last[0], last[1] + 1)
            return False
        held = 0 if last is None else last[1]
        if last is None and len(self._kinds) >= MAX_KINDS:
            del self._kinds[next(iter(self._kinds))]
        self._kinds[kind] = (now, 0)
        self._log(level, message if not held else f'{message} ({held} more of this kind held back)')
        return True


class CallbackGuard:
    """Counts and logs exceptions escaping the callbacks it wraps (``wrap``), per callback name."""

    def __init__(self, problems: ProblemLog) -> None:
        self._problems = problems
        self.errors: dict[str, int] = {}

    def wrap(self, name: str, callback: F, failed: Callable[[Exception], Any] | None = None) -> F:
        """``callback`` such that an Exception it raises is counted under ``name``, logged once per kind, and
        swallowed: the call returns ``failed(exc)`` (default None). The signature is kept (rclpy reads it to pass
        message info). The good path is one call and a try block: nothing allocated, nothing looked up."""
        def caught(exc: Exception) -> Any:
            self.errors[name] = self.errors.get(name, 0) + 1
            with contextlib.suppress(Exception):  # a failing logger must not carry it past the boundary
                self._problems.error(f'callback {name} {type(exc).__name__}', f'callback {name} failed '
                                     f'({self.errors[name]} so far): {type(exc).__name__}: {one_line(exc)}')
            return None if failed is None else failed(exc)

        if len(inspect.signature(callback).parameters) == 1:  # a subscription's: no argument tuple per call
            def guarded_one(msg: Any) -> Any:
                try:
                    return callback(msg)
                except Exception as exc:  # the boundary: nothing may stop the node
                    return caught(exc)
            return functools.wraps(callback)(guarded_one)  # type: ignore[return-value]

        def guarded(*args: Any) -> Any:
            try:
                return callback(*args)
            except Exception as exc:  # the boundary: nothing may stop the node
                return caught(exc)
        return functools.wraps(callback)(guarded)  # type: ignore[return-value]

    @property
    def total(self) -> int:
        """Exceptions caught in every callback."""
        return sum(self.errors.values())

    def diagnostic_values(self) -> list[tuple[str, str]]:
        """``callback_errors`` and one ``callback_errors_<name>`` per callback that raised."""
        return [('callback_errors', str(self.total)),
                *((f'callback_errors_{name}', str(n)) for name, n in sorted(self.errors.items()))]
