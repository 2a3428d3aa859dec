"""A one-joint ``trajectory_msgs/JointTrajectory``, built once for rclpy's and rosbags' message classes."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any, NamedTuple

from fourbar_ros.interface.stamps import from_ns

#: The ROS type names ``joint_trajectory`` reads from its ``types`` (a rosbags typestore's ``types`` holds them all).
TYPE_NAMES = ('trajectory_msgs/msg/JointTrajectory', 'trajectory_msgs/msg/JointTrajectoryPoint',
              'std_msgs/msg/Header', 'builtin_interfaces/msg/Time', 'builtin_interfaces/msg/Duration')


class DurationFields(NamedTuple):
    """A ``builtin_interfaces/Duration``'s fields."""

    sec: int
    nanosec: int


class PointFields(NamedTuple):
    """One JointTrajectoryPoint's fields: positions rad, velocities rad/s, accelerations rad/s^2, effort N m (each
    one value, or empty), time_from_start."""

    positions: list[float]
    velocities: list[float]
    accelerations: list[float]
    effort: list[float]
    time_from_start: DurationFields


def joint_trajectory(types: Mapping[str, Any], joint: str, points: Sequence[PointFields], stamp_ns: int,
                     floats: Callable[[list[float]], Any] = list) -> Any:
    """The JointTrajectory of ``points`` for ``joint``, header stamp ``stamp_ns`` (0: start on arrival), built of
    ``types`` (ROS type name -> message class, ``TYPE_NAMES``); ``floats`` makes a float64[] field's value."""
    trajectory, point, header, time, duration = (types[name] for name in TYPE_NAMES)
    sec, nanosec = from_ns(stamp_ns)
    return trajectory(header=header(stamp=time(sec=sec, nanosec=nanosec), frame_id=''), joint_names=[joint], points=[
        point(positions=floats(p.positions), velocities=floats(p.velocities), accelerations=floats(p.accelerations),
              effort=floats(p.effort), time_from_start=duration(sec=p.time_from_start.sec,
                                                                nanosec=p.time_from_start.nanosec))
        for p in points])
