"""What the actuator modes make of their inputs, written once (the node per message, ``fourbar process`` per
recorded message). No ROS: messages are read through the attributes they share with rosbags' classes.

- An antenna trajectory (a ``trajectory_msgs/JointTrajectory`` of the one joint ``ANTENNA_JOINT``: positions theta
  rad, optional velocities and accelerations) becomes the driven joint's trajectory (``serve_antenna_trajectory``):
  refused when it would end in the past or still moving (unless the controller allows a moving end), validated
  (``motion.trajectory``), converted by the chain rule, refined until the controller's interpolation stays within
  ``trajectory_tolerance`` of the requested path (``motion.refine``), and checked against every limit, rejected or
  retimed by ``limit_policy`` (``motion.limits``). Whatever is wrong gives one line and a ``TrajectoryProblem``.
- A plain angle command (rad, after the node's accept/clamp/reject policy) becomes a jerk-limited plan from the
  current driven-joint state (``plan_command``), sampled as trajectory points 1/control_rate apart (trajectory
  mode, ``planned_points``) or as setpoints at control_rate (forward mode, ``planned_setpoints``), every point or
  setpoint checked against the limits before it is returned. Forward mode streams an antenna trajectory's
  driven-joint spline the same way (``trajectory_setpoints``).
- Every trajectory goes out as ``point_fields`` (no effort unless ``effort_feedforward``) and only after the
  controller's contract (``rules.controller_contract``) accepts it (``outgoing_refusal``).
- ``Motion`` is what the drive is following (a plan or a sent trajectory from its start time). A new command plans
  on from the motion's state while the measured driven joint is within ``replan_tolerance`` of it, else from the
  measured state (``replan_start``): the drive is never sent a step larger than that tolerance.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import NamedTuple

import numpy as np

from fourbar_ros.config.antenna_config import AntennaConfig, ConfigError
from fourbar_ros.config.controllers import (
    ForwardControllerSettings,
    TrajectoryControllerSettings,
    forward_controller,
    trajectory_controller,
)
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
    sample_grid,
    setpoints,
    trajectory_points,
)
from fourbar_ros.motion.refine import refine
from fourbar_ros.motion.splines import evaluate, hermite_coefficients
from fourbar_ros.motion.trajectory import DrivenTrajectory, SplineKind, antenna_trajectory, to_driven
from fourbar_ros.rules.controller_contract import ContractRule, PointLike, Refusal, check_trajectory, duration_ns

__all__ = ['ActuationCounters', 'Converted', 'DurationFields', 'EndMovingError', 'EndsInPastError', 'Motion',
           'PointFields', 'PointLike', 'TrajectoryProblem', 'actuation_contract', 'antenna_arrays', 'convert',
           'duration_parts', 'outgoing_refusal', 'plan_command', 'planned_points', 'planned_setpoints',
           'point_fields', 'problem_of', 'replan_start', 'serve_antenna_trajectory', 'trajectory_setpoints']


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
    INVALID = 'invalid'  #: anything else: mismatched arrays, accelerations without velocities, ...


class EndMovingError(TrajectoryError):
    """An antenna trajectory whose last point still moves, for a controller that refuses a moving end."""


class EndsInPastError(TrajectoryError):
    """A stamped antenna trajectory whose last point's time has passed when it arrives."""


_PROBLEMS: tuple[tuple[type[FourBarError], TrajectoryProblem], ...] = (
    (EmptyTrajectoryError, TrajectoryProblem.EMPTY), (TooManyPointsError, TrajectoryProblem.TOO_MANY_POINTS),
    (WrongJointError, TrajectoryProblem.WRONG_JOINT), (NotFiniteError, TrajectoryProblem.NOT_FINITE),
    (TimeNotIncreasingError, TrajectoryProblem.TIME_NOT_INCREASING), (UnreachableError, TrajectoryProblem.OUT_OF_REACH),
    (LimitError, TrajectoryProblem.OVER_LIMITS), (EndMovingError, TrajectoryProblem.END_MOVING),
    (EndsInPastError, TrajectoryProblem.ENDS_IN_PAST))


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
    commands_replanned_from_measured: int = 0  # the measured joint was off the motion by more than replan_tolerance
    setpoints_published: int = 0
    rejected: dict[TrajectoryProblem, int] = field(default_factory=lambda: dict.fromkeys(TrajectoryProblem, 0))
    #: messages of this package's own making the controller's contract refused (never sent)
    refused: dict[ContractRule, int] = field(default_factory=lambda: dict.fromkeys(ContractRule, 0))

    def as_dict(self) -> dict[str, int]:
        """Counter name -> value, one ``trajectories_rejected_<problem>`` per problem and one
        ``contract_refused_<rule>`` per contract rule."""
        out = {k: v for k, v in asdict(self).items() if k not in ('rejected', 'refused')}
        out.update({f'trajectories_rejected_{p.value}': n for p, n in self.rejected.items()})
        out.update({f'contract_refused_{r.value}': n for r, n in self.refused.items()})
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


def serve_antenna_trajectory(cfg: AntennaConfig, allow_moving_end: bool, joint_names: Sequence[str],
                             points: Sequence[PointLike], stamp_ns: int, now_ns: int) -> Converted:
    """``convert``, after the two refusals a controller would make of the result whatever the conversion does:
    a stamped trajectory (``stamp_ns`` != 0) whose last point's time is before ``now_ns`` (EndsInPastError), and a
    last velocity that is not 0 while ``allow_moving_end`` is false (EndMovingError; the chain rule keeps a zero
    velocity zero). Stamps and times in ns on the receiver's clock."""
    if points:
        last = points[-1]
        if stamp_ns != 0 and stamp_ns + duration_ns(last.time_from_start) < now_ns:
            raise EndsInPastError(f'stamped to start at {stamp_ns * 1e-9:.9f} s, its last point is '
                                  f'{(now_ns - stamp_ns - duration_ns(last.time_from_start)) * 1e-9:.6g} s past')
        if not allow_moving_end and len(last.velocities) and last.velocities[0] != 0.0:
            raise EndMovingError(f'the last point moves (theta_dot = {float(last.velocities[0])!r} rad/s): the '
                                 'controller takes trajectories that end at rest '
                                 '(allow_nonzero_velocity_at_trajectory_end is false)')
    return convert(cfg, joint_names, points)


def duration_parts(t: float) -> tuple[int, int]:
    """(sec, nanosec) of a time t >= 0 s, nanosec rounded and in [0, 1e9)."""
    ns = round(t * 1e9)
    return ns // 1_000_000_000, ns % 1_000_000_000


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


def point_fields(traj: DrivenTrajectory, effort: bool) -> list[PointFields]:
    """The points of the JointTrajectory sent for a driven-joint trajectory (the node live, ``fourbar process`` for a
    bag): one joint; velocities and accelerations where given, else empty; the static torque as effort only when
    ``effort`` (the feed-forward), else no effort field."""
    vel, acc = traj.velocities, traj.accelerations
    efforts = traj.efforts.tolist()
    return [PointFields([p], [] if vel is None else [float(vel[i])], [] if acc is None else [float(acc[i])],
                        [efforts[i]] if effort else [], DurationFields(*duration_parts(t)))
            for i, (t, p) in enumerate(zip(traj.times.tolist(), traj.positions.tolist(), strict=True))]


def outgoing_refusal(contract: TrajectoryControllerSettings, joint: str, points: Sequence[PointFields], stamp_ns: int,
                     now_ns: int) -> Refusal | None:
    """What the trajectory controller would refuse of a trajectory this package sends (``joint``, ``points``,
    header stamp ``stamp_ns``), arriving at ``now_ns``: None for nothing. A refused one is not sent."""
    return check_trajectory(contract, [joint], points, stamp_ns, now_ns)


def actuation_contract(cfg: AntennaConfig, mode: str | None = None,
                       ) -> TrajectoryControllerSettings | ForwardControllerSettings:
    """The settings of the controller that ``mode`` (default: the configured one; trajectory or forward) sends to,
    from ``controllers_file``. Raises ConfigError (one line) when they cannot take what the node sends: the
    controller's joints not the one driven joint, or ``effort_feedforward`` without an effort command interface."""
    if (mode or cfg.mode) == 'trajectory':
        contract: TrajectoryControllerSettings | ForwardControllerSettings = trajectory_controller(
            cfg.controllers_file, cfg.trajectory_controller)
    else:
        contract = forward_controller(cfg.controllers_file, cfg.forward_controller)
    if list(contract.joints) != [cfg.driven_joint]:
        raise ConfigError(f'controllers_file: the controller {contract.name} has joints {list(contract.joints)}; the '
                          f'node drives the one joint {cfg.driven_joint!r}', ('controllers_file',))
    if (cfg.effort_feedforward and isinstance(contract, TrajectoryControllerSettings)
            and not contract.has_effort_command_interface):
        raise ConfigError(f'effort_feedforward: the controller {contract.name} has command_interfaces '
                          f'{list(contract.command_interfaces)}, and it refuses points with effort unless one is '
                          'effort: give it [position, effort]', ('effort_feedforward',))
    return contract


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
    """The plan's positions at control_rate, checked (``checked_setpoints``) before they are returned."""
    return checked_setpoints(cfg, setpoints(cfg, plan))


def trajectory_setpoints(cfg: AntennaConfig, traj: DrivenTrajectory) -> Setpoints:
    """Forward mode's stream of a driven-joint trajectory: the spline joint_trajectory_controller would interpolate
    through its points (``motion.splines``), sampled at control_rate from 0 to its last time included, checked
    (``checked_setpoints``) before it is returned."""
    hz = cfg.control_rate
    times = sample_grid(float(traj.times[-1]), 1.0 / hz)
    if times.size > cfg.max_trajectory_points:
        raise TooManyPointsError(f'{times.size} setpoints at {hz!r} Hz exceed max_trajectory_points = '
                                 f'{cfg.max_trajectory_points}')
    if len(traj) == 1:
        return checked_setpoints(cfg, Setpoints(times, np.full(times.size, float(traj.positions[0]))))
    c = hermite_coefficients(traj.times, traj.positions, traj.velocities, traj.accelerations)
    i = np.clip(np.searchsorted(traj.times, times, side='right') - 1, 0, len(traj) - 2)
    h = traj.times[i + 1] - traj.times[i]
    s = np.clip((times - traj.times[i]) / h, 0.0, 1.0)
    # What the spline bounds: linear segments their speed, cubic ones their acceleration too (it may step at a
    # point, where the jerk is unbounded), quintic ones the jerk as well.
    orders = {SplineKind.LINEAR: 1, SplineKind.CUBIC: 2, SplineKind.QUINTIC: 3}[traj.kind]
    return checked_setpoints(cfg, Setpoints(times, evaluate(c[i], s[:, None])[:, 0]), orders)


def checked_setpoints(cfg: AntennaConfig, out: Setpoints, orders: int = 3) -> Setpoints:
    """``out`` if each setpoint is within the driven joint's range over [theta_min, theta_max] and the stream's
    speed, acceleration and jerk (up to the derivative ``orders`` its source bounds), as its divided differences give
    them (k! f[t_i .. t_i+k] for order k), are within the motor's limits; else LimitError naming the worst. Samples of
    a motion within the limits pass: each divided difference is an average of the motion's own derivative between
    its samples."""
    lower, upper = np.sort(driven_angles(cfg, np.array([cfg.theta_min, cfg.theta_max])))
    p = out.positions
    outside = (p < lower) | (p > upper)
    if outside.any():
        i = int(np.argmax(outside))
        raise LimitError(f'setpoint {i} (t = {float(out.times[i]):.6g} s): position {float(p[i])!r} rad is outside '
                         f'the driven joint\'s range [{float(lower)!r}, {float(upper)!r}] rad')
    limits = JointLimits.from_config(cfg)
    t, diff, factorial = out.times, p, 1.0
    ulp = float(np.spacing(np.max(np.abs(p)))) if p.size else 0.0
    for order in range(1, orders + 1):
        if diff.size < 2:
            break
        diff = np.diff(diff) / (t[order:] - t[:-order])  # Newton's divided differences
        factorial *= order
        value = limits.ratio * factorial * np.abs(diff)
        # The positions' own rounding (half an ulp each) moves an order-k difference by up to 2^k ulp / h^k.
        rounding = limits.ratio * 2.0 ** order * ulp / float(np.min(np.diff(t))) ** order
        i = int(np.argmax(value))
        if value[i] > limits.motor(order) + rounding:
            name, unit = _SETPOINT_QUANTITIES[order]
            raise LimitError(f'setpoints {i} to {i + order}: motor {name} {float(value[i]):.6g} {unit} exceeds its '
                             f'limit {limits.motor(order):.6g} {unit}')
    return out


_SETPOINT_QUANTITIES = {1: ('speed', 'rad/s'), 2: ('acceleration', 'rad/s^2'), 3: ('jerk', 'rad/s^3')}


def replan_start(motion: Motion | None, measured: JointMotionState | None, now_ns: int, tolerance: float,
                 speed_limit: float = math.inf) -> tuple[JointMotionState | None, bool]:
    """Where a new command's motion starts, and whether the running motion was left for the measurement.

    The running motion's state at ``now_ns`` while the measured driven position is within ``tolerance`` rad of it
    (or nothing is measured yet); else the measured state (position rad, velocity rad/s within +-``speed_limit``,
    acceleration 0): a drive held by its controller, or lagging, is not sent a step. With no motion running: the
    measured state, else the end of the last motion; None before any of them exists. (A measured speed at or past
    the limit, as a saturated drive or encoder noise gives, is planned from the limit: a plan may not start over
    it.)"""
    if measured is not None and abs(measured.velocity) > speed_limit:
        measured = JointMotionState(measured.position, math.copysign(speed_limit, measured.velocity))
    if motion is not None and not motion.done(now_ns):
        state = motion.state_at(now_ns)
        if measured is None or abs(measured.position - state.position) <= tolerance:
            return state, False
        return measured, True
    if measured is not None:
        return measured, False
    return (None if motion is None else motion.state_at(now_ns)), False


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

