"""What a user's motor implements for the drive bridge (``DriveBackend``), and an in-memory one for tests.

Every value is at the driven joint: position rad, velocity rad/s, effort N m. docs/how-to/drive-bridge.md.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Protocol, runtime_checkable

#: One reading: position rad, velocity rad/s or None, effort N m or None (all at the driven joint).
Reading = tuple[float, float | None, float | None]


@runtime_checkable
class DriveBackend(Protocol):
    """A motor as the bridge drives it; each call may raise (the bridge counts it and goes on)."""

    def enable(self) -> None:
        """Power the motor and make it ready for ``write``."""

    def read(self) -> Reading:
        """The measured (position rad, velocity rad/s or None, effort N m or None) at the joint."""

    def write(self, position: float) -> None:
        """Move towards ``position`` rad (a finite value in range, at most the bridge's step from the last read)."""

    def disable(self) -> None:
        """Stop and release the motor (called once, on the way out)."""


class SimulatedBackend:
    """A position drive in memory: moves towards its last target at ``speed_limit`` rad/s on ``clock`` (s).

    Faults for tests: ``nan_reads`` (read gives NaN), ``stuck`` (read repeats the last one), ``slip`` (rad added
    to every reading). ``writes`` records every target written; ``reports_velocity`` False reads velocity None.
    """

    def __init__(self, position: float, speed_limit: float, clock: Callable[[], float] = time.monotonic,
                 reports_velocity: bool = True) -> None:
        if not (math.isfinite(position) and math.isfinite(speed_limit) and speed_limit > 0.0):
            raise ValueError(f'position {position!r} and speed_limit {speed_limit!r} must be finite, the speed > 0')
        self.position = position
        self.target = position
        self.speed_limit = speed_limit
        self.reports_velocity = reports_velocity
        self.enabled = False
        self.nan_reads = False
        self.stuck = False
        self.slip = 0.0
        self.writes: list[float] = []
        self._clock = clock
        self._time = clock()
        self._velocity = 0.0
        self._last: Reading = (position, 0.0, 0.0)

    def _advance(self) -> None:
        now = self._clock()
        dt, self._time = max(now - self._time, 0.0), now
        step = max(-self.speed_limit * dt, min(self.speed_limit * dt, self.target - self.position))
        self.position += step
        self._velocity = step / dt if dt > 0.0 else 0.0

    def enable(self) -> None:
        """Ready to move."""
        self._advance()
        self.enabled = True

    def read(self) -> Reading:
        """The simulated measurement (with any fault injected)."""
        self._advance()
        if self.stuck:
            return self._last
        if self.nan_reads:
            return (math.nan, math.nan, None)
        self._last = (self.position + self.slip, self._velocity if self.reports_velocity else None, 0.0)
        return self._last

    def write(self, position: float) -> None:
        """A new target (rad); RuntimeError while disabled."""
        if not self.enabled:
            raise RuntimeError('the simulated drive is disabled')
        self._advance()
        self.writes.append(position)
        self.target = position

    def disable(self) -> None:
        """Stop where it is."""
        self._advance()
        self.target = self.position
        self.enabled = False
