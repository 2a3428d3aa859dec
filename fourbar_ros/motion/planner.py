"""Plain angle commands to motion the motor can follow: time-optimal, jerk-limited profiles of the driven joint.

``ruckig`` (imported on first use) plans from the current state to the target at rest; a plan starts at exactly
that state, so replanning from ``Plan.state_at(t)`` leaves no jump. docs/explanation/motion.md."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.core.antenna import Driven
from fourbar_ros.core.errors import UnreachableError
from fourbar_ros.core.numeric import FloatArray
from fourbar_ros.motion.errors import LimitError, TrajectoryError
from fourbar_ros.motion.limits import JointLimits, over_at_rocker, range_slack, segment_magnitudes, worst_violation
from fourbar_ros.motion.trajectory import AntennaTrajectory, DrivenTrajectory, SplineKind, on_wire, static_efforts

#: The shortest piece (s) a segment is split into at a phase boundary when its interpolation passes a limit: the
#: controller's quintic takes its jerk from positions over h^3, so a shorter one would turn the positions' rounding
#: (ulps of ~1 rad) into a sizeable share of the jerk margin (at 0.1 ms: 0.7% of the default rocker limit).
SWITCH_FLOOR = 1e-4

#: ruckig is given the limits times this: its own rounding (seen at ~1e-13 relative) and that of the controller's
#: jerk at a point (positions over h^3: ``min_segment``) then leave every sampled point within the limits
#: themselves; the motion is 1e-4 slower than time-optimal.
PLAN_SHRINK = 1.0 - 1e-4
#: The factors ruckig's speed, acceleration and jerk limits are given. The controller's quintic through the sampled
#: profile follows it exactly on a segment without a jerk change, but a segment holding a phase boundary (one left
#: out of the points, ``_point_times``) deviates from it between its points: its acceleration by up to 0.08% and
#: its jerk by up to 13% of the limit, seen in test_motion's replans from any state (segment_extremes). These
#: margins keep the interpolated motion itself within the limits; the speed needs none beyond PLAN_SHRINK.
PLAN_SHRINKS = (PLAN_SHRINK, 1.0 - 2e-3, 1.0 - 0.15)

__all__ = ['END_SPAN', 'PLAN_SHRINK', 'PLAN_SHRINKS', 'JointMotionState', 'Plan', 'Setpoints', 'driven_angles',
           'min_segment', 'plan_motion', 'plan_stop', 'plan_to_angle', 'rocker_states', 'sample_grid', 'setpoints',
           'stream_grid', 'trajectory_points']


@dataclass(frozen=True)
class JointMotionState:
    """Driven-joint state: position rad, velocity rad/s, acceleration rad/s^2."""

    position: float
    velocity: float = 0.0
    acceleration: float = 0.0


@dataclass(frozen=True)
class Setpoints:
    """A setpoint stream: times s from the plan's start (1/control_rate apart, the end included) and positions rad."""

    times: FloatArray
    positions: FloatArray


class Plan:
    """A planned motion of the driven joint (wraps a ruckig trajectory); times in s from the plan's start.
    ``extrema``: ruckig's ``position_extrema`` are taken too (not under its velocity interface, where their minimum
    reads 0.0: seen for a stop from 0.85 to 0.8625 rad)."""

    def __init__(self, trajectory: Any, extrema: bool = True) -> None:
        self._trajectory = trajectory
        self._extrema = extrema
        self.duration = float(trajectory.duration)

    def state_at(self, t: float) -> JointMotionState:
        """Position, velocity and acceleration at time t s (clamped to [0, duration]): where a replan starts."""
        p, v, a = self._trajectory.at_time(min(max(t, 0.0), self.duration))
        return JointMotionState(float(p[0]), float(v[0]), float(a[0]))

    def sample(self, times: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Positions, velocities, accelerations at the given times (s, within [0, duration])."""
        at = self._trajectory.at_time
        out = np.array([[x[0] for x in at(float(t))] for t in times]).reshape(-1, 3)
        return out[:, 0], out[:, 1], out[:, 2]

    def switch_times(self) -> FloatArray:
        """Times (s) where the profile's jerk changes (its phase boundaries, inside (0, duration)): sample points
        there and each segment between points lies on one cubic piece, which the controller's quintic reproduces."""
        profile = self._trajectory.profiles[0][0]
        phases = [*profile.brake.t, *profile.accel.t, *profile.t]
        t = np.cumsum(phases)
        return t[(t > 0.0) & (t < self.duration)]

    def position_range(self) -> tuple[float, float]:
        """Lowest and highest position (rad) over the whole motion, in closed form: at the phases' ends and where the
        velocity (v + a t + j t^2 / 2 on a phase of constant jerk j) is 0 inside one, each evaluated by ruckig.
        ruckig's own ``position_extrema`` (taken too) can miss an extremum inside a phase: from a start moving away
        from the target at the speed limit, one of 0.7196 rad for a motion that reaches 0.7131 rad."""
        profile = self._trajectory.profiles[0][0]
        times, start = [0.0, self.duration], 0.0
        for part in (profile.brake, profile.accel, profile):
            for h, v, a, j in zip(part.t, part.v, part.a, part.j, strict=False):
                times += [start + h, *(start + r for r in _velocity_roots(v, a, j) if 0.0 < r < h)]
                start += h
        q = self.sample(np.array([t for t in times if t <= self.duration]))[0]
        if not self._extrema:
            return float(np.min(q)), float(np.max(q))
        e = self._trajectory.position_extrema[0]
        return min(float(np.min(q)), float(e.min)), max(float(np.max(q)), float(e.max))


def _velocity_roots(v: float, a: float, j: float) -> list[float]:
    """The real roots t (s) of v + a t + j t^2 / 2 = 0 (rad/s, rad/s^2, rad/s^3), by the stable quadratic formula."""
    if j == 0.0:
        return [] if a == 0.0 else [-v / a]
    disc = a * a - 2.0 * j * v
    if disc < 0.0:
        return []
    q = -0.5 * (a + math.copysign(math.sqrt(disc), a))
    return [2.0 * q / j] + ([v / q] if q != 0.0 else [])


def _ruckig() -> Any:
    try:
        import ruckig  # type: ignore[import-not-found,unused-ignore]  # a compiled module without type stubs
    except ImportError:
        raise TrajectoryError('motion planning needs the Python module ruckig: pip install ruckig==0.19.4') from None
    return ruckig


def _solved(start: JointMotionState, limits: JointLimits, target: float | None) -> tuple[Any, str]:
    """ruckig's trajectory from ``start`` within ``limits`` (PLAN_SHRINKS of each) to rest: at ``target`` (rad), or
    wherever it comes to rest soonest (None: the velocity interface); and '', or what ruckig said where it found
    no profile (the trajectory then None)."""
    rk = _ruckig()
    inp = rk.InputParameter(1)
    if target is None:
        inp.control_interface = rk.ControlInterface.Velocity
    else:
        inp.target_position = [target]
    inp.current_position, inp.current_velocity, inp.current_acceleration = [start.position], [start.velocity], [
        start.acceleration]
    inp.target_velocity, inp.target_acceleration = [0.0], [0.0]
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = (
        [shrink * limits.at_rocker(k)] for k, shrink in zip((1, 2, 3), PLAN_SHRINKS, strict=True))
    trajectory = rk.Trajectory(1)
    result = rk.Ruckig(1).calculate(inp, trajectory)
    return (trajectory, '') if result in (rk.Result.Working, rk.Result.Finished) else (None, str(result))


def plan_motion(start: JointMotionState, target: float, limits: JointLimits) -> Plan:
    """The time-optimal jerk-limited motion from ``start`` to rest at ``target`` (rad), within ``limits``.

    Raises TrajectoryError (one line) for a non-finite state or target, or if ruckig finds no profile.
    """
    values = (start.position, start.velocity, start.acceleration, target)
    if not all(math.isfinite(v) for v in values):
        raise TrajectoryError(f'non-finite motion input: start {start}, target {target!r} rad')
    trajectory, failed = _solved(start, limits, target)
    if failed:
        raise TrajectoryError(f'no motion from {start} to {target!r} rad within the limits: ruckig says {failed}')
    return Plan(trajectory)


def plan_stop(start: JointMotionState, limits: JointLimits) -> Plan:
    """The time-optimal jerk-limited stop from ``start``: to rest (velocity and acceleration 0) as soon as
    ``limits`` allow, wherever that is (ruckig's velocity interface; the plan's end is the stopping position, rad).
    The same limits' margins as ``plan_motion`` (PLAN_SHRINKS). From rest it is a plan of no duration there.

    Raises TrajectoryError (one line) for a non-finite state, or if ruckig finds no profile.
    """
    values = (start.position, start.velocity, start.acceleration)
    if not all(math.isfinite(v) for v in values):
        raise TrajectoryError(f'non-finite motion input: start {start}')
    trajectory, failed = _solved(start, limits, None)
    if failed:
        raise TrajectoryError(f'no stop from {start} within the limits: ruckig says {failed}')
    return Plan(trajectory, extrema=False)


def plan_to_angle(cfg: AntennaConfig, limits: JointLimits, start: JointMotionState, theta: float) -> Plan:
    """The motion to antenna angle theta (rad, within [theta_min, theta_max]) from the driven-joint state ``start``.

    Raises UnreachableError for theta outside the range (the caller applies its reject/clamp policy first) or when
    the motion would pass beyond the range on the way (the drive cannot stop in time from its current velocity).
    """
    if not cfg.theta_min <= theta <= cfg.theta_max:
        raise UnreachableError(f'theta = {theta!r} rad is outside [theta_min, theta_max] = '
                               f'[{cfg.theta_min!r}, {cfg.theta_max!r}] rad')
    # One evaluation per angle: the range's ends and the target come from the same solve of the same value, so a
    # command at theta_min or theta_max has the range's own end as its target.
    ends = driven_angles(cfg, np.array([cfg.theta_min, cfg.theta_max]))
    q_target = float(ends[0] if theta == cfg.theta_min else ends[1] if theta == cfg.theta_max
                     else driven_angles(cfg, np.array([theta]))[0])
    plan = plan_motion(start, q_target, limits)
    lo, hi = plan.position_range()
    q_lo, q_hi = sorted((float(ends[0]), float(ends[1])))
    slack = range_slack(q_lo, q_hi)
    if lo < q_lo - slack or hi > q_hi + slack:
        raise UnreachableError(
            f'the motion to theta = {theta!r} rad passes the driven joint through [{lo!r}, {hi!r}] rad, beyond '
            f'its range [{q_lo!r}, {q_hi!r}] rad for [theta_min, theta_max]: it cannot stop in time')
    return plan


def driven_angles(cfg: AntennaConfig, theta: FloatArray) -> FloatArray:
    """The driven rocker's angles (rad) at antenna angles theta (rad)."""
    angles = cfg.linkage.rocker_angles(theta, cfg.branch)
    return np.asarray(angles.gamma if cfg.driven is Driven.GAMMA else angles.delta)


def sample_grid(duration: float, step: float) -> FloatArray:
    """0, step, 2 step, ... and the end (s); a grid time within step / 2 of the end gives way to the end."""
    if duration <= 0.0:
        return np.zeros(1)
    t = np.arange(math.floor(duration / step) + 1) * step
    return np.append(t[t < duration - 0.5 * step], duration) if duration > 0.5 * step else np.array([0.0, duration])


def stream_grid(duration: float, step: float) -> FloatArray:
    """0, step, 2 step, ... up to the first at or after the end (s): a setpoint stream one step apart throughout,
    so that a controller taking one setpoint per period sees the motion's own differences (an irregular last step
    published one period after the one before it passed the jerk limit by 1.6x)."""
    return np.arange(max(math.ceil(duration / step), 0) + 1, dtype=np.float64) * step


def min_segment(limits: JointLimits, q_scale: float) -> float:
    """The shortest segment (s) between two points of a plan: the positions on the wire are doubles, each within
    half an ulp of the plan (ruckig's evaluation adds about as much), and the controller's quintic takes its jerk
    from them as 60 dp / h^3 (``splines.hermite_coefficients``): over 4 ulps of the largest |position| q_scale
    (rad), h^3 >= 240 ulp(q_scale) / (margin J) keeps that rounding within a quarter of the margin 1 - PLAN_SHRINK
    left under the rocker's jerk limit J (0.5 to 0.65 ms with the defaults)."""
    margin = (1.0 - PLAN_SHRINK) * limits.at_rocker(3)
    return float(np.cbrt(240.0 * math.ulp(q_scale) / margin))


#: A segment may hold jerk changes (phase boundaries that are not points) when they all lie in its first or all in
#: its last END_SPAN of its length: the quintic's jerk at each end is then an average, with weights >= 0 summing to 1,
#: of the profile's jerk over the segment (the weights at s = 0 are 30 s^2 - 36 s + 9 per unit of s, those at s = 1 the
#: same in 1 - s; both are >= 0 on [0, END_SPAN] and [1 - END_SPAN, 1]), so it stays within the limit the profile
#: keeps. A segment with changes further inside can overshoot the jerk at its ends by up to 1.375 times the step.
END_SPAN = (4.0 - math.sqrt(6.0)) / 10.0


def _point_times(grid: FloatArray, switches: FloatArray, gap: float, shortest: float) -> FloatArray:
    """The grid (s, from 0 to the end) with the switch times added, no two points within ``shortest`` (s, <= gap).

    A switch time within ``shortest`` of the previous point kept (0 or a switch) is left out: that point then leads a
    cluster, and the next point follows at least the cluster's extent / END_SPAN after it (grid times before are left
    out, and a switch time there joins the cluster). The switch times within ``shortest`` of the end form the end's
    cluster the same way, backwards; a cluster that would overlap it joins it. So every jerk change that is not a
    point lies in the first or the last END_SPAN of its segment (only a plan that is one cluster from 0 to the end
    cannot be cut so). Grid times within ``gap`` of a point that is not on the grid give way to it."""
    end = float(grid[-1])
    leads: list[list[float]] = [[0.0, 0.0]]  # [time of a point, extent of the cluster it leads] (s)
    back = 0.0  # extent of the end's cluster (s)
    for t in np.unique(switches).tolist():
        if t >= end - shortest:
            back = max(back, end - t)
        elif t - leads[-1][0] <= max(shortest, leads[-1][1] / END_SPAN):
            leads[-1][1] = t - leads[-1][0]
        else:
            leads.append([t, 0.0])
    while len(leads) > 1 and leads[-1][0] + leads[-1][1] / END_SPAN > end - back / END_SPAN:
        back = end - leads.pop()[0]
    points = [t for t, _ in leads] + [end]
    for bound in sorted([t + extent / END_SPAN for t, extent in leads if extent > 0.0]
                        + ([end - back / END_SPAN] if back > 0.0 else [])):
        if 0.0 < bound < end and min(abs(bound - p) for p in points) >= shortest:
            points.append(bound)
    zones = [(t, t + extent / END_SPAN) for t, extent in leads] + [(end - back / END_SPAN, end)]
    inside = np.zeros(grid.size, dtype=bool)
    for lo, hi in zones:
        inside |= (grid > lo) & (grid < hi)
    fixed = np.array(points)
    near = np.abs(grid[:, None] - fixed[None, :]).min(axis=1) <= gap
    near[0] = near[-1] = False
    return np.unique(np.concatenate([grid[~(near | inside)], fixed]))


def trajectory_points(cfg: AntennaConfig, limits: JointLimits, plan: Plan, spacing: float) -> DrivenTrajectory:
    """The plan as trajectory points ``spacing`` s apart plus its phase boundaries (the end included): positions,
    velocities, accelerations (quintic segments for the controller, each on one cubic piece of the profile) and the
    static effort at each pose; the antenna path beside them.

    Every point and segment is checked against the limits (``worst_violation``, the interpolated motion between the
    points included; a segment over them is first split at its phase boundaries): LimitError names the worst one,
    e.g. a pose needing more torque than the motor or the reducer gives, or a start state already over a limit. No
    two points are within ``min_segment`` (or spacing / 2, if less) of each other; a phase shorter than that leaves a
    boundary out, and the segment holding it is made long enough that it lies in the segment's first or last END_SPAN
    (``_point_times``), so the quintic's jerk at the points stays within the profile's. A plan shorter than that (the
    drive already within rounding of the target) becomes one segment of that length from the start state to the target
    at rest. Raises TrajectoryError for a spacing that is not positive or that gives more than max_trajectory_points.
    """
    if not (math.isfinite(spacing) and spacing > 0.0):
        raise TrajectoryError(f'point spacing {spacing!r} s must be finite and positive')
    if plan.duration / spacing + 2 > cfg.max_trajectory_points:
        raise TrajectoryError(f'a {plan.duration:.6g} s motion at {spacing!r} s spacing exceeds '
                              f'max_trajectory_points = {cfg.max_trajectory_points}')
    lo, hi = plan.position_range()
    shortest = min(min_segment(limits, max(abs(lo), abs(hi))), 0.5 * spacing)
    if plan.duration < shortest:
        times = on_wire(np.array([0.0, shortest]))
    else:
        times = on_wire(_point_times(sample_grid(plan.duration, spacing), plan.switch_times(), 0.5 * spacing, shortest))
    out = _sampled(cfg, plan, times)
    over = worst_violation(out, limits, cfg)
    if over is not None and over.where != 'point':
        # A segment holding a phase boundary (left out for being within ``shortest`` of a point) can pass a limit
        # between its points; split it at its boundaries at least SWITCH_FLOOR from its points: the pieces then
        # follow single cubic pieces of the profile, which the quintics reproduce.
        bad = np.zeros(len(out) - 1, dtype=bool)
        for order, m in segment_magnitudes(out).items():
            bad |= over_at_rocker(m, limits, order)
        switches = on_wire(plan.switch_times())
        i = np.clip(np.searchsorted(times, switches, side='right') - 1, 0, len(times) - 2)
        keep = bad[i] & (switches - times[i] >= SWITCH_FLOOR) & (times[i + 1] - switches >= SWITCH_FLOOR)
        if keep.any():
            times = np.unique(np.concatenate([times, switches[keep]]))
            out = _sampled(cfg, plan, times)
            over = worst_violation(out, limits, cfg)
    if over is not None:
        raise LimitError(over.describe())
    return out


def _sampled(cfg: AntennaConfig, plan: Plan, times: FloatArray) -> DrivenTrajectory:
    """The plan's states at ``times`` (s, on the wire) with the static effort at each pose and the antenna path."""
    q, q_dot, q_ddot = plan.sample(np.minimum(times, plan.duration))
    return rocker_states(cfg, times, q, q_dot, q_ddot, SplineKind.QUINTIC)


def rocker_states(cfg: AntennaConfig, times: FloatArray, q: FloatArray, q_dot: FloatArray, q_ddot: FloatArray,
                  kind: SplineKind, antenna_rates: bool = False) -> DrivenTrajectory:
    """Driven-joint states (rad, rad/s, rad/s^2 at ``times`` s) as a trajectory of ``kind`` (the fields it
    carries), with the static effort at each pose and the antenna path: theta, and with ``antenna_rates`` its rates
    where the kind has them (theta_dot = q_dot / q', theta_ddot = (q_ddot - q'' theta_dot^2) / q')."""
    theta_a, other_a = cfg.linkage.from_rocker(q, cfg.driven, cfg.measured_branch)
    theta, other = np.asarray(theta_a), np.asarray(other_a)
    gamma, delta = (q, other) if cfg.driven is Driven.GAMMA else (other, q)
    rates = cfg.linkage.rates_at(theta, gamma, delta)
    g1 = np.asarray(rates.dgamma_dtheta)
    q1 = g1 if cfg.driven is Driven.GAMMA else np.asarray(rates.ddelta_dtheta)
    efforts = static_efforts(cfg, theta, gamma, g1, q1)
    if kind is SplineKind.LINEAR or not antenna_rates:
        v, a = (None, None) if kind is SplineKind.LINEAR else (q_dot, q_ddot if kind is SplineKind.QUINTIC else None)
        return DrivenTrajectory(times, q, v, a, efforts, AntennaTrajectory(times, theta))
    theta_dot = q_dot / q1
    if kind is SplineKind.CUBIC:
        return DrivenTrajectory(times, q, q_dot, None, efforts, AntennaTrajectory(times, theta, theta_dot))
    q2 = np.asarray(cfg.linkage.second_derivative_at(theta, gamma, delta, rates, cfg.driven))
    theta_ddot = (q_ddot - q2 * theta_dot * theta_dot) / q1
    return DrivenTrajectory(times, q, q_dot, q_ddot, efforts, AntennaTrajectory(times, theta, theta_dot, theta_ddot))


def setpoints(cfg: AntennaConfig, plan: Plan, rate: float | None = None) -> Setpoints:
    """The plan's positions at ``rate`` Hz (default: the configured control_rate), from 0 to the end included."""
    hz = cfg.control_rate if rate is None else rate
    if not (math.isfinite(hz) and hz > 0.0):
        raise TrajectoryError(f'control rate {hz!r} Hz must be finite and positive')
    if plan.duration * hz + 2 > cfg.max_trajectory_points:
        raise TrajectoryError(f'a {plan.duration:.6g} s motion at {hz!r} Hz exceeds '
                              f'max_trajectory_points = {cfg.max_trajectory_points} setpoints')
    times = stream_grid(plan.duration, 1.0 / hz)
    return Setpoints(times, plan.sample(np.minimum(times, plan.duration))[0])
