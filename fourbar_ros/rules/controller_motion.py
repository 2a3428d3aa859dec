"""What joint_trajectory_controller does with a trajectory over time, for one joint: the reference it follows.

Follows ros2_controllers' jazzy branch, topic interface, ``interpolation_method: splines``: docs/explanation/motion.md.
Times are float seconds from an origin the caller picks (e.g. the arrival): keep them small, not seconds since 1970."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from fourbar_ros.config.controllers import TrajectoryControllerSettings
from fourbar_ros.core.numeric import FloatArray
from fourbar_ros.motion.splines import evaluate, hermite_segments, segment_extremes

__all__ = ['ControllerPoint', 'Reference', 'controller_reference', 'lead_in_segment', 'motion_settings_problem',
           'segment_coefficients']

_DEGREE_COLUMNS = 6  # quintic: every segment's power-basis coefficients padded to six


@dataclass(frozen=True)
class ControllerPoint:
    """One trajectory point of one joint: time s from the trajectory's origin; position rad, velocity rad/s,
    acceleration rad/s^2, each None where the message leaves the field empty."""

    time: float
    position: float | None
    velocity: float | None = None
    acceleration: float | None = None


def segment_coefficients(h: float, a: ControllerPoint, b: ControllerPoint) -> FloatArray:
    """Power-basis coefficients in s = (t - t_a) / h of the controller's polynomial from ``a`` to ``b`` (positions
    given), padded to six: linear, cubic when both give velocities, quintic when both give accelerations too
    (``motion.splines.hermite_segments``)."""
    row: FloatArray = _coefficients([(replace(a, time=0.0), replace(b, time=h))])[0][0]
    return row


def _deduce(a: ControllerPoint, b: ControllerPoint, dt: float) -> tuple[ControllerPoint, ControllerPoint]:
    """``deduce_from_derivatives``: b's missing position (and velocity) by the trapezoid rule from a."""
    if b.position is not None:
        return a, b
    va = 0.0 if a.velocity is None else a.velocity
    vb = b.velocity
    aa = a.acceleration
    if vb is None:
        aa = 0.0 if aa is None else aa
        vb = va + (aa + (b.acceleration or 0.0)) * 0.5 * dt
    a = ControllerPoint(a.time, a.position, va, aa)
    return a, ControllerPoint(b.time, float(a.position) + (va + vb) * 0.5 * dt, vb, b.acceleration)  # type: ignore[arg-type]


def lead_in_segment(velocity_state: bool, measured_position: float, measured_velocity: float | None,
                    first: ControllerPoint) -> ControllerPoint:
    """The state the controller interpolates from at the takeover (time 0 of the lead-in): the measured position,
    the measured velocity with a velocity state interface (``velocity_state``), zero-filled velocity /
    acceleration where ``first`` gives one and the state lacks it."""
    velocity = measured_velocity if velocity_state else None
    if velocity is None and first.velocity is not None:
        velocity = 0.0
    acceleration = 0.0 if first.acceleration is not None else None
    return ControllerPoint(0.0, measured_position, velocity, acceleration)


@dataclass(frozen=True)
class Reference:
    """The controller's reference from ``takeover`` on (s): segments between ``knots`` (s, increasing) with
    power-basis ``coefficients`` (rad, one row per segment, s in [0, 1]) and their ``degrees`` (1, 3, 5); then
    ``hold`` (position rad, velocity rad/s) from the last knot on. ``lead_in`` says whether the first segment is the
    controller's own, from the measured state. ``period`` is the update period (s)."""

    takeover: float
    knots: FloatArray
    coefficients: FloatArray
    degrees: tuple[int, ...]
    hold: tuple[float, float]
    lead_in: bool
    period: float

    def sample(self, t: float) -> tuple[float, float, float]:
        """(position rad, velocity rad/s, acceleration rad/s^2) of the reference at time t (s; before the
        takeover: its value at the takeover)."""
        t = max(t, self.takeover)
        knots = self.knots
        if knots.size < 2 or t >= knots[-1]:
            return self.hold[0], self.hold[1], 0.0
        i = max(int(np.searchsorted(knots, t, side='right')) - 1, 0)
        h = float(knots[i + 1] - knots[i])
        s = np.array([[min(max((t - float(knots[i])) / h, 0.0), 1.0)]])
        c = self.coefficients[i:i + 1]
        p, v, a = (float(evaluate(c, s, k)[0, 0]) / h ** k for k in range(3))
        return p, v, a

    def command(self, update_time: float) -> float:
        """The position (rad) the update at ``update_time`` (s) writes: the reference one period ahead."""
        return self.sample(update_time + self.period)[0]

    def extremes(self) -> dict[int, float]:
        """Derivative order (1 velocity, 2 acceleration, 3 jerk) -> its largest magnitude over every segment from
        the takeover on (rad/s^k, closed form). A linear segment bounds the speed only (its acceleration is a step
        at each point); a segment wholly before the takeover is not followed and left out."""
        out = {1: 0.0, 2: 0.0, 3: 0.0}
        if self.knots.size < 2:
            return out
        followed = self.knots[1:] > self.takeover
        degrees = np.array(self.degrees)
        for order in out:
            rows = followed & (degrees > 1) if order > 1 else followed
            if rows.any():
                idx = np.flatnonzero(rows)
                h = self.knots[idx + 1] - self.knots[idx]
                values = segment_extremes(np.concatenate([[0.0], np.cumsum(h)]), self.coefficients[idx], order)
                out[order] = float(values.max())
        return out


def controller_reference(velocity_state: bool, points: Sequence[ControllerPoint], stamp: float | None,
                         takeover: float, measured_position: float, measured_velocity: float | None,
                         period: float) -> Reference:
    """The reference the controller follows for an accepted trajectory of ``points`` (times from its origin),
    stamped at ``stamp`` s (None: a zero stamp, the origin is the takeover), taken over at ``takeover`` s from the
    measured state (rad, rad/s or None; the velocity counts only with a velocity state interface,
    ``velocity_state``), with update period ``period`` s (module docstring)."""
    origin = takeover if stamp is None else stamp
    pts = [ControllerPoint(origin + p.time, p.position, p.velocity, p.acceleration) for p in points]
    first = pts[0]
    pairs: list[tuple[ControllerPoint, ControllerPoint]] = []
    lead_in = takeover < first.time
    if lead_in:
        before = lead_in_segment(velocity_state, measured_position, measured_velocity, first)
        before = ControllerPoint(takeover, before.position, before.velocity, before.acceleration)
        before, first = _deduce(before, first, first.time - takeover)
        pts[0] = first
        pairs.append((before, first))
    for i in range(len(pts) - 1):
        a, b = pts[i], pts[i + 1]
        if a.position is None:  # only the first point can lack one here, without a lead-in: no state to deduce from
            a = ControllerPoint(a.time, measured_position, a.velocity, a.acceleration)
        a, b = _deduce(a, b, b.time - a.time)
        pts[i], pts[i + 1] = a, b
        pairs.append((a, b))
    last = pts[-1]
    hold = (float(last.position if last.position is not None else measured_position), float(last.velocity or 0.0))
    if not pairs:
        return Reference(takeover, np.array([last.time]), np.zeros((0, _DEGREE_COLUMNS)), (), hold, lead_in, period)
    knots = np.array([a.time for a, _ in pairs] + [last.time])
    coefficients, degrees = _coefficients(pairs)
    return Reference(takeover, knots, coefficients, degrees, hold, lead_in, period)


def _coefficients(pairs: Sequence[tuple[ControllerPoint, ControllerPoint]]) -> tuple[FloatArray, tuple[int, ...]]:
    """The power-basis coefficients (padded to six) and the degree of the controller's polynomial from a to b over
    b.time - a.time, for every (a, b) pair (positions given; ``segment_coefficients``), a degree at a time."""
    fields = np.array([[0.0 if x is None else x for x in (a.time, a.position, a.velocity, a.acceleration, b.time,
                                                          b.position, b.velocity, b.acceleration)]
                       for a, b in pairs], dtype=np.float64)
    ta, pa, va, aa, tb, pb, vb, ab = fields.T
    h = tb - ta
    out = np.zeros((len(pairs), _DEGREE_COLUMNS))
    degrees = np.array([_degree(a, b) for a, b in pairs])
    cubic, quintic = degrees >= 3, degrees == 5
    for rows, fields_given in ((~cubic, 1), (cubic & ~quintic, 2), (quintic, 3)):
        if rows.any():
            given = [(va, vb), (aa, ab)][:fields_given - 1]
            c = hermite_segments(h[rows], pa[rows], pb[rows], *(x[rows] for pair in given for x in pair))
            out[rows, :c.shape[1]] = c
    return out, tuple(int(d) for d in degrees)


def _degree(a: ControllerPoint, b: ControllerPoint) -> int:
    if a.velocity is None or b.velocity is None:
        return 1
    return 3 if a.acceleration is None or b.acceleration is None else 5


def motion_settings_problem(settings: TrajectoryControllerSettings) -> str | None:
    """One line naming a controller setting that changes the motion in a way this model does not follow (the node
    refuses to start with it), or None. Modelled: splines, the state interfaces (velocity or not),
    allow_integration_in_goal_trajectories, allow_nonzero_velocity_at_trajectory_end, the tolerances."""
    if settings.interpolation_method != 'splines':
        return (f'{settings.name}.interpolation_method is {settings.interpolation_method!r}: the controller then '
                'jumps from point to point; give splines')
    if settings.interpolate_from_desired_state or settings.open_loop_control:
        key = 'interpolate_from_desired_state' if settings.interpolate_from_desired_state else 'open_loop_control'
        return (f'{settings.name}.{key} is true: the controller then starts a trajectory from its last command, '
                'not the measured state; set it false')
    if 'acceleration' in settings.state_interfaces:
        return (f'{settings.name}.state_interfaces has acceleration: the controller then starts from a measured '
                'acceleration; give [position] or [position, velocity]')
    if settings.speed_scaling:
        return (f'{settings.name}.speed_scaling is set: the controller then plays trajectories at a variable rate; '
                'leave it unset')
    if settings.cmd_timeout > 0.0:
        return (f'{settings.name}.cmd_timeout is {settings.cmd_timeout!r} s: the controller then stops a '
                'trajectory on its own; set it 0')
    # The controller checks the velocity at the goal only where it computes a velocity error (compute_error): with
    # a velocity state interface and a velocity or effort command interface.
    checks_velocity = 'velocity' in settings.state_interfaces and bool(
        {'velocity', 'effort'} & set(settings.command_interfaces))
    if checks_velocity and settings.stopped_velocity_tolerance != 0.01:
        return (f'{settings.name}.constraints.stopped_velocity_tolerance with a velocity state interface and a '
                'velocity or effort command interface changes when the controller holds; leave it at its default '
                '0.01 rad/s')
    if not math.isfinite(settings.goal_time):
        return f'{settings.name}.constraints.goal_time must be finite'
    return None
