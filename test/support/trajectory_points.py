"""Plain stand-ins for ``trajectory_msgs/JointTrajectoryPoint`` and ``builtin_interfaces/Duration``: the rules read
only these fields, so the pure tests build points without the ROS message packages."""

from __future__ import annotations

from dataclasses import dataclass, field

from fourbar_ros.interface.stamps import from_ns, seconds_to_ns


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


def antenna_points(times: list[float], theta: list[float], theta_dot: list[float] | None = None) -> list[Point]:
    """An antenna trajectory's points: theta rad at times s, with theta_dot rad/s when given."""
    return [Point([th], [] if theta_dot is None else [theta_dot[i]],
                  time_from_start=Duration(*from_ns(seconds_to_ns(t))))
            for i, (t, th) in enumerate(zip(times, theta, strict=True))]
