"""Where a new motion of the driven joint starts, and the stamp a trajectory goes out with.

``motion_start``, ``continued``, ``connect`` and ``outgoing_stamp``. The rule and why:
docs/explanation/motion.md#what-the-controller-does-with-a-trajectory-and-how-the-node-starts-a-new-one."""

from __future__ import annotations

from dataclasses import astuple, dataclass
from typing import NamedTuple

import numpy as np

from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.core.numeric import FloatArray
from fourbar_ros.interface.stamps import ns_to_seconds, seconds_to_ns
from fourbar_ros.motion.limits import JointLimits, range_slack
from fourbar_ros.motion.planner import JointMotionState, rocker_states, stream_grid
from fourbar_ros.motion.splines import evaluate, segment_extremes
from fourbar_ros.motion.trajectory import AntennaTrajectory, DrivenTrajectory, SplineKind, on_wire
from fourbar_ros.rules.antenna_trajectory import CannotReachError, Converted
from fourbar_ros.rules.controller_motion import ControllerPoint, segment_coefficients
from fourbar_ros.rules.motion_plan import QUANTITIES, Motion, driven_range


@dataclass(frozen=True)
class Start:
    """Where a new motion starts: the driven joint's ``state`` at ``at`` s after ``origin_ns`` (node clock), the
    time 0 of the trajectory sent. Continuing a running trajectory, ``before`` holds its points from the one at or
    before now up to the one at ``at`` (excluded; all of them where it ends before ``at``, the drive resting at its
    end until then), times from ``origin_ns`` (its stamp), and ``now_state`` its state now; else ``origin_ns`` is
    now and ``at`` 0. ``from_measured``: the last motion sent was left for the measured state; ``clamped``: the
    measured state was moved onto an end of the range."""

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


#: The longest (s) a trajectory may take from the node's now to its takeover by the controller (planning, delivery,
#: the controller's next update): a start from the measured state lies this far ahead, and a continuing motion
#: departs from the running one no sooner. Planning takes 1-2 ms of CPU; delivery to a controller manager under
#: load took up to 170 ms (a 2-core machine under twice its load), hence 0.25 s.
ARRIVAL_MARGIN_S = 0.25


def rest_speed(cfg: AntennaConfig) -> float:
    """The fastest measured driven speed (rad/s) taken as at rest when a motion starts from the measured state: the
    controller's lead-in starts at the drive's own velocity, and a quintic from speed v to rest in time d peaks at
    a jerk of 36 v / d^2; taken over half ``ARRIVAL_MARGIN_S`` before the first point, a drive this slow keeps it
    within the jerk limit (8.7e-4 rad/s at the default limits, above the simulated drive's last braking step of
    2e-4 rad/s as it lands)."""
    return JointLimits.from_config(cfg).at_rocker(3) * (0.5 * ARRIVAL_MARGIN_S) ** 2 / 36.0


class Unsettled(NamedTuple):
    """No start can be vouched for: the drive is measured moving (``reason``) off every motion the node knows."""

    reason: str


def motion_start(cfg: AntennaConfig, motion: Motion | None, measured: JointMotionState | None, now_ns: int,
                 lead: float, measured_ns: int | None = None,
                 setpoint_ns: int | None = None) -> Start | Unsettled | None:
    """Where a new motion starts (``Start``), ``lead`` s after ``now_ns`` in trajectory mode (``lead`` > 0), at now
    in forward mode (``lead`` 0), from what is known of the drive: the last ``motion`` sent (after its end, at its
    end at rest) and the ``measured`` driven joint at ``measured_ns`` (node clock; None or after now: now); in
    forward mode ``setpoint_ns``, the time (node clock) the latest setpoint published stands for.

    - On the motion, where the measurement is within ``replan_tolerance`` of it at its stamp, predates its start,
      or there is none: continuing a running quintic trajectory at its first point ``lead`` s or more after now
      (where it ends sooner, at its end held until then); in forward mode a running stream at its setpoint after
      the latest published (``next_setpoint``); else at its state then.
    - Off it, or with no motion: from the measured position at rest, if the drive is measured at rest (within
      ``rest_speed``) or within ``measured_range_tolerance`` past an end of the range (then at that end);
      ``Unsettled`` if it is moving (no velocity is planned from that the node cannot vouch for).
    - None with neither a motion nor a measurement."""
    at_ns = now_ns if measured_ns is None else min(measured_ns, now_ns)
    # In trajectory mode a start from the measured state lies ARRIVAL_MARGIN_S ahead: the controller holds the drive
    # until then (its lead-in to a first point where the drive is), so the motion starts at its beginning, not
    # part-way in, whenever the trajectory arrives within the margin.
    origin_ns = now_ns + seconds_to_ns(ARRIVAL_MARGIN_S if lead > 0.0 else 0.0)
    if motion is not None and (measured is None or at_ns < motion.start_ns
                               or abs(measured.position - motion.state_at(at_ns).position) <= cfg.replan_tolerance):
        traj = motion.trajectory
        if lead > 0.0 and traj is not None and traj.kind is SplineKind.QUINTIC and not motion.done(now_ns):
            return _continuing(motion, traj, now_ns, lead, motion.state_at(now_ns))
        if lead == 0.0 and setpoint_ns is not None and not motion.done(now_ns):
            return next_setpoint(cfg, motion, setpoint_ns)
        # Not continued point for point (setpoints, a cubic or linear antenna trajectory, or a motion that has
        # ended): from its state where the new one starts, ahead like a start from the measured state, so that it
        # goes out stamped and the node's model of it is the controller's.
        return Start(motion.state_at(origin_ns), origin_ns)
    if measured is None:
        return None
    return _from_measured(cfg, measured, origin_ns, left=motion is not None)


def next_setpoint(cfg: AntennaConfig, motion: Motion, setpoint_ns: int) -> Start:
    """Forward mode, a stream running: from its setpoint after the latest one published (at ``setpoint_ns``; one of
    the stream before it: its first), on its sample grid. The control timer publishes the latest setpoint due at
    each tick, so the new stream's first setpoint goes out at the tick the running one's next would have: the
    controller's samples stay one period apart (a new stream from the state at the command's own time, off the grid,
    stepped by up to two periods' motion in one: 31x the acceleration limit at full speed)."""
    times = motion.start_ns + seconds_to_ns(stream_grid(motion.duration, 1.0 / cfg.control_rate))
    after = int(np.searchsorted(times, setpoint_ns, side='right'))
    at_ns = int(times[min(after, times.size - 1)])
    return Start(motion.state_at(at_ns), at_ns)


def _continuing(motion: Motion, traj: DrivenTrajectory, now_ns: int, lead: float,
                now_state: JointMotionState) -> Start:
    t = motion.elapsed(now_ns)
    times = traj.times
    k0 = max(int(np.searchsorted(times, t, side='right')) - 1, 0)
    k1 = int(np.searchsorted(times, t + lead, side='left'))
    assert traj.velocities is not None and traj.accelerations is not None
    if k1 == len(traj):
        depart = float(on_wire(np.array([t + lead]))[0])
        if depart > times[-1]:  # it ends before then: held at its end, at rest, until the departure
            return Start(JointMotionState(float(traj.positions[-1])), motion.start_ns, depart, _cut(traj, k0),
                         now_state)
        k1 -= 1
    state = JointMotionState(float(traj.positions[k1]), float(traj.velocities[k1]), float(traj.accelerations[k1]))
    return Start(state, motion.start_ns, float(times[k1]), _cut(traj, k0, k1), now_state)


def _from_measured(cfg: AntennaConfig, measured: JointMotionState, origin_ns: int, left: bool) -> Start | Unsettled:
    lower, upper = driven_range(cfg)
    q, v, tol = measured.position, measured.velocity, cfg.measured_range_tolerance
    if lower - tol <= q < lower or upper < q <= upper + tol:
        # Just past an end, whatever its speed, the drive presses on the end or settles there: at the end, at rest.
        return Start(JointMotionState(min(max(q, lower), upper)), origin_ns, from_measured=left, clamped=True)
    if abs(v) > rest_speed(cfg):
        return Unsettled(f'the drive is measured moving ({v:.3g} rad/s at {q!r} rad) off the motion sent: a motion '
                         'starts once it is measured at rest')
    return Start(JointMotionState(q), origin_ns, from_measured=left)


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
    """The converted antenna trajectory joined to the drive's ``start`` by a connecting segment to its first point
    still due (times from ``start.origin_ns``; a zero stamp puts its time 0 at the start), retimed or refused
    (CannotReachError) when that segment is over a limit, with the stamp it goes out with."""
    traj = converted.trajectory
    if traj.kind is not SplineKind.QUINTIC:
        start = start.here(now_ns)
    at = start.at
    offset = at if stamp_ns == 0 else ns_to_seconds(stamp_ns - start.origin_ns)  # the trajectory's time 0, from origin
    due = offset + traj.times < at
    keep = int(np.argmin(due)) if not due.all() else len(traj)
    if keep == len(traj):
        raise CannotReachError(f'every point is due before {at - ns_to_seconds(now_ns - start.origin_ns):.6g} s from '
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
    return Converted(joined, converted.inserted, converted.bound, converted.retimed or shift > 0.0,
                     outgoing_stamp(cfg, start, joined, now_ns) if stamp_ns == 0 else start.origin_ns)


def outgoing_stamp(cfg: AntennaConfig, start: Start, traj: DrivenTrajectory, now_ns: int) -> int:
    """The stamp (ns) of a trajectory ``traj`` starting at ``start`` (times from ``start.origin_ns``): that origin,
    or 0 (start on arrival) for a new one that ends within ``ARRIVAL_MARGIN_S`` of ``now_ns`` (stamped, the
    controller could find it ended on arrival, and refuse it). A start ahead of now (from the measured state) or a
    continuation departs the margin after now or later, so it is always stamped: the node's model of the motion
    is the controller's."""
    end = float(traj.times[-1]) - ns_to_seconds(now_ns - start.origin_ns)
    return 0 if start.before is None and end <= ARRIVAL_MARGIN_S else start.origin_ns


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
            name, unit = QUANTITIES[order]
            return (f'the motor {name} {limits.ratio * value:.6g} {unit} exceeds its limit '
                    f'{limits.motor(order):.6g} {unit}')
    p = evaluate(c, np.linspace(0.0, 1.0, 65)[None, :])
    slack = range_slack(lower, upper)  # a segment to a point at an end evaluates there to its rounding
    if p.min() < lower - slack or p.max() > upper + slack:
        return f'it passes the driven joint through [{p.min()!r}, {p.max()!r}] rad, beyond [{lower!r}, {upper!r}] rad'
    return None


def _at(x: FloatArray | None, i: int) -> float | None:
    return None if x is None else float(x[i])


def _least_gap(head: DrivenTrajectory, tail: DrivenTrajectory, gap: float, limits: JointLimits, lower: float,
               upper: float) -> float:
    """The least connecting time (s, to 1e-6 relative or the wire's 1 ns, on the wire) at least ``gap`` within the
    limits."""
    bad, good = max(gap, 0.0), max(2.0 * gap, 1e-3)
    while _connection_problem(head, tail, good, limits, lower, upper) is not None:
        bad, good = good, 2.0 * good
        if good > 3600.0:
            raise CannotReachError(f'no connecting time up to 3600 s brings the motion from '
                                   f'{float(head.positions[0])!r} rad to {float(tail.positions[0])!r} rad within '
                                   'the limits and the range')
    # The absolute floor ends the search where any time will do (a first point where the drive rests: the least
    # time is 0+, which no relative tolerance reaches).
    while good - bad > max(1e-6 * good, 1e-9):
        mid = 0.5 * (bad + good)
        if _connection_problem(head, tail, mid, limits, lower, upper) is None:
            good = mid
        else:
            bad = mid
    return float(on_wire(np.array([good]))[0]) + 1e-9

