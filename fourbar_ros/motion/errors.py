"""One-line errors of the motion layer (``FourBarError`` subclasses, like the core's)."""

from __future__ import annotations

from fourbar_ros.core.errors import FourBarError


class TrajectoryError(FourBarError):
    """A trajectory that cannot be served as given: empty, too long, time not increasing, NaN, mismatched arrays."""


class LimitError(FourBarError):
    """A point over a motor or reducer limit that the policy cannot (or may not) fix; names the worst point."""
