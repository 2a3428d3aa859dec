"""One-line errors of the motion layer (``FourBarError`` subclasses, like the core's)."""

from __future__ import annotations

from fourbar_ros.core.errors import FourBarError


class TrajectoryError(FourBarError):
    """A trajectory that cannot be served as given: empty, too long, time not increasing, NaN, mismatched arrays."""


class LimitError(FourBarError):
    """A point over a motor or reducer limit that the policy cannot (or may not) fix; names the worst point."""


class EmptyTrajectoryError(TrajectoryError):
    """A trajectory without points."""


class TooManyPointsError(TrajectoryError):
    """More points than ``max_trajectory_points`` (refused before anything is built: memory stays bounded)."""


class NotFiniteError(TrajectoryError):
    """A NaN or inf among a trajectory's values."""


class TimeNotIncreasingError(TrajectoryError):
    """Point times that are negative or do not strictly increase."""


class WrongJointError(TrajectoryError):
    """A trajectory for joints other than the one expected (a message's joint_names)."""
