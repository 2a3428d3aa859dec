"""Plain stand-ins for ``trajectory_msgs/JointTrajectoryPoint`` and ``builtin_interfaces/Duration``: the rules read
only these fields, so the pure tests build points without the ROS message packages."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class Duration:
    """``builtin_interfaces/Duration``: whole seconds and nanoseconds."""

    sec: int = 0
    nanosec: int = 0


@dataclass
class Point:
    """``trajectory_msgs/JointTrajectoryPoint`` (rad, rad/s, rad/s^2, N m; time from the trajectory's start)."""

    positions: list[float]
    velocities: list[float] = field(default_factory=list)
    accelerations: list[float] = field(default_factory=list)
    effort: list[float] = field(default_factory=list)
    time_from_start: Duration = field(default_factory=Duration)
