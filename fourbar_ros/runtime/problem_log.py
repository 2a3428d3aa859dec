"""Logging by problem kind, and the callback boundary no exception crosses.

rclpy throttles a log call per call site (function, file, line): two different problems logged from one line share
one throttle, and the second goes unlogged. ``ProblemLog`` throttles per problem kind instead: the first message of
a kind is logged at once; later ones of the same kind at most once per period (steady clock), saying how many were
held back since. ``CallbackGuard`` wraps a node's callbacks: an exception is counted per callback, logged once per
(callback, exception type) through ``ProblemLog``, and swallowed, so the node stays up.
"""

from __future__ import annotations

import contextlib
import functools
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

    def wrap(self, name: str, callback: F) -> F:
        """``callback`` such that an Exception it raises is counted under ``name``, logged once per kind, and
        swallowed (the call returns None). The signature is kept (rclpy reads it to pass message info)."""
        @functools.wraps(callback)
        def guarded(*args: Any, **kwargs: Any) -> Any:
            try:
                return callback(*args, **kwargs)
            except Exception as exc:  # the boundary: nothing may stop the node
                self.errors[name] = self.errors.get(name, 0) + 1
                with contextlib.suppress(Exception):  # a failing logger must not carry it past the boundary
                    self._problems.error(f'callback {name} {type(exc).__name__}',
                                         f'callback {name} failed ({self.errors[name]} so far): '
                                         f'{type(exc).__name__}: {one_line(exc)}')
                return None
        return guarded  # type: ignore[return-value]

    @property
    def total(self) -> int:
        """Exceptions caught in every callback."""
        return sum(self.errors.values())

    def diagnostic_values(self) -> list[tuple[str, str]]:
        """``callback_errors`` and one ``callback_errors_<name>`` per callback that raised."""
        return [('callback_errors', str(self.total)),
                *((f'callback_errors_{name}', str(n)) for name, n in sorted(self.errors.items()))]
