"""Motor and reducer limits, checked at every point of a driven-joint trajectory; reject or retime.

The motor's limits over the reducer ratio, checked over each interpolating segment, not only at the points;
retiming and what it leaves unchanged: docs/explanation/motion.md."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
import numpy.typing as npt

from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.core.loads import motor_torque
from fourbar_ros.core.numeric import FloatArray
from fourbar_ros.motion.errors import LimitError
from fourbar_ros.motion.splines import derivatives_at, hermite_coefficients, segment_extremes
from fourbar_ros.motion.trajectory import DrivenTrajectory, SplineKind

__all__ = ['RANGE_ULPS', 'JointLimits', 'LimitPolicy', 'Violation', 'enforce_limits', 'over_at_rocker',
           'range_slack', 'segment_magnitudes', 'worst_violation']

LimitPolicy = Literal['reject', 'retime']

#: Relative step added to the retiming factor when rounding leaves a point a few ulps over a limit.
_RETIME_NUDGE = 8.0 * math.ulp(1.0)

#: How far (in ulps of the range's larger end) a position may pass an end of the driven joint's range and still be
#: at that end: a motion that ends exactly there passes it by its own rounding (ruckig's extrema, a spline's
#: evaluation at its end point, a conversion of the end's angle), a few ulps.
RANGE_ULPS = 16


def range_slack(lower: float, upper: float) -> float:
    """The slack (rad) of "at an end" of the range [lower, upper] rad: ``RANGE_ULPS`` ulps of its larger end."""
    return RANGE_ULPS * math.ulp(max(abs(lower), abs(upper)))


@dataclass(frozen=True)
class JointLimits:
    """Motor limits as configured: speed rad/s, acceleration rad/s^2, jerk rad/s^3 at the motor, the reducer ratio,
    the motor's torque limit (N m, motor side) and the reducer's rated torque (N m, at the driven rocker)."""

    ratio: float
    motor_speed: float
    motor_acceleration: float
    motor_jerk: float
    motor_torque: float
    output_torque: float

    @classmethod
    def from_config(cls, cfg: AntennaConfig) -> JointLimits:
        """The configuration's limits."""
        return cls(cfg.reduction, cfg.motor_speed_limit, cfg.motor_acceleration_limit, cfg.motor_jerk_limit,
                   cfg.motor_torque_limit, cfg.output_torque_limit)

    def at_rocker(self, order: int) -> float:
        """The limit on the driven rocker's order-th time derivative (1 velocity rad/s, 2 acceleration rad/s^2,
        3 jerk rad/s^3): the motor's divided by the ratio."""
        return self.motor(order) / self.ratio

    def motor(self, order: int) -> float:
        """The motor's limit on its order-th time derivative (1 speed, 2 acceleration, 3 jerk)."""
        return (self.motor_speed, self.motor_acceleration, self.motor_jerk)[order - 1]


@dataclass(frozen=True)
class Violation:
    """The worst place over a limit: the point (torque) or the segment starting at that point (motion), its time
    (s), the quantity, its value and limit (motor side for the motor's quantities), and the ratio value / limit."""

    index: int
    time: float
    quantity: str
    unit: str
    value: float
    limit: float
    where: str = 'point'  #: 'point', or 'segment from point' for motion between points

    @property
    def ratio(self) -> float:
        return self.value / self.limit

    def describe(self) -> str:
        """One line: which point, what, by how much."""
        return (f'{self.where} {self.index} (t = {self.time:.6g} s): {self.quantity} {self.value:.6g} {self.unit} '
                f'exceeds its limit {self.limit:.6g} {self.unit} by {self.value - self.limit:.3g} {self.unit} '
                f'({100.0 * (self.ratio - 1.0):.3g}%)')


def _per_point(n: int, start: FloatArray, end: FloatArray) -> FloatArray:
    """Largest |value| at each point from the segments starting and ending there (one-sided values)."""
    out = np.zeros(n)
    out[:-1] = np.abs(start)
    out[1:] = np.maximum(out[1:], np.abs(end))
    return out


def point_magnitudes(traj: DrivenTrajectory) -> dict[int, FloatArray]:
    """Derivative order (1 velocity, 2 acceleration, 3 jerk) -> |rocker quantity| at each point, as the controller's
    segments reach it from either side (orders the trajectory's kind does not bound are left out)."""
    n = len(traj)
    kind = traj.kind
    orders = (1,) if kind is SplineKind.LINEAR else (1, 2, 3)
    if n == 1:  # no segment: only what the point carries
        given = {1: traj.velocities, 2: traj.accelerations}
        return {k: np.abs(v) for k, v in given.items() if v is not None}
    coefficients = hermite_coefficients(traj.times, traj.positions, traj.velocities, traj.accelerations)
    return {k: _per_point(n, *derivatives_at(traj.times, coefficients, k)) for k in orders}


_QUANTITIES = {1: ('motor speed', 'rad/s'), 2: ('motor acceleration', 'rad/s^2'), 3: ('motor jerk', 'rad/s^3')}


def _worst(traj: DrivenTrajectory, quantity: str, unit: str, values: FloatArray, limit: float,
           where: str = 'point') -> Violation | None:
    i = int(np.argmax(values))
    if not values[i] > limit:
        return None
    return Violation(i, float(traj.times[i]), quantity, unit, float(values[i]), limit, where)


def torque_violation(traj: DrivenTrajectory, limits: JointLimits, cfg: AntennaConfig) -> Violation | None:
    """The worst point whose static torque exceeds the motor's limit or the reducer's rated torque, if any."""
    effort = np.abs(traj.efforts)
    found = [_worst(traj, 'motor torque', 'N m', np.abs(motor_torque(cfg, effort)), limits.motor_torque),
             _worst(traj, 'reducer output torque', 'N m', effort, limits.output_torque)]
    return max((v for v in found if v is not None), key=lambda v: v.ratio, default=None)


def segment_magnitudes(traj: DrivenTrajectory) -> dict[int, FloatArray]:
    """Derivative order (1 velocity, 2 acceleration, 3 jerk) -> the largest |rocker quantity| over each segment the
    controller interpolates (closed form; orders the trajectory's kind does not bound are left out). A trajectory
    of one point has no segment: the values it carries."""
    if len(traj) == 1:
        return point_magnitudes(traj)
    orders = (1,) if traj.kind is SplineKind.LINEAR else (1, 2, 3)
    coefficients = hermite_coefficients(traj.times, traj.positions, traj.velocities, traj.accelerations)
    return {k: segment_extremes(traj.times, coefficients, k) for k in orders}


def over_at_rocker(values: FloatArray, limits: JointLimits, order: int) -> npt.NDArray[np.bool_]:
    """Where rocker values (|order-th derivative|, rad/s^order) are over the motor's limit on it, judged at the
    rocker against ``at_rocker(order)``, the double nearest motor / ratio (IEEE division is correctly rounded).

    A double v passes iff v <= fl(motor / ratio): every v within the real limit passes (rounding is monotonic) and
    none passes beyond it by more than half an ulp of the rocker's limit, the float's own resolution there. A value
    derived from the limit (ruckig's limits, ``motion_start``'s clamp, a start at the limit) is within it to the
    bit. Judged at the motor instead, ratio * v rounds once more and such a value comes out an ulp over
    (31.41592653589793 rad/s by 3.55e-15 rad/s with the defaults)."""
    over: npt.NDArray[np.bool_] = values > limits.at_rocker(order)
    return over


def motion_violations(traj: DrivenTrajectory, limits: JointLimits) -> list[tuple[int, Violation]]:
    """(derivative order, the worst segment over the motor's limit on it, ``over_at_rocker``) for each order over
    its limit; the violation's value and limit are motor side."""
    out = []
    for order, values in segment_magnitudes(traj).items():
        i = int(np.argmax(values))
        if over_at_rocker(values[i:i + 1], limits, order)[0]:
            out.append((order, Violation(i, float(traj.times[i]), *_QUANTITIES[order],
                                         limits.ratio * float(values[i]), limits.motor(order),
                                         'point' if len(traj) == 1 else 'segment from point')))
    return out


def worst_violation(traj: DrivenTrajectory, limits: JointLimits, cfg: AntennaConfig) -> Violation | None:
    """The point furthest over any limit (largest value / limit), or None when every point is within them."""
    found = [*(v for _, v in motion_violations(traj, limits)), torque_violation(traj, limits, cfg)]
    return max((v for v in found if v is not None), key=lambda v: v.ratio, default=None)


def enforce_limits(traj: DrivenTrajectory, limits: JointLimits, cfg: AntennaConfig,
                   policy: LimitPolicy) -> DrivenTrajectory:
    """``traj`` if every point is within the limits; else, by policy, LimitError naming the worst point ('reject'),
    or the trajectory retimed by the smallest factor k >= 1 that brings speed (1/k), acceleration (1/k^2) and jerk
    (1/k^3) within them ('retime'). A torque over its limit is rejected under both policies (time cannot change a
    static torque). The returned trajectory has been checked point by point."""
    torque = torque_violation(traj, limits, cfg)
    if torque is not None:
        raise LimitError(f'{torque.describe()}; a static torque does not depend on timing')
    motion = motion_violations(traj, limits)
    if not motion:
        return traj
    if policy == 'reject':
        raise LimitError(max((v for _, v in motion), key=lambda v: v.ratio).describe())
    # Over at the rocker, ratio * value may round to the motor's limit itself (a ratio of 1): never below 1.
    k = max(1.0, *(v.ratio ** (1.0 / order) for order, v in motion))
    for attempt in range(8):  # rounding (of the values, of the times to ns) may leave a point just over: again
        out = traj.scaled_in_time(k)
        left = motion_violations(out, limits)
        if not left:
            return out
        # Times go on the wire in whole ns, which moves a segment's dp/h by up to 0.5 ns / h: add that much too.
        wire = 0.5e-9 / float(np.min(np.diff(out.times))) if len(out) > 1 else 0.0
        k *= max(1.0, *(v.ratio ** (1.0 / order) for order, v in left)) * (
            1.0 + _RETIME_NUDGE * 2.0 ** attempt + 2.0 * wire)
    raise LimitError(f'retiming by {k:.6g} left {left[0][1].describe()}')  # pragma: no cover - rounding only
