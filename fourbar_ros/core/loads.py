"""Loads on the antenna and torques along the drive: constant torque plus the antenna's weight. No ROS.

The load model and its sign convention: docs/reference/python.md."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple, Protocol, overload

import numpy as np

from fourbar_ros.core.antenna import AntennaLinkage, Branch, Driven, LinkageState
from fourbar_ros.core.numeric import ArrayLike, FloatArray, RealLike, RealScalar, real


class LoadSpec(Protocol):
    """What the load model reads (``fourbar_ros.config.antenna_config.AntennaConfig`` provides it; any object with these
    read-only attributes does)."""

    @property
    def linkage(self) -> AntennaLinkage:
        """The linkage (lengths in m)."""
    @property
    def driven(self) -> Driven:
        """The rocker the motor drives."""
    @property
    def branch(self) -> Branch:
        """The assembly branch."""
    @property
    def load_torque(self) -> float:
        """Constant load torque about theta (N m, +theta sense)."""
    @property
    def antenna_mass(self) -> float:
        """Antenna mass (kg); 0 for no weight."""
    @property
    def gravity(self) -> float:
        """Gravitational acceleration (m/s^2)."""
    @property
    def com_offset_along(self) -> float:
        """Centre of mass beyond the coupler's midpoint along B->C (m)."""
    @property
    def com_offset_normal(self) -> float:
        """Centre of mass off the coupler along its normal n (m)."""
    @property
    def reducer_ratio(self) -> float:
        """Reducer ratio, motor turns per rocker turn (dimensionless; negative for a reversed motor)."""
    @property
    def reducer_efficiency(self) -> float:
        """Reducer efficiency in (0, 1] (dimensionless)."""


def has_gravity_load(cfg: LoadSpec) -> bool:
    """True when the antenna weight adds an angle-dependent load (mass and gravity both positive)."""
    return cfg.antenna_mass > 0.0 and cfg.gravity > 0.0


@overload
def com_height_rate(cfg: LoadSpec, theta: float, gamma: float, dgamma_dtheta: float) -> float: ...
@overload
def com_height_rate(cfg: LoadSpec, theta: FloatArray, gamma: FloatArray, dgamma_dtheta: FloatArray) -> FloatArray: ...
@overload
def com_height_rate(cfg: LoadSpec, theta: RealLike, gamma: RealLike, dgamma_dtheta: RealLike) -> ArrayLike: ...


def com_height_rate(cfg: LoadSpec, theta: RealLike, gamma: RealLike, dgamma_dtheta: RealLike) -> ArrayLike:
    """d y_com / d theta (m/rad): how fast the antenna's centre of mass rises as theta grows. Real scalars (as
    the float of their value) take the math module's functions, arrays numpy's (element-wise the same operations)."""
    cos_gamma: ArrayLike
    cos_theta: ArrayLike
    sin_theta: ArrayLike
    if not (type(theta) is float and type(gamma) is float and type(dgamma_dtheta) is float):
        theta, gamma, dgamma_dtheta = real(theta), real(gamma), real(dgamma_dtheta)
    if not (isinstance(theta, float) and isinstance(gamma, float)):
        cos_gamma, cos_theta, sin_theta = np.cos(gamma), np.cos(theta), np.sin(theta)
    else:
        cos_gamma, cos_theta, sin_theta = math.cos(gamma), math.cos(theta), math.sin(theta)
    along = 0.5 * cfg.linkage.coupler + cfg.com_offset_along
    rate: ArrayLike = (cfg.linkage.rocker_ab * cos_gamma * dgamma_dtheta
                       - along * cos_theta - cfg.com_offset_normal * sin_theta)
    return rate


@overload
def gravity_torque(cfg: LoadSpec, theta: float, gamma: float, dgamma_dtheta: float) -> float: ...
@overload
def gravity_torque(cfg: LoadSpec, theta: FloatArray, gamma: FloatArray, dgamma_dtheta: FloatArray) -> ArrayLike: ...
@overload
def gravity_torque(cfg: LoadSpec, theta: RealLike, gamma: RealLike, dgamma_dtheta: RealLike) -> ArrayLike: ...


def gravity_torque(cfg: LoadSpec, theta: RealLike, gamma: RealLike, dgamma_dtheta: RealLike) -> ArrayLike:
    """Torque (N m, about theta, +theta sense) that holds the antenna's weight at this pose (0.0 without one)."""
    if not has_gravity_load(cfg):
        return 0.0
    return cfg.antenna_mass * cfg.gravity * com_height_rate(cfg, theta, gamma, dgamma_dtheta)


@overload
def load_torque(cfg: LoadSpec, theta: float, gamma: float, dgamma_dtheta: float) -> float: ...
@overload
def load_torque(cfg: LoadSpec, theta: FloatArray, gamma: FloatArray, dgamma_dtheta: FloatArray) -> ArrayLike: ...
@overload
def load_torque(cfg: LoadSpec, theta: RealLike, gamma: RealLike, dgamma_dtheta: RealLike) -> ArrayLike: ...


def load_torque(cfg: LoadSpec, theta: RealLike, gamma: RealLike, dgamma_dtheta: RealLike) -> ArrayLike:
    """Total load torque about theta (N m): the constant ``load_torque`` plus the gravity term; floats or
    arrays (element-wise)."""
    return cfg.load_torque + gravity_torque(cfg, theta, gamma, dgamma_dtheta)


def load_at_pose(cfg: LoadSpec, theta: RealLike, gamma: RealLike, delta: RealLike,
                 dgamma_dtheta: RealLike | None = None) -> ArrayLike:
    """The load torque about theta (N m) at a solved pose (theta, gamma, delta in rad); floats or arrays. The
    antenna's weight needs dgamma/dtheta: pass it if known, else it is computed (only then)."""
    if not has_gravity_load(cfg):
        return cfg.load_torque
    if dgamma_dtheta is None:
        dgamma_dtheta = cfg.linkage.rates_at(theta, gamma, delta).dgamma_dtheta
    return load_torque(cfg, theta, gamma, dgamma_dtheta)


def solve(cfg: LoadSpec, theta: RealScalar) -> LinkageState:
    """The whole linkage state at antenna angle theta (rad) under the configured load (the pose below plus the
    rates and the transmission angle). Raises the core's ``UnreachableError``/``DeadPointError`` for an angle the
    linkage cannot serve."""
    link = cfg.linkage
    theta = float(real(theta))
    gamma, delta = link.rocker_angles(theta, cfg.branch)
    rates = link.rates_at(theta, gamma, delta)
    load = load_at_pose(cfg, theta, gamma, delta, rates.dgamma_dtheta)
    advantage = rates.dgamma_dtheta if cfg.driven is Driven.GAMMA else rates.ddelta_dtheta
    return LinkageState(theta, gamma, delta, rates.dgamma_dtheta, rates.ddelta_dtheta, advantage,
                        link.torque_at(theta, gamma, delta, load, cfg.driven),
                        link.transmission_angle_at(theta, gamma, delta, cfg.driven))


class Pose(NamedTuple):
    """What a command publishes: rocker angles gamma, delta (rad) and the driven rocker's torque (N m)."""

    gamma: float
    delta: float
    input_torque: float


# The pose, one angle and many: the same core calls in the same order, on Python floats (math module) and on
# numpy arrays. They agree within the core's few-ulp bound (numpy's SIMD transcendentals against libm).

def pose_solver(cfg: LoadSpec) -> Callable[[RealScalar], Pose]:
    """``theta (rad) -> Pose`` with the configuration's lookups bound once (the node's per-command call). Raises
    the core's ``UnreachableError``/``DeadPointError`` for an angle the linkage cannot serve."""
    angles, torque_at = cfg.linkage.rocker_angles, cfg.linkage.torque_at
    branch, driven, constant = cfg.branch, cfg.driven, cfg.load_torque
    gravity = has_gravity_load(cfg)

    def solved_pose(theta: RealScalar) -> Pose:
        if type(theta) is not float:
            theta = float(real(theta))
        gamma, delta = angles(theta, branch)
        load = load_at_pose(cfg, theta, gamma, delta) if gravity else constant
        return Pose(float(gamma), float(delta), float(torque_at(theta, gamma, delta, load, driven)))

    return solved_pose


def pose(cfg: LoadSpec, theta: RealScalar) -> Pose:
    """The pose at one antenna angle theta (rad): ``pose_solver(cfg)(theta)``."""
    return pose_solver(cfg)(theta)


def poses(cfg: LoadSpec, theta: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """gamma, delta (rad) and the driven rocker's torque (N m) at each angle theta (rad): the pose on arrays, NaN
    where the core cannot solve (out of reach, a dead point)."""
    link = cfg.linkage
    theta = np.asarray(theta, dtype=np.float64)
    gamma, delta = link.rocker_angles(theta, cfg.branch, on_invalid='nan')
    with np.errstate(invalid='ignore'):  # an infinite theta gives NaN, as documented, not a RuntimeWarning
        load = load_at_pose(cfg, theta, gamma, delta)
    torque = np.asarray(link.torque_at(theta, gamma, delta, load, cfg.driven), dtype=np.float64)
    return np.asarray(gamma), np.asarray(delta), torque


@overload
def motor_torque(cfg: LoadSpec, input_torque: RealScalar) -> float: ...
@overload
def motor_torque(cfg: LoadSpec, input_torque: FloatArray) -> FloatArray: ...


def motor_torque(cfg: LoadSpec, input_torque: RealLike) -> ArrayLike:
    """Motor-side torque (N m) for a driven-rocker torque, driving through the reducer:
    input_torque / (reducer_ratio * reducer_efficiency), in the motor's own sense (a negative ratio, a reversed
    motor, flips the sign); real scalars or arrays. (Back-driven, the motor would need less.)"""
    return real(input_torque) / (cfg.reducer_ratio * cfg.reducer_efficiency)
