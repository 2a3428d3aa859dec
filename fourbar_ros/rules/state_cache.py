"""Reuse the last solved state when the same angle is commanded again. No ROS.

Counters make the saving observable: ``computed`` counts real solves, ``reused`` the repeats.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Generic, TypeVar

S = TypeVar('S')


class StateCache(Generic[S]):
    """One-entry cache of ``solve(theta)`` keyed by the exact float theta (rad)."""

    def __init__(self, solve: Callable[[float], S]) -> None:
        self._solve = solve
        self._theta: float | None = None
        self._state: S | None = None
        self.computed = 0
        self.reused = 0

    def get(self, theta: float) -> S:
        """The state at theta; solved only if theta differs from the last one solved."""
        if self._state is not None and theta == self._theta:
            self.reused += 1
            return self._state
        state = self._solve(theta)
        self._theta, self._state = theta, state
        self.computed += 1
        return state

    def reset(self, solve: Callable[[float], S] | None = None) -> None:
        """Forget the cached state (after a configuration change), optionally with a new solver."""
        if solve is not None:
            self._solve = solve
        self._theta = None
        self._state = None
