"""An antenna trajectory message as the driven joint's trajectory (``convert``), or why it is refused.

Validated, converted by the chain rule, refined to ``trajectory_tolerance`` and held to the limits by
``limit_policy``; messages are read through the attributes rclpy's and rosbags' classes share. Explained in
docs/explanation/motion.md."""

from __future__ import annotations

import enum
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.core.antenna import Driven
from fourbar_ros.core.errors import FourBarError, UnreachableError
from fourbar_ros.interface.topics import ANTENNA_JOINT
from fourbar_ros.motion.errors import (
    EmptyTrajectoryError,
    LimitError,
    NotFiniteError,
    TimeNotIncreasingError,
    TooManyPointsError,
    TrajectoryError,
    WrongJointError,
)
from fourbar_ros.motion.limits import JointLimits, LimitPolicy, enforce_limits
from fourbar_ros.motion.refine import refine
from fourbar_ros.motion.trajectory import AntennaTrajectory, DrivenTrajectory, antenna_trajectory, to_driven
from fourbar_ros.rules.controller_contract import FLOAT_EPSILON, PointLike


class TrajectoryProblem(enum.Enum):
    """Why an antenna trajectory was refused; the value names its counter (``trajectories_rejected_<value>``)."""

    EMPTY = 'empty'
    TOO_MANY_POINTS = 'too_many_points'
    WRONG_JOINT = 'wrong_joint'
    NOT_FINITE = 'not_finite'
    TIME_NOT_INCREASING = 'time_not_increasing'
    OUT_OF_REACH = 'out_of_reach'
    OVER_LIMITS = 'over_limits'
    END_MOVING = 'end_moving'  #: the last point's velocity is not 0 (the controller would refuse it)
    ENDS_IN_PAST = 'ends_in_past'  #: stamped, and its last point's time is already past on arrival
    #: the drive cannot get from where it is to the first point by that point's time within the limits
    CANNOT_REACH_IN_TIME = 'cannot_reach_in_time'
    INVALID = 'invalid'  #: anything else: mismatched arrays, accelerations without velocities, ...


class EndMovingError(TrajectoryError):
    """An antenna trajectory whose last point still moves, for a controller that refuses a moving end."""


class EndsInPastError(TrajectoryError):
    """A stamped antenna trajectory whose last point's time has passed when it arrives."""


class CannotReachError(TrajectoryError):
    """The motion from the drive's start to an antenna trajectory's first point is over the limits in the time the
    trajectory leaves it."""


_PROBLEMS: tuple[tuple[type[FourBarError], TrajectoryProblem], ...] = (
    (EmptyTrajectoryError, TrajectoryProblem.EMPTY), (TooManyPointsError, TrajectoryProblem.TOO_MANY_POINTS),
    (WrongJointError, TrajectoryProblem.WRONG_JOINT), (NotFiniteError, TrajectoryProblem.NOT_FINITE),
    (TimeNotIncreasingError, TrajectoryProblem.TIME_NOT_INCREASING), (UnreachableError, TrajectoryProblem.OUT_OF_REACH),
    (LimitError, TrajectoryProblem.OVER_LIMITS), (EndMovingError, TrajectoryProblem.END_MOVING),
    (EndsInPastError, TrajectoryProblem.ENDS_IN_PAST), (CannotReachError, TrajectoryProblem.CANNOT_REACH_IN_TIME))


def problem_of(exc: FourBarError) -> TrajectoryProblem:
    """The class of a refusal, from the error ``convert`` raised."""
    return next((p for kind, p in _PROBLEMS if isinstance(exc, kind)), TrajectoryProblem.INVALID)



def antenna_arrays(joint_names: Sequence[str], points: Sequence[PointLike], joint: str, max_points: int,
                   ) -> tuple[list[float], list[float], list[float] | None, list[float] | None]:
    """(times s, theta rad, theta_dot rad/s or None, theta_ddot rad/s^2 or None) of a JointTrajectory for the one
    joint ``joint``. Raises (one line) EmptyTrajectoryError, TooManyPointsError (before reading any point),
    WrongJointError, or TrajectoryError for a point without one position or with velocities or accelerations on
    some points only. Values are not checked here (``antenna_trajectory`` does)."""
    n = len(points)
    if n == 0:
        raise EmptyTrajectoryError('empty trajectory: no points')
    if n > max_points:
        raise TooManyPointsError(f'{n} points exceed max_trajectory_points = {max_points}')
    names = list(joint_names)
    if names != [joint]:
        raise WrongJointError(f'joint_names {names!r}: an antenna trajectory has the one joint {joint!r}')
    sizes = {(len(p.positions), len(p.velocities), len(p.accelerations)) for p in points}
    if len(sizes) != 1 or not sizes <= {(1, 0, 0), (1, 1, 0), (1, 1, 1), (1, 0, 1)}:
        raise TrajectoryError(f'points carry {sorted(sizes)} (positions, velocities, accelerations) values: each '
                              'point needs one position, and velocities and accelerations on every point or none')
    times = [p.time_from_start.sec + 1e-9 * p.time_from_start.nanosec for p in points]
    (_, nv, na), = sizes
    theta = [p.positions[0] for p in points]
    theta_dot = [p.velocities[0] for p in points] if nv else None
    theta_ddot = [p.accelerations[0] for p in points] if na else None
    return times, theta, theta_dot, theta_ddot


@dataclass(frozen=True)
class Converted:
    """A converted antenna trajectory: the driven joint's (every point within the limits), the points inserted by
    refinement, the largest deviation bound of its segments (rad), whether it was retimed, and the stamp (ns) it
    goes out with (0: start on arrival)."""

    trajectory: DrivenTrajectory
    inserted: int
    bound: float
    retimed: bool
    stamp_ns: int = 0


def convert(cfg: AntennaConfig, joint_names: Sequence[str], points: Sequence[PointLike],
            allow_moving_end: bool = True) -> Converted:
    """An antenna trajectory message's driven-joint trajectory. Raises FourBarError (one line;
    ``problem_of`` classifies it) when it cannot be served as given: nothing is returned partially. Unless
    ``allow_moving_end``, the last velocity must be 0 as the controller judges it (``at_rest_end``)."""
    arrays = antenna_arrays(joint_names, points, ANTENNA_JOINT, cfg.max_trajectory_points)
    antenna = antenna_trajectory(cfg, *arrays)
    if not allow_moving_end:
        antenna = at_rest_end(cfg, antenna)
    driven = to_driven(cfg, antenna)
    refined = refine(cfg, driven)
    policy: LimitPolicy = 'retime' if cfg.limit_policy == 'retime' else 'reject'
    out = enforce_limits(refined.trajectory, JointLimits.from_config(cfg), cfg, policy)
    return Converted(out, refined.inserted, refined.bound, out is not refined.trajectory)


def at_rest_end(cfg: AntennaConfig, antenna: AntennaTrajectory) -> AntennaTrajectory:
    """``antenna`` with its last theta_dot set to exactly 0 when the driven joint's last velocity (q' theta_dot,
    rad/s) is within FLOAT_EPSILON, as the controller judges a trajectory's end at rest; EndMovingError beyond."""
    td = antenna.theta_dot
    if td is None or td[-1] == 0.0:
        return antenna
    theta = antenna.theta[-1:]
    gamma, delta = cfg.linkage.rocker_angles(theta, cfg.branch)
    rates = cfg.linkage.rates_at(theta, gamma, delta)
    q1 = float(np.asarray(rates.dgamma_dtheta if cfg.driven is Driven.GAMMA else rates.ddelta_dtheta)[0])
    velocity = q1 * float(td[-1])
    if abs(velocity) > FLOAT_EPSILON:
        raise EndMovingError(f'the last point moves (theta_dot = {float(td[-1])!r} rad/s, the driven joint '
                             f'{velocity!r} rad/s, above float epsilon {FLOAT_EPSILON:.3g}): the controller takes '
                             'trajectories that end at rest (allow_nonzero_velocity_at_trajectory_end is false)')
    rest = td.copy()
    rest[-1] = 0.0
    return replace(antenna, theta_dot=rest)

