"""A served command's motion (``plan_command``), sampled and checked against the limits, and ``Motion``.

Trajectory points or setpoints of the jerk-limited plan, forward mode's setpoints of a driven-joint trajectory, and
what the drive is following. Explained in docs/explanation/motion.md#planning-a-plain-angle-command."""

from __future__ import annotations

import numpy as np

from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.interface.stamps import ns_to_seconds
from fourbar_ros.motion.errors import LimitError, TooManyPointsError
from fourbar_ros.motion.limits import JointLimits, range_slack
from fourbar_ros.motion.planner import (
    JointMotionState,
    Plan,
    Setpoints,
    driven_angles,
    plan_to_angle,
    setpoints,
    stream_grid,
    trajectory_points,
)
from fourbar_ros.motion.splines import evaluate, hermite_coefficients
from fourbar_ros.motion.trajectory import DrivenTrajectory, SplineKind

#: Derivative order -> (the motor's quantity, its unit), for one-line refusals.
QUANTITIES = {1: ('speed', 'rad/s'), 2: ('acceleration', 'rad/s^2'), 3: ('jerk', 'rad/s^3')}


def driven_range(cfg: AntennaConfig) -> tuple[float, float]:
    """The driven joint's range (rad) over [theta_min, theta_max], lowest first."""
    lower, upper = np.sort(driven_angles(cfg, np.array([cfg.theta_min, cfg.theta_max])))
    return float(lower), float(upper)


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
    times = stream_grid(float(traj.times[-1]), 1.0 / hz)
    if times.size > cfg.max_trajectory_points:
        raise TooManyPointsError(f'{times.size} setpoints at {hz!r} Hz exceed max_trajectory_points = '
                                 f'{cfg.max_trajectory_points}')
    if len(traj) == 1:
        return checked_setpoints(cfg, Setpoints(times, np.full(times.size, float(traj.positions[0]))))
    c = hermite_coefficients(traj.times, traj.positions, traj.velocities, traj.accelerations)
    i = np.clip(np.searchsorted(traj.times, times, side='right') - 1, 0, len(traj) - 2)
    h = traj.times[i + 1] - traj.times[i]
    s = np.clip((times - traj.times[i]) / h, 0.0, 1.0)
    # At a point's time the point itself (the polynomial at s = 1 need not give it back to the bit).
    p = np.where(s == 1.0, traj.positions[i + 1], evaluate(c[i], s[:, None])[:, 0])
    # What the spline bounds: linear segments their speed, cubic ones their acceleration too (it may step at a
    # point, where the jerk is unbounded), quintic ones the jerk as well.
    orders = {SplineKind.LINEAR: 1, SplineKind.CUBIC: 2, SplineKind.QUINTIC: 3}[traj.kind]
    return checked_setpoints(cfg, Setpoints(times, p), orders)


def checked_setpoints(cfg: AntennaConfig, out: Setpoints, orders: int = 3) -> Setpoints:
    """``out`` if each setpoint is within the driven joint's range over [theta_min, theta_max] (rad) and the stream's
    speed, acceleration and jerk (up to the derivative ``orders`` its source bounds), as its divided differences give
    them (k! f[t_i .. t_i+k] for order k), are within the motor's limits; else LimitError naming the worst. Samples of
    a motion within the limits pass: each divided difference is an average of the motion's own derivative between
    its samples.

    A setpoint past an end by at most ``range_slack`` is at that end (a plan to the end sampled at its end, a spline
    evaluated at its end point, pass it by their rounding) and goes out as the end itself: forward_position_controller
    hands positions to the hardware as they are, so none goes past the range. That moves it by at most the slack,
    which the derivatives' rounding bound below then counts."""
    lower, upper = driven_range(cfg)
    slack = range_slack(lower, upper)
    p = out.positions
    outside = (p < lower - slack) | (p > upper + slack)
    if outside.any():
        i = int(np.argmax(outside))
        raise LimitError(f'setpoint {i} (t = {float(out.times[i]):.6g} s): position {float(p[i])!r} rad is outside '
                         f'the driven joint\'s range [{lower!r}, {upper!r}] rad')
    moved = 0.0  # the most a setpoint was moved onto an end (rad)
    if ((p < lower) | (p > upper)).any():
        p = np.clip(p, lower, upper)
        moved, out = slack, Setpoints(out.times, p)
    limits = JointLimits.from_config(cfg)
    t, diff, factorial = out.times, p, 1.0
    ulp = float(np.spacing(np.max(np.abs(p)))) if p.size else 0.0
    for order in range(1, orders + 1):
        if diff.size < 2:
            break
        diff = np.diff(diff) / (t[order:] - t[:-order])  # Newton's divided differences
        factorial *= order
        value = limits.ratio * factorial * np.abs(diff)
        # The positions' own rounding (half an ulp each) and a move onto an end (up to the slack each, where one
        # was made) move an order-k difference by up to 2^k (ulp + moved) / h^k.
        rounding = limits.ratio * 2.0 ** order * (ulp + moved) / float(np.min(np.diff(t))) ** order
        i = int(np.argmax(value))
        if value[i] > limits.motor(order) + rounding:
            name, unit = QUANTITIES[order]
            raise LimitError(f'setpoints {i} to {i + order}: motor {name} {float(value[i]):.6g} {unit} exceeds its '
                             f'limit {limits.motor(order):.6g} {unit}')
    return out


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
        return ns_to_seconds(now_ns - self.start_ns)

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

