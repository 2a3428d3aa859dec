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
- ``Motion`` is what the drive is following: a plan (forward mode), or the reference joint_trajectory_controller
  follows for a sent trajectory (``rules.controller_motion``). A new motion starts where ``motion_start`` says: on
  the running motion, ``takeover_lead`` s ahead, while the measured driven joint is within ``replan_tolerance`` of
  it, else from the measured state (moved onto the driven joint's range when it lies outside by no more than
  ``measured_range_tolerance``). A trajectory continuing a running motion is stamped with the node's time of its
  first point, the running motion's state at that time: the controller, taking it over at its first update after
  arrival, continues the reference it was following (no lead-in from the measured state, no step) and reaches the
  new motion at the lead (``outgoing_stamp``: only a trajectory too short to arrive in time starts at the
  takeover). An antenna
  trajectory is joined to the measured drive's start by a connecting segment, checked against the limits like
  every other and, for a zero stamp under ``limit_policy: retime``, given the time it needs (``connect``).
"""

from __future__ import annotations

import enum
import math
from collections.abc import Sequence
from dataclasses import asdict, astuple, dataclass, field, replace
from typing import NamedTuple

import numpy as np

from fourbar_ros.config.antenna_config import AntennaConfig, ConfigError
from fourbar_ros.config.controllers import (
    ForwardControllerSettings,
    TrajectoryControllerSettings,
    forward_controller,
    trajectory_controller,
)
from fourbar_ros.core.antenna import Driven
from fourbar_ros.core.errors import FourBarError, UnreachableError
from fourbar_ros.core.numeric import FloatArray
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
from fourbar_ros.motion.planner import (
    PLAN_SHRINK,
    JointMotionState,
    Plan,
    Setpoints,
    driven_angles,
    plan_to_angle,
    rocker_states,
    sample_grid,
    setpoints,
    trajectory_points,
)
from fourbar_ros.motion.refine import refine
from fourbar_ros.motion.splines import evaluate, hermite_coefficients, segment_extremes
from fourbar_ros.motion.trajectory import (
    AntennaTrajectory,
    DrivenTrajectory,
    SplineKind,
    antenna_trajectory,
    on_wire,
    to_driven,
)
from fourbar_ros.rules.controller_contract import (
    FLOAT_EPSILON,
    ContractRule,
    PointLike,
    Refusal,
    check_trajectory,
    duration_ns,
)
from fourbar_ros.rules.controller_motion import ControllerPoint, motion_settings_problem, segment_coefficients

__all__ = ['ARRIVAL_MARGIN_S', 'MEASURED_AGE_MAX_S', 'TAKEOVER_SPACINGS', 'ActuationCounters', 'CannotReachError',
           'Converted', 'DurationFields', 'EndMovingError', 'EndsInPastError', 'Motion', 'PointFields', 'PointLike',
           'Start', 'TrajectoryProblem', 'actuation_contract', 'antenna_arrays', 'at_rest_end', 'carried', 'connect',
           'continued', 'convert', 'driven_range', 'duration_parts', 'ends_soon', 'motion_start', 'outgoing_refusal',
           'outgoing_stamp', 'plan_command', 'planned_points', 'planned_setpoints', 'point_fields', 'problem_of',
           'serve_antenna_trajectory', 'takeover_lead', 'trajectory_setpoints']


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
    measured_start_clamped: int = 0  # a start measured outside the range by at most measured_range_tolerance
    trajectories_connected: int = 0  # antenna trajectories given a connecting segment from the drive's state
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
    refinement, the largest deviation bound of its segments (rad), whether it was retimed, and the stamp (ns) it
    goes out with (0: start on arrival)."""

    trajectory: DrivenTrajectory
    inserted: int
    bound: float
    retimed: bool
    stamp_ns: int = 0


def convert(cfg: AntennaConfig, joint_names: Sequence[str], points: Sequence[PointLike],
            allow_moving_end: bool = True) -> Converted:
    """An antenna trajectory message's driven-joint trajectory (module docstring). Raises FourBarError (one line;
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


def serve_antenna_trajectory(cfg: AntennaConfig, allow_moving_end: bool, joint_names: Sequence[str],
                             points: Sequence[PointLike], stamp_ns: int, now_ns: int,
                             start: Start | None = None) -> Converted:
    """``convert``, after the refusal a controller would make of the result whatever the conversion does: a
    stamped trajectory (``stamp_ns`` != 0) whose last point's time is before ``now_ns`` plus ``ARRIVAL_MARGIN_S``
    (EndsInPastError: it could end before the controller takes it over); then, given the drive's ``start``
    (``motion_start`` at ``now_ns``), joined to it (``connect``). Without a start (nothing measured yet) it goes out
    as given, and the controller's own lead-in from the measured state is not checked. Stamps and times in ns on
    the receiver's clock."""
    if points:
        last = points[-1]
        end_ns = stamp_ns + duration_ns(last.time_from_start)
        if stamp_ns != 0 and end_ns < now_ns + round(ARRIVAL_MARGIN_S * 1e9):
            when = 'past' if end_ns < now_ns else 'ahead, before the controller can take it over'
            raise EndsInPastError(f'stamped to start at {stamp_ns * 1e-9:.9f} s, its last point is '
                                  f'{abs(now_ns - end_ns) * 1e-9:.6g} s {when}')
    converted = convert(cfg, joint_names, points, allow_moving_end)
    if start is None:
        return replace(converted, stamp_ns=stamp_ns)
    return connect(cfg, converted, start, stamp_ns, now_ns)


@dataclass(frozen=True)
class Start:
    """Where a new motion starts: the driven joint's ``state`` at ``at`` s after ``origin_ns`` (node clock), the
    time 0 of the trajectory sent. Continuing a running trajectory, ``before`` holds that trajectory's own points
    from the one at or before now up to the one at ``at`` (excluded), times from ``origin_ns`` (its stamp): sent
    first, they keep the controller on the very segments it follows until it takes the new trajectory over, and the
    new motion starts at that trajectory's point ``at``; ``now_state`` is the running motion's state now. Else
    ``origin_ns`` is now and ``at`` 0. ``from_measured``: a running motion was left for the measured state;
    ``clamped``: the measured state was moved onto an end of the range (``motion_start``)."""

    state: JointMotionState
    origin_ns: int
    at: float = 0.0
    before: DrivenTrajectory | None = None
    now_state: JointMotionState | None = None
    from_measured: bool = False
    clamped: bool = False

    def here(self, now_ns: int) -> Start:
        """The same start without the continuation: the running motion's state now."""
        if self.before is None or self.now_state is None:
            return self
        return Start(self.now_state, now_ns)


#: Trajectory mode: a continuing motion starts at the running trajectory's first point at least this many point
#: spacings (1/control_rate) after the node's now, so that the controller, taking the new trajectory over at its
#: first update after arrival, is still on the running trajectory's own segments.
TAKEOVER_SPACINGS = 2


#: The longest (s) a trajectory may take to reach the controller and be taken over: one stamped to end sooner after
#: the node's now could end before it arrives, and the controller would refuse it.
ARRIVAL_MARGIN_S = 0.1


def takeover_lead(cfg: AntennaConfig) -> float:
    """How far ahead (s) of the node's now a continuing motion starts at least, in trajectory mode."""
    return TAKEOVER_SPACINGS / cfg.control_rate


def driven_range(cfg: AntennaConfig) -> tuple[float, float]:
    """The driven joint's range (rad) over [theta_min, theta_max], lowest first."""
    lower, upper = np.sort(driven_angles(cfg, np.array([cfg.theta_min, cfg.theta_max])))
    return float(lower), float(upper)


#: The most (s) a measurement's stamp may lie before the node's now and still stand for when it was measured: an
#: older stamp (a stream that stopped, or a drive stamping from another clock) is taken as measured now. Three times
#: the latest arrival seen on a 2-core machine under twice its load (0.6 s).
MEASURED_AGE_MAX_S = 2.0


def motion_start(cfg: AntennaConfig, motion: Motion | None, measured: JointMotionState | None, now_ns: int,
                 lead: float, measured_ns: int | None = None) -> Start | None:
    """Where a new motion starts (``Start``): continuing a running quintic trajectory at its first point ``lead``
    s or more after ``now_ns`` (``lead`` > 0), else now.

    On the running motion while the measured driven position is within ``replan_tolerance`` of it at the time
    measured (``measured_ns``, node clock; None or over ``MEASURED_AGE_MAX_S`` before now or after it: now), or
    nothing is measured yet; else from the measured state (position rad, velocity within the planner's speed limit,
    acceleration 0) carried on to now at that velocity (``carried``): a drive held by its controller, or lagging, is
    not sent a step, and a measurement that arrives late is not taken for a drive off its motion. A measured position
    within ``measured_range_tolerance`` of an end of the range, outside it or moving outward, starts from that end
    at rest (an encoder rounds to whole counts, so a drive parked at an end may read half a count beyond it). With
    no motion running: the measured state, else the end of the last motion; None before any of them exists."""
    if measured is not None:
        speed = PLAN_SHRINK * cfg.motor_speed_limit / cfg.reducer_ratio
        if abs(measured.velocity) > speed:
            measured = JointMotionState(measured.position, math.copysign(speed, measured.velocity))
    at_ns = now_ns
    if measured_ns is not None and 0 <= now_ns - measured_ns <= round(MEASURED_AGE_MAX_S * 1e9):
        at_ns = measured_ns
    age = (now_ns - at_ns) * 1e-9
    if motion is not None and not motion.done(now_ns):
        now_state = motion.state_at(now_ns)
        if measured is None or abs(measured.position - motion.state_at(at_ns).position) <= cfg.replan_tolerance:
            traj = motion.trajectory
            if lead > 0.0 and traj is not None and traj.kind is SplineKind.QUINTIC:
                return _continuing(motion, traj, now_ns, lead, now_state)
            return Start(now_state, now_ns)
        return _from_measured(cfg, carried(cfg, measured, age), now_ns, left=True)
    if measured is not None:
        return _from_measured(cfg, carried(cfg, measured, age), now_ns, left=False)
    return None if motion is None else Start(motion.state_at(now_ns), now_ns)


def _continuing(motion: Motion, traj: DrivenTrajectory, now_ns: int, lead: float,
                now_state: JointMotionState) -> Start:
    t = motion.elapsed(now_ns)
    times = traj.times
    k0 = max(int(np.searchsorted(times, t, side='right')) - 1, 0)
    k1 = min(int(np.searchsorted(times, t + lead, side='left')), len(traj) - 1)
    assert traj.velocities is not None and traj.accelerations is not None
    state = JointMotionState(float(traj.positions[k1]), float(traj.velocities[k1]), float(traj.accelerations[k1]))
    return Start(state, motion.start_ns, float(times[k1]), _cut(traj, k0, k1), now_state)


def carried(cfg: AntennaConfig, measured: JointMotionState, age: float) -> JointMotionState:
    """The measured driven state ``age`` s after it was measured: its position moved on at its velocity, not past
    an end of the range it was within (the drive stops there); velocity as measured, acceleration 0."""
    if age == 0.0 or measured.velocity == 0.0:
        return measured
    q = measured.position + measured.velocity * age
    lower, upper = driven_range(cfg)
    if lower <= measured.position <= upper:
        q = min(max(q, lower), upper)
    return JointMotionState(q, measured.velocity)


def _from_measured(cfg: AntennaConfig, measured: JointMotionState, now_ns: int, left: bool) -> Start:
    lower, upper = driven_range(cfg)
    q, v, tol = measured.position, measured.velocity, cfg.measured_range_tolerance
    # Within the tolerance of an end (inside or out), a speed outward is the drive pressing on the end or settling
    # there, not a motion that could go on: it starts at the end, at rest.
    at_lower, at_upper = lower - tol <= q < lower + tol and v <= 0.0, upper - tol < q <= upper + tol and v >= 0.0
    if (at_lower or at_upper) and (not lower <= q <= upper or v != 0.0):
        clamped = JointMotionState(min(max(q, lower), upper), 0.0)
        return Start(clamped, now_ns, from_measured=left, clamped=True)
    return Start(measured, now_ns, from_measured=left)


def continued(start: Start, traj: DrivenTrajectory) -> DrivenTrajectory:
    """A trajectory ``traj`` that starts at ``start.state`` (its time 0), as the node sends it: times from
    ``start.origin_ns``, ``start.before`` first when it continues a running trajectory, ``traj`` from ``start.at``
    on (its first point is the running trajectory's point there, to the bit)."""
    if start.before is None:
        return traj
    return _joined(start.before, traj, start.at)


def _state_point(cfg: AntennaConfig, state: JointMotionState, like: DrivenTrajectory) -> DrivenTrajectory:
    """One point at time 0 holding ``state``, with the fields of ``like``."""
    q, v, a = (np.array([x]) for x in astuple(state))
    return rocker_states(cfg, np.array([0.0]), q, v, a, like.kind, like.antenna.theta_dot is not None)


def _joined(head: DrivenTrajectory, tail: DrivenTrajectory, shift: float) -> DrivenTrajectory:
    """``head``'s points, then ``tail``'s ``shift`` s later (times on the wire); fields as ``tail``'s kind."""
    def cat(a: FloatArray | None, b: FloatArray | None) -> FloatArray | None:
        return None if a is None or b is None else np.concatenate([a, b])

    times = on_wire(np.concatenate([head.times, tail.times + shift]))
    ha, ta = head.antenna, tail.antenna
    antenna = AntennaTrajectory(times, np.concatenate([ha.theta, ta.theta]), cat(ha.theta_dot, ta.theta_dot),
                                cat(ha.theta_ddot, ta.theta_ddot))
    return DrivenTrajectory(times, np.concatenate([head.positions, tail.positions]),
                            cat(head.velocities, tail.velocities), cat(head.accelerations, tail.accelerations),
                            np.concatenate([head.efforts, tail.efforts]), antenna)


def connect(cfg: AntennaConfig, converted: Converted, start: Start, stamp_ns: int, now_ns: int) -> Converted:
    """The converted antenna trajectory joined to the drive's ``start``: ``start``'s points (``continued``; only
    for a quintic trajectory, else it starts at the running motion's state now), a connecting segment to the first
    point still due after the start, then the rest; times from ``start.origin_ns``. A zero stamp puts the
    trajectory's time 0 at the start; a stamp puts it at the stamp. The connecting segment is the controller's
    polynomial of the trajectory's kind; when it is over a limit or leaves the range, a zero-stamped trajectory
    under ``limit_policy: retime`` is delayed by the least time that brings it within them, and anything else is
    refused (CannotReachError). Points already due at the start are dropped."""
    traj = converted.trajectory
    if traj.kind is not SplineKind.QUINTIC:
        start = start.here(now_ns)
    at = start.at
    offset = at if stamp_ns == 0 else (stamp_ns - start.origin_ns) * 1e-9  # the trajectory's time 0, from origin
    due = offset + traj.times < at
    keep = int(np.argmin(due)) if not due.all() else len(traj)
    if keep == len(traj):
        raise CannotReachError(f'every point is due before {at - (now_ns - start.origin_ns) * 1e-9:.6g} s from '
                               'now, when the drive can take the trajectory over')
    tail = _cut(traj, keep)
    gap = offset + float(tail.times[0]) - at
    # How far the drive is from the first point, counting a step's worth of its speed.
    step = abs(float(tail.positions[0]) - start.state.position) + abs(start.state.velocity) / cfg.control_rate
    shift = 0.0
    if gap <= 0.0 and step <= cfg.measured_range_tolerance and start.before is None:
        # The first point is where the drive rests, at the takeover: it stands for the start itself.
        joined = _joined(_cut(tail, len(tail)), tail, offset)
    else:
        head = _state_point(cfg, start.state, traj)
        limits = JointLimits.from_config(cfg)
        lower, upper = driven_range(cfg)
        problem = _connection_problem(head, tail, gap, limits, lower, upper)
        if problem is not None:
            if stamp_ns != 0 or cfg.limit_policy != 'retime':
                raise CannotReachError(f'from {float(start.state.position)!r} rad, the first point '
                                       f'{float(tail.positions[0])!r} rad in {gap:.6g} s: {problem}')
            shift = _least_gap(head, tail, gap, limits, lower, upper) - gap
        joined = continued(start, _joined(head, tail, offset - at + shift))
    if stamp_ns == 0 and start.before is not None and _ends_soon(joined, start, now_ns):
        return connect(cfg, converted, start.here(now_ns), stamp_ns, now_ns)
    return Converted(joined, converted.inserted, converted.bound, converted.retimed or shift > 0.0,
                     outgoing_stamp(cfg, start, joined, now_ns) if stamp_ns == 0 else start.origin_ns)


def outgoing_stamp(cfg: AntennaConfig, start: Start, traj: DrivenTrajectory, now_ns: int) -> int:
    """The stamp (ns) of a trajectory ``traj`` starting at ``start`` (times from ``start.origin_ns``): that origin,
    so that the controller, wherever it takes the trajectory over, is on it (continuing the segments it followed,
    or at the measured state the trajectory starts from) and the node's model of the motion is the controller's.
    One starting now that ends within ``ARRIVAL_MARGIN_S`` could end before it arrives (the controller would
    refuse it): it goes out with stamp 0, to start at the takeover, a short motion shifted by the arrival's delay.
    (A continuing one that would end that soon is planned from ``Start.here`` instead: ``ends_soon``.)"""
    if start.before is None and _ends_soon(traj, start, now_ns):
        return 0
    return start.origin_ns


def ends_soon(start: Start, duration: float, now_ns: int) -> bool:
    """Whether a motion of ``duration`` s from ``start`` would end within ``ARRIVAL_MARGIN_S`` of ``now_ns``."""
    return start.at + duration - (now_ns - start.origin_ns) * 1e-9 <= ARRIVAL_MARGIN_S


def _ends_soon(traj: DrivenTrajectory, start: Start, now_ns: int) -> bool:
    return float(traj.times[-1]) - (now_ns - start.origin_ns) * 1e-9 <= ARRIVAL_MARGIN_S


def _cut(traj: DrivenTrajectory, first: int, end: int | None = None) -> DrivenTrajectory:
    """Points ``first`` to ``end`` (excluded; None: the last included) of ``traj``."""
    if first == 0 and end is None:
        return traj
    keep = slice(first, end)
    a = traj.antenna

    def cut(x: FloatArray | None) -> FloatArray | None:
        return None if x is None else x[keep]

    antenna = AntennaTrajectory(a.times[keep], a.theta[keep], cut(a.theta_dot), cut(a.theta_ddot))
    return DrivenTrajectory(traj.times[keep], traj.positions[keep], cut(traj.velocities),
                            cut(traj.accelerations), traj.efforts[keep], antenna)


def _connection_problem(head: DrivenTrajectory, tail: DrivenTrajectory, gap: float, limits: JointLimits,
                        lower: float, upper: float) -> str | None:
    """What of the connecting segment (``gap`` s from head's one point to tail's first) is over a limit or out of
    the range, or None."""
    if not gap > 0.0:
        return 'no time to get there'
    a, b = (ControllerPoint(0.0, float(t.positions[i]), _at(t.velocities, i), _at(t.accelerations, i))
            for t, i in ((head, 0), (tail, 0)))
    b = ControllerPoint(gap, b.position, b.velocity, b.acceleration)
    c = segment_coefficients(gap, a, b)[None, :]
    times = np.array([0.0, gap])
    orders = (1,) if tail.kind is SplineKind.LINEAR else (1, 2, 3)
    for order in orders:
        value = float(segment_extremes(times, c, order)[0])
        if value > limits.at_rocker(order):
            name, unit = _SETPOINT_QUANTITIES[order]
            return (f'the motor {name} {limits.ratio * value:.6g} {unit} exceeds its limit '
                    f'{limits.motor(order):.6g} {unit}')
    p = evaluate(c, np.linspace(0.0, 1.0, 65)[None, :])
    if p.min() < lower or p.max() > upper:
        return f'it passes the driven joint through [{p.min()!r}, {p.max()!r}] rad, beyond [{lower!r}, {upper!r}] rad'
    return None


def _at(x: FloatArray | None, i: int) -> float | None:
    return None if x is None else float(x[i])


def _least_gap(head: DrivenTrajectory, tail: DrivenTrajectory, gap: float, limits: JointLimits, lower: float,
               upper: float) -> float:
    """The least connecting time (s, to 1e-6 relative, on the wire) at least ``gap`` within the limits."""
    bad, good = max(gap, 0.0), max(2.0 * gap, 1e-3)
    while _connection_problem(head, tail, good, limits, lower, upper) is not None:
        bad, good = good, 2.0 * good
        if good > 3600.0:
            raise CannotReachError(f'no connecting time up to 3600 s brings the motion from '
                                   f'{float(head.positions[0])!r} rad to {float(tail.positions[0])!r} rad within '
                                   'the limits and the range')
    while good - bad > 1e-6 * good:
        mid = 0.5 * (bad + good)
        if _connection_problem(head, tail, mid, limits, lower, upper) is None:
            good = mid
        else:
            bad = mid
    return float(on_wire(np.array([good]))[0]) + 1e-9


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


def actuation_contract(cfg: AntennaConfig, mode: str | None = None, namespace: str = '/',
                       ) -> TrajectoryControllerSettings | ForwardControllerSettings:
    """The settings of the controller that ``mode`` (default: the configured one; trajectory or forward) sends to,
    from ``controllers_file`` as the controller manager in ``namespace`` reads it. Raises ConfigError (one line)
    when they cannot take what the node sends: the controller's joints not the one driven joint,
    ``effort_feedforward`` without an effort command interface, or a setting that changes the motion in a way the
    node does not model (``rules.controller_motion.motion_settings_problem``)."""
    if (mode or cfg.mode) == 'trajectory':
        contract: TrajectoryControllerSettings | ForwardControllerSettings = trajectory_controller(
            cfg.controllers_file, cfg.trajectory_controller, namespace)
    else:
        contract = forward_controller(cfg.controllers_file, cfg.forward_controller, namespace)
    if isinstance(contract, TrajectoryControllerSettings):
        problem = motion_settings_problem(contract)
        if problem is not None:
            raise ConfigError(f'controllers_file: {problem}', ('controllers_file',))
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


class Motion:
    """What the drive is following from ``start_ns`` (integer ns, node clock: a float of seconds since 1970 would
    keep only ~0.2 us): a plan, or a sent trajectory whose times count from ``start_ns`` (its stamp; the
    controller's reference on its segments, ``rules.controller_motion``). ``state_at`` gives its position, velocity
    and acceleration at a time: a replan starts there."""

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
        if t >= times[-1] or len(traj) == 1:
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

