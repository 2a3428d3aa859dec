"""Trajectories as plain arrays, their validation, and the antenna-to-driven-joint conversion.

The conversion and how the arrays a trajectory carries decide its interpolation: docs/explanation/motion.md."""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, replace

import numpy as np

from fourbar_ros.config.antenna_config import AntennaConfig
from fourbar_ros.core.antenna import Driven
from fourbar_ros.core.errors import UnreachableError
from fourbar_ros.core.loads import has_gravity_load
from fourbar_ros.core.loads import load_torque as total_load_torque
from fourbar_ros.core.numeric import FloatArray
from fourbar_ros.motion.errors import (
    EmptyTrajectoryError,
    NotFiniteError,
    TimeNotIncreasingError,
    TooManyPointsError,
    TrajectoryError,
)

__all__ = ['AntennaTrajectory', 'DrivenTrajectory', 'SplineKind', 'antenna_trajectory', 'check_tilt_range',
           'check_times', 'on_wire', 'static_efforts', 'to_driven']


def on_wire(times: FloatArray) -> FloatArray:
    """Times (s) rounded to whole nanoseconds, as a ``builtin_interfaces/Duration`` carries them. Every time this
    package computes for a point (a plan's samples, refinement's midpoints, a retimed trajectory) is on the wire
    before the point's values are computed or checked: a controller's quintic takes its jerk from positions over
    h^3, so a time moved by rounding on the wire (0.5 ns) would move the jerk by about 1% at 10 ms segments."""
    out: FloatArray = np.round(times * 1e9) / 1e9
    return out



class SplineKind(enum.IntEnum):
    """How joint_trajectory_controller interpolates between points; the value is the polynomial degree."""

    LINEAR = 1  #: positions only
    CUBIC = 3  #: positions and velocities
    QUINTIC = 5  #: positions, velocities and accelerations


@dataclass(frozen=True)
class AntennaTrajectory:
    """A validated antenna trajectory (build it with ``antenna_trajectory``): times s, theta rad, theta_dot rad/s,
    theta_ddot rad/s^2 (None where not given). Arrays are float64, one element per point."""

    times: FloatArray
    theta: FloatArray
    theta_dot: FloatArray | None = None
    theta_ddot: FloatArray | None = None

    @property
    def kind(self) -> SplineKind:
        """The controller's interpolation for this trajectory's fields."""
        return _kind(self.theta_dot, self.theta_ddot)

    def __len__(self) -> int:
        return int(self.times.size)


@dataclass(frozen=True)
class DrivenTrajectory:
    """A driven-joint trajectory: times s, positions rad, velocities rad/s and accelerations rad/s^2 (None where not
    given), efforts N m (the static input torque, a feed-forward). ``antenna`` is the path it follows."""

    times: FloatArray
    positions: FloatArray
    velocities: FloatArray | None
    accelerations: FloatArray | None
    efforts: FloatArray
    antenna: AntennaTrajectory

    @property
    def kind(self) -> SplineKind:
        """The controller's interpolation for this trajectory's fields."""
        return _kind(self.velocities, self.accelerations)

    def __len__(self) -> int:
        return int(self.times.size)

    def scaled_in_time(self, k: float) -> DrivenTrajectory:
        """The same path k times slower (k > 0): times * k (``on_wire``), velocities / k, accelerations / k^2,
        efforts unchanged."""
        a = self.antenna
        times = on_wire(self.times * k)
        antenna = AntennaTrajectory(times, a.theta, _div(a.theta_dot, k), _div(a.theta_ddot, k * k))
        return replace(self, times=times, velocities=_div(self.velocities, k),
                       accelerations=_div(self.accelerations, k * k), antenna=antenna)


def _div(x: FloatArray | None, k: float) -> FloatArray | None:
    return None if x is None else x / k


def _kind(velocities: FloatArray | None, accelerations: FloatArray | None) -> SplineKind:
    if velocities is None:
        return SplineKind.LINEAR
    return SplineKind.CUBIC if accelerations is None else SplineKind.QUINTIC


def _as_array(name: str, values: object, n: int | None) -> FloatArray:
    try:
        a = np.array(values, dtype=np.float64, ndmin=1)
    except (TypeError, ValueError):
        raise TrajectoryError(f'{name}: not a sequence of numbers') from None
    if a.ndim != 1:
        raise TrajectoryError(f'{name}: expected one value per point, got an array of shape {a.shape}')
    if n is not None and a.size != n:
        raise TrajectoryError(f'{name}: {a.size} values for {n} points')
    bad = ~np.isfinite(a)
    if bad.any():
        i = int(np.argmax(bad))
        raise NotFiniteError(f'{name}[{i}] = {float(a[i])!r} is not finite')
    return a


def check_times(times: FloatArray) -> None:
    """Raise TrajectoryError unless times (s) are finite, >= 0 and strictly increasing."""
    if times.size and times[0] < 0.0:
        raise TimeNotIncreasingError(f'times[0] = {float(times[0])!r} s is negative (times count from the start)')
    steps = np.diff(times)
    if steps.size and not (steps > 0.0).all():
        i = int(np.argmax(~(steps > 0.0))) + 1
        raise TimeNotIncreasingError(f'time not increasing at point {i}: t = {float(times[i])!r} s after '
                              f'{float(times[i - 1])!r} s')


def antenna_trajectory(cfg: AntennaConfig, times: object, theta: object, theta_dot: object | None = None,
                       theta_ddot: object | None = None) -> AntennaTrajectory:
    """Validate an antenna trajectory (times s, theta rad, theta_dot rad/s, theta_ddot rad/s^2) for ``cfg``.

    Raises TrajectoryError (empty, more than ``cfg.max_trajectory_points`` points, arrays of different lengths, a
    NaN or inf, time not increasing, accelerations without velocities) or UnreachableError (a theta outside
    [theta_min, theta_max]), each one line naming the first offending point. Nothing is returned partially.
    """
    t = _as_array('times', times, None)
    n = t.size
    if n == 0:
        raise EmptyTrajectoryError('empty trajectory: no points')
    if n > cfg.max_trajectory_points:
        raise TooManyPointsError(f'{n} points exceed max_trajectory_points = {cfg.max_trajectory_points}')
    th = _as_array('theta', theta, n)
    td = None if theta_dot is None else _as_array('theta_dot', theta_dot, n)
    tdd = None if theta_ddot is None else _as_array('theta_ddot', theta_ddot, n)
    if tdd is not None and td is None:
        raise TrajectoryError('accelerations without velocities: give theta_dot too (the controller would '
                              'interpolate linearly and ignore them)')
    check_times(t)
    check_tilt_range(cfg, th, t)
    return AntennaTrajectory(t, th, td, tdd)


def check_tilt_range(cfg: AntennaConfig, theta: FloatArray, times: FloatArray) -> None:
    """Raise UnreachableError naming the first theta (rad) outside [theta_min, theta_max]."""
    out = (theta < cfg.theta_min) | (theta > cfg.theta_max)
    if out.any():
        i = int(np.argmax(out))
        raise UnreachableError(
            f'point {i} (t = {float(times[i])!r} s): theta = {float(theta[i])!r} rad '
            f'({math.degrees(float(theta[i])):.6g} deg) is outside [theta_min, theta_max] = '
            f'[{cfg.theta_min!r}, {cfg.theta_max!r}] rad')


def static_efforts(cfg: AntennaConfig, theta: FloatArray, gamma: FloatArray, dgamma_dtheta: FloatArray,
                   dq_dtheta: FloatArray) -> FloatArray:
    """Static input torque (N m at the driven rocker, sense of increasing q) holding the configured load (N m about
    theta) at each solved pose: by power balance tau_in dq = tau_load dtheta, tau_in = tau_load / (dq/dtheta).

    dq/dtheta is the driven rocker's rate (the mechanical advantage): never zero inside a validated tilt range (the
    configuration has no dead point there). A constant load needs no more; a gravity load is evaluated point by
    point through the core's load model (``fourbar_ros.core.loads``, scalar).
    """
    if has_gravity_load(cfg):
        load: FloatArray | float = np.array([total_load_torque(cfg, float(t), float(g), float(r))
                                             for t, g, r in zip(theta, gamma, dgamma_dtheta, strict=True)])
    else:
        load = cfg.load_torque
    efforts: FloatArray = load / dq_dtheta
    return efforts


def to_driven(cfg: AntennaConfig, traj: AntennaTrajectory) -> DrivenTrajectory:
    """The driven-joint trajectory of a validated antenna trajectory: positions, velocities and accelerations by the
    chain rule through the core's exact derivatives (only those the input's fields call for), and the static effort.

    Vectorized: one position solve, both rates, the driven rocker's second derivative when accelerations are given.
    """
    link = cfg.linkage
    theta = traj.theta
    gamma, delta = link.rocker_angles(theta, cfg.branch)
    rates = link.rates_at(theta, gamma, delta)
    gamma_driven = cfg.driven is Driven.GAMMA
    positions = np.asarray(gamma if gamma_driven else delta)
    q1 = np.asarray(rates.dgamma_dtheta if gamma_driven else rates.ddelta_dtheta)
    velocities = accelerations = None
    if traj.theta_dot is not None:
        velocities = q1 * traj.theta_dot
        if traj.theta_ddot is not None:
            q2 = np.asarray(link.second_derivative_at(theta, gamma, delta, rates, cfg.driven))
            accelerations = q2 * traj.theta_dot * traj.theta_dot + q1 * traj.theta_ddot
    efforts = static_efforts(cfg, theta, np.asarray(gamma), np.asarray(rates.dgamma_dtheta), q1)
    return DrivenTrajectory(traj.times, positions, velocities, accelerations, efforts, traj)
