"""What the actuator modes make of their inputs, written once (the node per message, ``fourbar process`` per
recorded message). No ROS: messages are read through the attributes they share with rosbags' classes.

- An antenna trajectory (a ``trajectory_msgs/JointTrajectory`` of the one joint ``ANTENNA_JOINT``: positions theta
  rad, optional velocities and accelerations) becomes the driven joint's trajectory (``convert``): validated
  (``motion.trajectory``), converted by the chain rule, refined until the controller's interpolation stays within
  ``trajectory_tolerance`` of the requested path (``motion.refine``), and checked against every limit, rejected or
  retimed by ``limit_policy`` (``motion.limits``). Whatever is wrong gives one line and a ``TrajectoryProblem``.
- A plain angle command (rad, after the node's accept/clamp/reject policy) becomes a jerk-limited plan from the
  current driven-joint state (``plan_command``), sampled as trajectory points 1/control_rate apart (trajectory
  mode, ``planned_points``) or as setpoints at control_rate (forward mode, ``planned_setpoints``), every point or
  setpoint checked against the limits before it is returned.
- ``Motion`` is what the drive is following (a plan or a sent trajectory from its start time): a new command
  replans from its position, velocity and acceleration at the current time, so the motion has no jump.
"""

from __future__ import annotations

import enum
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Protocol

import numpy as np

from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.config.interface import ANTENNA_JOINT
from fourbar_ros.core.errors import FourBarError, UnreachableError
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
from fourbar_ros.motion.planner import (
    JointMotionState,
    Plan,
    Setpoints,
    driven_angles,
    plan_to_angle,
    setpoints,
    trajectory_points,
)
from fourbar_ros.motion.refine import refine
from fourbar_ros.motion.splines import evaluate, hermite_coefficients
from fourbar_ros.motion.trajectory import DrivenTrajectory, antenna_trajectory, to_driven

__all__ = ['ActuationCounters', 'Converted', 'Motion', 'PointLike', 'TrajectoryProblem', 'antenna_arrays', 'convert',
           'duration_parts', 'plan_command', 'planned_points', 'planned_setpoints', 'point_values', 'problem_of']


class DurationLike(Protocol):
    """``builtin_interfaces/Duration``."""

    @property
    def sec(self) -> int: ...
    @property
    def nanosec(self) -> int: ...


class PointLike(Protocol):
    """``trajectory_msgs/JointTrajectoryPoint``: what is read of it."""

    @property
    def positions(self) -> Sequence[float]: ...
    @property
    def velocities(self) -> Sequence[float]: ...
    @property
    def accelerations(self) -> Sequence[float]: ...
    @property
    def time_from_start(self) -> DurationLike: ...


class TrajectoryProblem(enum.Enum):
    """Why an antenna trajectory was refused; the value names its counter (``trajectories_rejected_<value>``)."""

    EMPTY = 'empty'
    TOO_MANY_POINTS = 'too_many_points'
    WRONG_JOINT = 'wrong_joint'
    NOT_FINITE = 'not_finite'
    TIME_NOT_INCREASING = 'time_not_increasing'
    OUT_OF_REACH = 'out_of_reach'
    OVER_LIMITS = 'over_limits'
    INVALID = 'invalid'  #: anything else: mismatched arrays, accelerations without velocities, ...


_PROBLEMS: tuple[tuple[type[FourBarError], TrajectoryProblem], ...] = (
    (EmptyTrajectoryError, TrajectoryProblem.EMPTY), (TooManyPointsError, TrajectoryProblem.TOO_MANY_POINTS),
    (WrongJointError, TrajectoryProblem.WRONG_JOINT), (NotFiniteError, TrajectoryProblem.NOT_FINITE),
    (TimeNotIncreasingError, TrajectoryProblem.TIME_NOT_INCREASING), (UnreachableError, TrajectoryProblem.OUT_OF_REACH),
    (LimitError, TrajectoryProblem.OVER_LIMITS))


def problem_of(exc: FourBarError) -> TrajectoryProblem:
    """The class of a refusal, from the error ``convert`` raised."""
    return next((p for kind, p in _PROBLEMS if isinstance(exc, kind)), TrajectoryProblem.INVALID)


@dataclass
class ActuationCounters:
    """What the actuator modes did, counted (diagnostics keys, and ``fourbar process``'s summary)."""

    trajectories_received: int = 0
    trajectories_sent: int = 0
    trajectories_retimed: int = 0
    trajectory_points_sent: int = 0
    trajectory_points_inserted: int = 0
    commands_planned: int = 0
    commands_not_planned: int = 0  # no start state yet, or the motion cannot stop within the range
    setpoints_published: int = 0
    rejected: dict[TrajectoryProblem, int] = field(default_factory=lambda: dict.fromkeys(TrajectoryProblem, 0))

    def as_dict(self) -> dict[str, int]:
        """Counter name -> value, one ``trajectories_rejected_<problem>`` per problem."""
        out = {k: v for k, v in asdict(self).items() if k != 'rejected'}
        out.update({f'trajectories_rejected_{p.value}': n for p, n in self.rejected.items()})
        return out


# --------------------------------------------------------------------------- antenna trajectories

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
    refinement, the largest deviation bound of its segments (rad), and whether it was retimed."""

    trajectory: DrivenTrajectory
    inserted: int
    bound: float
    retimed: bool


def convert(cfg: AntennaConfig, joint_names: Sequence[str], points: Sequence[PointLike]) -> Converted:
    """An antenna trajectory message's driven-joint trajectory (module docstring). Raises FourBarError (one line;
    ``problem_of`` classifies it) when it cannot be served as given: nothing is returned partially."""
    arrays = antenna_arrays(joint_names, points, ANTENNA_JOINT, cfg.max_trajectory_points)
    driven = to_driven(cfg, antenna_trajectory(cfg, *arrays))
    refined = refine(cfg, driven)
    policy: LimitPolicy = 'retime' if cfg.limit_policy == 'retime' else 'reject'
    out = enforce_limits(refined.trajectory, JointLimits.from_config(cfg), cfg, policy)
    return Converted(out, refined.inserted, refined.bound, out is not refined.trajectory)


def duration_parts(t: float) -> tuple[int, int]:
    """(sec, nanosec) of a time t >= 0 s, nanosec rounded and in [0, 1e9)."""
    ns = round(t * 1e9)
    return ns // 1_000_000_000, ns % 1_000_000_000


#: One JointTrajectoryPoint's fields: positions rad, velocities rad/s, accelerations rad/s^2, effort N m, and
#: time_from_start (sec, nanosec).
PointValues = tuple[list[float], list[float], list[float], list[float], tuple[int, int]]


def point_values(traj: DrivenTrajectory) -> list[PointValues]:
    """The points of the JointTrajectory sent for a driven-joint trajectory (the node live, ``fourbar process`` for a
    bag): one joint; velocities and accelerations where given, else empty; the static torque as effort."""
    vel, acc = traj.velocities, traj.accelerations
    return [([p], [] if vel is None else [float(vel[i])], [] if acc is None else [float(acc[i])], [e],
             duration_parts(t))
            for i, (t, p, e) in enumerate(zip(traj.times.tolist(), traj.positions.tolist(), traj.efforts.tolist(),
                                              strict=True))]


# --------------------------------------------------------------------------- plain commands

def plan_command(cfg: AntennaConfig, start: JointMotionState, theta: float) -> Plan:
    """The jerk-limited motion from ``start`` to the served angle theta (rad). Raises FourBarError (one line) when
    theta is outside [theta_min, theta_max] or the drive cannot stop within the range from ``start``."""
    return plan_to_angle(cfg, JointLimits.from_config(cfg), start, theta)


def planned_points(cfg: AntennaConfig, plan: Plan) -> DrivenTrajectory:
    """The plan as trajectory points 1/control_rate s apart (plus its phase boundaries), each checked against the
    limits (LimitError otherwise)."""
    return trajectory_points(cfg, JointLimits.from_config(cfg), plan, 1.0 / cfg.control_rate)


def planned_setpoints(cfg: AntennaConfig, plan: Plan) -> Setpoints:
    """The plan's positions at control_rate, checked before they are returned: each within the driven joint's range
    over [theta_min, theta_max], and no step between two setpoints faster than the motor's speed limit (LimitError
    naming the worst)."""
    out = setpoints(cfg, plan)
    lower, upper = np.sort(driven_angles(cfg, np.array([cfg.theta_min, cfg.theta_max])))
    p = out.positions
    outside = (p < lower) | (p > upper)
    if outside.any():
        i = int(np.argmax(outside))
        raise LimitError(f'setpoint {i} (t = {float(out.times[i]):.6g} s): position {float(p[i])!r} rad is outside '
                         f'the driven joint\'s range [{float(lower)!r}, {float(upper)!r}] rad')
    if p.size > 1:
        limits = JointLimits.from_config(cfg)
        speed = limits.ratio * np.abs(np.diff(p)) / np.diff(out.times)
        i = int(np.argmax(speed))
        if speed[i] > limits.motor_speed:
            raise LimitError(f'setpoints {i} and {i + 1}: motor speed {float(speed[i]):.6g} rad/s exceeds its limit '
                             f'{limits.motor_speed:.6g} rad/s')
    return out


class Motion:
    """What the drive is following from ``start_ns`` (integer ns, node clock: a float of seconds since 1970 would
    keep only ~0.2 us): a plan, or a sent trajectory whose times count from ``start_ns``. ``state_at`` gives its
    position, velocity and acceleration at a time: a replan starts there."""

    def __init__(self, start_ns: int, plan: Plan | None = None, trajectory: DrivenTrajectory | None = None) -> None:
        if (plan is None) == (trajectory is None):
            raise ValueError('a Motion follows a plan or a trajectory')
        self.start_ns = start_ns
        self.plan = plan
        self.trajectory = trajectory
        self.duration = plan.duration if plan is not None else float(trajectory.times[-1])  # type: ignore[union-attr]

    def elapsed(self, now_ns: int) -> float:
        """Seconds since the start at ``now_ns``."""
        return (now_ns - self.start_ns) * 1e-9

    def state_at(self, now_ns: int) -> JointMotionState:
        """The reference at ``now_ns``: before the start, the first state; after the end, the last position at
        rest (the controller holds it)."""
        t = self.elapsed(now_ns)
        if self.plan is not None:
            return self.plan.state_at(t)
        traj = self.trajectory
        assert traj is not None
        times = traj.times
        if t >= times[-1]:
            return JointMotionState(float(traj.positions[-1]))
        i = max(int(np.searchsorted(times, t, side='right')) - 1, 0)
        seg = slice(i, i + 2)
        vel = None if traj.velocities is None else traj.velocities[seg]
        acc = None if traj.accelerations is None else traj.accelerations[seg]
        c = hermite_coefficients(times[seg], traj.positions[seg], vel, acc)
        h = float(times[i + 1] - times[i])
        s = np.array([[min(max((t - float(times[i])) / h, 0.0), 1.0)]])
        p, v, a = (float(evaluate(c, s, k)[0, 0]) / h ** k for k in range(3))
        return JointMotionState(p, v, a)

    def done(self, now_ns: int) -> bool:
        """True from the end of the motion on."""
        return self.elapsed(now_ns) >= self.duration

