"""What the actuator modes make of their inputs: one entry per input, what goes out or a refusal.

``serve_command`` (a served command) and ``serve_antenna_trajectory`` (an antenna trajectory message) return
``Outgoing`` (a trajectory, or setpoints in forward mode) or ``Refused``, counted in ``ActuationCounters``; the node
calls them per message, ``fourbar process`` per recorded message; ``serve_brake`` is the halt's stop. How:
docs/explanation/motion.md."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, replace
from typing import Any, NamedTuple

from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.config.controllers import ForwardControllerSettings, TrajectoryControllerSettings
from fourbar_ros.core.errors import FourBarError, one_line
from fourbar_ros.interface.joint_trajectory import PointFields
from fourbar_ros.interface.stamps import ns_to_seconds, seconds_to_ns, to_ns
from fourbar_ros.interface.topics import MEASURED_JOINT_STATES
from fourbar_ros.motion.limits import JointLimits, range_slack
from fourbar_ros.motion.planner import JointMotionState, Plan, Setpoints, plan_stop
from fourbar_ros.rules.antenna_trajectory import (
    CannotReachError,
    Converted,
    EndsInPastError,
    TrajectoryProblem,
    convert,
    problem_of,
)
from fourbar_ros.rules.controller_contract import ContractRule, PointLike
from fourbar_ros.rules.motion_plan import (
    Motion,
    driven_range,
    plan_command,
    planned_points,
    planned_setpoints,
    trajectory_setpoints,
)
from fourbar_ros.rules.outgoing import held_to_arrival, outgoing_refusal, point_fields
from fourbar_ros.rules.takeover import (
    ARRIVAL_MARGIN_S,
    Start,
    Unsettled,
    connect,
    continued,
    motion_start,
    next_setpoint,
    outgoing_stamp,
)

#: The settings of the controller the actuator mode sends to (``rules.outgoing.actuation_contract``).
Contract = TrajectoryControllerSettings | ForwardControllerSettings


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
    brakes_planned: int = 0  # the halt's stops planned from a running motion (``serve_brake``)
    brakes_from_measured: int = 0  # of them, from the measured state: the drive measured moving off the motion
    #: measurements stamped before the controller's latest readiness change or the measurements' latest stop
    measurements_outdated: int = 0
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


class Drive(NamedTuple):
    """What the receiver knows of the drive: the ``motion`` it follows, the ``measured`` driven joint at
    ``measured_ns`` (node clock), and in forward mode the time the latest setpoint published stands for
    (``setpoint_ns``, node clock; None before any)."""

    motion: Motion | None = None
    measured: JointMotionState | None = None
    measured_ns: int = 0
    setpoint_ns: int | None = None


class Outgoing(NamedTuple):
    """What goes out, and the ``motion`` the drive then follows: a trajectory (``points``, header stamp ``stamp_ns``,
    0: start on arrival) in trajectory mode, ``setpoints`` in forward mode."""

    motion: Motion
    points: Sequence[PointFields] = ()
    stamp_ns: int = 0
    setpoints: Setpoints | None = None


class Refused(NamedTuple):
    """Nothing goes out: the refusal's kind (one per problem or contract rule) and one line saying why; ``wait``
    (a served command only) says why it can go later, once the drive is measured at rest (``takeover.Unsettled``)."""

    key: str
    line: str
    wait: str = ''


def serve_command(cfg: AntennaConfig, contract: Contract, drive: Drive, theta: float, now_ns: int,
                  counters: ActuationCounters) -> Outgoing | Refused:
    """A served command to theta (rad, after the node's policy) at ``now_ns``: the plan from the drive's start
    (``motion_start``), as trajectory points or setpoints for ``contract``'s controller."""
    start = _start(cfg, contract, drive, now_ns, counters)
    if not isinstance(start, Start):
        counters.commands_not_planned += 1
        if start is None:
            return Refused('command no start', f'command theta = {theta!r} rad not planned: no measured '
                           f'{cfg.driven_joint} on {MEASURED_JOINT_STATES.name} yet')
        return Refused('command unsettled', f'command theta = {theta!r} rad not planned: {start.reason}',
                       start.reason)
    try:
        out = _outgoing(cfg, contract, start, plan_command(cfg, start.state, theta), now_ns, 'trajectory', counters)
    except FourBarError as exc:
        out = Refused(f'command {type(exc).__name__}', f'command theta = {theta!r} rad not planned: {one_line(exc)}')
    counters.commands_planned += isinstance(out, Outgoing)
    counters.commands_not_planned += isinstance(out, Refused)
    return out


def _outgoing(cfg: AntennaConfig, contract: Contract, start: Start, plan: Plan, now_ns: int, what: str,
              counters: ActuationCounters) -> Outgoing | Refused:
    """``plan`` from ``start`` as ``contract``'s controller takes it: setpoints, or trajectory points (``what``
    names them in a refusal) continuing the running trajectory, stamped."""
    if isinstance(contract, ForwardControllerSettings):
        return Outgoing(Motion(start.origin_ns, plan=plan), setpoints=planned_setpoints(cfg, plan))
    points = continued(start, planned_points(cfg, plan))
    return _sent(cfg, contract, Motion(start.origin_ns, trajectory=points), outgoing_stamp(cfg, start, points, now_ns),
                 now_ns, what, counters)


def serve_brake(cfg: AntennaConfig, contract: Contract, drive: Drive, now_ns: int,
                counters: ActuationCounters) -> Outgoing | Refused:
    """The halt's stop at ``now_ns``: the time-optimal brake to rest (``plan_stop``, wherever the limits bring the
    drive to rest) from where a command's motion would start (``motion_start``: the running trajectory's state at
    its takeover ``ARRIVAL_MARGIN_S`` ahead, its points up to there repeated; in forward mode the running stream's
    next setpoint, on its grid), as trajectory points or setpoints for ``contract``'s controller. Not a return to
    the measured angle: that would turn a moving drive back.

    In forward mode a running stream is braked on its grid wherever the drive is measured: the controller passes
    each setpoint on as it comes, so the brake continues what it commands, however far the drive lags (stopping
    the stream would step the command from full speed to rest). In trajectory mode, where the drive is measured
    moving off every motion the node knows (``Unsettled``), from the measured state instead
    (``_measured_brake_start``): the controller's lead-in starts from the drive's state, and a brake not sent would
    leave the drive running on to the old target; refused where that stop would leave the driven range (the running
    motion, which stays in it, goes on). Refused where no start can be vouched for: no motion and no measurement, or
    in forward mode a drive measured moving with no stream running (the controller holds its last setpoint)."""
    lead = ARRIVAL_MARGIN_S if isinstance(contract, TrajectoryControllerSettings) else 0.0
    motion, setpoint_ns = drive.motion, drive.setpoint_ns
    start: Start | Unsettled | None
    if lead == 0.0 and motion is not None and setpoint_ns is not None and not motion.done(now_ns):
        start = next_setpoint(cfg, motion, setpoint_ns)
    else:
        start = motion_start(cfg, motion, drive.measured, now_ns, lead, drive.measured_ns, setpoint_ns)
    if start is None:
        return Refused('brake no start', f'no brake planned: no measured {cfg.driven_joint} on '
                       f'{MEASURED_JOINT_STATES.name} yet')
    off_motion = isinstance(start, Unsettled)
    if isinstance(start, Unsettled):
        if lead == 0.0 or drive.measured is None:
            return Refused('brake unsettled', f'no brake planned: {start.reason}')
        start = _measured_brake_start(drive.measured, drive.measured_ns, now_ns)
    try:
        plan = plan_stop(start.state, JointLimits.from_config(cfg))
        if off_motion and (beyond := _beyond_range(cfg, plan)):
            return Refused('brake beyond the range', f'no brake planned: from the measured state {start.state} the '
                           f'stop within the limits {beyond}: the motion the controller runs goes on')
        out = _outgoing(cfg, contract, start, plan, now_ns, 'brake', counters)
    except FourBarError as exc:
        out = Refused(f'brake {type(exc).__name__}', f'no brake planned: {one_line(exc)}')
    counters.brakes_planned += isinstance(out, Outgoing)
    counters.brakes_from_measured += off_motion and isinstance(out, Outgoing)
    return out


def _beyond_range(cfg: AntennaConfig, plan: Plan) -> str:
    """How a stop ``plan`` leaves the driven range ('' where it stays within it, to its rounding)."""
    lower, upper = driven_range(cfg)
    lo, hi = plan.position_range()
    if lo < lower - range_slack(lower, upper) or hi > upper + range_slack(lower, upper):
        return f'passes the driven joint through [{lo!r}, {hi!r}] rad, beyond [{lower!r}, {upper!r}] rad'
    return ''


def _measured_brake_start(measured: JointMotionState, measured_ns: int, now_ns: int) -> Start:
    """The brake's start from a drive measured moving (position rad, velocity rad/s at ``measured_ns``, node clock;
    0 or after now: now): that state at acceleration 0, brought at its velocity to ``ARRIVAL_MARGIN_S`` after
    ``now_ns``, the trajectory's time 0 (as every start from the measured state: the controller's lead-in carries
    the drive from its state at the takeover to the first point)."""
    at_ns = min(measured_ns, now_ns) if measured_ns > 0 else now_ns
    origin_ns = now_ns + seconds_to_ns(ARRIVAL_MARGIN_S)
    q = measured.position + measured.velocity * ns_to_seconds(origin_ns - at_ns)
    return Start(JointMotionState(q, measured.velocity, 0.0), origin_ns, from_measured=True)


def serve_antenna_trajectory(cfg: AntennaConfig, contract: Contract, drive: Drive, msg: Any, now_ns: int,
                             counters: ActuationCounters) -> Outgoing | Refused:
    """An antenna trajectory ``msg`` (a ``trajectory_msgs/JointTrajectory``, rclpy's or rosbags') arriving at
    ``now_ns``: its driven-joint motion (``antenna_motion``, joined to the drive only where it is measured: a model
    of the motion alone is not where the drive is), sent as is or as setpoints for ``contract``'s controller."""
    stamp_ns = to_ns(msg.header.stamp)  # 0: start on arrival
    allow_moving_end = (isinstance(contract, TrajectoryControllerSettings)
                        and contract.allow_nonzero_velocity_at_trajectory_end)
    try:
        start = _start(cfg, contract, drive, now_ns, counters) if drive.measured is not None else None
        if isinstance(start, Unsettled):
            raise CannotReachError(start.reason)
        converted = antenna_motion(cfg, allow_moving_end, msg.joint_names, msg.points, stamp_ns, now_ns, start)
        if isinstance(contract, ForwardControllerSettings):  # streamed from the start's origin, not stamped
            motion = Motion(converted.stamp_ns or (start.origin_ns if start is not None else now_ns),
                            trajectory=converted.trajectory)
            out: Outgoing | Refused = Outgoing(motion, setpoints=trajectory_setpoints(cfg, converted.trajectory))
        else:
            motion = Motion(converted.stamp_ns or now_ns, trajectory=converted.trajectory)
            out = _sent(cfg, contract, motion, converted.stamp_ns, now_ns, 'antenna trajectory', counters)
    except FourBarError as exc:
        problem = problem_of(exc)
        counters.rejected[problem] += 1
        return Refused(f'antenna trajectory {problem.value}',
                       f'antenna trajectory refused ({problem.value}): {one_line(exc)}')
    if isinstance(out, Refused):
        return out
    counters.trajectory_points_inserted += converted.inserted
    counters.trajectories_retimed += converted.retimed
    counters.trajectories_connected += start is not None
    return out


def antenna_motion(cfg: AntennaConfig, allow_moving_end: bool, joint_names: Sequence[str],
                   points: Sequence[PointLike], stamp_ns: int, now_ns: int, start: Start | None = None) -> Converted:
    """An antenna trajectory's driven-joint motion (``convert``, joined to the drive's ``start`` if given: ``connect``),
    or FourBarError (one line; ``problem_of`` classifies it), EndsInPastError when stamped (``stamp_ns`` != 0) to end
    before ``now_ns`` plus ``ARRIVAL_MARGIN_S``. Stamps and times in ns on the receiver's clock."""
    if points:
        end_ns = stamp_ns + to_ns(points[-1].time_from_start)
        if stamp_ns != 0 and end_ns < now_ns + seconds_to_ns(ARRIVAL_MARGIN_S):
            when = 'past' if end_ns < now_ns else 'ahead, before the controller can take it over'
            raise EndsInPastError(f'stamped to start at {ns_to_seconds(stamp_ns):.9f} s, its last point is '
                                  f'{ns_to_seconds(abs(now_ns - end_ns)):.6g} s {when}')
    converted = convert(cfg, joint_names, points, allow_moving_end)
    if start is None:
        return replace(converted, stamp_ns=stamp_ns)
    return connect(cfg, converted, start, stamp_ns, now_ns)


def _start(cfg: AntennaConfig, contract: Contract, drive: Drive, now_ns: int,
           counters: ActuationCounters) -> Start | Unsettled | None:
    """``motion_start`` (in trajectory mode ``ARRIVAL_MARGIN_S`` ahead of now when it continues the running motion),
    counting a motion left for the measured state and a measured start moved onto the range."""
    lead = ARRIVAL_MARGIN_S if isinstance(contract, TrajectoryControllerSettings) else 0.0
    start = motion_start(cfg, drive.motion, drive.measured, now_ns, lead, drive.measured_ns, drive.setpoint_ns)
    if isinstance(start, Start):
        counters.commands_replanned_from_measured += start.from_measured
        counters.measured_start_clamped += start.clamped
    return start


def _sent(cfg: AntennaConfig, contract: TrajectoryControllerSettings, motion: Motion, stamp_ns: int, now_ns: int,
          what: str, counters: ActuationCounters) -> Outgoing | Refused:
    """``motion``'s trajectory stamped ``stamp_ns`` if the controller's contract takes it, counted; else the
    refusal naming ``what``, counted."""
    traj = motion.trajectory
    assert traj is not None
    points = held_to_arrival(point_fields(traj, cfg.effort_feedforward), stamp_ns, now_ns)
    refusal = outgoing_refusal(contract, cfg.driven_joint, points, stamp_ns, now_ns)
    if refusal is not None:
        counters.refused[refusal.rule] += 1
        return Refused(f'{what} refused {refusal.rule.value}', f'{what} not sent: the controller would refuse it '
                       f'({refusal.rule.value}): {refusal.reason}')
    counters.trajectories_sent += 1
    counters.trajectory_points_sent += len(points)
    return Outgoing(motion, points, stamp_ns)
